//! The least-squares fit of docs/model.md §11: a grid start over the gap, Levenberg–Marquardt
//! on the exact sensitivities, intervals from the fit and, where they mislead, a profile of the
//! cost; identifiability from the Jacobian's conditioning and the flanks the run visits.

use super::data::Run;
use super::model::{Model, Simulation, DELTA_INDEX, K_INDEX, P, U0_INDEX};
use nalgebra::{DMatrix, DVector, SymmetricEigen};
use std::cell::Cell;

/// 97.5 % quantile of the standard normal: the 95 % two-sided interval.
const Z95: f64 = 1.959_963_984_540_054;
/// A change of u0 that grows by more than this over the run makes the run chaotic for a fit
/// by simulation (docs/model.md §11): 1e-9 of the gap would become 1e-3 of it.
pub const CHAOS_GROWTH: f64 = 1e6;

/// A weighted least-squares problem: the run, the model with its known values, the fitted
/// indices into [`NAMES`].
pub struct Problem<'a> {
    pub run: &'a Run,
    pub base: Model,
    pub fit: Vec<usize>,
    pub t0: f64,
    /// 1/σ per measured output.
    pub weights: Vec<f64>,
    pub evaluations: Cell<usize>,
}

/// One evaluation: the weighted cost ½‖r‖² and, with sensitivities, JᵀJ and Jᵀr over `cols`.
pub struct Evaluation {
    pub cost: f64,
    pub jtj: DMatrix<f64>,
    pub jtr: DVector<f64>,
    pub sim: Simulation,
    /// Sum of squared unweighted residuals per output.
    pub ssr: Vec<f64>,
}

impl Problem<'_> {
    fn model(&self, theta: &[f64; P], sens: Vec<usize>) -> Model {
        let mut m = self.base.clone();
        m.theta = *theta;
        m.sens = sens;
        m
    }

    /// The cost at `theta`, with the sensitivities of `cols` (indices into NAMES) when not empty.
    pub fn evaluate(&self, theta: &[f64; P], cols: &[usize]) -> Result<Evaluation, String> {
        self.evaluations.set(self.evaluations.get() + 1);
        let mut sens = cols.to_vec();
        if !cols.is_empty() && !sens.contains(&U0_INDEX) {
            sens.push(U0_INDEX); // for the chaos test
        }
        let sim = self
            .model(theta, sens)
            .simulate(&self.run.inputs, self.run.step, self.t0)?;
        let m = cols.len();
        let mut jtj = DMatrix::zeros(m, m);
        let mut jtr = DVector::zeros(m);
        let mut cost = 0.0;
        let mut ssr = vec![0.0; self.run.outputs.len()];
        let mut row = vec![0.0; m];
        for (o, (state, values)) in self.run.outputs.iter().enumerate() {
            let w = self.weights[o];
            for (k, meas) in values.iter().enumerate() {
                let r = meas - sim.states[k][*state];
                ssr[o] += r * r;
                cost += 0.5 * (w * r) * (w * r);
                if m > 0 {
                    for (j, rj) in row.iter_mut().enumerate() {
                        *rj = w * sim.sens[k][j][*state];
                    }
                    for a in 0..m {
                        jtr[a] += row[a] * w * r;
                        for b in 0..=a {
                            jtj[(a, b)] += row[a] * row[b];
                        }
                    }
                }
            }
        }
        for a in 0..m {
            for b in 0..a {
                jtj[(b, a)] = jtj[(a, b)];
            }
        }
        Ok(Evaluation {
            cost,
            jtj,
            jtr,
            sim,
            ssr,
        })
    }

    /// Keeps a step inside the parameters' ranges: inertias and stiffness > 0, frictions and Δ
    /// ≥ 0, u0 in [−g, g] (the run starts at rest inside the gap or on a flank).
    fn project(&self, old: &[f64; P], new: &mut [f64; P]) {
        for i in 0..P {
            match i {
                0 | 1 | K_INDEX if new[i] <= 0.0 => new[i] = 0.1 * old[i],
                2 | 3 | DELTA_INDEX if new[i] < 0.0 => new[i] = 0.0,
                _ => {}
            }
        }
        let g = self.base.clone().with_theta(new).g();
        new[U0_INDEX] = new[U0_INDEX].clamp(-g, g);
    }

    /// Levenberg–Marquardt over `cols` from `theta` (Marquardt's scaling by diag JᵀJ).
    pub fn levenberg_marquardt(&self, mut theta: [f64; P], cols: &[usize]) -> Result<([f64; P], Evaluation), String> {
        let mut current = self.evaluate(&theta, cols)?;
        let mut lambda = 1e-3;
        for _ in 0..60 {
            let m = cols.len();
            let mut accepted = false;
            for _ in 0..12 {
                let mut a = current.jtj.clone();
                for i in 0..m {
                    a[(i, i)] += lambda * current.jtj[(i, i)].max(1e-300);
                }
                let Some(step) = a.cholesky().map(|c| c.solve(&current.jtr)) else {
                    lambda *= 10.0;
                    continue;
                };
                let mut trial = theta;
                for (j, &i) in cols.iter().enumerate() {
                    trial[i] += step[j];
                }
                self.project(&theta, &mut trial);
                match self.evaluate(&trial, cols) {
                    Ok(e) if e.cost < current.cost => {
                        let gain = (current.cost - e.cost) / current.cost.max(f64::MIN_POSITIVE);
                        let moved = cols
                            .iter()
                            .all(|&i| (trial[i] - theta[i]).abs() <= 1e-10 * theta[i].abs().max(1e-300));
                        theta = trial;
                        current = e;
                        lambda = (lambda / 5.0).max(1e-12);
                        accepted = true;
                        if gain < 1e-12 || moved {
                            return Ok((theta, current));
                        }
                        break;
                    }
                    _ => lambda *= 8.0,
                }
            }
            if !accepted {
                break;
            }
        }
        Ok((theta, current))
    }
}

impl Model {
    pub fn with_theta(mut self, theta: &[f64; P]) -> Model {
        self.theta = *theta;
        self
    }
}

/// The start: a coarse grid over the half gap (and the stiffness, when fitted) and three
/// positions in the gap, costed by simulation without sensitivities; the best few points go on
/// to Levenberg–Marquardt. A local method does not find the gap from a bad guess (the cost is
/// flat in Δ while the gap is smaller than the run's lost motion and rough beyond it), so Δ's
/// candidates span the lost motion read from the data when angles (or speeds) of both sides are
/// measured, and three decades around the known value otherwise.
pub fn grid_start(p: &Problem, theta: [f64; P], lost_motion: Option<f64>) -> Result<Vec<[f64; P]>, String> {
    let alpha = p.base.clone().with_theta(&theta).g() / theta[DELTA_INDEX].max(f64::MIN_POSITIVE);
    let alpha = if alpha.is_finite() && alpha > 0.0 { alpha } else { 1.0 };
    let deltas: Vec<f64> = if !p.fit.contains(&DELTA_INDEX) {
        vec![theta[DELTA_INDEX]]
    } else {
        let top = match lost_motion {
            Some(l) if l > 0.0 => l / alpha,
            _ => 30.0 * theta[DELTA_INDEX].max(1e-12),
        };
        (0..8).map(|i| top * 10f64.powf(-3.0 * i as f64 / 7.0)).collect()
    };
    let stiffnesses: Vec<f64> = if p.fit.contains(&K_INDEX) {
        [0.5, 1.0, 2.0].iter().map(|f| f * theta[K_INDEX]).collect()
    } else {
        vec![theta[K_INDEX]]
    };
    let positions: &[f64] = if p.fit.contains(&U0_INDEX) {
        &[-0.9, 0.0, 0.9]
    } else {
        &[f64::NAN]
    };
    let mut scored: Vec<(f64, [f64; P])> = Vec::new();
    for &d in &deltas {
        for &k in &stiffnesses {
            for &pos in positions {
                let mut t = theta;
                t[DELTA_INDEX] = d;
                t[K_INDEX] = k;
                if pos.is_finite() {
                    t[U0_INDEX] = pos * alpha * d;
                }
                if let Ok(e) = p.evaluate(&t, &[]) {
                    scored.push((e.cost, t));
                }
            }
        }
    }
    if scored.is_empty() {
        return Err("no start on the grid gives a finite simulation".into());
    }
    scored.sort_by(|a, b| a.0.total_cmp(&b.0));
    // A finer scan of Δ around the best grid point (between its neighbours on the grid): the
    // basin of the true gap is narrow when the drive rattles through the gap many times. Its
    // best point joins the grid's two best as a third start.
    let mut starts: Vec<[f64; P]> = scored.iter().take(2).map(|(_, t)| *t).collect();
    if p.fit.contains(&DELTA_INDEX) && deltas.len() > 1 {
        let best = scored[0].1;
        let ratio = deltas[0] / deltas[1];
        let mut fine: Option<(f64, [f64; P])> = None;
        for i in 1..12 {
            let d = best[DELTA_INDEX] * ratio.powf(-1.0 + 2.0 * i as f64 / 12.0);
            for &pos in positions {
                let mut t = best;
                t[DELTA_INDEX] = d;
                if pos.is_finite() {
                    t[U0_INDEX] = pos * alpha * d;
                }
                if let Ok(e) = p.evaluate(&t, &[]) {
                    if fine.as_ref().is_none_or(|(c, _)| e.cost < *c) {
                        fine = Some((e.cost, t));
                    }
                }
            }
        }
        starts.extend(fine.map(|(_, t)| t));
    }
    Ok(starts)
}

/// An estimate with its interval and whether the data determine it.
#[derive(Clone, Debug, PartialEq)]
pub struct Estimate {
    pub name: usize,
    pub value: f64,
    pub ci95: Option<(f64, f64)>,
    pub identifiable: bool,
}

/// Linearised 95 % intervals from s² (JᵀJ)⁻¹ and the parameters the Jacobian does not
/// determine: the fitted columns scaled to unit length, an eigenvalue of their Gram matrix
/// below 1e-10 of the largest marks the parameters loading on its eigenvector.
pub fn intervals(
    fit: &[usize],
    theta: &[f64; P],
    e: &Evaluation,
    dof: usize,
    name: impl Fn(usize) -> &'static str,
) -> (Vec<Estimate>, Vec<(usize, String)>) {
    let m = fit.len();
    let s2 = 2.0 * e.cost / dof.max(1) as f64;
    // A column of zeros (the outputs do not depend on the parameter) keeps scale 1: its zero
    // eigenvalue then marks it below.
    let scale: Vec<f64> = (0..m)
        .map(|i| {
            let norm = e.jtj[(i, i)].sqrt();
            if norm > 0.0 && norm.is_finite() {
                norm
            } else {
                1.0
            }
        })
        .collect();
    let c = DMatrix::from_fn(m, m, |i, j| e.jtj[(i, j)] / (scale[i] * scale[j]));
    let eig = SymmetricEigen::new(c.clone());
    let top = eig.eigenvalues.max();
    let mut weak = vec![false; m];
    let mut reasons = Vec::new();
    for (k, &lam) in eig.eigenvalues.iter().enumerate() {
        if !(lam >= 1e-10 * top && top > 0.0) {
            let v = eig.eigenvectors.column(k);
            let involved: Vec<usize> = (0..m).filter(|&i| v[i].abs() > 0.1).collect();
            for &i in &involved {
                weak[i] = true;
            }
            let names: Vec<&str> = involved.iter().map(|&i| name(fit[i])).collect();
            for &i in &involved {
                let why = if involved.len() == 1 {
                    "the outputs of this run do not depend on it".to_string()
                } else {
                    format!(
                        "the sensitivities of {} are linearly dependent on this run",
                        names.join(", ")
                    )
                };
                reasons.push((fit[i], format!("{} is not determined by the data: {why}", name(fit[i]))));
            }
        }
    }
    // Covariance on the determined subspace (pseudo-inverse of the scaled Gram matrix).
    let mut cov = DMatrix::zeros(m, m);
    for (k, &lam) in eig.eigenvalues.iter().enumerate() {
        if lam >= 1e-10 * top && top > 0.0 {
            let v = eig.eigenvectors.column(k);
            cov += v * v.transpose() / lam;
        }
    }
    let estimates: Vec<Estimate> = (0..m)
        .map(|i| {
            let half = Z95 * (s2 * cov[(i, i)]).sqrt() / scale[i];
            let value = theta[fit[i]];
            Estimate {
                name: fit[i],
                value,
                ci95: (!weak[i] && half.is_finite()).then_some((value - half, value + half)),
                identifiable: !weak[i] && half.is_finite(),
            }
        })
        .collect();
    for e in &estimates {
        if !e.identifiable && !reasons.iter().any(|(i, _)| *i == e.name) {
            reasons.push((
                e.name,
                format!(
                    "{} is not determined by the data: the run carries no information on it",
                    name(e.name)
                ),
            ));
        }
    }
    (estimates, reasons)
}

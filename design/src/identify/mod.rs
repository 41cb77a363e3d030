//! Identification (docs/model.md §11): a drive's half gap, stiffness and load from one
//! measured run, with 95 % intervals and what the data do not determine.
//!
//! - [`data`]: the run as a CSV or a table, checked (one-line refusals naming row or column);
//! - [`model`]: the exact model of the run with its sensitivities (one linear system per mode,
//!   stepped by its matrix exponential; switches located, no saltation for the undamped law);
//! - [`fit`]: the grid start, Levenberg–Marquardt, intervals, identifiability;
//! - [`excite`]: a torque schedule that makes the gap identifiable (`backlash excite`).
//!
//! [`identify`] ties them: request → answer; [`to_json`] and [`to_text`] write it.

pub mod command;
pub mod data;
pub mod excite;
pub mod fit;
pub mod model;

use crate::request::{self, Request as DesignRequest, Setting, Vocabulary};
use crate::{study, web, Form};
use backlash_physics::{Geometry, PiGains, Plant, PlantParams};
use data::{Columns, Run, OUTPUTS};
use fit::{Estimate, Problem};
use model::{Model, DELTA_INDEX, K_INDEX, NAMES, P, U0_INDEX};
use serde_json::{json, Map, Value};
use std::cell::Cell;

/// What an identification is asked for: the form, the known values, what to fit.
#[derive(Clone, Debug)]
pub struct Request {
    pub form: Form,
    /// Known (or default) drive parameters; the fitted ones are the start.
    pub params: PlantParams,
    /// u(0) when not fitted, and the start when fitted (default 0: the middle of the gap).
    pub u0: f64,
    /// Indices into [`model::NAMES`].
    pub fit: Vec<usize>,
    pub accuracy: Option<f64>,
    pub tension_accuracy: Option<f64>,
    pub gains: Option<PiGains>,
    pub tension_gains: PiGains,
}

/// The stiffness's name on `form`.
fn stiffness_name(form: Form) -> &'static str {
    match form {
        Form::Shaft => "k",
        _ => "K_b",
    }
}

/// The FMU name of a fit parameter on `form`.
pub fn name(form: Form, index: usize) -> &'static str {
    if index == K_INDEX {
        stiffness_name(form)
    } else {
        NAMES[index]
    }
}

/// The fit's default: the half gap, the stiffness, `J_L`, `b_L`, `u0` (docs/model.md §11).
pub const DEFAULT_FIT: [usize; 5] = [DELTA_INDEX, K_INDEX, 1, 3, U0_INDEX];

/// A request from settings by name (the design's, plus `u0`) and the names to fit.
pub fn build(
    form: Form,
    settings: &[Setting],
    fit: Option<&[String]>,
    vocabulary: Vocabulary,
) -> Result<Request, String> {
    let mut u0 = 0.0;
    let mut design: Vec<Setting> = Vec::new();
    let (mut accuracy, mut tension_accuracy) = (None, None);
    for s in settings {
        match s.name {
            "u0" if !s.value.is_finite() => return Err(format!("{} = {} must be finite", s.label, s.text)),
            "u0" => u0 = s.value,
            "accuracy" => {
                accuracy = Some(s.value);
                design.push(s.clone())
            }
            "tension_accuracy" => {
                tension_accuracy = Some(s.value);
                design.push(s.clone())
            }
            _ => design.push(s.clone()),
        }
    }
    // The design's request checks every value; it needs its accuracies, which are optional here.
    let placeholder = |name: &'static str| Setting {
        name,
        label: name,
        text: "1".into(),
        value: 1.0,
    };
    if accuracy.is_none() {
        design.push(placeholder("accuracy"));
    }
    if tension_accuracy.is_none() && form == Form::Web {
        design.push(placeholder("tension_accuracy"));
    }
    let (params, gains, tension_gains) = match request::build(form, &design, vocabulary).map_err(|r| r.message)? {
        DesignRequest::Speed(r) => (r.params, r.gains, PiGains::default()),
        DesignRequest::Web(r) => (
            PlantParams {
                web: Some(r.web),
                ..r.drive
            },
            r.gains,
            r.tension_gains,
        ),
        DesignRequest::TwoStage(_) => {
            return Err("identification covers the models shaft, belt and web; two-stage is not identified yet".into())
        }
    };
    if params.damping.d > 0.0 {
        return Err(format!(
            "identification covers the undamped contact law: {} must be 0",
            if form == Form::Shaft { "d" } else { "D_b" }
        ));
    }
    let fit = match fit {
        None => DEFAULT_FIT.to_vec(),
        Some(names) => {
            let mut fit = Vec::new();
            for n in names {
                let n = n.trim();
                let index = (0..P).find(|&i| name(form, i) == n).ok_or_else(|| {
                    let all: Vec<&str> = (0..P).map(|i| name(form, i)).collect();
                    format!(
                        "fit: `{n}` is not a parameter the fit estimates on model {}: choose from {}",
                        form.name(),
                        all.join(", ")
                    )
                })?;
                if fit.contains(&index) {
                    return Err(format!("fit: {n} given twice"));
                }
                fit.push(index);
            }
            if fit.is_empty() {
                return Err("fit: no parameter named".into());
            }
            fit
        }
    };
    Ok(Request {
        form,
        params,
        u0,
        fit,
        accuracy,
        tension_accuracy,
        gains,
        tension_gains,
    })
}

/// The answer: estimates, residuals, how the fit went.
#[derive(Clone, Debug)]
pub struct Answer {
    pub form: Form,
    pub estimates: Vec<Estimate>,
    /// (output name, RMS of measured − simulated).
    pub residual_rms: Vec<(&'static str, f64)>,
    pub samples: usize,
    pub messages: Vec<String>,
    /// Model evaluations the fit took (simulations of the run, with or without sensitivities).
    pub evaluations: usize,
    pub accuracy: Option<Value>,
}

/// Half the range of the measured u = r_m θ_m − r_L θ_L (from angles, or speeds summed over the
/// samples): the run's lost motion, an upper end for the gap's grid.
fn lost_motion(run: &Run, model: &Model, r: (f64, f64)) -> Option<f64> {
    let col = |i: usize| run.outputs.iter().find(|(s, _)| *s == i).map(|(_, v)| v.clone());
    let integrate = |w: Vec<f64>| {
        let mut a = 0.0;
        w.iter()
            .map(|x| {
                let v = a;
                a += x * run.step;
                v
            })
            .collect::<Vec<f64>>()
    };
    let tm = col(0).or_else(|| col(1).map(integrate))?;
    let tl = col(2).or_else(|| col(3).map(integrate))?;
    let u: Vec<f64> = tm.iter().zip(&tl).map(|(a, b)| r.0 * a - r.1 * b).collect();
    let (lo, hi) = u.iter().fold((f64::MAX, f64::MIN), |(l, h), &x| (l.min(x), h.max(x)));
    let _ = model;
    Some(0.5 * (hi - lo))
}

/// The transmission ratios (r_m, r_L) of `params`.
fn ratios(params: &PlantParams) -> (f64, f64) {
    match params.geometry {
        Geometry::Shaft { .. } => (1.0, 1.0),
        Geometry::Belt {
            r_1, r_2, r_g1, r_g2, ..
        } => (r_1, r_2 * r_g2 / r_g1),
    }
}

/// `params` with the fitted values of `theta`.
fn with_theta(params: &PlantParams, theta: &[f64; P]) -> PlantParams {
    let mut p = *params;
    p.j_m = theta[0];
    p.j_l = theta[1];
    p.b_m = theta[2];
    p.b_l = theta[3];
    p = study::with_stiffness(&p, theta[K_INDEX]);
    p.with_half_gap(theta[DELTA_INDEX])
}

/// Identifies the drive of `request` from `columns`.
pub fn identify(request: &Request, columns: &Columns) -> Result<Answer, String> {
    let run = data::run_from_columns(columns, request.form == Form::Web)?;
    let base = Model::new(&request.params, request.u0, Vec::new());
    let t0 = columns
        .iter()
        .find(|(n, _)| n == "T")
        .or_else(|| columns.iter().find(|(n, _)| n == "T_in"))
        .map_or(0.0, |(_, v)| v[0]);
    // First weights: each output by its spread, so that no unit dominates.
    let weights = run
        .outputs
        .iter()
        .map(|(_, v)| {
            let mean = v.iter().sum::<f64>() / v.len() as f64;
            let rms = (v.iter().map(|x| (x - mean) * (x - mean)).sum::<f64>() / v.len() as f64).sqrt();
            if rms > 0.0 {
                1.0 / rms
            } else {
                1.0
            }
        })
        .collect();
    let mut problem = Problem {
        run: &run,
        base: base.clone(),
        fit: request.fit.clone(),
        t0,
        weights,
        evaluations: Cell::new(0),
    };
    let theta0 = base.theta;
    let starts = fit::grid_start(&problem, theta0, lost_motion(&run, &base, ratios(&request.params)))?;
    let mut best: Option<([f64; P], fit::Evaluation)> = None;
    for start in starts {
        if let Ok((t, e)) = problem.levenberg_marquardt(start, &request.fit) {
            if best.as_ref().is_none_or(|(_, b)| e.cost < b.cost) {
                best = Some((t, e));
            }
        }
    }
    let (theta, first) = best.ok_or("no start leads to a finite simulation of the run")?;
    // Weights from the residuals: each output by its own noise level, then refined.
    let n_samples = run.samples as f64;
    problem.weights = first
        .ssr
        .iter()
        .zip(&problem.weights)
        .map(|(s, w)| {
            let rms = (s / n_samples).sqrt();
            if rms > 0.0 {
                1.0 / rms
            } else {
                *w
            }
        })
        .collect();
    let (theta, fitted) = problem.levenberg_marquardt(theta, &request.fit)?;
    let mut messages = Vec::new();
    if fitted.sim.u0_growth > fit::CHAOS_GROWTH {
        return Err(format!(
            "the run is chaotic over its length: a change of u0 grows {:.1e}-fold, so the logged inputs cannot be simulated to the measurement (docs/model.md §11); fit a shorter segment",
            fitted.sim.u0_growth
        ));
    }
    let dof = run.samples * run.outputs.len() - request.fit.len();
    let (mut estimates, reasons) = fit::intervals(&request.fit, &theta, &fitted, dof, |i| name(request.form, i));
    messages.extend(reasons.into_iter().map(|(_, r)| r));
    let both_flanks = fitted.sim.flanks.0 && fitted.sim.flanks.1;
    for e in estimates.iter_mut() {
        let gap_named = e.name == DELTA_INDEX || e.name == U0_INDEX;
        if gap_named && !both_flanks && request.fit.contains(&DELTA_INDEX) {
            if e.identifiable {
                messages.push(format!(
                    "{} is not determined: the run never reverses the force through the gap (it reaches one flank only), which fixes u0 - Delta but not each",
                    NAMES[e.name]
                ));
            }
            e.identifiable = false;
            e.ci95 = None;
        }
    }
    // Where the linearised interval misleads (Δ near 0, few switches), the profile of the cost.
    let delta_at = estimates.iter().position(|e| e.name == DELTA_INDEX && e.identifiable);
    if let Some(i) = delta_at {
        let e = &estimates[i];
        let (lo, hi) = e.ci95.unwrap_or((0.0, 2.0 * e.value));
        // One flank seen only (a run that does not reverse the force): a wider gap with the seen
        // flank kept in place costs nothing, and the linear interval hides it. One evaluation
        // each way tells.
        let flat_above = [1.0, -1.0].iter().any(|&side| {
            let mut t = theta;
            let grow = e.value.max(hi - lo);
            t[DELTA_INDEX] = e.value + grow;
            t[U0_INDEX] += side * (base.clone().with_theta(&t).g() - base.clone().with_theta(&theta).g());
            let threshold = fitted.cost * (1.0 + 0.5 * 3.841_458_820_694_124 / dof.max(1) as f64 * 2.0);
            problem.evaluate(&t, &[]).is_ok_and(|c| c.cost <= threshold)
        });
        if flat_above || lo <= 0.0 || hi - lo > 0.5 * e.value || fitted.sim.switches < 8 {
            match profile(&problem, &theta, fitted.cost, dof, (hi - lo) / 2.0) {
                Ok((lo, hi)) => {
                    messages.push(format!(
                        "Delta: the linearised interval misleads here (near 0 or few reversals: {} switches); ci95 is the profile of the cost",
                        fitted.sim.switches
                    ));
                    estimates[i].ci95 = Some((lo, hi));
                }
                Err(reason) => {
                    messages.push(reason);
                    estimates[i].ci95 = None;
                    estimates[i].identifiable = false;
                }
            }
        }
    }
    for ((state, values), ssr) in run.outputs.iter().zip(&fitted.ssr) {
        let rms = (ssr / n_samples).sqrt();
        let noise = data::noise_level(values);
        if noise > 0.0 && rms > 3.0 * noise {
            messages.push(format!(
                "the fit does not reach the noise of {}: residual rms {rms:.3e} against about {noise:.3e} from the data's sample-to-sample scatter; a side minimum of the cost or a drive the model does not describe, so the intervals are not to be trusted",
                OUTPUTS[*state]
            ));
        }
    }
    let residual_rms = run
        .outputs
        .iter()
        .zip(&fitted.ssr)
        .map(|((s, _), ssr)| (OUTPUTS[*s], (ssr / n_samples).sqrt()))
        .collect();
    let accuracy = accuracy(request, &theta, &estimates, &mut messages)?;
    Ok(Answer {
        form: request.form,
        estimates,
        residual_rms,
        samples: run.samples,
        messages,
        evaluations: problem.evaluations.get(),
        accuracy,
    })
}

/// The profile of the cost in Δ: the other parameters refitted at each Δ; the 95 % interval is
/// where the cost stays within ½ χ²₁(0.95) s² of its minimum.
fn profile(p: &Problem, theta: &[f64; P], cost_min: f64, dof: usize, half: f64) -> Result<(f64, f64), String> {
    let s2 = 2.0 * cost_min / dof.max(1) as f64;
    let threshold = cost_min + 0.5 * 3.841_458_820_694_124 * s2;
    let others: Vec<usize> = p.fit.iter().copied().filter(|&i| i != DELTA_INDEX).collect();
    let value = theta[DELTA_INDEX];
    let step0 = half.max(0.05 * value).max(1e-15) / 2.0;
    let mut ends = [0.0; 2];
    for (side, sign) in [(0, -1.0), (1, 1.0)] {
        let (mut prev_d, mut prev_c) = (value, cost_min);
        let mut t = *theta;
        let mut step = step0;
        let mut found = None;
        for i in 0..12 {
            let d = prev_d + sign * step;
            if d <= 0.0 {
                found = Some(0.0);
                break;
            }
            t[DELTA_INDEX] = d;
            let cost = if others.is_empty() {
                p.evaluate(&t, &[])?.cost
            } else {
                let (tt, e) = p.levenberg_marquardt(t, &others)?;
                t = tt;
                e.cost
            };
            if cost > threshold {
                // Linear interpolation between the last point inside and this one.
                let f = (threshold - prev_c) / (cost - prev_c);
                found = Some(prev_d + f * (d - prev_d));
                break;
            }
            (prev_d, prev_c) = (d, cost);
            if i >= 3 {
                step *= 2.0;
            }
        }
        ends[side] = found.ok_or_else(|| {
            format!(
                "Delta is not determined: the profile of the cost stays within the 95 % threshold from {value:.3e} to {prev_d:.3e}"
            )
        })?;
    }
    Ok((ends[0], ends[1]))
}

/// With an accuracy: bound_sup (bound_T_sup on the web) at the estimate and at the worst corner
/// of the confidence box, and whether the drive meets it.
fn accuracy(
    request: &Request,
    theta: &[f64; P],
    estimates: &[Estimate],
    messages: &mut Vec<String>,
) -> Result<Option<Value>, String> {
    if request.accuracy.is_none() && request.tension_accuracy.is_none() {
        return Ok(None);
    }
    let at = with_theta(&request.params, theta);
    let gains = match request.gains {
        Some(g) => g,
        None => {
            study::best_damped_gains(&Plant::new(PlantParams { web: None, ..at }).map_err(|e| e.to_string())?)
                .map_err(|e| e.to_string())?
                .gains
        }
    };
    // (speed bound, tension bound) of a parameter set.
    let sups = |p: &PlantParams| -> (f64, f64) {
        match p.web {
            None => (study::bound_sup(p, gains).unwrap_or(f64::INFINITY), f64::NAN),
            Some(span) => web::sups(&PlantParams { web: None, ..*p }, &span, gains, request.tension_gains)
                .map_or((f64::INFINITY, f64::INFINITY), |s| (s.speed, s.tension)),
        }
    };
    let estimate = sups(&at);
    let boxed: Vec<&Estimate> = estimates.iter().filter(|e| e.name != U0_INDEX).collect();
    let mut worst = estimate;
    if boxed.iter().any(|e| !e.identifiable) {
        worst = (f64::INFINITY, f64::INFINITY);
        messages.push("accuracy: a fitted parameter is not determined, so the worst case is unbounded".into());
    } else {
        for corner in 0..(1usize << boxed.len()) {
            let mut t = *theta;
            for (b, e) in boxed.iter().enumerate() {
                let (lo, hi) = e.ci95.expect("identifiable estimates have intervals");
                let v = if corner >> b & 1 == 1 { hi } else { lo };
                t[e.name] = if e.name == DELTA_INDEX {
                    v.max(0.0)
                } else {
                    v.max(1e-3 * e.value.abs())
                };
            }
            let s = sups(&with_theta(&request.params, &t));
            worst = (worst.0.max(s.0), worst.1.max(s.1));
        }
    }
    let mut out = Map::new();
    if let Some(eps) = request.accuracy {
        out.insert(
            "accuracy".into(),
            json!({"epsilon": eps, "bound_sup_estimate": estimate.0, "bound_sup_worst": worst.0,
                   "meets": worst.0 <= eps, "Kp": gains.kp, "Ki": gains.ki}),
        );
    }
    if let Some(eps) = request.tension_accuracy {
        out.insert(
            "tension_accuracy".into(),
            json!({"epsilon_T": eps, "bound_T_sup_estimate": estimate.1, "bound_T_sup_worst": worst.1,
                   "meets": worst.1 <= eps}),
        );
    }
    Ok(Some(Value::Object(out)))
}

/// The answer as the JSON object of docs/model.md §11 (and `accuracy` / `tension_accuracy` when asked).
pub fn to_value(a: &Answer) -> Value {
    let mut estimates = Map::new();
    for e in &a.estimates {
        estimates.insert(
            name(a.form, e.name).into(),
            json!({"value": e.value, "ci95": e.ci95.map(|(l, h)| vec![l, h]), "identifiable": e.identifiable}),
        );
    }
    let rms: Map<String, Value> = a.residual_rms.iter().map(|(n, v)| (n.to_string(), json!(v))).collect();
    let mut out = json!({
        "model": a.form.name(),
        "estimates": estimates,
        "residual_rms": rms,
        "samples": a.samples,
        "messages": a.messages,
        "evaluations": a.evaluations,
    });
    if let Some(Value::Object(acc)) = &a.accuracy {
        for (k, v) in acc {
            out[k] = v.clone();
        }
    }
    out
}

pub fn to_json(a: &Answer) -> String {
    serde_json::to_string_pretty(&to_value(a)).expect("a JSON value serialises")
}

/// The answer as text: one line per estimate, then residuals and messages.
pub fn to_text(a: &Answer) -> String {
    let mut s = format!(
        "model {}, {} samples, {} model evaluations\n",
        a.form.name(),
        a.samples,
        a.evaluations
    );
    for e in &a.estimates {
        let ci = match (e.identifiable, e.ci95) {
            (true, Some((l, h))) => format!("95% [{l:.6e}, {h:.6e}]"),
            _ => "not identifiable".into(),
        };
        s += &format!("  {:<6} = {:.6e}  {ci}\n", name(a.form, e.name), e.value);
    }
    for (n, v) in &a.residual_rms {
        s += &format!("  residual rms {n} = {v:.3e}\n");
    }
    if let Some(Value::Object(acc)) = &a.accuracy {
        for (k, v) in acc {
            s += &format!("  {k}: {v}\n");
        }
    }
    for m in &a.messages {
        s += &format!("note: {m}\n");
    }
    s.trim_end().to_string()
}

/// The identification as JSON for `model` (the Python binding's entry): a table by columns,
/// the names to fit, settings by name.
pub fn identify_json(
    model: &str,
    columns: &Columns,
    fit: Option<&[String]>,
    settings: &[Setting],
) -> Result<String, String> {
    let form = request::form_named(model)
        .ok_or_else(|| format!("model = {model:?}: choose \"shaft\", \"belt\" or \"web\""))?;
    let request = build(form, settings, fit, Vocabulary::Arguments)?;
    Ok(to_json(&identify(&request, columns)?))
}

#[cfg(test)]
mod tests;

//! The exact model of a measured run and its sensitivities (docs/model.md §11).
//!
//! State x = [θ_m, ω_m, θ_L, ω_L] (and T on the web), angles from the start, and
//! u = u0 + r_m θ_m − r_L θ_L. In each contact mode the plant is affine, x' = A x + B w + c, with w the held inputs.
//! The sensitivities S_j = ∂x/∂p_j obey S_j' = A S_j + A_j x + B_j w + c_j, affine too, so the
//! state and its sensitivities together are one linear system y' = M y, stepped exactly by
//! e^{M s}. A, B, c and their parameter derivatives A_j, B_j, c_j come from the right-hand side
//! written once over dual numbers (forward-mode automatic differentiation, exact).
//!
//! Switches: at u = ±g the force ψ = K dz(u, g) is continuous (undamped law), so the vector
//! field is continuous across the switch: the saltation correction (f⁺ − f⁻) dt*/dp of the
//! sensitivities vanishes and S passes the switch unchanged. The switch instant itself is
//! located to round-off by a safeguarded Newton iteration on the guard, as the stepper does.

use backlash_physics::{Geometry, PlantParams, WebSpan};
use nalgebra::{DMatrix, DVector};

/// The parameters a fit can estimate, by their FMU names; the stiffness is `k` or `K_b`.
pub const NAMES: [&str; 7] = ["J_m", "J_L", "b_m", "b_L", "K", "Delta", "u0"];
pub const P: usize = NAMES.len();
pub const K_INDEX: usize = 4;
pub const DELTA_INDEX: usize = 5;
pub const U0_INDEX: usize = 6;

/// A number with its gradient over the seven parameters of [`NAMES`].
#[derive(Clone, Copy, Debug)]
struct Dual {
    v: f64,
    g: [f64; P],
}

impl Dual {
    fn c(v: f64) -> Dual {
        Dual { v, g: [0.0; P] }
    }
    fn var(v: f64, i: usize) -> Dual {
        let mut g = [0.0; P];
        g[i] = 1.0;
        Dual { v, g }
    }
    fn zip(self, o: Dual, v: f64, a: f64, b: f64) -> Dual {
        let mut g = [0.0; P];
        for (i, gi) in g.iter_mut().enumerate() {
            *gi = a * self.g[i] + b * o.g[i];
        }
        Dual { v, g }
    }
    fn add(self, o: Dual) -> Dual {
        self.zip(o, self.v + o.v, 1.0, 1.0)
    }
    fn sub(self, o: Dual) -> Dual {
        self.zip(o, self.v - o.v, 1.0, -1.0)
    }
    fn mul(self, o: Dual) -> Dual {
        self.zip(o, self.v * o.v, o.v, self.v)
    }
    fn div(self, o: Dual) -> Dual {
        self.zip(o, self.v / o.v, 1.0 / o.v, -self.v / (o.v * o.v))
    }
}

/// The drive of a run: the known parameters, which of [`NAMES`] get sensitivities, and the
/// geometry's fixed ratios.
#[derive(Clone, Debug)]
pub struct Model {
    /// Values of [`NAMES`] (K the stiffness k or K_b, u0 the initial u).
    pub theta: [f64; P],
    /// r_m, r_L, α_2 (g = α_2 Δ).
    r_m: f64,
    r_l: f64,
    alpha_2: f64,
    web: Option<WebSpan>,
    /// Indices into [`NAMES`] that get sensitivities.
    pub sens: Vec<usize>,
}

/// A simulated run: the states at the samples, their sensitivities, what it cost.
pub struct Simulation {
    /// x at each sample (n entries each).
    pub states: Vec<Vec<f64>>,
    /// ∂x/∂p_j at each sample: `sens[k][j][i]` for state i, sensitivity j.
    pub sens: Vec<Vec<Vec<f64>>>,
    /// Mode switches located (u crossing ±g).
    pub switches: usize,
    /// Flanks visited: (negative, positive).
    pub flanks: (bool, bool),
    /// Largest |∂u/∂u0| over the run (when u0 has a sensitivity): the growth of a change of the
    /// initial position, the chaos test of docs/model.md §11.
    pub u0_growth: f64,
}

impl Model {
    pub fn new(params: &PlantParams, u0: f64, sens: Vec<usize>) -> Model {
        let (r_m, r_l, alpha_2, k, delta) = match params.geometry {
            Geometry::Shaft { k, delta } => (1.0, 1.0, 1.0, k, delta),
            Geometry::Belt {
                k_b,
                r_1,
                r_2,
                r_g1,
                r_g2,
                delta,
            } => (r_1, r_2 * r_g2 / r_g1, r_2 / r_g1, k_b, delta),
        };
        Model {
            theta: [params.j_m, params.j_l, params.b_m, params.b_l, k, delta, u0],
            r_m,
            r_l,
            alpha_2,
            web: params.web,
            sens,
        }
    }

    /// States: 4, or 5 with a web span.
    pub fn n(&self) -> usize {
        if self.web.is_some() {
            5
        } else {
            4
        }
    }

    /// Half gap g in u.
    pub fn g(&self) -> f64 {
        self.alpha_2 * self.theta[DELTA_INDEX]
    }

    /// u of a state.
    pub fn u(&self, x: &[f64]) -> f64 {
        self.r_m * x[0] - self.r_l * x[2] + self.theta[U0_INDEX]
    }

    /// The fastest rate of the plant [1/s] (contact frequency, damping, web), for the piece length.
    fn fastest_rate(&self) -> f64 {
        let t = &self.theta;
        let kappa = self.r_m * self.r_m / t[0] + self.r_l * self.r_l / t[1];
        let mut rate = (t[K_INDEX] * kappa).sqrt().max(t[2] / t[0]).max(t[3] / t[1]);
        if let Some(w) = self.web {
            rate = rate.max((t[K_INDEX] * kappa + w.ea * w.r_w * w.r_w / (w.l_w * t[1])).sqrt());
            rate = rate.max(w.v_ref / w.l_w);
        }
        rate
    }

    /// The right-hand side in mode σ (−1, 0, +1) over duals: x' for state `x`, inputs `w`.
    fn rhs(&self, sigma: f64, x: &[f64], w: &[f64; 4]) -> Vec<Dual> {
        let p: Vec<Dual> = (0..P).map(|i| Dual::var(self.theta[i], i)).collect();
        let (jm, jl, bm, bl, k, delta, u0) = (p[0], p[1], p[2], p[3], p[4], p[5], p[6]);
        let (rm, rl) = (Dual::c(self.r_m), Dual::c(self.r_l));
        let xd: Vec<Dual> = x.iter().map(|&v| Dual::c(v)).collect();
        let u = rm.mul(xd[0]).sub(rl.mul(xd[2])).add(u0);
        let g = Dual::c(self.alpha_2).mul(delta);
        let psi = if sigma == 0.0 {
            Dual::c(0.0)
        } else {
            k.mul(u.sub(Dual::c(sigma).mul(g)))
        };
        let tension = if self.web.is_some() { xd[4] } else { Dual::c(0.0) };
        let rw = Dual::c(self.web.map_or(0.0, |s| s.r_w));
        let wm = Dual::c(w[0]).sub(bm.mul(xd[1])).sub(rm.mul(psi)).div(jm);
        let wl = Dual::c(w[1])
            .sub(bl.mul(xd[3]))
            .add(rl.mul(psi))
            .sub(rw.mul(tension))
            .div(jl);
        let mut f = vec![xd[1], wm, xd[3], wl];
        if let Some(s) = self.web {
            // L_w T' = EA (R_w ω_L − v_in) + v_ref (T_in − T) (docs/model.md §7).
            let t = (s.ea * (s.r_w * x[3] - w[2]) + s.v_ref * (w[3] - x[4])) / s.l_w;
            f.push(Dual::c(t));
        }
        f
    }

    /// M of mode σ over y = [x, S_1 … S_m, w (4), 1].
    pub fn mode_matrix(&self, sigma: f64) -> DMatrix<f64> {
        let n = self.n();
        let m = self.sens.len();
        let dim = n * (m + 1) + 5;
        let (wi, one) = (n * (m + 1), n * (m + 1) + 4);
        let zero_x = vec![0.0; n];
        let c = self.rhs(sigma, &zero_x, &[0.0; 4]);
        let mut mat = DMatrix::zeros(dim, dim);
        // Columns of A (state) and B (inputs) as differences of the affine rhs.
        let mut cols: Vec<(usize, Vec<Dual>)> = Vec::new();
        for j in 0..n {
            let mut e = zero_x.clone();
            e[j] = 1.0;
            cols.push((j, self.rhs(sigma, &e, &[0.0; 4])));
        }
        for j in 0..4 {
            let mut e = [0.0; 4];
            e[j] = 1.0;
            cols.push((n + j, self.rhs(sigma, &zero_x, &e)));
        }
        for i in 0..n {
            mat[(i, one)] = c[i].v;
            for (s, &pj) in self.sens.iter().enumerate() {
                mat[(n * (s + 1) + i, one)] = c[i].g[pj];
            }
            for (col, f) in &cols {
                let (value, grad) = (f[i].v - c[i].v, |pj: usize| f[i].g[pj] - c[i].g[pj]);
                let target = if *col < n { *col } else { wi + col - n };
                mat[(i, target)] = value;
                for (s, &pj) in self.sens.iter().enumerate() {
                    mat[(n * (s + 1) + i, target)] = grad(pj);
                    if *col < n {
                        // A acting on S_s.
                        mat[(n * (s + 1) + i, n * (s + 1) + col)] = value;
                    }
                }
            }
        }
        mat
    }

    /// The force's mode at u: −1, 0, +1 (exactly on ±g: the mode entered given u').
    fn mode_at(&self, u: f64, du: f64) -> f64 {
        let g = self.g();
        if u > g || (u == g && du > 0.0) || (g == 0.0 && u >= 0.0) {
            1.0
        } else if u < -g || (u == -g && du < 0.0) || g == 0.0 {
            -1.0
        } else {
            0.0
        }
    }

    /// Simulates the run from rest with inputs held per sample (step `h`), `t0` the initial
    /// tension; with `sens` the sensitivities. Returns `Err` when the state stops being finite.
    pub fn simulate(&self, inputs: &[[f64; 4]], h: f64, t0: f64) -> Result<Simulation, String> {
        let n = self.n();
        let m = self.sens.len();
        let dim = n * (m + 1) + 5;
        let (wi, one) = (n * (m + 1), n * (m + 1) + 4);
        let pieces = ((h * self.fastest_rate() / 0.5).ceil() as usize).max(1);
        let hp = h / pieces as f64;
        let mats: Vec<DMatrix<f64>> = [-1.0, 0.0, 1.0].iter().map(|&s| self.mode_matrix(s)).collect();
        let steps: Vec<DMatrix<f64>> = mats.iter().map(|a| (a * hp).exp()).collect();
        let mut y = DVector::zeros(dim);
        if n == 5 {
            y[4] = t0;
        }
        y[one] = 1.0;
        let (rm, rl, g) = (self.r_m, self.r_l, self.g());
        let u_of = |y: &DVector<f64>| rm * y[0] - rl * y[2] + self.theta[U0_INDEX];
        let du_of = |y: &DVector<f64>| rm * y[1] - rl * y[3];
        let mut sigma = self.mode_at(u_of(&y), 0.0);
        let u0_col = self.sens.iter().position(|&j| j == U0_INDEX);
        let mut sim = Simulation {
            states: Vec::with_capacity(inputs.len()),
            sens: Vec::with_capacity(inputs.len()),
            switches: 0,
            flanks: (sigma < 0.0, sigma > 0.0),
            u0_growth: 1.0,
        };
        let record = |y: &DVector<f64>, sim: &mut Simulation| {
            sim.states.push(y.rows(0, n).iter().copied().collect());
            sim.sens.push(
                (0..m)
                    .map(|s| y.rows(n * (s + 1), n).iter().copied().collect())
                    .collect(),
            );
            if let Some(s) = u0_col {
                let growth = (rm * y[n * (s + 1)] - rl * y[n * (s + 1) + 2] + 1.0).abs();
                sim.u0_growth = sim.u0_growth.max(growth);
            }
        };
        for (k, w) in inputs.iter().enumerate() {
            for (j, v) in w.iter().enumerate() {
                y[wi + j] = *v;
            }
            record(&y, &mut sim);
            if k + 1 == inputs.len() {
                break;
            }
            for _ in 0..pieces {
                let mut left = hp;
                let mut full = true;
                // At most a few switches per piece; each one ends a sub-piece exactly.
                for _ in 0..16 {
                    let idx = (sigma + 1.0) as usize;
                    let next = if full {
                        &steps[idx] * &y
                    } else {
                        (&mats[idx] * left).exp() * &y
                    };
                    match self.first_switch(&mats[idx], &y, &next, left, sigma, g) {
                        None => {
                            y = next;
                            break;
                        }
                        Some(s) => {
                            y = (&mats[idx] * s).exp() * &y;
                            let du = du_of(&y);
                            let u = u_of(&y);
                            // The mode entered: past the guard that was crossed.
                            sigma = if sigma == 0.0 {
                                if u > 0.0 {
                                    1.0
                                } else {
                                    -1.0
                                }
                            } else {
                                0.0
                            };
                            if g == 0.0 {
                                sigma = if du >= 0.0 { 1.0 } else { -1.0 };
                            }
                            sim.switches += 1;
                            sim.flanks.0 |= sigma < 0.0;
                            sim.flanks.1 |= sigma > 0.0;
                            left -= s;
                            full = false;
                            if left <= 0.0 {
                                break;
                            }
                        }
                    }
                }
            }
            if !y.iter().all(|v| v.is_finite()) {
                return Err(format!("the simulation is not finite after sample {}", k + 1));
            }
        }
        Ok(sim)
    }

    /// The time in (0, len] at which the trajectory from `y` in mode σ (reaching `end` after
    /// `len`) first crosses the guard that ends the mode, if it does; a graze (u turning back
    /// inside the piece) is checked at the turn.
    fn first_switch(
        &self,
        mat: &DMatrix<f64>,
        y: &DVector<f64>,
        end: &DVector<f64>,
        len: f64,
        sigma: f64,
        g: f64,
    ) -> Option<f64> {
        if g == 0.0 {
            return None; // Both flanks are one spring: no switch changes the dynamics.
        }
        let (rm, rl, u0) = (self.r_m, self.r_l, self.theta[U0_INDEX]);
        let u = |y: &DVector<f64>| rm * y[0] - rl * y[2] + u0;
        // The guard that ends the mode, ≥ 0 inside it and affine in the state: in contact σ,
        // σ (u − σ g); free, g − u towards the positive flank or u + g towards the negative one.
        let towards = |y: &DVector<f64>| {
            if sigma != 0.0 {
                sigma
            } else if u(y) > 0.0 {
                1.0
            } else {
                -1.0
            }
        };
        let guard = move |side: f64| {
            move |y: &DVector<f64>| {
                let u = rm * y[0] - rl * y[2] + u0;
                if sigma != 0.0 {
                    sigma * (u - sigma * g)
                } else {
                    g - side * u
                }
            }
        };
        let side = towards(end);
        let hi = if guard(side)(end) < 0.0 {
            len
        } else {
            // A graze: u' changes sign inside the piece; look at the turning point.
            let du = |y: &DVector<f64>| rm * y[1] - rl * y[3];
            let (d0, d1) = (du(y), du(end));
            if d0 * d1 >= 0.0 {
                return None;
            }
            // The turn can reach the guard only if the guard's value at the ends is within what
            // the speed covers over the piece: |γ| ≤ max|u'| len.
            let reach = d0.abs().max(d1.abs()) * len;
            let side = towards(y);
            if guard(side)(y).min(guard(side)(end)) > reach {
                return None;
            }
            let turn = self.root(mat, y, len, |z| du(z) * d0.signum());
            let at_turn = self.propagate_small(mat, y, turn);
            let side = towards(&at_turn);
            if guard(side)(&at_turn) >= 0.0 {
                return None;
            }
            return Some(self.root(mat, y, turn, guard(side)).max(f64::MIN_POSITIVE));
        };
        Some(self.root(mat, y, hi, guard(side)).max(f64::MIN_POSITIVE))
    }

    /// e^{M s} y on the state, inputs and 1 only (they do not depend on the sensitivities), as a
    /// full-length vector with zero sensitivities.
    fn propagate_small(&self, mat: &DMatrix<f64>, y: &DVector<f64>, s: f64) -> DVector<f64> {
        let n = self.n();
        let full = mat.nrows();
        let keep: Vec<usize> = (0..n).chain(full - 5..full).collect();
        let small = DMatrix::from_fn(keep.len(), keep.len(), |i, j| mat[(keep[i], keep[j])]);
        let ys = DVector::from_iterator(keep.len(), keep.iter().map(|&i| y[i]));
        let z = (&small * s).exp() * &ys;
        let mut out = DVector::zeros(full);
        for (i, &k) in keep.iter().enumerate() {
            out[k] = z[i];
        }
        out
    }

    /// The root in (0, hi] of an affine function `f` of the state along e^{M s} y that is ≥ 0
    /// at 0 and < 0 at `hi`, to round-off: Newton steps (f' = f(M z) − f(0), f being affine)
    /// kept inside a shrinking bracket, bisection where Newton would leave it.
    fn root(&self, mat: &DMatrix<f64>, y: &DVector<f64>, hi: f64, f: impl Fn(&DVector<f64>) -> f64) -> f64 {
        let n = self.n();
        let full = mat.nrows();
        let keep: Vec<usize> = (0..n).chain(full - 5..full).collect();
        let small = DMatrix::from_fn(keep.len(), keep.len(), |i, j| mat[(keep[i], keep[j])]);
        let ys = DVector::from_iterator(keep.len(), keep.iter().map(|&i| y[i]));
        let widen = |z: &DVector<f64>| {
            let mut out = DVector::zeros(full);
            for (i, &k) in keep.iter().enumerate() {
                out[k] = z[i];
            }
            out
        };
        let offset = f(&DVector::zeros(full));
        let (mut lo, mut hi) = (0.0_f64, hi);
        let mut s = hi;
        for _ in 0..100 {
            let z = (&small * s).exp() * &ys;
            let value = f(&widen(&z));
            if value < 0.0 {
                hi = s;
            } else {
                lo = s;
            }
            if value == 0.0 || hi - lo <= 4.0 * f64::EPSILON * hi {
                return s;
            }
            let rate = f(&widen(&(&small * &z))) - offset;
            let newton = s - value / rate;
            if (newton - s).abs() <= 4.0 * f64::EPSILON * s {
                return newton.clamp(lo, hi);
            }
            s = if newton.is_finite() && newton > lo && newton < hi {
                newton
            } else {
                0.5 * (lo + hi)
            };
        }
        hi
    }
}

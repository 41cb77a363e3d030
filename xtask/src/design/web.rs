//! The tension half of the paper's future work: which backlash and belt stiffness keep the web
//! tension (and, if asked, the load speed) within a given accuracy (docs/model.md §8).
//!
//! The web line is the belt drive of docs/model.md §1 whose load is a roller of radius R_w
//! pulling one span of web (length L_w, stiffness EA, transport speed v_ref), with the speed PI of
//! §3 and an optional outer PI on tension that trims the speed reference. Backlash enters as the
//! bounded disturbance φ (|φ| ≤ K g) of §3, so the deviations it causes are bounded by
//! `bound_T_sup = K g ∫_0^∞ |h_T|` (tension) and `bound_sup = K g ∫_0^∞ |h|` (load speed), h_T
//! and h the impulse responses from φ of the backlash-free loop, computed here on that loop's
//! dense matrix by [`l1_norm`].

use nalgebra::{DMatrix, DVector};
use serde_json::{json, Value};

use backlash_fmu::physics::{PiGains, Plant, PlantParams, Unbounded};

use super::study::{self, DesignError, StiffnessScan, StiffnessStudy};

/// The web span and roller driven by the belt drive (docs/model.md §8).
pub use backlash_fmu::physics::WebSpan as Web;

/// Both suprema for one parameter set.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Sups {
    /// Bound on |T with backlash − T without| [N].
    pub tension: f64,
    /// Bound on |ω_L with backlash − ω_L without| [rad/s].
    pub speed: f64,
}

/// The backlash-free loop: dx/ds = A x + d φ; T = tension_row·x, ω_L = speed_row·x.
pub struct LoopMatrices {
    pub a: DMatrix<f64>,
    pub d: DVector<f64>,
    pub tension_row: DVector<f64>,
    pub speed_row: DVector<f64>,
}

/// The backlash-free web loop in the coordinates h and h_T depend on, x = [u, ω_m, ω_L, T] and
/// x_c (when Ki ≠ 0), x_T (when Ki_T ≠ 0): the angle translation at fixed u is neither excited
/// by φ nor seen by T or ω_L, and an integrator without gain feeds nothing back. Returns A, the
/// column by which φ enters, and the rows that pick T and ω_L.
pub fn reduced_loop(
    drive: &PlantParams,
    web: &Web,
    speed: PiGains,
    tension: PiGains,
) -> Result<LoopMatrices, DesignError> {
    let plant = Plant::new(PlantParams {
        web: Some(*web),
        ..*drive
    })?;
    let (r_m, r_l, k) = (plant.r_m(), plant.r_l(), plant.stiffness());
    let (j_m, j_l, b_m, b_l) = (drive.j_m, drive.j_l, drive.b_m, drive.b_l);
    const U: usize = 0;
    const WM: usize = 1;
    const WL: usize = 2;
    const T: usize = 3;
    let xc = (speed.ki != 0.0).then_some(4);
    let xt = (tension.ki != 0.0).then_some(4 + xc.is_some() as usize);
    let n = 4 + xc.is_some() as usize + xt.is_some() as usize;
    let mut a = DMatrix::zeros(n, n);
    // The speed error with zero references: e = −ω_m − Kp_T T + Ki_T x_T; τ_m = Kp e + Ki x_c.
    let mut e = DVector::zeros(n);
    e[WM] = -1.0;
    e[T] = -tension.kp;
    if let Some(i) = xt {
        e[i] = tension.ki;
    }
    a[(U, WM)] = r_m;
    a[(U, WL)] = -r_l;
    for j in 0..n {
        a[(WM, j)] = speed.kp * e[j] / j_m;
    }
    if let Some(i) = xc {
        a[(WM, i)] += speed.ki / j_m;
        for j in 0..n {
            a[(i, j)] = e[j];
        }
    }
    a[(WM, U)] -= k * r_m / j_m;
    a[(WM, WM)] -= b_m / j_m;
    a[(WL, U)] = k * r_l / j_l;
    a[(WL, WL)] = -b_l / j_l;
    a[(WL, T)] = -web.r_w / j_l;
    a[(T, WL)] = web.ea * web.r_w / web.l_w;
    a[(T, T)] = -web.v_ref / web.l_w;
    if let Some(i) = xt {
        a[(i, T)] = -1.0;
    }
    let mut d = DVector::zeros(n);
    d[WM] = r_m / j_m;
    d[WL] = -r_l / j_l;
    let pick = |i: usize| {
        let mut c = DVector::zeros(n);
        c[i] = 1.0;
        c
    };
    Ok(LoopMatrices {
        a,
        d,
        tension_row: pick(T),
        speed_row: pick(WL),
    })
}

/// `bound_T_sup` and `bound_sup` of the web line; `DesignError::Unbounded` when the loop is not
/// asymptotically stable.
pub fn sups(drive: &PlantParams, web: &Web, speed: PiGains, tension: PiGains) -> Result<Sups, DesignError> {
    let LoopMatrices {
        a,
        d,
        tension_row,
        speed_row,
    } = reduced_loop(drive, web, speed, tension)?;
    let plant = Plant::new(*drive)?;
    let scale = plant.stiffness() * plant.half_gap();
    let norms = l1_norms(&a, &d, &[tension_row, speed_row]).map_err(|reason| DesignError::Unbounded {
        kp: speed.kp,
        ki: speed.ki,
        reason,
    })?;
    Ok(Sups {
        tension: scale * norms[0],
        speed: scale * norms[1],
    })
}

/// ∫_0^∞ |c e^{As} d| ds for one output row c; see [`l1_norms`].
#[cfg(test)]
fn l1_norm(a: &DMatrix<f64>, d: &DVector<f64>, c: &DVector<f64>) -> Result<f64, Unbounded> {
    Ok(l1_norms(a, d, std::slice::from_ref(c))?[0])
}

/// Grid intervals per radian of the fastest eigenvalue.
const INTERVALS_PER_RADIAN: f64 = 2.0;
/// Taylor terms of h on one interval: the remainder is below (ρw)^TERMS / TERMS! ≈ 1e-33 of |x|.
const TERMS: usize = 25;
/// Terms the cheap test of each interval computes; the rest enter by their norms.
const CHEAP: usize = 4;
/// Points at which an interval that may hold a sign change is sampled: two sign changes closer
/// than w / SUBINTERVALS (a grazing touch of zero) are not resolved, which changes the integral
/// by less than the integral of |h| between them.
const SUBINTERVALS: usize = 64;
/// The integration stops once a bound on the rest is below this fraction of the sum.
const TAIL_TOLERANCE: f64 = 1e-13;
/// The tail bound decays at this fraction of the slowest decay rate (< 1: the closer to 1, the
/// sooner the integration stops, and the larger the Gramian).
const TAIL_DECAY: f64 = 0.8;
/// Most grid intervals one norm may take.
const MAX_INTERVALS: usize = 1 << 24;

/// ∫_0^∞ |c_i e^{As} d| ds for each row c_i, for a Hurwitz A (`Err` otherwise). The response
/// x(s) = e^{As} d is propagated exactly on a grid of INTERVALS_PER_RADIAN intervals per radian
/// of the fastest eigenvalue. On each interval h is its Taylor polynomial Σ (c A^k x) σ^k / k!
/// (exact to round-off there); where its first terms and a bound on the others show that h
/// keeps its sign, the integral is exact, c ∫_0^w e^{Aσ}dσ x (both matrices from one
/// exponential of an augmented matrix); elsewhere the polynomial's sign changes are located
/// (see [`abs_integral`]) and its parts integrated term by term. The integration stops when the tail bound of a Lyapunov Gramian
/// (∫_T^∞ |c x| ≤ sqrt(xᵀWx / 2ε), see [`gramian`]) is below TAIL_TOLERANCE of the sum, and the
/// bound is added: an upper bound, tight to 1e-13.
pub fn l1_norms(a: &DMatrix<f64>, d: &DVector<f64>, rows: &[DVector<f64>]) -> Result<Vec<f64>, Unbounded> {
    let eigenvalues = a
        .clone()
        .try_schur(f64::EPSILON, 10_000)
        .ok_or(Unbounded::Indeterminate)?
        .complex_eigenvalues();
    let abscissa = eigenvalues.iter().map(|l| l.re).fold(f64::NEG_INFINITY, f64::max);
    if abscissa >= 0.0 {
        return Err(Unbounded::Unstable { abscissa });
    }
    let radius = eigenvalues.iter().map(|l| l.norm()).fold(0.0, f64::max);
    let w = 1.0 / (INTERVALS_PER_RADIAN * radius);
    let (phi, gamma) = flow(a, w);
    // The weight of the tail bound: its decay rate; A + εI stays Hurwitz.
    let epsilon = -TAIL_DECAY * abscissa;
    let tails: Vec<DMatrix<f64>> = rows
        .iter()
        .map(|c| gramian(a, c, epsilon))
        .collect::<Option<_>>()
        .ok_or(Unbounded::Indeterminate)?;
    // The rows c A^k / k!, k < TERMS, of each output: h's Taylor coefficients are their products
    // with x.
    let taylor_rows: Vec<Vec<DVector<f64>>> = rows
        .iter()
        .map(|c| {
            let mut out = vec![c.clone()];
            for k in 1..TERMS {
                let next = a.tr_mul(&out[k - 1]) / k as f64;
                out.push(next);
            }
            out
        })
        .collect();
    // Σ_{k ≥ CHEAP} |c A^k / k!| w^k, entrywise: its product with |x| bounds the Taylor terms
    // that the cheap test (h cannot vanish on an interval) does not compute.
    let far_terms: Vec<DVector<f64>> = taylor_rows
        .iter()
        .map(|r| (CHEAP..TERMS).fold(DVector::zeros(a.nrows()), |sum, k| sum + r[k].abs() * w.powi(k as i32)))
        .collect();
    let tail = |x: &DVector<f64>, i: usize| (x.dot(&(&tails[i] * x)).max(0.0) / (2.0 * epsilon)).sqrt();
    let mut sums = vec![0.0; rows.len()];
    let mut x = d.clone();
    let mut next = d.clone();
    let mut integral = d.clone();
    let mut coefficients = vec![0.0; TERMS];
    for step in 0..MAX_INTERVALS {
        // Every 64 intervals: done when every tail is negligible.
        if step % 64 == 0 && step > 0 {
            let rests: Vec<f64> = (0..rows.len()).map(|i| tail(&x, i)).collect();
            if rests.iter().zip(&sums).all(|(r, s)| *r <= TAIL_TOLERANCE * s) {
                return Ok(sums.iter().zip(&rests).map(|(s, r)| s + r).collect());
            }
        }
        phi.mul_to(&x, &mut next);
        gamma.mul_to(&x, &mut integral);
        let size = x.abs();
        for (i, r) in taylor_rows.iter().enumerate() {
            // h keeps its sign on the interval when |h(0)| exceeds every other term's reach.
            let h0 = r[0].dot(&x);
            let reach: f64 =
                (1..CHEAP).map(|k| r[k].dot(&x).abs() * w.powi(k as i32)).sum::<f64>() + far_terms[i].dot(&size);
            sums[i] += if h0.abs() > reach {
                r[0].dot(&integral).abs()
            } else {
                for (k, row) in r.iter().enumerate() {
                    coefficients[k] = row.dot(&x);
                }
                abs_integral(&coefficients, w)
            };
        }
        std::mem::swap(&mut x, &mut next);
    }
    // Not decayed within the work cap: the Gramian bound still makes the sum an upper bound.
    Ok((0..rows.len()).map(|i| sums[i] + tail(&x, i)).collect())
}

/// e^{Aw} and ∫_0^w e^{Aσ} dσ, from the exponential of [[A, I], [0, 0]] w.
fn flow(a: &DMatrix<f64>, w: f64) -> (DMatrix<f64>, DMatrix<f64>) {
    let n = a.nrows();
    let mut m = DMatrix::zeros(2 * n, 2 * n);
    m.view_mut((0, 0), (n, n)).copy_from(&(a * w));
    m.view_mut((0, n), (n, n)).copy_from(&(DMatrix::identity(n, n) * w));
    let e = m.exp();
    (e.view((0, 0), (n, n)).into_owned(), e.view((0, n), (n, n)).into_owned())
}

/// ∫_0^w |p(σ)| dσ for the polynomial p = Σ coefficients[k] σ^k: its sign changes found on
/// SUBINTERVALS points and located by bisection to the resolution of σ, each part integrated
/// term by term.
fn abs_integral(coefficients: &[f64], w: f64) -> f64 {
    let value = |s: f64| coefficients.iter().rev().fold(0.0, |acc, c| acc * s + c);
    let primitive = |s: f64| {
        coefficients
            .iter()
            .enumerate()
            .rev()
            .fold(0.0, |acc, (k, c)| acc * s + c / (k + 1) as f64)
            * s
    };
    let mut total = 0.0;
    let (mut from, mut at_from) = (0.0, 0.0);
    let mut previous = (0.0, value(0.0));
    for j in 1..=SUBINTERVALS {
        let s = w * j as f64 / SUBINTERVALS as f64;
        let v = value(s);
        if (previous.1 > 0.0 && v < 0.0) || (previous.1 < 0.0 && v > 0.0) {
            let positive_before = previous.1 > 0.0;
            let (mut lo, mut hi) = (previous.0, s);
            loop {
                let mid = 0.5 * (lo + hi);
                if mid <= lo || mid >= hi {
                    break;
                }
                if (value(mid) > 0.0) == positive_before {
                    lo = mid;
                } else {
                    hi = mid;
                }
            }
            let root = 0.5 * (lo + hi);
            let at_root = primitive(root);
            total += (at_root - at_from).abs();
            (from, at_from) = (root, at_root);
        }
        previous = (s, v);
    }
    debug_assert!(from <= w);
    total + (primitive(w) - at_from).abs()
}

/// W with (A + εI)ᵀ W + W (A + εI) = −cᵀc (by the Kronecker form; None if singular). Then
/// ∫_T^∞ |c x(s)| ds ≤ sqrt(∫ e^{-2ε(s−T)}) sqrt(∫ e^{2ε(s−T)} (c x)²) = sqrt(x(T)ᵀ W x(T) / 2ε).
fn gramian(a: &DMatrix<f64>, c: &DVector<f64>, epsilon: f64) -> Option<DMatrix<f64>> {
    let n = a.nrows();
    let shifted = a + DMatrix::identity(n, n) * epsilon;
    let identity = DMatrix::<f64>::identity(n, n);
    // vec(Aᵀ W + W A) = (I ⊗ Aᵀ + Aᵀ ⊗ I) vec(W), column-major vec.
    let at = shifted.transpose();
    let system = identity.kronecker(&at) + at.kronecker(&identity);
    let rhs = -(c * c.transpose());
    let solution = system.lu().solve(&DVector::from_column_slice(rhs.as_slice()))?;
    let w = DMatrix::from_column_slice(n, n, solution.as_slice());
    Some((&w + w.transpose()) * 0.5)
}

/// The largest Δ meeting the tension accuracy, and the speed accuracy when given, from the
/// bounds per unit Δ (both are linear in Δ). Returns (Δ_max, Δ_max for tension alone, Δ_max for
/// speed alone).
pub fn delta_max(per_delta: Sups, tension_accuracy: f64, accuracy: Option<f64>) -> (f64, f64, Option<f64>) {
    let for_tension = tension_accuracy / per_delta.tension;
    let for_speed = accuracy.map(|eps| eps / per_delta.speed);
    (
        for_speed.map_or(for_tension, |s| s.min(for_tension)),
        for_tension,
        for_speed,
    )
}

/// The inputs of one web design.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Request {
    /// Required tension accuracy ε_T [N].
    pub tension_accuracy: f64,
    /// Required load-speed accuracy ε [rad/s], if any.
    pub accuracy: Option<f64>,
    /// The belt drive (belt geometry).
    pub drive: PlantParams,
    pub web: Web,
    /// Speed PI; `None`: the best-damped rule on the belt drive alone.
    pub gains: Option<PiGains>,
    /// Tension PI (Kp_T [rad/s per N], Ki_T [rad/s² per N]); zero: no tension loop.
    pub tension_gains: PiGains,
}

/// The web design's answer.
pub struct Answer {
    pub request: Request,
    pub gains: PiGains,
    /// The gains came from the best-damped rule.
    pub rule: bool,
    /// Both suprema per unit Δ, and at the requested Δ.
    pub per_delta: Sups,
    pub at_delta: Sups,
    pub delta_max: f64,
    pub delta_max_tension: f64,
    pub delta_max_speed: Option<f64>,
    /// The K_b window in which every accuracy holds at the requested Δ: the study of
    /// max(bound_T_sup/ε_T, bound_sup/ε) against 1.
    pub study: StiffnessStudy,
    /// (K_b, bound_T_sup, bound_sup) on the study's scan.
    pub scan: Vec<(f64, f64, f64)>,
}

/// max(bound_T_sup/ε_T, bound_sup/ε): at most 1 where every accuracy holds.
fn worst_ratio(s: Sups, request: &Request) -> f64 {
    let speed = request.accuracy.map_or(0.0, |eps| s.speed / eps);
    (s.tension / request.tension_accuracy).max(speed)
}

pub fn solve(request: Request) -> Result<Answer, String> {
    let fail = |e: DesignError| e.to_string();
    let drive = request.drive;
    let (gains, rule) = match request.gains {
        Some(g) => (g, false),
        None => {
            let plant = Plant::new(study::with_half_gap(&drive, 0.0)).map_err(|e| e.to_string())?;
            (study::best_damped_gains(&plant).map_err(fail)?.gains, true)
        }
    };
    let (web, tension) = (request.web, request.tension_gains);
    let per_delta = sups(&study::with_half_gap(&drive, 1.0), &web, gains, tension).map_err(|e| match e {
        DesignError::Unbounded { reason, .. } => format!(
            "with Kp = {}, Ki = {}, Kp_T = {}, Ki_T = {} the web loop has no finite bound: {reason}",
            gains.kp, gains.ki, tension.kp, tension.ki
        ),
        e => e.to_string(),
    })?;
    let (delta_max, delta_max_tension, delta_max_speed) =
        delta_max(per_delta, request.tension_accuracy, request.accuracy);
    let at_delta = sups(&drive, &web, gains, tension).map_err(fail)?;
    let evaluated = std::cell::RefCell::new(Vec::new());
    let eval = |k: f64| -> Result<f64, DesignError> {
        // A loop that is not stable meets no accuracy: +∞, as in the speed design.
        let s = match sups(&study::with_stiffness(&drive, k), &web, gains, tension) {
            Err(DesignError::Unbounded { .. }) => Sups {
                tension: f64::INFINITY,
                speed: f64::INFINITY,
            },
            other => other?,
        };
        evaluated.borrow_mut().push((k, s.tension, s.speed));
        Ok(worst_ratio(s, &request))
    };
    let study = study::stiffness_scan(
        study::stiffness(&drive),
        study::half_gap(&drive),
        1.0,
        StiffnessScan::default(),
        &eval,
    )
    .map_err(fail)?;
    let evaluated = evaluated.into_inner();
    let scan = study
        .scan
        .iter()
        .map(|&(k, _)| {
            *evaluated
                .iter()
                .find(|e| e.0 == k)
                .expect("every scan point was evaluated")
        })
        .collect();
    Ok(Answer {
        request,
        gains,
        rule,
        per_delta,
        at_delta,
        delta_max,
        delta_max_tension,
        delta_max_speed,
        study,
        scan,
    })
}

fn parameters(a: &Answer) -> Vec<(&'static str, f64)> {
    let mut named = super::named_parameters(&a.request.drive);
    named.extend(a.request.web.named());
    named
}

/// The answer as text.
pub fn to_text(a: &Answer) -> String {
    let r = &a.request;
    let listed: Vec<String> = parameters(a).iter().map(|(n, v)| format!("{n} = {v}")).collect();
    let mut out = vec![format!(
        "plant (web line: belt drive and one web span): {}",
        listed.join(", ")
    )];
    out.push(format!(
        "speed PI ({}): Kp = {:.6}, Ki = {:.6}; tension PI: {}",
        if a.rule {
            "best-damped rule on the belt drive"
        } else {
            "given"
        },
        a.gains.kp,
        a.gains.ki,
        if r.tension_gains == PiGains::default() {
            "none".to_string()
        } else {
            format!("Kp_T = {}, Ki_T = {}", r.tension_gains.kp, r.tension_gains.ki)
        }
    ));
    out.push(format!(
        "required: tension accuracy eps_T = {:e} N{}",
        r.tension_accuracy,
        r.accuracy
            .map_or(String::new(), |e| format!(", speed accuracy eps = {e:e} rad/s"))
    ));
    out.push(format!(
        "per unit Delta: bound_T_sup {:.9} N/m, bound_sup {:.9} (rad/s)/m; at Delta = {} m: bound_T_sup = {:.6e} N, bound_sup = {:.6e} rad/s",
        a.per_delta.tension,
        a.per_delta.speed,
        study::half_gap(&r.drive),
        a.at_delta.tension,
        a.at_delta.speed
    ));
    out.push(format!(
        "delta_max = {:.9e} m (tension alone {:.9e} m{})",
        a.delta_max,
        a.delta_max_tension,
        a.delta_max_speed
            .map_or(String::new(), |d| format!(", speed alone {d:.9e} m"))
    ));
    let s = &a.study;
    let edge = |c: Option<study::Crossing>, side: &str| {
        c.map_or(format!("none within the scan (feasible to its {side} edge)"), |c| {
            format!("{:.6} N/m", c.k)
        })
    };
    match s.nominal_interval {
        Some(_) => {
            out.push(format!("  K_b min = {}", edge(s.k_min(), "lower")));
            out.push(format!("  K_b max = {}", edge(s.k_max(), "upper")));
        }
        None => out.push(format!(
            "  no: an accuracy is not met at the nominal K_b = {} N/m and Delta = {} m",
            s.k_nominal, s.delta
        )),
    }
    out.join("\n")
}

/// The answer as one JSON object (keys in the README's design section).
pub fn to_json(a: &Answer) -> Value {
    let mut plant = serde_json::Map::new();
    plant.insert("form".into(), json!("web"));
    for (name, value) in parameters(a) {
        plant.insert(name.into(), json!(value));
    }
    let s = &a.study;
    json!({
        "plant": plant,
        "tension_accuracy": a.request.tension_accuracy,
        "accuracy": a.request.accuracy,
        "gain_rule": if a.rule { "best-damped on the belt drive" } else { "given" },
        "Kp": a.gains.kp,
        "Ki": a.gains.ki,
        "Kp_T": a.request.tension_gains.kp,
        "Ki_T": a.request.tension_gains.ki,
        "bound_T_sup_per_unit_delta": a.per_delta.tension,
        "bound_sup_per_unit_delta": a.per_delta.speed,
        "bound_T_sup_at_delta": a.at_delta.tension,
        "bound_sup_at_delta": a.at_delta.speed,
        "delta_max": a.delta_max,
        "delta_max_tension": a.delta_max_tension,
        "delta_max_speed": a.delta_max_speed,
        "k_min": s.k_min().map(|c| c.k),
        "k_max": s.k_max().map(|c| c.k),
        "k_intervals": s.intervals.iter().map(|iv| json!([iv.lo.map(|c| c.k), iv.hi.map(|c| c.k)])).collect::<Vec<_>>(),
        "k_scan": a.scan.iter().map(|(k, t, w)| json!([k, t, w])).collect::<Vec<_>>(),
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use backlash_fmu::physics::closed_loop::reduced_loop_matrix;

    /// The dense norm against the FMU's own bound_sup (sign changes located on Taylor models,
    /// a different method) on the speed loops of both rigs.
    #[test]
    fn the_dense_norm_agrees_with_the_fmu_bound_sup() {
        let belt = crate::design::default_params(crate::design::Form::Belt);
        for (params, gains) in [
            (PlantParams::paper_rig(0.775e-3), PiGains { kp: 42.0, ki: 180.0 }),
            (belt, PiGains { kp: 0.18, ki: 57.6 }),
        ] {
            let plant = Plant::new(params).unwrap();
            let a4 = reduced_loop_matrix(&plant, gains);
            let a = DMatrix::from_iterator(4, 4, a4.iter().copied());
            let p = plant.params();
            let d = DVector::from_vec(vec![0.0, plant.r_m() / p.j_m, -plant.r_l() / p.j_l, 0.0]);
            let c = DVector::from_vec(vec![0.0, 0.0, 1.0, 0.0]);
            let dense = plant.stiffness() * plant.half_gap() * l1_norm(&a, &d, &c).unwrap();
            let fmu = study::bound_sup(&params, gains).unwrap();
            assert!((dense / fmu - 1.0).abs() < 1e-9, "dense {dense} vs bound_sup {fmu}");
        }
    }

    /// A first-order response e^{-s} has ∫|h| = 1; an oscillator e^{-s} sin(ωs) the closed form
    /// of its rectified integral.
    #[test]
    fn the_dense_norm_of_closed_forms() {
        let a = DMatrix::from_row_slice(1, 1, &[-1.0]);
        let one = DVector::from_vec(vec![1.0]);
        assert!((l1_norm(&a, &one, &one).unwrap() - 1.0).abs() < 1e-13);
        // h = e^{-σs} sin(ωs): ∫_0^∞ |h| = (ω/(σ²+ω²)) (1 + e^{-σπ/ω}) / (1 − e^{-σπ/ω}).
        let (sigma, omega) = (0.3, 5.0);
        let a = DMatrix::from_row_slice(2, 2, &[-sigma, omega, -omega, -sigma]);
        let d = DVector::from_vec(vec![0.0, 1.0]);
        let c = DVector::from_vec(vec![1.0, 0.0]);
        let q = (-sigma * std::f64::consts::PI / omega).exp();
        let exact = omega / (sigma * sigma + omega * omega) * (1.0 + q) / (1.0 - q);
        let got = l1_norm(&a, &d, &c).unwrap();
        assert!((got / exact - 1.0).abs() < 1e-11, "{got} vs {exact}");
        let unstable = DMatrix::from_row_slice(1, 1, &[0.1]);
        assert!(l1_norm(&unstable, &one, &one).is_err());
    }
}

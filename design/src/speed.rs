//! The speed design of the shaft and belt forms: for a required load-speed accuracy ε and a PI
//! loop on the motor speed, the PI gains (given, or the best-damped rule), the largest half gap
//! Δ_max and the stiffness window in which `bound_sup` (docs/model.md §3) stays ≤ ε. The
//! computations are in [`crate::study`]; this module runs them for one request and writes the
//! answer as text or JSON.

use serde_json::{json, Value};

use backlash_physics::chain::Coulomb;
use backlash_physics::{closed_loop, Geometry, PiGains, Plant, PlantParams};

use crate::study::{self, Crossing, GainDesign, StiffnessStudy};
use crate::Form;

/// The inputs of one design run.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Request {
    pub accuracy: f64,
    pub params: PlantParams,
    /// Gains given by the user; `None` means the best-damped rule.
    pub gains: Option<PiGains>,
    /// Coulomb friction with stiction in the motor's and the load's bearing (docs/model.md §12).
    pub friction: [Coulomb; 2],
}

/// The answer, with everything needed to write it as text or JSON.
pub struct Answer {
    pub request: Request,
    pub gains: PiGains,
    /// Set when the gains came from the rule.
    pub rule: Option<GainDesign>,
    /// Smallest damping ratio of the backlash-free loop at `gains`.
    pub min_damping: f64,
    /// bound_sup at Δ = 1 and the nominal stiffness [rad/s per unit Δ].
    pub bound_sup_per_delta: f64,
    /// bound_sup at the requested Δ and the nominal stiffness (with the friction's part).
    pub bound_sup_nominal: f64,
    /// The friction's part of bound_sup at the nominal stiffness, the same at every Δ (0 without
    /// friction).
    pub friction_sup: f64,
    /// The largest Δ with bound_sup ≤ ε; None when the friction alone spends ε.
    pub delta_max: Option<f64>,
    pub study: StiffnessStudy,
}

/// The form of a drive's parameters.
fn form_of(params: &PlantParams) -> Form {
    match params.geometry {
        Geometry::Shaft { .. } => Form::Shaft,
        Geometry::Belt { .. } => Form::Belt,
    }
}

/// Units of the stiffness and the half gap of a drive.
fn units(params: &PlantParams) -> (&'static str, &'static str) {
    match params.geometry {
        Geometry::Shaft { .. } => ("N.m/rad", "rad"),
        Geometry::Belt { .. } => ("N/m", "m"),
    }
}

/// Runs the design computations of [`study`] for `request`.
pub fn solve(request: Request) -> Result<Answer, String> {
    let params = request.params;
    let plant = Plant::new(params.with_half_gap(0.0)).map_err(|e| e.to_string())?;
    let (gains, rule) = match request.gains {
        Some(g) => (g, None),
        None => {
            let d = study::best_damped_gains(&plant).map_err(|e| e.to_string())?;
            (d.gains, Some(d))
        }
    };
    let min_damping = study::min_damping_ratio(&plant, gains);
    let friction = request.friction;
    let bound_sup_per_delta = study::bound_sup(&params.with_half_gap(1.0), gains).map_err(|e| e.to_string())?;
    let friction_sup = study::friction_sup(&params, friction, gains).map_err(|e| e.to_string())?;
    let bound_sup_nominal = study::bound_sup(&params, gains).map_err(|e| e.to_string())? + friction_sup;
    let delta_max = study::delta_max(&params, gains, request.accuracy, friction_sup).map_err(|e| e.to_string())?;
    let study = study::stiffness_study(&params, friction, gains, request.accuracy).map_err(|e| e.to_string())?;
    Ok(Answer {
        request,
        gains,
        rule,
        min_damping,
        bound_sup_per_delta,
        bound_sup_nominal,
        friction_sup,
        delta_max,
        study,
    })
}

fn describe_crossing(c: &Option<Crossing>, edge: &str) -> String {
    match c {
        Some(c) => format!(
            "{:.6} (bound_sup there {:.6e}; bracket [{:.4}, {:.4}], bound_sup {} on it: {})",
            c.k,
            c.bound_sup,
            c.bracket.0,
            c.bracket.1,
            if c.decreasing { "decreasing" } else { "increasing" },
            if c.monotone_in_bracket {
                "monotone, checked"
            } else {
                "NOT monotone"
            }
        ),
        None => format!("none within the scan (feasible to its {edge} edge)"),
    }
}

/// The answer as text, one line per item (no final newline).
pub fn to_text(a: &Answer) -> String {
    let p = &a.request.params;
    let form = form_of(p);
    let (k_unit, delta_unit) = units(p);
    let listed: Vec<String> = p
        .named_drive_train()
        .iter()
        .map(|(n, v)| format!("{n} = {v}"))
        .collect();
    let mut out = vec![format!("plant ({} form): {}", form.name(), listed.join(", "))];
    out.push(match &a.rule {
        Some(_) => format!(
            "PI gains (best-damped rule): Kp = {:.6}, Ki = {:.6}; smallest closed-loop damping ratio {:.6}",
            a.gains.kp, a.gains.ki, a.min_damping
        ),
        None => format!(
            "PI gains (given): Kp = {}, Ki = {}; smallest closed-loop damping ratio {:.6}",
            a.gains.kp, a.gains.ki, a.min_damping
        ),
    });
    out.push(format!("required accuracy eps = {:e} rad/s", a.request.accuracy));
    out.push(format!(
        "bound_sup per unit Delta at k = {} {k_unit}: {:.9} (rad/s)/{delta_unit}",
        study::stiffness(p),
        a.bound_sup_per_delta
    ));
    out.push(friction_text(a));
    out.push(match a.delta_max {
        Some(delta_max) => format!(
            "delta_max = {:.9e} {delta_unit} (gap 2*delta_max = {:.9e}); at Delta = {}: bound_sup = {:.6e}",
            delta_max,
            2.0 * delta_max,
            study::half_gap(p),
            a.bound_sup_nominal
        ),
        None => format!(
            "delta_max: none: bearing friction alone spends the accuracy ({:.6e} >= eps); at Delta = {}: \
             bound_sup = {:.6e}",
            a.friction_sup,
            study::half_gap(p),
            a.bound_sup_nominal
        ),
    });
    let s = &a.study;
    out.push(format!(
        "stiffness at Delta = {} {delta_unit} (scan {} points, k in [{:.4}, {:.4}] {k_unit}): bound_sup is {}",
        s.delta,
        s.scan.len(),
        s.scan.first().map_or(0.0, |x| x.0),
        s.scan.last().map_or(0.0, |x| x.0),
        if s.monotone() {
            "monotone in k".to_string()
        } else {
            format!(
                "NOT monotone in k (turning points near k = {})",
                join(&s.turning_points)
            )
        }
    ));
    match s.nominal_interval {
        Some(_) => {
            out.push(format!("  k_min = {}", describe_crossing(&s.k_min(), "lower")));
            out.push(format!("  k_max = {}", describe_crossing(&s.k_max(), "upper")));
        }
        None => out.push(format!(
            "  no: bound_sup > eps at the nominal k = {}; no k_min on its branch",
            s.k_nominal
        )),
    }
    for iv in &s.intervals {
        out.push(format!(
            "  feasible interval: [{}, {}]",
            iv.lo.map_or("<scan edge".to_string(), |c| format!("{:.6}", c.k)),
            iv.hi.map_or(">scan edge".to_string(), |c| format!("{:.6}", c.k))
        ));
    }
    out.join("\n")
}

/// Whether the answer holds with bearing friction (docs/model.md §10, §12), on one line.
fn friction_text(a: &Answer) -> String {
    let [m, l] = a.request.friction;
    match a.friction_sup {
        0.0 => "bearing friction: none (tau_c_m = tau_c_L = 0); with Coulomb friction bound_sup gains \
                2 peak tau_c int|h_b| per body, which no gap shrinks: give --tau-c-m/--tau-c-l to include it"
            .to_string(),
        f => format!(
            "bearing friction: tau_c_m = {}, peak_m = {}, tau_c_L = {}, peak_L = {}: its part of bound_sup is \
             {f:.6e} rad/s at every Delta (docs/model.md §10), included below",
            m.tau_c, m.peak, l.tau_c, l.peak
        ),
    }
}

fn join(values: &[f64]) -> String {
    values.iter().map(|v| format!("{v:.4}")).collect::<Vec<_>>().join(", ")
}

/// A crossing's details, or null.
fn crossing_json(c: &Option<Crossing>) -> Value {
    match c {
        None => Value::Null,
        Some(c) => json!({
            "k": c.k,
            "bound_sup": c.bound_sup,
            "bracket": [c.bracket.0, c.bracket.1],
            "monotone_in_bracket": c.monotone_in_bracket,
            "decreasing": c.decreasing,
        }),
    }
}

/// The answer as one JSON object (keys documented in docs/design-a-drive.md): each
/// top-level key on its line, its value on that line (no final newline). Numbers are shortest
/// round-trip; JSON has no infinity or NaN, so those become null.
pub fn to_json(a: &Answer) -> String {
    crate::layout::laid_out(&to_value(a))
}

/// The answer as a JSON value.
pub fn to_value(a: &Answer) -> Value {
    let p = &a.request.params;
    let s = &a.study;
    let poles = match &a.rule {
        Some(d) => d.poles.to_vec(),
        None => {
            let plant = Plant::new(p.with_half_gap(0.0)).expect("validated in solve");
            closed_loop::reduced_loop_poles(&plant, a.gains).to_vec()
        }
    };
    let gain_rule = if a.rule.is_some() {
        "best-damped: maximise the smallest damping ratio of the backlash-free closed-loop poles"
    } else {
        "given"
    };
    let mut plant = serde_json::Map::new();
    plant.insert("form".into(), json!(form_of(p).name()));
    for (name, value) in p.named_drive_train() {
        plant.insert(name.into(), json!(value));
    }
    json!({
        "plant": plant,
        "accuracy": a.request.accuracy,
        "gain_rule": gain_rule,
        "Kp": a.gains.kp,
        "Ki": a.gains.ki,
        "min_damping_ratio": a.min_damping,
        "poles": poles.iter().map(|z| json!([z.re, z.im])).collect::<Vec<_>>(),
        "bound_sup_per_unit_delta": a.bound_sup_per_delta,
        "bound_sup_at_delta": a.bound_sup_nominal,
        "friction": {
            "tau_c_m": a.request.friction[0].tau_c,
            "peak_m": a.request.friction[0].peak,
            "tau_c_L": a.request.friction[1].tau_c,
            "peak_L": a.request.friction[1].peak,
        },
        "bound_sup_friction": a.friction_sup,
        "delta_max": a.delta_max,
        "k_min": s.k_min().map(|c| c.k),
        "k_max": s.k_max().map(|c| c.k),
        "k_min_detail": crossing_json(&s.k_min()),
        "k_max_detail": crossing_json(&s.k_max()),
        "k_monotone": s.monotone(),
        "k_turning_points": s.turning_points,
        "k_intervals": s.intervals.iter().map(|iv| json!([iv.lo.map(|c| c.k), iv.hi.map(|c| c.k)])).collect::<Vec<_>>(),
        "k_scan": s.scan.iter().map(|(k, b)| json!([k, b])).collect::<Vec<_>>(),
    })
}

//! The tension half of the paper's future work: which backlash and belt stiffness keep the web
//! tension (and, if asked, the load speed) within a given accuracy (docs/model.md §8).
//!
//! The web line is the belt drive of docs/model.md §1 whose load is a roller of radius R_w
//! pulling one span of web (length L_w, stiffness EA, transport speed v_ref), with the speed PI of
//! §3 and an optional outer PI on tension that trims the speed reference. Backlash enters as the
//! bounded disturbance φ (|φ| ≤ K g) of §3, so the deviations it causes are bounded by
//! `bound_T_sup = K g ∫_0^∞ |h_T|` (tension) and `bound_sup = K g ∫_0^∞ |h|` (load speed), h_T
//! and h the impulse responses from φ of the backlash-free loop, computed by the plant library
//! ([`WebTensionBound`], [`WebSpeedBound`], docs/model.md §8).

use serde_json::{json, Value};

use backlash_physics::{Damping, PiGains, Plant, PlantParams, WebSpeedBound, WebTensionBound};

use crate::study::{self, DesignError, StiffnessScan, StiffnessStudy};

/// The web span and roller driven by the belt drive (docs/model.md §8).
pub use backlash_physics::WebSpan as Web;

/// BacklashWeb.fmu's web span (its parameters' start values): a film line, 50 mm roller, 1 m
/// span, EA = 1e5 N (e.g. 50 µm PET, 0.5 m wide), 2 m/s.
pub fn film_line() -> Result<Web, DesignError> {
    let identifier = "BacklashWeb";
    crate::described_params(identifier)?
        .web
        .ok_or(DesignError::NoWebSpan { identifier })
}

/// Both suprema for one parameter set.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Sups {
    /// Bound on |T with backlash − T without| [N].
    pub tension: f64,
    /// Bound on |ω_L with backlash − ω_L without| [rad/s].
    pub speed: f64,
}

/// `bound_T_sup` and `bound_sup` of the web line (the plant library's [`WebTensionBound`] and
/// [`WebSpeedBound`]); `DesignError::Unbounded` when the loop is not asymptotically stable.
pub fn sups(drive: &PlantParams, web: &Web, speed: PiGains, tension: PiGains) -> Result<Sups, DesignError> {
    let plant = Plant::new(PlantParams {
        damping: Damping::NONE,
        web: Some(*web),
        ..*drive
    })?;
    let unbounded = |reason| DesignError::Unbounded {
        kp: speed.kp,
        ki: speed.ki,
        reason,
    };
    Ok(Sups {
        tension: WebTensionBound::new(&plant, speed, tension)?.sup().map_err(unbounded)?,
        speed: WebSpeedBound::new(&plant, speed, tension)?.sup().map_err(unbounded)?,
    })
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

/// Runs the web design for `request` (gains, both suprema, Δ_max and the K_b window).
pub fn solve(request: Request) -> Result<Answer, String> {
    let fail = |e: DesignError| e.to_string();
    let drive = request.drive;
    let (gains, rule) = match request.gains {
        Some(g) => (g, false),
        None => {
            let plant = Plant::new(drive.with_half_gap(0.0)).map_err(|e| e.to_string())?;
            (study::best_damped_gains(&plant).map_err(fail)?.gains, true)
        }
    };
    let (web, tension) = (request.web, request.tension_gains);
    let per_delta = sups(&drive.with_half_gap(1.0), &web, gains, tension).map_err(|e| match e {
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
    let mut named = a.request.drive.named_drive_train();
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

/// The answer as one JSON object (keys in docs/design-a-drive.md), laid out as
/// [`crate::speed::to_json`] lays out the speed answer.
pub fn to_json(a: &Answer) -> String {
    crate::layout::laid_out(&to_value(a))
}

/// The answer as a JSON value.
pub fn to_value(a: &Answer) -> Value {
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

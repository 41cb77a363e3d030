//! The design of a two-stage gearbox (docs/model.md §10, `BacklashTwoStage`): for a required
//! load-speed accuracy ε and a PI loop on the motor speed, which mesh's backlash costs the
//! accuracy. `bound_sup` = s_1 Δ_1 + s_2 Δ_2 is linear in each half gap (s_j is stage j's
//! `bound_sup` per unit of its gap, the rest of the drive held), so the admissible gaps form the
//! triangle s_1 Δ_1 + s_2 Δ_2 ≤ ε: this module gives its corners ε/s_j, the largest Δ_j with the
//! other gap at its value, and the stage whose gap spends more of the bound.

use backlash_physics::chain::{self, Chain, ChainParams, TwoStageBound};
use backlash_physics::PiGains;
use nalgebra::Complex;
use serde_json::{json, Value};

use crate::study::{self, damping_ratio, DesignError};

/// The inputs of one two-stage design.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Request {
    pub accuracy: f64,
    pub drive: ChainParams<2>,
    /// Gains given by the user; `None` means the best-damped rule.
    pub gains: Option<PiGains>,
}

/// What one stage's gap does to the bound.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct StageAnswer {
    /// s_j: `bound_sup` per unit of Δ_j [rad/s per rad].
    pub per_delta: f64,
    /// Δ_j as given [rad].
    pub delta: f64,
    /// s_j Δ_j: its part of `bound_sup` at the given gaps [rad/s].
    pub share: f64,
    /// ε / s_j: the largest Δ_j with the other gap closed [rad].
    pub delta_max_alone: f64,
    /// (ε − s_k Δ_k) / s_j: the largest Δ_j with the other gap at its value; None when the other
    /// gap alone already spends the accuracy [rad].
    pub delta_max: Option<f64>,
}

/// The answer, with everything needed to write it as text or JSON.
pub struct Answer {
    pub request: Request,
    pub gains: PiGains,
    /// Whether the gains came from the best-damped rule.
    pub rule: bool,
    pub min_damping: f64,
    pub poles: Vec<Complex<f64>>,
    pub stages: [StageAnswer; 2],
    /// s_1 Δ_1 + s_2 Δ_2 [rad/s].
    pub bound_sup: f64,
}

impl Answer {
    /// Stage (1 or 2) whose gap spends more of `bound_sup` at the given gaps (1 on a tie).
    pub fn dominant(&self) -> usize {
        if self.stages[1].share > self.stages[0].share {
            2
        } else {
            1
        }
    }

    pub fn meets(&self) -> bool {
        self.bound_sup <= self.request.accuracy
    }
}

/// The FMU whose drive this form designs: its parameters' names, start values and mapping to
/// the chain are its description's (`modelDescription/src/models/two_stage.rs`).
pub const MODEL: &str = "BacklashTwoStage";

/// [`MODEL`]'s parameters by name at their start values: the default drive, before settings.
pub fn default_values() -> Result<Vec<(&'static str, f64)>, DesignError> {
    model_description::default_parameters(MODEL).ok_or(DesignError::NoModel { identifier: MODEL })
}

/// The drive of [`MODEL`] at the parameter `values` (as [`default_values`] lists them, each
/// admitted by its setting's range), by the model's own mapping.
pub fn drive_of(values: &[(&'static str, f64)]) -> Result<ChainParams<2>, DesignError> {
    model_description::two_stage_params(MODEL, values).ok_or(DesignError::NoModel { identifier: MODEL })
}

/// The drive's parameters by their names in docs/model.md §10 (the inverse of [`drive_of`]: a
/// test maps them back).
pub fn named(drive: &ChainParams<2>) -> [(&'static str, f64); 15] {
    let [first, second] = drive.stages;
    let [shaft, load] = drive.driven;
    [
        ("J_m", drive.motor.j),
        ("J_i", shaft.j),
        ("J_L", load.j),
        ("b_m", drive.motor.b),
        ("b_i", shaft.b),
        ("b_L", load.b),
        ("n_1", first.c),
        ("n_2", second.c),
        ("k_1", first.k),
        ("k_2", second.k),
        ("Delta_1", first.g),
        ("Delta_2", second.g),
        ("d_1", first.damper.d),
        ("d_2", second.damper.d),
        ("contact_law", f64::from(first.damper.law.code())),
    ]
}

/// The smallest damping ratio of the backlash-free loop's poles at `gains`; −∞ if they cannot be
/// computed.
fn min_damping(chain: &Chain<2>, gains: PiGains) -> (f64, Vec<Complex<f64>>) {
    match chain::loop_poles::<2, 7>(chain, gains) {
        Some(poles) => (
            poles.iter().map(|&p| damping_ratio(p)).fold(f64::INFINITY, f64::min),
            poles,
        ),
        None => (f64::NEG_INFINITY, Vec::new()),
    }
}

/// Runs the design for `request`.
pub fn solve(request: Request) -> Result<Answer, String> {
    let chain = Chain::new(request.drive).map_err(|e| e.to_string())?;
    if chain.has_friction() {
        // The answer shares the tolerance among the gaps' terms, linear in each g_j; the
        // friction's term (docs/model.md §10) does not shrink with the gaps.
        return Err(
            "a body of the drive has Coulomb friction: the two-stage design shares the tolerance among the gaps only"
                .to_string(),
        );
    }
    let (gains, rule) = match request.gains {
        Some(gains) => (gains, false),
        None => {
            let d = &request.drive;
            // The inertia reflected to the motor through both ratios, and the fastest contact
            // rate of the chain to centre the search on (it spans ±3 decades).
            let (n1, n2) = (d.stages[0].c / d.stages[0].a, d.stages[1].c / d.stages[1].a);
            let j_eq = d.motor.j + d.driven[0].j / (n1 * n1) + d.driven[1].j / (n1 * n1 * n2 * n2);
            let search = |g| min_damping(&chain, g).0;
            let (gains, _) =
                study::best_damped_search(&search, j_eq, chain.fastest_rate()).map_err(|e| e.to_string())?;
            (gains, true)
        }
    };
    let (min_damping, poles) = min_damping(&chain, gains);
    // s_j: the bound of the same drive with unit gaps, stage by stage.
    let mut unit = request.drive;
    for stage in &mut unit.stages {
        stage.g = 1.0;
    }
    let unit = Chain::new(unit).map_err(|e| e.to_string())?;
    let bound = TwoStageBound::new(&unit, gains).map_err(|e| e.to_string())?;
    let unbounded = |reason| {
        format!(
            "with Kp = {}, Ki = {} the bound is infinite: {reason}",
            gains.kp, gains.ki
        )
    };
    let per_delta = [bound.stage_sup(0), bound.stage_sup(1)];
    let per_delta = [per_delta[0].map_err(unbounded)?, per_delta[1].map_err(unbounded)?];
    let eps = request.accuracy;
    let deltas = [request.drive.stages[0].g, request.drive.stages[1].g];
    let stages: [StageAnswer; 2] = std::array::from_fn(|j| {
        let other = per_delta[1 - j] * deltas[1 - j];
        StageAnswer {
            per_delta: per_delta[j],
            delta: deltas[j],
            share: per_delta[j] * deltas[j],
            delta_max_alone: eps / per_delta[j],
            delta_max: (other < eps).then(|| (eps - other) / per_delta[j]),
        }
    });
    Ok(Answer {
        request,
        gains,
        rule,
        min_damping,
        poles,
        bound_sup: stages[0].share + stages[1].share,
        stages,
    })
}

/// The answer as text, one line per item (no final newline).
pub fn to_text(a: &Answer) -> String {
    let listed: Vec<String> = named(&a.request.drive)
        .iter()
        .map(|(n, v)| format!("{n} = {v}"))
        .collect();
    let mut out = vec![format!("plant (two-stage form): {}", listed.join(", "))];
    out.push(format!(
        "PI gains ({}): Kp = {}, Ki = {}; smallest closed-loop damping ratio {:.6}",
        if a.rule { "best-damped rule" } else { "given" },
        a.gains.kp,
        a.gains.ki,
        a.min_damping
    ));
    out.push(format!("required accuracy eps = {:e} rad/s", a.request.accuracy));
    for (j, s) in a.stages.iter().enumerate() {
        let n = j + 1;
        out.push(format!(
            "stage {n}: bound_sup per unit Delta_{n} {:.9} (rad/s)/rad; at Delta_{n} = {} rad it spends {:.6e} rad/s ({:.1}%)",
            s.per_delta,
            s.delta,
            s.share,
            100.0 * s.share / a.bound_sup.max(f64::MIN_POSITIVE)
        ));
        let other = 2 - j;
        out.push(match s.delta_max {
            Some(max) => format!(
                "  delta_max of Delta_{n} = {max:.9e} rad with Delta_{other} at its value ({:.9e} rad with Delta_{other} = 0)",
                s.delta_max_alone
            ),
            None => format!(
                "  delta_max of Delta_{n}: none, Delta_{other} alone spends the accuracy ({:.9e} rad with Delta_{other} = 0)",
                s.delta_max_alone
            ),
        });
    }
    out.push(format!(
        "bound_sup at the given gaps = {:.6e} rad/s: {}; stage {} dominates",
        a.bound_sup,
        if a.meets() { "meets eps" } else { "does NOT meet eps" },
        a.dominant()
    ));
    out.join("\n")
}

/// The answer as one JSON object (keys documented in docs/design-a-drive.md), laid out as the
/// other forms' answers.
pub fn to_json(a: &Answer) -> String {
    crate::layout::laid_out(&to_value(a))
}

/// The answer as a JSON value.
pub fn to_value(a: &Answer) -> Value {
    let mut plant = serde_json::Map::new();
    plant.insert("form".into(), json!("two-stage"));
    for (name, value) in named(&a.request.drive) {
        plant.insert(name.into(), json!(value));
    }
    let stages: Vec<Value> = a
        .stages
        .iter()
        .enumerate()
        .map(|(j, s)| {
            json!({
                "stage": j + 1,
                "bound_sup_per_unit_delta": s.per_delta,
                "delta": s.delta,
                "bound_sup_share": s.share,
                "delta_max": s.delta_max,
                "delta_max_alone": s.delta_max_alone,
            })
        })
        .collect();
    json!({
        "plant": plant,
        "accuracy": a.request.accuracy,
        "gain_rule": if a.rule {
            "best-damped: maximise the smallest damping ratio of the backlash-free closed-loop poles"
        } else {
            "given"
        },
        "Kp": a.gains.kp,
        "Ki": a.gains.ki,
        "min_damping_ratio": a.min_damping,
        "poles": a.poles.iter().map(|z| json!([z.re, z.im])).collect::<Vec<_>>(),
        "stages": stages,
        "bound_sup": a.bound_sup,
        "meets": a.meets(),
        "dominant_stage": a.dominant(),
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn request(gains: Option<PiGains>) -> Request {
        Request {
            accuracy: 0.05,
            drive: ChainParams::two_stage_rig(),
            gains,
        }
    }

    #[test]
    fn the_gaps_at_their_largest_spend_the_accuracy() {
        let answer = solve(request(Some(PiGains { kp: 42.0, ki: 180.0 }))).unwrap();
        for (j, s) in answer.stages.iter().enumerate() {
            // Δ_j at its largest, the other at its value: the bound of that drive, computed
            // afresh, is ε (to the bound's own relative slack and the division's rounding).
            let Some(max) = s.delta_max else { continue };
            let mut drive = answer.request.drive;
            drive.stages[j].g = max;
            let bound = TwoStageBound::new(&Chain::new(drive).unwrap(), answer.gains).unwrap();
            let sup = bound.sup().unwrap();
            assert!((sup - 0.05).abs() <= 1e-12 * 0.05, "stage {j}: {sup}");
        }
        let direct = TwoStageBound::new(&Chain::new(answer.request.drive).unwrap(), answer.gains)
            .unwrap()
            .sup()
            .unwrap();
        assert!((answer.bound_sup - direct).abs() <= 1e-12 * direct);
    }

    #[test]
    fn the_rule_gives_a_better_damped_loop_than_its_neighbours() {
        let answer = solve(request(None)).unwrap();
        assert!(answer.rule && answer.min_damping > 0.0);
        let chain = Chain::new(answer.request.drive).unwrap();
        for (fk, fi) in [(1.05, 1.0), (0.95, 1.0), (1.0, 1.05), (1.0, 0.95)] {
            let near = PiGains {
                kp: answer.gains.kp * fk,
                ki: answer.gains.ki * fi,
            };
            assert!(min_damping(&chain, near).0 <= answer.min_damping + 1e-9);
        }
    }
}

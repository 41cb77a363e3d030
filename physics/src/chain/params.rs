//! The chain's parameters and their validation: bodies (J, b) joined by stages (a, c, K, g)
//! (docs/model.md §1 for one stage, docs/model.md §10 for several).

use crate::damper::DampedMember;
use crate::params::{ContactLaw, Damping, Plant, WebSpan, SCALE_LIMIT};
use std::fmt;
use thiserror::Error;

/// One rigid body of the chain.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Body {
    /// Inertia J [kg·m²].
    pub j: f64,
    /// Viscous friction b [N·m·s/rad].
    pub b: f64,
    /// Coulomb friction with stiction in its bearing (none: [`Coulomb::NONE`]).
    pub friction: Coulomb,
}

impl Body {
    /// A body without Coulomb friction.
    pub const fn new(j: f64, b: f64) -> Body {
        Body {
            j,
            b,
            friction: Coulomb::NONE,
        }
    }
}

/// Coulomb friction with stiction in a body's bearing (Modelica's `BearingFriction` with a
/// constant `tau_pos` and its `peak`): sliding, the torque ∓`tau_c` against the motion; at rest,
/// whatever holds the body still up to the breakaway torque `peak`·`tau_c`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Coulomb {
    /// The sliding friction torque τ_c ≥ 0 [N·m] (0: no friction modes).
    pub tau_c: f64,
    /// Breakaway over sliding, peak ≥ 1.
    pub peak: f64,
}

impl Coulomb {
    pub const NONE: Coulomb = Coulomb { tau_c: 0.0, peak: 1.0 };

    /// The breakaway torque peak·τ_c [N·m].
    pub fn breakaway(&self) -> f64 {
        self.peak * self.tau_c
    }
}

/// One stage: a compliant member in series with a backlash between body i and body i + 1.
/// Its coordinate is u = a θ_i − c θ_{i+1}, its force ψ = K dz(u, g) without a damper, or with
/// a damper D in parallel with the spring the clipped force of docs/model.md §1 under its law;
/// body i receives −a ψ and body i + 1 receives +c ψ (docs/model.md §1 with r_m = a, r_L = c).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Stage {
    /// Lever arm of the driving body, a (the shaft's 1, the belt's R_1 [m]).
    pub a: f64,
    /// Lever arm of the driven body, c (the shaft's 1, the belt's α_1 [m], docs/model.md §10's n_j).
    pub c: f64,
    /// Stiffness K [N·m/rad, or N/m when u is a length].
    pub k: f64,
    /// Half gap g in u [rad, or m] (the shaft's Δ, the belt's α_2 Δ).
    pub g: f64,
    /// The damper in parallel with the spring: D in u's units [N·m·s/rad, or N·s/m] (0: none)
    /// and its contact law (docs/model.md §1).
    pub damper: Damping,
}

impl Stage {
    /// D of the damper (0 without one).
    pub fn d(&self) -> f64 {
        self.damper.d
    }

    /// Law 1 (`ElastoBacklash`) with a damper: the capped modes exist.
    pub fn capped(&self) -> bool {
        self.damper.d > 0.0 && self.damper.law == ContactLaw::ElastoBacklash
    }

    /// The stage's damper as its surfaces see it (crate::damper), for a stage with one.
    #[inline(always)]
    pub(crate) fn damped_member(&self) -> DampedMember {
        DampedMember {
            k: self.k,
            d: self.d(),
            g: self.g,
            law1: self.capped(),
        }
    }
}

/// Parameters of a chain of S stages as a user gives them: body 0 (the motor, which τ_m
/// drives), then stage i joining body i to body i + 1, body S being the load (which τ_L acts on).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ChainParams<const S: usize> {
    /// Body 0, the motor.
    pub motor: Body,
    /// Bodies 1..=S; `driven[i]` is the body stage i drives.
    pub driven: [Body; S],
    /// Stages 0..S; stage i joins body i to body i + 1 (docs/model.md §10's stage j = i + 1).
    pub stages: [Stage; S],
    /// A web span pulled by a roller on the last body (docs/model.md §8), or none.
    pub web: Option<WebSpan>,
}

impl<const S: usize> ChainParams<S> {
    /// Body `j` (0 ..= S).
    pub fn body(&self, j: usize) -> &Body {
        if j == 0 {
            &self.motor
        } else {
            &self.driven[j - 1]
        }
    }
}

impl ChainParams<1> {
    /// The one-stage chain of a plant of docs/model.md §1 (shaft or belt): a = r_m, c = r_L,
    /// K, g, its damper and its web span (§8).
    pub fn from_plant(plant: &Plant) -> Option<ChainParams<1>> {
        let p = plant.params();
        Some(ChainParams {
            motor: Body::new(p.j_m, p.b_m),
            driven: [Body::new(p.j_l, p.b_l)],
            stages: [Stage {
                a: plant.r_m(),
                c: plant.r_l(),
                k: plant.stiffness(),
                g: plant.half_gap(),
                damper: Damping {
                    d: plant.damping(),
                    law: plant.contact_law(),
                },
            }],
            web: plant.web().copied(),
        })
    }
}

impl ChainParams<2> {
    /// `BacklashTwoStage`'s drive (docs/model.md §10): the paper's rig (docs/model.md §4) with
    /// its compliance and its gap split over two meshes of ratio 1: motor J_m = 2.28, load
    /// J_L = 2.55 kg·m² (b = 0.05 N·m·s/rad each), a light intermediate shaft J_i = 0.1 kg·m²
    /// (b_i = 0.01), each stage k = 400 N·m/rad (200 in series, the rig's k) and half gap
    /// Δ = 0.3875 mrad (0.775 mrad in all, the rig's Δ of Fig. 11).
    pub fn two_stage_rig() -> ChainParams<2> {
        let stage = Stage {
            a: 1.0,
            c: 1.0,
            k: 400.0,
            g: 0.3875e-3,
            damper: Damping::NONE,
        };
        ChainParams {
            motor: Body::new(2.28, 0.05),
            driven: [Body::new(0.1, 0.01), Body::new(2.55, 0.05)],
            stages: [stage; 2],
            web: None,
        }
    }
}

/// Where an invalid parameter sits.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Part {
    Body(usize),
    Stage(usize),
    /// The web span on the last body.
    Web,
}

impl fmt::Display for Part {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Part::Body(j) => write!(f, "body {j}"),
            Part::Stage(i) => write!(f, "stage {i}"),
            Part::Web => write!(f, "the web span"),
        }
    }
}

/// An invalid chain parameter: names it, where it sits, and its value.
#[derive(Clone, Copy, Debug, PartialEq, Error)]
pub enum ChainError {
    #[error("parameter {name} of {at} = {value} must be finite")]
    NotFinite { at: Part, name: &'static str, value: f64 },
    #[error("parameter {name} of {at} = {value} must be > 0")]
    NotPositive { at: Part, name: &'static str, value: f64 },
    #[error("parameter {name} of {at} = {value} must be >= 0")]
    Negative { at: Part, name: &'static str, value: f64 },
    #[error("parameter {name} of {at} = {value:e} is outside the range the chain integrates: 0 or 1e-100 ..= 1e100 in magnitude")]
    OutOfScale { at: Part, name: &'static str, value: f64 },
    #[error("parameter peak of {at} = {value} must be >= 1 (the breakaway torque is peak times tau_c)")]
    PeakBelowOne { at: Part, value: f64 },
    #[error("{name} of {at} = {value:e}, derived from the parameters, is outside 1e-200 ..= 1e200: the time scales of the chain are too far apart to integrate")]
    DerivedOutOfScale { at: Part, name: &'static str, value: f64 },
}

/// `value` checked finite, in scale (as params.rs's [`SCALE_LIMIT`]: products of a few
/// parameters must stay in f64), and > 0 when `positive`, else ≥ 0.
fn check(at: Part, name: &'static str, value: f64, positive: bool) -> Result<(), ChainError> {
    if !value.is_finite() {
        return Err(ChainError::NotFinite { at, name, value });
    }
    if positive && value <= 0.0 {
        return Err(ChainError::NotPositive { at, name, value });
    }
    if value < 0.0 {
        return Err(ChainError::Negative { at, name, value });
    }
    if value != 0.0 && !(1.0 / SCALE_LIMIT..=SCALE_LIMIT).contains(&value) {
        return Err(ChainError::OutOfScale { at, name, value });
    }
    Ok(())
}

/// A validated chain of S stages.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Chain<const S: usize> {
    params: ChainParams<S>,
}

impl<const S: usize> Chain<S> {
    /// Validates `params`: J > 0, b ≥ 0 for every body; a, c, K > 0 and g ≥ 0 for every stage;
    /// all finite and in scale. A chain has at least one stage.
    pub fn new(params: ChainParams<S>) -> Result<Chain<S>, ChainError> {
        assert!(S >= 1, "a chain has at least one stage");
        for j in 0..=S {
            let body = params.body(j);
            check(Part::Body(j), "J", body.j, true)?;
            check(Part::Body(j), "b", body.b, false)?;
            check(Part::Body(j), "tau_c", body.friction.tau_c, false)?;
            check(Part::Body(j), "peak", body.friction.peak, true)?;
            if body.friction.peak < 1.0 {
                return Err(ChainError::PeakBelowOne {
                    at: Part::Body(j),
                    value: body.friction.peak,
                });
            }
        }
        for (i, stage) in params.stages.iter().enumerate() {
            check(Part::Stage(i), "a", stage.a, true)?;
            check(Part::Stage(i), "c", stage.c, true)?;
            check(Part::Stage(i), "K", stage.k, true)?;
            check(Part::Stage(i), "g", stage.g, false)?;
            check(Part::Stage(i), "D", stage.d(), false)?;
        }
        // The rates and forces the integration works with, as params.rs's Plant::new checks
        // them: square rates K a²/J and K c²/J, damping rates b/J, input accelerations 1/J, the
        // gap force K g and the lever ratio c/a. Outside 1e±200 they over- or underflow in
        // products.
        let (first, last) = (params.body(0), params.body(S));
        let inputs = [
            ("1/J", Part::Body(0), 1.0 / first.j),
            ("1/J", Part::Body(S), 1.0 / last.j),
        ];
        let bodies = (0..=S).flat_map(|j| {
            let body = params.body(j);
            [
                ("b/J", Part::Body(j), body.b / body.j),
                ("tau_c/J", Part::Body(j), body.friction.tau_c / body.j),
            ]
        });
        let stages = params.stages.iter().enumerate().flat_map(|(i, s)| {
            let (driving, driven) = (params.body(i).j, params.body(i + 1).j);
            [
                ("K*a^2/J", Part::Stage(i), s.k * s.a * s.a / driving),
                ("K*c^2/J", Part::Stage(i), s.k * s.c * s.c / driven),
                ("K*g", Part::Stage(i), s.k * s.g),
                ("c/a", Part::Stage(i), s.c / s.a),
                ("D*a^2/J", Part::Stage(i), s.d() * s.a * s.a / driving),
                ("D*c^2/J", Part::Stage(i), s.d() * s.c * s.c / driven),
                ("D/K", Part::Stage(i), s.d() / s.k),
            ]
        });
        if let Some(w) = &params.web {
            for (name, value) in [("R_w", w.r_w), ("L_w", w.l_w), ("EA", w.ea), ("v_ref", w.v_ref)] {
                check(Part::Web, name, value, true)?;
            }
        }
        let web = params.web.iter().flat_map(|w| {
            [
                ("EA*R_w^2/(L_w*J)", Part::Web, w.ea * w.r_w * w.r_w / (w.l_w * last.j)),
                ("v_ref/L_w", Part::Web, w.v_ref / w.l_w),
                ("EA/L_w", Part::Web, w.ea / w.l_w),
            ]
        });
        for (name, at, value) in inputs.into_iter().chain(bodies).chain(stages).chain(web) {
            if value != 0.0 && !(1e-200..=1e200).contains(&value) {
                return Err(ChainError::DerivedOutOfScale { at, name, value });
            }
        }
        Ok(Chain { params })
    }

    pub fn params(&self) -> &ChainParams<S> {
        &self.params
    }

    /// Body `j` (0 ..= S).
    pub fn body(&self, j: usize) -> &Body {
        self.params.body(j)
    }

    /// Stage `i` (0 .. S).
    pub fn stage(&self, i: usize) -> &Stage {
        &self.params.stages[i]
    }

    /// The chain's fastest rate [1/s]: the larger of the damping rates b/J, the bound
    /// √(Σ_i K_i (a_i²/J_i + c_i²/J_{i+1})) on the contact frequencies (the trace of the
    /// mass-normalized stiffness; for one stage exactly docs/model.md §2's ω_0), with a damper
    /// under law 1 the capped contact's √2 times it, and each damper's rate
    /// D_i (a_i²/J_i + c_i²/J_{i+1}) (for one stage docs/model.md §2's rate, term for term); with
    /// a web span the frequency of the springs and the span together,
    /// √(ω_0² + EA R_w²/(L_w J_S)), and the span's relaxation rate v_ref/L_w.
    pub fn fastest_rate(&self) -> f64 {
        let rate = self.drive_rate();
        match &self.params.web {
            None => rate.0,
            Some(w) => {
                let web_sq = w.ea * w.r_w * w.r_w / (w.l_w * self.body(S).j);
                let omega0 = rate.1;
                rate.0.max((omega0 * omega0 + web_sq).sqrt()).max(w.v_ref / w.l_w)
            }
        }
    }

    /// a_i²/J_i + c_i²/J_{i+1}: how stage i's stiffness accelerates its two bodies apart.
    fn kappa(&self, i: usize) -> f64 {
        let s = self.stage(i);
        s.a * s.a / self.body(i).j + s.c * s.c / self.body(i + 1).j
    }

    /// The bound √(Σ_i K_i (a_i²/J_i + c_i²/J_{i+1})) on the undamped contact frequencies
    /// [rad/s] (for one stage exactly docs/model.md §2's ω_0, `Plant::contact_frequency`).
    pub fn contact_frequency(&self) -> f64 {
        let stiff: f64 = (0..S).map(|i| self.stage(i).k * self.kappa(i)).sum();
        stiff.sqrt()
    }

    /// The drive's fastest rate without the span, and the contact frequency it took (√2 times
    /// it with a capped stage).
    fn drive_rate(&self) -> (f64, f64) {
        let mut omega0 = self.contact_frequency();
        let bodies = (0..=S).map(|j| self.body(j).b / self.body(j).j).fold(omega0, f64::max);
        if (0..S).all(|i| self.stage(i).d() == 0.0) {
            return (bodies, omega0);
        }
        if (0..S).any(|i| self.stage(i).capped()) {
            omega0 *= std::f64::consts::SQRT_2;
        }
        let rate = (0..S)
            .map(|i| self.stage(i).d() * self.kappa(i))
            .fold(bodies.max(omega0), f64::max);
        (rate, omega0)
    }

    /// Whether some body has Coulomb friction.
    pub fn has_friction(&self) -> bool {
        (0..=S).any(|j| self.body(j).friction.tau_c > 0.0)
    }

    /// The web span on the last body, if any.
    pub fn web(&self) -> Option<&WebSpan> {
        self.params.web.as_ref()
    }
}

//! The chain's mode (one contact mode per stage, one friction mode per body) and its state.

use super::params::Chain;
use crate::mode::{damped_mode_at, mode_at, ContactMode};

/// A body's friction mode (Coulomb friction with stiction, docs/model.md §10): sliding forward
/// (ω > 0, friction −τ_c), sliding backward (ω < 0, +τ_c), or stuck (ω = 0, the friction holds
/// whatever else acts, up to peak·τ_c). A body without friction stays `Forward`: it has no
/// friction modes.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum BodyMode {
    Forward,
    Backward,
    Stuck,
}

impl BodyMode {
    /// In the order of [`BodyMode::index`].
    pub const ALL: [BodyMode; 3] = [BodyMode::Forward, BodyMode::Backward, BodyMode::Stuck];

    pub(crate) fn index(self) -> usize {
        match self {
            BodyMode::Forward => 0,
            BodyMode::Backward => 1,
            BodyMode::Stuck => 2,
        }
    }

    /// +1 sliding forward, −1 backward, 0 stuck (the FMUs' `sliding_*` for a body with
    /// friction).
    pub fn sliding(self) -> i32 {
        match self {
            BodyMode::Forward => 1,
            BodyMode::Backward => -1,
            BodyMode::Stuck => 0,
        }
    }

    /// The friction torque's sign while sliding: −1 forward, +1 backward, 0 stuck (where the
    /// friction is whatever holds the body).
    pub fn friction_sign(self) -> f64 {
        match self {
            BodyMode::Forward => -1.0,
            BodyMode::Backward => 1.0,
            BodyMode::Stuck => 0.0,
        }
    }
}

/// The mode of a chain: the tuple of its stages' modes and of its bodies' friction modes. A
/// stage without a damper is `Negative`, `Free` or `Positive`; one with a damper may also be
/// slack or (law 1) capped (docs/model.md §1). Each mode is linear (docs/model.md §2).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct ChainMode<const S: usize> {
    pub(crate) stages: [ContactMode; S],
    pub(crate) motor: BodyMode,
    pub(crate) driven: [BodyMode; S],
}

impl<const S: usize> ChainMode<S> {
    /// The mode with these stage modes, every body sliding forward (a body without friction
    /// has no other mode).
    pub fn new(stages: [ContactMode; S]) -> ChainMode<S> {
        ChainMode {
            stages,
            motor: BodyMode::Forward,
            driven: [BodyMode::Forward; S],
        }
    }

    /// Each stage's mode.
    pub fn stages(&self) -> &[ContactMode; S] {
        &self.stages
    }

    /// Body j's friction mode (j ≤ S).
    pub fn body(&self, j: usize) -> BodyMode {
        if j == 0 {
            self.motor
        } else {
            self.driven[j - 1]
        }
    }

    /// Sets body j's friction mode.
    pub fn set_body(&mut self, j: usize, mode: BodyMode) {
        if j == 0 {
            self.motor = mode;
        } else {
            self.driven[j - 1] = mode;
        }
    }

    /// How many stage modes there are: 7^S (every stage's seven modes of [`ContactMode::ALL`]).
    const STAGE_COUNT: usize = 7usize.pow(S as u32);

    /// How many modes there are: 7^S stage modes times 3^(S+1) body modes.
    pub const COUNT: usize = Self::STAGE_COUNT * 3usize.pow(S as u32 + 1);

    /// A number in 0..COUNT: the stages' modes as base-7 digits in the order of
    /// [`ContactMode::ALL`] (Negative 0, Free 1, Positive 2, then the damper's), stage 0 the
    /// lowest, then the bodies' as base-3 digits in the order of [`BodyMode::ALL`] (so that a
    /// chain without friction numbers its modes below 7^S).
    pub fn index(&self) -> usize {
        let stages = self.stages.iter().rev().fold(0, |acc, m| 7 * acc + m.index());
        let bodies = self.driven.iter().rev().fold(0, |acc, m| 3 * acc + m.index());
        stages + Self::STAGE_COUNT * (3 * bodies + self.motor.index())
    }

    /// The mode of an [`ChainMode::index`] (< COUNT).
    pub fn from_index(index: usize) -> ChainMode<S> {
        let (mut stages, mut bodies) = (index % Self::STAGE_COUNT, index / Self::STAGE_COUNT);
        let motor = BodyMode::ALL[bodies % 3];
        bodies /= 3;
        ChainMode {
            stages: std::array::from_fn(|_| {
                let digit = stages % 7;
                stages /= 7;
                ContactMode::ALL[digit]
            }),
            motor,
            driven: std::array::from_fn(|_| {
                let digit = bodies % 3;
                bodies /= 3;
                BodyMode::ALL[digit]
            }),
        }
    }
}

/// Angle and speed of one body.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Motion {
    /// Angle θ [rad].
    pub theta: f64,
    /// Speed ω [rad/s].
    pub omega: f64,
}

/// State of a chain: every body's angle and speed, every stage's u and u′ carried alongside
/// (advanced exactly rather than recomputed from the angles and speeds, which would cancel when
/// the drive turns fast: docs/model.md §2, "One linear system per mode"), and the mode.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ChainState<const S: usize> {
    /// Body 0, the motor.
    pub motor: Motion,
    /// Bodies 1..=S.
    pub driven: [Motion; S],
    /// u_i = a_i θ_i − c_i θ_{i+1} of each stage [rad, or m].
    pub u: [f64; S],
    /// u_i′ = a_i ω_i − c_i ω_{i+1} [rad/s, or m/s].
    pub du: [f64; S],
    /// The mode in force at this instant (on ±g: the mode being entered).
    pub mode: ChainMode<S>,
    /// Per stage with a damper: an upper bound on ∫|u_i′| over the time it spent free, slack or
    /// capped since the start (exact where u_i is monotone), which the bound's damper term
    /// multiplies (docs/model.md §2, §3 "With a damper"); 0 without a damper.
    pub variation: [f64; S],
    /// The web span's tension T [N] (docs/model.md §8); 0 without a web span.
    pub tension: f64,
}

impl<const S: usize> ChainState<S> {
    /// A state from the bodies' motions; u and u′ from them, the mode as [`mode_of`].
    pub fn new(chain: &Chain<S>, motor: Motion, driven: [Motion; S]) -> ChainState<S> {
        let body = |j: usize| if j == 0 { motor } else { driven[j - 1] };
        let u = std::array::from_fn(|i| {
            let s = chain.stage(i);
            s.a * body(i).theta - s.c * body(i + 1).theta
        });
        let du = std::array::from_fn(|i| {
            let s = chain.stage(i);
            s.a * body(i).omega - s.c * body(i + 1).omega
        });
        let omega: Vec<f64> = (0..=S).map(|j| body(j).omega).collect();
        ChainState {
            motor,
            driven,
            u,
            du,
            mode: mode_of(chain, &u, &du, &omega),
            variation: [0.0; S],
            tension: 0.0,
        }
    }

    /// Body `j` (0 ..= S).
    pub fn body(&self, j: usize) -> &Motion {
        if j == 0 {
            &self.motor
        } else {
            &self.driven[j - 1]
        }
    }

    pub(crate) fn body_mut(&mut self, j: usize) -> &mut Motion {
        if j == 0 {
            &mut self.motor
        } else {
            &mut self.driven[j - 1]
        }
    }

    /// ψ_i of each stage (docs/model.md §1): K_i dz(u_i, g_i), or with a damper the clipped
    /// force of its law.
    pub fn forces(&self, chain: &Chain<S>) -> [f64; S] {
        std::array::from_fn(|i| {
            let s = chain.stage(i);
            if s.d() == 0.0 {
                s.k * crate::params::dead_zone(self.u[i], s.g)
            } else {
                crate::params::damped_force(s.k, s.d(), s.g, s.damper.law, self.u[i], self.du[i])
            }
        })
    }

    /// This state with web tension `tension` [N].
    pub fn with_tension(self, tension: f64) -> ChainState<S> {
        ChainState { tension, ..self }
    }

    /// All fields finite.
    #[inline]
    pub fn is_finite(&self) -> bool {
        let finite = crate::finite;
        let bodies = self
            .driven
            .iter()
            .fold(finite(self.motor.theta) & finite(self.motor.omega), |all, b| {
                all & finite(b.theta) & finite(b.omega)
            });
        self.u
            .iter()
            .chain(&self.du)
            .fold(bodies & finite(self.tension), |all, &x| all & finite(x))
    }
}

/// The mode of each stage from its u and u′ ([`mode_at`], with a damper [`damped_mode_at`]): on
/// a switching surface the mode being entered; each body with friction sliding by the sign of
/// its speed, stuck at rest (the stepper applies the law of stiction with the inputs at a step's
/// start: a body at rest that the torques on it break away slides from there).
pub fn mode_of<const S: usize>(chain: &Chain<S>, u: &[f64; S], du: &[f64; S], omega: &[f64]) -> ChainMode<S> {
    let body_mode = |j: usize| {
        let w = omega[j];
        if chain.body(j).friction.tau_c == 0.0 || w > 0.0 {
            BodyMode::Forward
        } else if w < 0.0 {
            BodyMode::Backward
        } else {
            BodyMode::Stuck
        }
    };
    ChainMode {
        stages: std::array::from_fn(|i| {
            let s = chain.stage(i);
            if s.d() == 0.0 {
                mode_at(u[i], du[i], s.g)
            } else {
                damped_mode_at(u[i], du[i], s.g, s.k, s.d(), s.damper.law)
            }
        }),
        motor: body_mode(0),
        driven: std::array::from_fn(|i| body_mode(i + 1)),
    }
}

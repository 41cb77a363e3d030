//! The chain's mode (one contact mode per stage) and its state.

use super::params::Chain;
use crate::mode::{damped_mode_at, mode_at, ContactMode};

/// The mode of a chain: the tuple of its stages' modes. A stage without a damper is
/// `Negative`, `Free` or `Positive`; one with a damper may also be slack or (law 1) capped
/// (docs/model.md §1). Each mode is linear (docs/model.md §2).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct ChainMode<const S: usize> {
    pub(crate) stages: [ContactMode; S],
}

impl<const S: usize> ChainMode<S> {
    /// The mode with these stage modes.
    pub fn new(stages: [ContactMode; S]) -> ChainMode<S> {
        ChainMode { stages }
    }

    /// Each stage's mode.
    pub fn stages(&self) -> &[ContactMode; S] {
        &self.stages
    }

    /// How many modes there are: 7^S (every stage's seven modes of [`ContactMode::ALL`]).
    pub const COUNT: usize = 7usize.pow(S as u32);

    /// A number in 0..COUNT: the stages' modes as base-7 digits in the order of
    /// [`ContactMode::ALL`] (Negative 0, Free 1, Positive 2, then the damper's), stage 0 the
    /// lowest.
    pub fn index(&self) -> usize {
        self.stages.iter().rev().fold(0, |acc, m| 7 * acc + m.index())
    }

    /// The mode of an [`ChainMode::index`] (< COUNT).
    pub fn from_index(mut index: usize) -> ChainMode<S> {
        ChainMode {
            stages: std::array::from_fn(|_| {
                let digit = index % 7;
                index /= 7;
                ContactMode::ALL[digit]
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
        ChainState {
            motor,
            driven,
            u,
            du,
            mode: mode_of(chain, &u, &du),
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
/// a switching surface the mode being entered.
pub fn mode_of<const S: usize>(chain: &Chain<S>, u: &[f64; S], du: &[f64; S]) -> ChainMode<S> {
    ChainMode {
        stages: std::array::from_fn(|i| {
            let s = chain.stage(i);
            if s.d() == 0.0 {
                mode_at(u[i], du[i], s.g)
            } else {
                damped_mode_at(u[i], du[i], s.g, s.k, s.d(), s.damper.law)
            }
        }),
    }
}

//! Exact stepping between contact switches (spec §2).

use super::linear::{self, AugMatrix, AugVector, AUG};
use super::mode::{ContactMode, PlantState};
use super::params::Plant;
use super::roots::{self, series_apply, Side, SignalRows};
use thiserror::Error;

/// Inputs over one step: values at the step start and their slopes over the step.
/// Slopes are 0 for a zero-order hold (FMI 2 CS default); non-zero for first-order hold.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Inputs {
    /// Motor torque τ_m at the step start [N·m].
    pub tau_m: f64,
    /// Load torque τ_L at the step start [N·m].
    pub tau_l: f64,
    /// dτ_m/dt over the step [N·m/s].
    pub dtau_m: f64,
    /// dτ_L/dt over the step [N·m/s].
    pub dtau_l: f64,
}

impl Inputs {
    pub fn held(tau_m: f64, tau_l: f64) -> Inputs {
        Inputs {
            tau_m,
            tau_l,
            dtau_m: 0.0,
            dtau_l: 0.0,
        }
    }
}

/// A contact switch located inside a step.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SwitchEvent {
    /// Time since the start of the step [s].
    pub offset: f64,
    pub from: ContactMode,
    pub to: ContactMode,
}

#[derive(Clone, Copy, Debug, PartialEq, Error)]
pub enum StepError {
    #[error("step size {h} must be finite and > 0")]
    BadStepSize { h: f64 },
    #[error("input {name} = {value} must be finite")]
    NonFiniteInput { name: &'static str, value: f64 },
    #[error("state is not finite")]
    NonFiniteState,
    #[error("the step overflowed: the state would not be finite at its end")]
    Overflow,
    #[error("more than {limit} contact switches in one step of {h} s")]
    TooManySwitches { limit: usize, h: f64 },
}

/// One contact mode: its augmented matrix and the derivative rows of u along it.
#[derive(Clone, Debug)]
struct ModeDynamics {
    m: AugMatrix,
    u_rows: SignalRows<AUG>,
}

/// Exponentials for the current step size: the step is cut into `pieces` of length `len`.
#[derive(Clone, Debug)]
struct StepCache {
    h: f64,
    pieces: usize,
    len: f64,
    /// e^{M len} per mode.
    phi: [AugMatrix; 3],
    /// Remainder rows of u''' for exactly `len` per mode (see `roots::SignalRows`).
    remainder: [AugVector; 3],
}

/// Advances the plant exactly (spec §2). Holds the exponentials for the current step size;
/// they are recomputed only when the step size changes.
#[derive(Clone, Debug)]
pub struct Stepper {
    plant: Plant,
    modes: [ModeDynamics; 3],
    /// Longest piece [s]: PIECE_RATE over the fastest rate of the plant.
    len_ref: f64,
    cache: Option<StepCache>,
}

/// The exit from the mode in force: when it happens and what follows.
#[derive(Clone, Copy, Debug)]
struct Exit {
    offset: f64,
    to: ContactMode,
    /// u on the crossed threshold (±g), exactly.
    u: f64,
}

impl Stepper {
    pub fn new(plant: Plant) -> Stepper {
        let rate = linear::fastest_rate(&plant);
        let len_ref = if rate > 0.0 {
            linear::PIECE_RATE / rate
        } else {
            f64::INFINITY
        };
        let mut e_u = AugVector::zeros();
        e_u[linear::U] = 1.0;
        let modes = ContactMode::ALL.map(|mode| {
            let m = linear::mode_matrix(&plant, mode);
            ModeDynamics {
                m,
                u_rows: SignalRows::new(e_u, &m, len_ref),
            }
        });
        Stepper {
            plant,
            modes,
            len_ref,
            cache: None,
        }
    }

    pub fn plant(&self) -> &Plant {
        &self.plant
    }

    fn ensure_cache(&mut self, h: f64) {
        if self.cache.as_ref().is_some_and(|c| c.h == h) {
            return;
        }
        let pieces = if self.len_ref.is_finite() {
            (h / self.len_ref).ceil().max(1.0)
        } else {
            1.0
        };
        let len = h / pieces;
        let phi = [0, 1, 2].map(|i| (self.modes[i].m * len).exp());
        let remainder = [0, 1, 2].map(|i| self.modes[i].u_rows.remainder_row(&self.modes[i].m, len));
        self.cache = Some(StepCache {
            h,
            pieces: pieces as usize,
            len,
            phi,
            remainder,
        });
    }

    /// Advances `state` over [t, t+h] with `inputs` (values at t, slopes over the step),
    /// calling `on_switch` for every contact switch in time order. Returns the number of
    /// switches. On error `state` is left unchanged.
    pub fn step(
        &mut self,
        state: &mut PlantState,
        inputs: &Inputs,
        h: f64,
        on_switch: &mut dyn FnMut(SwitchEvent),
    ) -> Result<usize, StepError> {
        if !(h.is_finite() && h > 0.0) {
            return Err(StepError::BadStepSize { h });
        }
        for (name, value) in [
            ("tau_m", inputs.tau_m),
            ("tau_L", inputs.tau_l),
            ("der(tau_m)", inputs.dtau_m),
            ("der(tau_L)", inputs.dtau_l),
        ] {
            if !value.is_finite() {
                return Err(StepError::NonFiniteInput { name, value });
            }
        }
        if !state.is_finite() {
            return Err(StepError::NonFiniteState);
        }
        self.ensure_cache(h);
        let cache = self.cache.as_ref().expect("cache was just filled");
        let (pieces, len) = (cache.pieces, cache.len);
        let switch_limit = 64 + 16 * pieces;

        let mut next = *state;
        let mut switches = 0;
        for piece in 0..pieces {
            let start = piece as f64 * len;
            let end = if piece + 1 == pieces {
                h
            } else {
                (piece + 1) as f64 * len
            };
            let mut t = start;
            let mut y = augmented(&next, inputs, t);
            loop {
                // A whole piece uses the cached exponential; after a switch, the rest of the
                // piece is shorter than `len_ref` and its Taylor series converges fast.
                let whole = t == start;
                let span = if whole { end - start } else { end - t };
                let mode = next.mode.index();
                let exact_row = if whole { Some(&cache.remainder[mode]) } else { None };
                match self.exit(&y, next.mode, span, exact_row) {
                    None => {
                        y = if whole && span == len {
                            cache.phi[mode] * y
                        } else {
                            series_apply(&self.modes[mode].m, &y, span)
                        };
                        break;
                    }
                    Some(exit) => {
                        y = series_apply(&self.modes[mode].m, &y, exit.offset);
                        y[linear::U] = exit.u;
                        t += exit.offset;
                        // Inputs are functions of time: re-evaluate rather than carry round-off.
                        y[linear::TAU_M] = inputs.tau_m + inputs.dtau_m * t;
                        y[linear::TAU_L] = inputs.tau_l + inputs.dtau_l * t;
                        on_switch(SwitchEvent {
                            offset: t,
                            from: next.mode,
                            to: exit.to,
                        });
                        next.mode = exit.to;
                        switches += 1;
                        if switches > switch_limit {
                            return Err(StepError::TooManySwitches { limit: switch_limit, h });
                        }
                        if t >= end {
                            break;
                        }
                    }
                }
            }
            next.theta_m += y[linear::DTHETA_M];
            next.theta_l += y[linear::DTHETA_L];
            next.u = y[linear::U];
            next.omega_m = y[linear::OMEGA_M];
            next.omega_l = y[linear::OMEGA_L];
        }
        if !next.is_finite() {
            return Err(StepError::Overflow);
        }
        *state = next;
        Ok(switches)
    }

    /// The first exit from `mode` within `span` after the state `y`, if any.
    fn exit(&self, y: &AugVector, mode: ContactMode, span: f64, exact_row: Option<&AugVector>) -> Option<Exit> {
        let g = self.plant.half_gap();
        if g == 0.0 {
            // No free region: both flanks carry ψ = K u, the plant is linear.
            return None;
        }
        let rows = &self.modes[mode.index()].u_rows;
        let u = y[linear::U];
        // Round-off floor of u ∓ g: a few ulps of the larger of |u| and g.
        let tol = 8.0 * f64::EPSILON * (u.abs() + g);
        let up = (
            Side {
                offset: g,
                sign: -1.0,
                tol,
            },
            ContactMode::Positive,
            g,
        );
        let down = (
            Side {
                offset: g,
                sign: 1.0,
                tol,
            },
            ContactMode::Negative,
            -g,
        );
        let sides = match mode {
            ContactMode::Free => [Some(up), Some(down)],
            ContactMode::Positive => [
                Some((
                    Side {
                        offset: -g,
                        sign: 1.0,
                        tol,
                    },
                    ContactMode::Free,
                    g,
                )),
                None,
            ],
            ContactMode::Negative => [
                Some((
                    Side {
                        offset: -g,
                        sign: -1.0,
                        tol,
                    },
                    ContactMode::Free,
                    -g,
                )),
                None,
            ],
        };
        let d = [rows.derivative(0, y), rows.derivative(1, y), rows.derivative(2, y)];
        let c3 = rows.third_bound(y, span, exact_row);
        let mut poly = None;
        let mut best: Option<Exit> = None;
        for (side, to, u_cross) in sides.into_iter().flatten() {
            let (f0, f1, f2) = (side.value(d[0]), side.sign * d[1], side.sign * d[2]);
            if roots::cubic_clear(f0, f1, f2, c3, span, tol) {
                continue;
            }
            let p = poly.get_or_insert_with(|| rows.taylor(y));
            let limit = best.map_or(span, |b| b.offset);
            if let Some(offset) = roots::first_exit(p, side, limit) {
                best = Some(Exit { offset, to, u: u_cross });
            }
        }
        best
    }

    /// The `order`-th time derivative (order ≥ 1) of [θ_m, ω_m, θ_L, ω_L] at `state` under the
    /// mode in force (at a switch instant: the mode being entered, i.e. the right derivative).
    pub fn time_derivative(&self, state: &PlantState, inputs: &Inputs, order: u32) -> [f64; 4] {
        let m = &self.modes[state.mode.index()].m;
        let mut y = augmented(state, inputs, 0.0);
        for _ in 0..order {
            y = m * y;
        }
        [
            y[linear::DTHETA_M],
            y[linear::OMEGA_M],
            y[linear::DTHETA_L],
            y[linear::OMEGA_L],
        ]
    }
}

/// The augmented vector of `state` at time `t` into the step (angle increments zero).
fn augmented(state: &PlantState, inputs: &Inputs, t: f64) -> AugVector {
    let mut y = AugVector::zeros();
    y[linear::U] = state.u;
    y[linear::OMEGA_M] = state.omega_m;
    y[linear::OMEGA_L] = state.omega_l;
    y[linear::TAU_M] = inputs.tau_m + inputs.dtau_m * t;
    y[linear::TAU_L] = inputs.tau_l + inputs.dtau_l * t;
    y[linear::ONE] = 1.0;
    y[linear::DTAU_M] = inputs.dtau_m;
    y[linear::DTAU_L] = inputs.dtau_l;
    y
}

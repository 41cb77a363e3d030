//! Exact stepping between contact switches (spec §2).

use super::mode::{ContactMode, PlantState};
use super::params::Plant;
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
        Inputs { tau_m, tau_l, dtau_m: 0.0, dtau_l: 0.0 }
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
}

/// Advances the plant exactly (spec §2). Holds the exponentials for the current step size;
/// they are recomputed only when the step size changes.
#[derive(Clone, Debug)]
pub struct Stepper {
    plant: Plant,
}

impl Stepper {
    pub fn new(plant: Plant) -> Stepper {
        Stepper { plant }
    }

    pub fn plant(&self) -> &Plant {
        &self.plant
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
        let _ = (state, inputs, h, on_switch);
        todo!()
    }

    /// The `order`-th time derivative (order ≥ 1) of [θ_m, ω_m, θ_L, ω_L] at `state` under the
    /// mode in force (at a switch instant: the mode being entered, i.e. the right derivative).
    pub fn time_derivative(&self, state: &PlantState, inputs: &Inputs, order: u32) -> [f64; 4] {
        let _ = (state, inputs, order);
        todo!()
    }
}

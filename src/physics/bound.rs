//! The speed-error bounds of spec §3 for a PI loop on motor speed.

use super::params::Plant;
use thiserror::Error;

/// PI speed controller on ω_m: τ_m = Kp e + Ki ∫e, e = ω_ref − ω_m (spec §3).
/// Kp [N·m·s/rad], Ki [N·m/rad]; Kp = Ki = 0 means the open-loop plant.
#[derive(Clone, Copy, Debug, PartialEq, Default)]
pub struct PiGains {
    pub kp: f64,
    pub ki: f64,
}

/// Why `bound_sup` is +∞.
#[derive(Clone, Copy, Debug, PartialEq, Error)]
pub enum Unbounded {
    #[error("the loop is unstable in the modes the backlash disturbance excites (spectral abscissa {abscissa:e} 1/s)")]
    Unstable { abscissa: f64 },
    #[error("the loop is undamped in the modes the backlash disturbance excites: the impulse response never decays")]
    Undamped,
}

/// Everything that evolves in [`SpeedErrorBound`], as plain numbers (for FMU-state saving).
#[derive(Clone, Copy, Debug, PartialEq, Default)]
pub struct BoundState {
    /// Time since the experiment's start [s].
    pub elapsed: f64,
    /// e^{A s} D_1 at s = elapsed (5 entries; the 5th is 0 in open loop).
    pub response: [f64; 5],
    /// ∫_0^elapsed e^{A s} D_1 ds.
    pub integral: [f64; 5],
    /// ∫_0^elapsed |h(s)| ds.
    pub l1: f64,
}

#[derive(Clone, Copy, Debug, PartialEq, Error)]
pub enum BoundError {
    #[error("gain {name} = {value} must be finite")]
    NonFiniteGain { name: &'static str, value: f64 },
    #[error("time advance {h} must be finite and >= 0")]
    BadAdvance { h: f64 },
    #[error("bound state is not finite or has negative time")]
    BadState,
}

/// bound(t), bound_paper(t) and bound_sup of spec §3, advanced alongside the simulation.
#[derive(Clone, Debug)]
pub struct SpeedErrorBound {
    state: BoundState,
}

impl SpeedErrorBound {
    pub fn new(plant: &Plant, gains: PiGains) -> Result<SpeedErrorBound, BoundError> {
        let _ = (plant, gains);
        todo!()
    }

    /// Back to the experiment's start (elapsed = 0).
    pub fn reset(&mut self) {
        todo!()
    }

    /// Advances time since the start by `h` ≥ 0.
    pub fn advance(&mut self, h: f64) -> Result<(), BoundError> {
        let _ = h;
        todo!()
    }

    /// K g ∫_0^t |h(s)| ds: a true bound on |ω_L^b − ω_L^0| [rad/s].
    pub fn bound(&self) -> f64 {
        todo!()
    }

    /// K g ‖∫_0^t e^{A s} D_1 ds‖₂, eq. (37)/(41) as printed: not a guarantee [rad/s].
    pub fn bound_paper(&self) -> f64 {
        todo!()
    }

    /// K g ∫_0^∞ |h(s)| ds, or why it is infinite.
    pub fn sup(&self) -> Result<f64, Unbounded> {
        todo!()
    }

    pub fn elapsed(&self) -> f64 {
        self.state.elapsed
    }

    pub fn state(&self) -> BoundState {
        self.state
    }

    /// Restores a saved state (validated: finite, elapsed ≥ 0).
    pub fn restore(&mut self, state: &BoundState) -> Result<(), BoundError> {
        let _ = state;
        todo!()
    }
}

//! The plant of docs/model.md §1–§3 and the web line of §8 as pure, safe Rust: no FFI, no FMI
//! words.
//!
//! Data flow: [`PlantParams`] → [`Plant`] (validated generic form, with or without a web span)
//! → [`Stepper`] (exact stepping, switches located to round-off) and [`SpeedErrorBound`]
//! (docs/model.md §3 bounds), or for a web line [`WebSpeedBound`] and [`WebTensionBound`];
//! `vector_field` gives the same plant as z' = f(z, τ) for solvers outside (docs/model.md §6);
//! [`SampledPi`] is the sampled controller that closes the loops around it (§3, §8).
//!
//! [`chain`] is the plant as a chain of S stages (bodies joined by compliant members with
//! backlash and optional dampers, a web span on the last body; docs/model.md §10), stepped
//! exactly by [`ChainStepper`], with the speed-error bound over one disturbance per stage
//! ([`chain::ChainBound`]); the FMU layer does not use it yet (the design study's two-stage
//! answer does).

pub mod bound;
pub mod chain;
pub mod closed_loop;
pub mod controller;
mod damper;
pub mod kernel;
pub mod linear;
pub mod mode;
pub mod params;
pub mod roots;
pub mod stepper;
pub mod taylor;
pub mod vector_field;

pub use bound::{
    BoundError, BoundState, PiGains, SpeedErrorBound, Trajectory, Unbounded, WebSpeedBound, WebTensionBound,
};
pub use chain::{Chain, ChainError, ChainMode, ChainParams, ChainState, ChainStepper, StageSwitch};
pub use controller::{ControllerParams, Reference, SampleError, SampledPi};
pub use mode::{contact_indicator, damped_mode_at, mode_at, ContactMode, PlantState};
pub use params::{dead_zone, ContactLaw, Damping, Geometry, ParamError, Plant, PlantParams, WebSpan};
pub use stepper::{
    max_step, Inputs, SlidingDriveStepper, SlidingWebStepper, StepError, Stepper, SwitchEvent, MAX_PERIODS_PER_STEP,
};

/// `x.is_finite()` as one floating-point comparison, for the tests that run on every step:
/// `is_finite` moves x to the integer unit and back.
#[inline(always)]
pub fn finite(x: f64) -> bool {
    x.abs() <= f64::MAX
}

//! The FMU instance in safe Rust: the FMI 2.0 state machines of Model Exchange and
//! Co-Simulation, value-reference dispatch over the generated variable table, stepping, the
//! vector field for Model Exchange, and FMU states. No FFI here; the C
//! ABI in `crate::ffi` converts pointers and calls [`Instance::run_status`].

pub mod adapter;
pub mod bounds;
pub mod error;
pub mod friction;
pub mod geared;
pub mod instance;
pub mod logging;
pub mod simulation;
pub mod snapshot;
pub mod state_machine;
pub mod templates;
pub mod variables;

pub use error::{FmuError, Status};
pub use instance::{CoSimulationOptions, EventInfo, Experiment, Instance, StatusKind, StepOutcome};
pub use logging::{Collected, LogCategory, LogSink};
pub use snapshot::Snapshot;
pub use state_machine::{Flavour, Function, Interface, Phase, Standard};
pub use variables::{
    model_by_guid, model_by_identifier, model_by_instantiation_token, model_for_instantiation, served, ModelInfo,
    Symbol, Variable, CONTROLLERS, MODELS,
};

#[cfg(test)]
mod tests;

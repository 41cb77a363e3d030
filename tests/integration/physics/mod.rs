//! The plant library (`backlash_fmu::physics`) without the FMU: the stepper, the speed-error
//! bounds and the web line against closed forms and independent integrators (`crate::support`).

mod bound;
mod closed_forms;
mod damping;
mod derivative;
mod energy;
mod params;
mod reference;
mod switching;
mod web;

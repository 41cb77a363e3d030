//! Compliance and backlash in series: an exact drive-train model (docs/model.md), served as
//! FMUs of FMI 2.0 and FMI 3.0, Model Exchange and Co-Simulation, from one library.
//!
//! Layers, each depending only on the one before: [`physics`] (pure numerics) ←
//! [`fmu`] (instance state machine, variables, FMU state) ← [`ffi`] (the C ABI).
//! `unsafe` is denied everywhere except in [`ffi`], where each block states why it is sound.

#![deny(unsafe_code)]

/// The plant and its bounds (the `backlash-physics` crate in physics/, which the interface
/// description computes nominals and dependencies with as well).
pub use backlash_physics as physics;

pub mod fmu;

#[allow(unsafe_code)]
pub mod ffi;

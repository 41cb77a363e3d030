//! Compliance and backlash in series: an exact drive-train model (spec `model.md`), served as
//! FMI 2.0 Co-Simulation units.
//!
//! Layers, each depending only on the one before: [`physics`] (pure numerics) ←
//! `fmu` (instance state machine, variables, FMU state) ← `ffi` (the C ABI).

pub mod physics;

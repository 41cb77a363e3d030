//! The FMU (`backlash_fmu::fmu`, `backlash_fmu::ffi`): stepping through its Rust API (the
//! plants, and the controller in `controller`), the
//! variable tables and the generated model descriptions, and the FMI 2.0 and FMI 3.0 C functions
//! called through the rlib. FMU states are in `crate::fmu_state`.

// Those with helpers that `crate::fmu_state` uses are `pub(crate)`.
mod controller;
#[cfg(all(target_os = "linux", any(target_arch = "x86_64", target_arch = "aarch64")))]
pub(crate) mod ffi;
mod fmi3_description;
#[cfg(all(target_os = "linux", any(target_arch = "x86_64", target_arch = "aarch64")))]
pub(crate) mod fmi3_ffi;
mod friction;
pub(crate) mod simulation;
mod variables;
pub(crate) mod web;

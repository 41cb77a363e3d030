//! The C ABI of FMI 2.0 (`fmi2Functions.h`): `extern "C"` shims that convert pointers to
//! slices and call the safe instance in [`crate::fmu`] through one guard ([`guard::guard`]).
//! All `unsafe` of the crate lives here; every block states why it is sound.
//!
//! Every model is served by the same exports; fmi2Instantiate tells them apart by guid. The
//! FMI 3.0 functions ([`fmi3`]) serve the same instances through the FMI 3.0 archives.

// Names and argument names follow the C headers, so that a generated header matches them.
#![allow(non_camel_case_types, non_snake_case, non_upper_case_globals)]
#![deny(unsafe_op_in_unsafe_fn)]

pub mod cosim;
pub mod fmi3;
pub mod fmu_state;
pub mod guard;
mod instantiate;
pub mod lifecycle;
pub mod model_exchange;
mod registry;
pub mod types;
pub mod values;

pub use cosim::*;
pub use fmu_state::*;
pub use lifecycle::*;
pub use model_exchange::*;
pub use types::*;
pub use values::*;

//! The integration tests of the library, one binary with one module per feature (a single test
//! binary links the library once). Run one feature with a name filter, e.g.
//! `cargo test --test integration fmu_state`.
//!
//! - `physics`: the stepper, the bounds and the web line against independent computations;
//! - `fmu`: the FMU through its Rust API and its C functions (FMI 2.0 and FMI 3.0), and the
//!   generated model descriptions;
//! - `fmu_state`: FMU states, through the Rust API and the C ABI, and under misuse;
//! - `robustness`: every misuse of the C ABI, panics, threads, extreme values and a fuzz;
//! - `support`, `robustness_common`: what the tests share (independent reference computations;
//!   an instance driven through the C ABI).
//!
//! The modules that call the C functions directly rely on the Linux x86-64 and AArch64 calling
//! conventions (the variadic logger, see `robustness_common`), and are built there only.

mod fmu;
mod fmu_state;
mod physics;
#[cfg(all(target_os = "linux", any(target_arch = "x86_64", target_arch = "aarch64")))]
mod robustness;
#[cfg(all(target_os = "linux", any(target_arch = "x86_64", target_arch = "aarch64")))]
mod robustness_common;
mod support;

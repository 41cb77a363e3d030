//! Misuse of the C ABI (`backlash_fmu::ffi`): every argument, every call in every state of the
//! FMI 2.0 and FMI 3.0 state machines, panics, concurrent instances, extreme finite values and a
//! seeded random-call fuzz. Each refusal is fmi2Error (fmi3Error) or a Discard with a logged
//! reason, and a fresh instance works afterwards. FMU states under misuse are in
//! `crate::fmu_state::misuse`.
//!
//! The long fuzz (docs/testing.md, `.ci/run`) runs the `fuzz` module alone:
//! `FUZZ_SECONDS=120 FUZZ_EXTREME=1 cargo test --release --test integration robustness::fuzz -- --nocapture`.

mod arguments;
mod extremes;
mod fmi3;
mod fuzz;
mod panic;
mod state_machine;
mod threads;

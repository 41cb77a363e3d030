//! FMU states (FMI 2.0.4 §2.1.8, and their FMI 3.0 counterparts): get, set, serialize,
//! deserialize and free; restored states continue bit for bit, in the same instance and in
//! another; misuse (bad bytes, bad handles, small buffers) is refused with a reason.
//!
//! - `rust_api`: through the FMU's Rust API (`Instance`);
//! - `c_abi`: through the FMI 2.0 and FMI 3.0 C functions;
//! - `misuse`: the C functions given bad bytes, bad handles and small buffers.

#[cfg(all(target_os = "linux", any(target_arch = "x86_64", target_arch = "aarch64")))]
mod c_abi;
#[cfg(all(target_os = "linux", any(target_arch = "x86_64", target_arch = "aarch64")))]
mod misuse;
mod rust_api;

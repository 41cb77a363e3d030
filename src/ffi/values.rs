//! fmi2Get/SetXXX by value reference (FMI 2.0.4 §2.1.7) and fmi2GetDirectionalDerivative.

use super::guard::{guard, input_array, output_array};
use super::types::*;
use crate::fmu::Function;

/// # Safety
/// Pointer arguments as FMI 2.0 defines them: NULL, or valid for the announced number of
/// elements (strings NUL-terminated) for the duration of the call.
#[no_mangle]
pub unsafe extern "C" fn fmi2GetReal(
    c: fmi2Component,
    vr: *const fmi2ValueReference,
    nvr: usize,
    value: *mut fmi2Real,
) -> fmi2Status {
    guard(c, Function::GetReal, |inst| {
        // SAFETY: FMI 2.0 passes `nvr` value references and room for `nvr` values.
        let vrs = unsafe { input_array(vr, nvr, "vr") }?;
        let out = unsafe { output_array(value, nvr, "value") }?;
        inst.get_real_body(vrs, out)
    })
}

/// # Safety
/// Pointer arguments as FMI 2.0 defines them: NULL, or valid for the announced number of
/// elements (strings NUL-terminated) for the duration of the call.
#[no_mangle]
pub unsafe extern "C" fn fmi2GetInteger(
    c: fmi2Component,
    vr: *const fmi2ValueReference,
    nvr: usize,
    value: *mut fmi2Integer,
) -> fmi2Status {
    guard(c, Function::GetInteger, |inst| {
        // SAFETY: as in fmi2GetReal.
        let vrs = unsafe { input_array(vr, nvr, "vr") }?;
        let out = unsafe { output_array(value, nvr, "value") }?;
        inst.get_integer_body(vrs, out)
    })
}

/// # Safety
/// Pointer arguments as FMI 2.0 defines them: NULL, or valid for the announced number of
/// elements (strings NUL-terminated) for the duration of the call.
#[no_mangle]
pub unsafe extern "C" fn fmi2GetBoolean(
    c: fmi2Component,
    vr: *const fmi2ValueReference,
    nvr: usize,
    value: *mut fmi2Boolean,
) -> fmi2Status {
    guard(c, Function::GetBoolean, |inst| {
        // SAFETY: as in fmi2GetReal.
        let vrs = unsafe { input_array(vr, nvr, "vr") }?;
        let out = unsafe { output_array(value, nvr, "value") }?;
        inst.get_untyped_body(vrs, out.len(), "Boolean")
    })
}

/// # Safety
/// Pointer arguments as FMI 2.0 defines them: NULL, or valid for the announced number of
/// elements (strings NUL-terminated) for the duration of the call.
#[no_mangle]
pub unsafe extern "C" fn fmi2GetString(
    c: fmi2Component,
    vr: *const fmi2ValueReference,
    nvr: usize,
    value: *mut fmi2String,
) -> fmi2Status {
    guard(c, Function::GetString, |inst| {
        // SAFETY: as in fmi2GetReal.
        let vrs = unsafe { input_array(vr, nvr, "vr") }?;
        let out = unsafe { output_array(value, nvr, "value") }?;
        inst.get_untyped_body(vrs, out.len(), "String")
    })
}

/// # Safety
/// Pointer arguments as FMI 2.0 defines them: NULL, or valid for the announced number of
/// elements (strings NUL-terminated) for the duration of the call.
#[no_mangle]
pub unsafe extern "C" fn fmi2SetReal(
    c: fmi2Component,
    vr: *const fmi2ValueReference,
    nvr: usize,
    value: *const fmi2Real,
) -> fmi2Status {
    guard(c, Function::SetReal, |inst| {
        // SAFETY: FMI 2.0 passes `nvr` value references and `nvr` values.
        let vrs = unsafe { input_array(vr, nvr, "vr") }?;
        let values = unsafe { input_array(value, nvr, "value") }?;
        inst.set_real_body(vrs, values)
    })
}

/// # Safety
/// Pointer arguments as FMI 2.0 defines them: NULL, or valid for the announced number of
/// elements (strings NUL-terminated) for the duration of the call.
#[no_mangle]
pub unsafe extern "C" fn fmi2SetInteger(
    c: fmi2Component,
    vr: *const fmi2ValueReference,
    nvr: usize,
    value: *const fmi2Integer,
) -> fmi2Status {
    guard(c, Function::SetInteger, |inst| {
        // SAFETY: as in fmi2SetReal.
        let vrs = unsafe { input_array(vr, nvr, "vr") }?;
        let values = unsafe { input_array(value, nvr, "value") }?;
        inst.set_integer_body(vrs, values)
    })
}

/// # Safety
/// Pointer arguments as FMI 2.0 defines them: NULL, or valid for the announced number of
/// elements (strings NUL-terminated) for the duration of the call.
#[no_mangle]
pub unsafe extern "C" fn fmi2SetBoolean(
    c: fmi2Component,
    vr: *const fmi2ValueReference,
    nvr: usize,
    value: *const fmi2Boolean,
) -> fmi2Status {
    guard(c, Function::SetBoolean, |inst| {
        // SAFETY: as in fmi2SetReal.
        let vrs = unsafe { input_array(vr, nvr, "vr") }?;
        let values = unsafe { input_array(value, nvr, "value") }?;
        inst.set_untyped_body(vrs, values.len(), "Boolean")
    })
}

/// # Safety
/// Pointer arguments as FMI 2.0 defines them: NULL, or valid for the announced number of
/// elements (strings NUL-terminated) for the duration of the call.
#[no_mangle]
pub unsafe extern "C" fn fmi2SetString(
    c: fmi2Component,
    vr: *const fmi2ValueReference,
    nvr: usize,
    value: *const fmi2String,
) -> fmi2Status {
    guard(c, Function::SetString, |inst| {
        // SAFETY: as in fmi2SetReal; the strings themselves are never read (no String variables).
        let vrs = unsafe { input_array(vr, nvr, "vr") }?;
        let values = unsafe { input_array(value, nvr, "value") }?;
        inst.set_untyped_body(vrs, values.len(), "String")
    })
}

/// The exact Jacobian of the mode in force (Model Exchange; providesDirectionalDerivative is
/// false for Co-Simulation, which refuses the call with a reason).
/// # Safety
/// Pointer arguments as FMI 2.0 defines them: NULL, or valid for the announced number of
/// elements for the duration of the call.
#[no_mangle]
pub unsafe extern "C" fn fmi2GetDirectionalDerivative(
    c: fmi2Component,
    vUnknown_ref: *const fmi2ValueReference,
    nUnknown: usize,
    vKnown_ref: *const fmi2ValueReference,
    nKnown: usize,
    dvKnown: *const fmi2Real,
    dvUnknown: *mut fmi2Real,
) -> fmi2Status {
    guard(c, Function::GetDirectionalDerivative, |inst| {
        inst.check_directional_derivative_provided()?;
        // SAFETY: FMI 2.0 passes `nUnknown` references and room for as many values, and
        // `nKnown` references with as many seed values.
        let unknowns = unsafe { input_array(vUnknown_ref, nUnknown, "vUnknown_ref") }?;
        let knowns = unsafe { input_array(vKnown_ref, nKnown, "vKnown_ref") }?;
        let seed = unsafe { input_array(dvKnown, nKnown, "dvKnown") }?;
        let out = unsafe { output_array(dvUnknown, nUnknown, "dvUnknown") }?;
        inst.get_directional_derivative_body(unknowns, knowns, seed, out)
    })
}

//! fmi2Get/SetXXX by value reference (FMI 2.0.4 §2.1.7) and fmi2GetDirectionalDerivative.

use super::guard::{guard, input_array, output_array};
use super::types::*;
use crate::fmu::{FmuError, Function};

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
        inst.set_untyped_body(vrs, values.len(), "Integer")
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

/// providesDirectionalDerivative = false: refused with a reason.
#[no_mangle]
pub extern "C" fn fmi2GetDirectionalDerivative(
    c: fmi2Component,
    vUnknown_ref: *const fmi2ValueReference,
    nUnknown: usize,
    vKnown_ref: *const fmi2ValueReference,
    nKnown: usize,
    dvKnown: *const fmi2Real,
    dvUnknown: *mut fmi2Real,
) -> fmi2Status {
    let _ = (vUnknown_ref, nUnknown, vKnown_ref, nKnown, dvKnown, dvUnknown);
    guard(c, Function::GetDirectionalDerivative, |_| {
        Err(FmuError::NotProvided(
            "fmi2GetDirectionalDerivative (providesDirectionalDerivative=\"false\")",
        ))
    })
}

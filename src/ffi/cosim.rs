//! The Co-Simulation functions (FMI 2.0.4 §4.2): input/output derivatives, stepping, status.

use super::guard::{guard, input_array, output_array, output_pointer};
use super::types::*;
use crate::fmu::{FmuError, Function, Status, StatusKind};

fn status_kind(kind: fmi2StatusKind) -> Result<StatusKind, FmuError> {
    match kind {
        fmi2DoStepStatus => Ok(StatusKind::DoStepStatus),
        fmi2PendingStatus => Ok(StatusKind::PendingStatus),
        fmi2LastSuccessfulTime => Ok(StatusKind::LastSuccessfulTime),
        fmi2Terminated => Ok(StatusKind::Terminated),
        other => Err(FmuError::InvalidArgument(format!("{other} is not an fmi2StatusKind"))),
    }
}

/// # Safety
/// Pointer arguments as FMI 2.0 defines them: NULL, or valid for the announced number of
/// elements (strings NUL-terminated) for the duration of the call.
#[no_mangle]
pub unsafe extern "C" fn fmi2SetRealInputDerivatives(
    c: fmi2Component,
    vr: *const fmi2ValueReference,
    nvr: usize,
    order: *const fmi2Integer,
    value: *const fmi2Real,
) -> fmi2Status {
    guard(c, Function::SetRealInputDerivatives, |inst| {
        // SAFETY: FMI 2.0 passes `nvr` value references, orders and values.
        let vrs = unsafe { input_array(vr, nvr, "vr") }?;
        let orders = unsafe { input_array(order, nvr, "order") }?;
        let values = unsafe { input_array(value, nvr, "value") }?;
        inst.set_real_input_derivatives_body(vrs, orders, values)
    })
}

/// # Safety
/// Pointer arguments as FMI 2.0 defines them: NULL, or valid for the announced number of
/// elements (strings NUL-terminated) for the duration of the call.
#[no_mangle]
pub unsafe extern "C" fn fmi2GetRealOutputDerivatives(
    c: fmi2Component,
    vr: *const fmi2ValueReference,
    nvr: usize,
    order: *const fmi2Integer,
    value: *mut fmi2Real,
) -> fmi2Status {
    guard(c, Function::GetRealOutputDerivatives, |inst| {
        // SAFETY: FMI 2.0 passes `nvr` value references and orders and room for `nvr` values.
        let vrs = unsafe { input_array(vr, nvr, "vr") }?;
        let orders = unsafe { input_array(order, nvr, "order") }?;
        let out = unsafe { output_array(value, nvr, "value") }?;
        inst.get_real_output_derivatives_body(vrs, orders, out)
    })
}

#[no_mangle]
pub extern "C" fn fmi2DoStep(
    c: fmi2Component,
    currentCommunicationPoint: fmi2Real,
    communicationStepSize: fmi2Real,
    noSetFMUStatePriorToCurrentPoint: fmi2Boolean,
) -> fmi2Status {
    // No result buffer to flush, so the hint changes nothing.
    let _ = noSetFMUStatePriorToCurrentPoint;
    guard(c, Function::DoStep, |inst| {
        inst.do_step_body(currentCommunicationPoint, communicationStepSize)
    })
}

/// Steps are synchronous, so there is never a step to cancel: always illegal.
#[no_mangle]
pub extern "C" fn fmi2CancelStep(c: fmi2Component) -> fmi2Status {
    guard(c, Function::CancelStep, |_| Ok(Status::Ok))
}

/// # Safety
/// Pointer arguments as FMI 2.0 defines them: NULL, or valid for the announced number of
/// elements (strings NUL-terminated) for the duration of the call.
#[no_mangle]
pub unsafe extern "C" fn fmi2GetStatus(c: fmi2Component, s: fmi2StatusKind, value: *mut fmi2Status) -> fmi2Status {
    guard(c, Function::GetStatus, |inst| {
        // SAFETY: FMI 2.0 passes a pointer to the importer's fmi2Status.
        let value = unsafe { output_pointer(value, "value") }?;
        *value = inst.get_status_body(status_kind(s)?)?.into();
        Ok(Status::Ok)
    })
}

/// # Safety
/// Pointer arguments as FMI 2.0 defines them: NULL, or valid for the announced number of
/// elements (strings NUL-terminated) for the duration of the call.
#[no_mangle]
pub unsafe extern "C" fn fmi2GetRealStatus(c: fmi2Component, s: fmi2StatusKind, value: *mut fmi2Real) -> fmi2Status {
    guard(c, Function::GetRealStatus, |inst| {
        // SAFETY: FMI 2.0 passes a pointer to the importer's fmi2Real.
        let value = unsafe { output_pointer(value, "value") }?;
        *value = inst.get_real_status_body(status_kind(s)?)?;
        Ok(Status::Ok)
    })
}

/// # Safety
/// Pointer arguments as FMI 2.0 defines them: NULL, or valid for the announced number of
/// elements (strings NUL-terminated) for the duration of the call.
#[no_mangle]
pub unsafe extern "C" fn fmi2GetIntegerStatus(
    c: fmi2Component,
    s: fmi2StatusKind,
    value: *mut fmi2Integer,
) -> fmi2Status {
    guard(c, Function::GetIntegerStatus, |inst| {
        // SAFETY: FMI 2.0 passes a pointer to the importer's fmi2Integer.
        let value = unsafe { output_pointer(value, "value") }?;
        *value = inst.get_integer_status_body(status_kind(s)?)?;
        Ok(Status::Ok)
    })
}

/// # Safety
/// Pointer arguments as FMI 2.0 defines them: NULL, or valid for the announced number of
/// elements (strings NUL-terminated) for the duration of the call.
#[no_mangle]
pub unsafe extern "C" fn fmi2GetBooleanStatus(
    c: fmi2Component,
    s: fmi2StatusKind,
    value: *mut fmi2Boolean,
) -> fmi2Status {
    guard(c, Function::GetBooleanStatus, |inst| {
        // SAFETY: FMI 2.0 passes a pointer to the importer's fmi2Boolean.
        let value = unsafe { output_pointer(value, "value") }?;
        *value = if inst.get_boolean_status_body(status_kind(s)?)? {
            fmi2True
        } else {
            fmi2False
        };
        Ok(Status::Ok)
    })
}

/// # Safety
/// Pointer arguments as FMI 2.0 defines them: NULL, or valid for the announced number of
/// elements (strings NUL-terminated) for the duration of the call.
#[no_mangle]
pub unsafe extern "C" fn fmi2GetStringStatus(
    c: fmi2Component,
    s: fmi2StatusKind,
    value: *mut fmi2String,
) -> fmi2Status {
    guard(c, Function::GetStringStatus, |inst| {
        // SAFETY: FMI 2.0 passes a pointer to the importer's fmi2String. Checked like every
        // other out-pointer, although no String status exists to be written through it.
        let _value = unsafe { output_pointer(value, "value") }?;
        inst.get_string_status_body(status_kind(s)?)?;
        Ok(Status::Ok)
    })
}

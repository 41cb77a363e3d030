//! The Model Exchange functions of FMI 2.0.4 §3.2.

use super::guard::{guard, input_array, output_array, output_pointer};
use super::types::*;
use crate::fmu::Function;

fn boolean(b: bool) -> fmi2Boolean {
    if b {
        fmi2True
    } else {
        fmi2False
    }
}

#[no_mangle]
pub extern "C" fn fmi2EnterEventMode(c: fmi2Component) -> fmi2Status {
    guard(c, Function::EnterEventMode, |inst| inst.enter_event_mode_body())
}

/// # Safety
/// `fmi2eventInfo` as FMI 2.0 defines it: NULL, or one writable fmi2EventInfo.
#[no_mangle]
pub unsafe extern "C" fn fmi2NewDiscreteStates(c: fmi2Component, fmi2eventInfo: *mut fmi2EventInfo) -> fmi2Status {
    guard(c, Function::NewDiscreteStates, |inst| {
        // SAFETY: FMI 2.0 passes a pointer to one fmi2EventInfo the FMU fills.
        let out = unsafe { output_pointer(fmi2eventInfo, "fmi2eventInfo") }?;
        let info = inst.new_discrete_states_body()?;
        *out = fmi2EventInfo {
            newDiscreteStatesNeeded: boolean(info.new_discrete_states_needed),
            terminateSimulation: boolean(info.terminate_simulation),
            nominalsOfContinuousStatesChanged: boolean(info.nominals_changed),
            valuesOfContinuousStatesChanged: boolean(info.values_changed),
            nextEventTimeDefined: boolean(info.next_event_time.is_some()),
            nextEventTime: info.next_event_time.unwrap_or(0.0),
        };
        Ok(crate::fmu::Status::Ok)
    })
}

#[no_mangle]
pub extern "C" fn fmi2EnterContinuousTimeMode(c: fmi2Component) -> fmi2Status {
    guard(c, Function::EnterContinuousTimeMode, |inst| {
        inst.enter_continuous_time_mode_body()
    })
}

/// # Safety
/// `enterEventMode` and `terminateSimulation` as FMI 2.0 defines them: one writable
/// fmi2Boolean each.
#[no_mangle]
pub unsafe extern "C" fn fmi2CompletedIntegratorStep(
    c: fmi2Component,
    noSetFMUStatePriorToCurrentPoint: fmi2Boolean,
    enterEventMode: *mut fmi2Boolean,
    terminateSimulation: *mut fmi2Boolean,
) -> fmi2Status {
    // Nothing is kept for a later fmi2SetFMUstate, so the promise changes nothing.
    let _ = noSetFMUStatePriorToCurrentPoint;
    guard(c, Function::CompletedIntegratorStep, |inst| {
        // SAFETY: FMI 2.0 passes pointers to one fmi2Boolean each, written by the FMU.
        let enter = unsafe { output_pointer(enterEventMode, "enterEventMode") }?;
        let terminate = unsafe { output_pointer(terminateSimulation, "terminateSimulation") }?;
        let (e, t) = inst.completed_integrator_step_body()?;
        *enter = boolean(e);
        *terminate = boolean(t);
        Ok(crate::fmu::Status::Ok)
    })
}

#[no_mangle]
pub extern "C" fn fmi2SetTime(c: fmi2Component, time: fmi2Real) -> fmi2Status {
    guard(c, Function::SetTime, |inst| inst.set_time_body(time))
}

/// # Safety
/// `x` as FMI 2.0 defines it: NULL, or `nx` readable values.
#[no_mangle]
pub unsafe extern "C" fn fmi2SetContinuousStates(c: fmi2Component, x: *const fmi2Real, nx: usize) -> fmi2Status {
    guard(c, Function::SetContinuousStates, |inst| {
        // SAFETY: FMI 2.0 passes `nx` state values.
        let x = unsafe { input_array(x, nx, "x") }?;
        inst.set_continuous_states_body(x)
    })
}

/// # Safety
/// `derivatives` as FMI 2.0 defines it: NULL, or room for `nx` values.
#[no_mangle]
pub unsafe extern "C" fn fmi2GetDerivatives(c: fmi2Component, derivatives: *mut fmi2Real, nx: usize) -> fmi2Status {
    guard(c, Function::GetDerivatives, |inst| {
        // SAFETY: FMI 2.0 passes room for `nx` values.
        let out = unsafe { output_array(derivatives, nx, "derivatives") }?;
        inst.get_derivatives_body(out)
    })
}

/// # Safety
/// `eventIndicators` as FMI 2.0 defines it: NULL, or room for `ni` values.
#[no_mangle]
pub unsafe extern "C" fn fmi2GetEventIndicators(
    c: fmi2Component,
    eventIndicators: *mut fmi2Real,
    ni: usize,
) -> fmi2Status {
    guard(c, Function::GetEventIndicators, |inst| {
        // SAFETY: FMI 2.0 passes room for `ni` values.
        let out = unsafe { output_array(eventIndicators, ni, "eventIndicators") }?;
        inst.get_event_indicators_body(out)
    })
}

/// # Safety
/// `x` as FMI 2.0 defines it: NULL, or room for `nx` values.
#[no_mangle]
pub unsafe extern "C" fn fmi2GetContinuousStates(c: fmi2Component, x: *mut fmi2Real, nx: usize) -> fmi2Status {
    guard(c, Function::GetContinuousStates, |inst| {
        // SAFETY: FMI 2.0 passes room for `nx` values.
        let out = unsafe { output_array(x, nx, "x") }?;
        inst.get_continuous_states_body(out)
    })
}

/// # Safety
/// `x_nominal` as FMI 2.0 defines it: NULL, or room for `nx` values.
#[no_mangle]
pub unsafe extern "C" fn fmi2GetNominalsOfContinuousStates(
    c: fmi2Component,
    x_nominal: *mut fmi2Real,
    nx: usize,
) -> fmi2Status {
    guard(c, Function::GetNominalsOfContinuousStates, |inst| {
        // SAFETY: FMI 2.0 passes room for `nx` values.
        let out = unsafe { output_array(x_nominal, nx, "x_nominal") }?;
        inst.get_nominals_body(out)
    })
}

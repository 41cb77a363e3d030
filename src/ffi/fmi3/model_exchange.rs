//! The Model Exchange functions of FMI 3.0 (§3.2): the same calls as FMI 2.0's (docs/model.md
//! §6), plus the counts of states and event indicators.

use super::super::guard::{input_array, output_array, output_pointer};
use super::types::*;
use super::{boolean, guard3};
use crate::fmu::{Function, Status};

#[no_mangle]
pub extern "C" fn fmi3EnterContinuousTimeMode(instance: fmi3Instance) -> fmi3Status {
    guard3(instance, Function::EnterContinuousTimeMode, |inst| {
        inst.enter_continuous_time_mode_body()
    })
}

/// # Safety
/// `enterEventMode` and `terminateSimulation`: one writable fmi3Boolean each.
#[no_mangle]
pub unsafe extern "C" fn fmi3CompletedIntegratorStep(
    instance: fmi3Instance,
    noSetFMUStatePriorToCurrentPoint: fmi3Boolean,
    enterEventMode: *mut fmi3Boolean,
    terminateSimulation: *mut fmi3Boolean,
) -> fmi3Status {
    // Nothing is kept for a later fmi3SetFMUState, so the promise changes nothing.
    let _ = noSetFMUStatePriorToCurrentPoint;
    guard3(instance, Function::CompletedIntegratorStep, |inst| {
        // SAFETY: FMI 3.0 passes one writable fmi3Boolean behind each pointer.
        let enter = unsafe { output_pointer(enterEventMode, "enterEventMode") }?;
        let terminate = unsafe { output_pointer(terminateSimulation, "terminateSimulation") }?;
        let (e, t) = inst.completed_integrator_step_body()?;
        *enter = boolean(e);
        *terminate = boolean(t);
        Ok(Status::Ok)
    })
}

#[no_mangle]
pub extern "C" fn fmi3SetTime(instance: fmi3Instance, time: fmi3Float64) -> fmi3Status {
    guard3(instance, Function::SetTime, |inst| inst.set_time_body(time))
}

/// # Safety
/// `continuousStates` NULL or `nContinuousStates` readable values.
#[no_mangle]
pub unsafe extern "C" fn fmi3SetContinuousStates(
    instance: fmi3Instance,
    continuousStates: *const fmi3Float64,
    nContinuousStates: usize,
) -> fmi3Status {
    guard3(instance, Function::SetContinuousStates, |inst| {
        // SAFETY: FMI 3.0 passes `nContinuousStates` values.
        let x = unsafe { input_array(continuousStates, nContinuousStates, "continuousStates") }?;
        inst.set_continuous_states_body(x)
    })
}

/// # Safety
/// `derivatives` NULL or room for `nContinuousStates` values.
#[no_mangle]
pub unsafe extern "C" fn fmi3GetContinuousStateDerivatives(
    instance: fmi3Instance,
    derivatives: *mut fmi3Float64,
    nContinuousStates: usize,
) -> fmi3Status {
    guard3(instance, Function::GetDerivatives, |inst| {
        // SAFETY: FMI 3.0 passes room for `nContinuousStates` values.
        let out = unsafe { output_array(derivatives, nContinuousStates, "derivatives") }?;
        inst.get_derivatives_body(out)
    })
}

/// # Safety
/// `eventIndicators` NULL or room for `nEventIndicators` values.
#[no_mangle]
pub unsafe extern "C" fn fmi3GetEventIndicators(
    instance: fmi3Instance,
    eventIndicators: *mut fmi3Float64,
    nEventIndicators: usize,
) -> fmi3Status {
    guard3(instance, Function::GetEventIndicators, |inst| {
        // SAFETY: FMI 3.0 passes room for `nEventIndicators` values.
        let out = unsafe { output_array(eventIndicators, nEventIndicators, "eventIndicators") }?;
        inst.get_event_indicators_body(out)
    })
}

/// # Safety
/// `continuousStates` NULL or room for `nContinuousStates` values.
#[no_mangle]
pub unsafe extern "C" fn fmi3GetContinuousStates(
    instance: fmi3Instance,
    continuousStates: *mut fmi3Float64,
    nContinuousStates: usize,
) -> fmi3Status {
    guard3(instance, Function::GetContinuousStates, |inst| {
        // SAFETY: FMI 3.0 passes room for `nContinuousStates` values.
        let out = unsafe { output_array(continuousStates, nContinuousStates, "continuousStates") }?;
        inst.get_continuous_states_body(out)
    })
}

/// # Safety
/// `nominals` NULL or room for `nContinuousStates` values.
#[no_mangle]
pub unsafe extern "C" fn fmi3GetNominalsOfContinuousStates(
    instance: fmi3Instance,
    nominals: *mut fmi3Float64,
    nContinuousStates: usize,
) -> fmi3Status {
    guard3(instance, Function::GetNominalsOfContinuousStates, |inst| {
        // SAFETY: FMI 3.0 passes room for `nContinuousStates` values.
        let out = unsafe { output_array(nominals, nContinuousStates, "nominals") }?;
        inst.get_nominals_body(out)
    })
}

/// # Safety
/// `nEventIndicators` NULL or one writable size_t.
#[no_mangle]
pub unsafe extern "C" fn fmi3GetNumberOfEventIndicators(
    instance: fmi3Instance,
    nEventIndicators: *mut usize,
) -> fmi3Status {
    guard3(instance, Function::GetNumberOfEventIndicators, |inst| {
        // SAFETY: FMI 3.0 passes a pointer to one size_t.
        let out = unsafe { output_pointer(nEventIndicators, "nEventIndicators") }?;
        *out = inst.event_indicator_count();
        Ok(Status::Ok)
    })
}

/// # Safety
/// `nContinuousStates` NULL or one writable size_t.
#[no_mangle]
pub unsafe extern "C" fn fmi3GetNumberOfContinuousStates(
    instance: fmi3Instance,
    nContinuousStates: *mut usize,
) -> fmi3Status {
    guard3(instance, Function::GetNumberOfContinuousStates, |inst| {
        // SAFETY: FMI 3.0 passes a pointer to one size_t.
        let out = unsafe { output_pointer(nContinuousStates, "nContinuousStates") }?;
        *out = inst.continuous_state_count();
        Ok(Status::Ok)
    })
}

//! Model Exchange entry points, exported with their standard signatures so that a loader
//! that resolves every FMI 2.0 symbol finds them; each returns fmi2Error with the reason.

use super::guard::guard;
use super::types::*;
use crate::fmu::{FmuError, Function};

fn refuse(c: fmi2Component, function: Function) -> fmi2Status {
    // The legal-state check refuses every Model Exchange function; the body never runs.
    guard(c, function, |_| {
        Err(FmuError::ModelExchangeOnly {
            function: function.c_name(),
        })
    })
}

#[no_mangle]
pub extern "C" fn fmi2EnterEventMode(c: fmi2Component) -> fmi2Status {
    refuse(c, Function::EnterEventMode)
}

#[no_mangle]
pub extern "C" fn fmi2NewDiscreteStates(c: fmi2Component, fmi2eventInfo: *mut fmi2EventInfo) -> fmi2Status {
    let _ = fmi2eventInfo;
    refuse(c, Function::NewDiscreteStates)
}

#[no_mangle]
pub extern "C" fn fmi2EnterContinuousTimeMode(c: fmi2Component) -> fmi2Status {
    refuse(c, Function::EnterContinuousTimeMode)
}

#[no_mangle]
pub extern "C" fn fmi2CompletedIntegratorStep(
    c: fmi2Component,
    noSetFMUStatePriorToCurrentPoint: fmi2Boolean,
    enterEventMode: *mut fmi2Boolean,
    terminateSimulation: *mut fmi2Boolean,
) -> fmi2Status {
    let _ = (noSetFMUStatePriorToCurrentPoint, enterEventMode, terminateSimulation);
    refuse(c, Function::CompletedIntegratorStep)
}

#[no_mangle]
pub extern "C" fn fmi2SetTime(c: fmi2Component, time: fmi2Real) -> fmi2Status {
    let _ = time;
    refuse(c, Function::SetTime)
}

#[no_mangle]
pub extern "C" fn fmi2SetContinuousStates(c: fmi2Component, x: *const fmi2Real, nx: usize) -> fmi2Status {
    let _ = (x, nx);
    refuse(c, Function::SetContinuousStates)
}

#[no_mangle]
pub extern "C" fn fmi2GetDerivatives(c: fmi2Component, derivatives: *mut fmi2Real, nx: usize) -> fmi2Status {
    let _ = (derivatives, nx);
    refuse(c, Function::GetDerivatives)
}

#[no_mangle]
pub extern "C" fn fmi2GetEventIndicators(c: fmi2Component, eventIndicators: *mut fmi2Real, ni: usize) -> fmi2Status {
    let _ = (eventIndicators, ni);
    refuse(c, Function::GetEventIndicators)
}

#[no_mangle]
pub extern "C" fn fmi2GetContinuousStates(c: fmi2Component, x: *mut fmi2Real, nx: usize) -> fmi2Status {
    let _ = (x, nx);
    refuse(c, Function::GetContinuousStates)
}

#[no_mangle]
pub extern "C" fn fmi2GetNominalsOfContinuousStates(
    c: fmi2Component,
    x_nominal: *mut fmi2Real,
    nx: usize,
) -> fmi2Status {
    let _ = (x_nominal, nx);
    refuse(c, Function::GetNominalsOfContinuousStates)
}

//! The Co-Simulation functions of FMI 3.0 (§4.2): fmi3DoStep, which with early return stops at
//! the first contact switch inside the step, Step Mode, and output derivatives.

use super::super::guard::{input_array, output_array, output_pointer};
use super::types::*;
use super::{boolean, guard3};
use crate::fmu::{Function, Status};

#[no_mangle]
pub extern "C" fn fmi3EnterStepMode(instance: fmi3Instance) -> fmi3Status {
    guard3(instance, Function::EnterStepMode, |inst| inst.enter_step_mode_body())
}

/// # Safety
/// As FMI 3.0 defines them: arrays NULL or of the announced lengths.
#[no_mangle]
pub unsafe extern "C" fn fmi3GetOutputDerivatives(
    instance: fmi3Instance,
    valueReferences: *const fmi3ValueReference,
    nValueReferences: usize,
    orders: *const fmi3Int32,
    values: *mut fmi3Float64,
    nValues: usize,
) -> fmi3Status {
    guard3(instance, Function::GetRealOutputDerivatives, |inst| {
        // SAFETY: FMI 3.0 passes `nValueReferences` references and orders, room for `nValues`.
        let vrs = unsafe { input_array(valueReferences, nValueReferences, "valueReferences") }?;
        let orders = unsafe { input_array(orders, nValueReferences, "orders") }?;
        let out = unsafe { output_array(values, nValues, "values") }?;
        inst.get_real_output_derivatives_body(vrs, orders, out)
    })
}

/// One communication step. With `earlyReturnAllowed` at instantiation it stops at the first
/// contact switch inside the step: `earlyReturn` is then true and `lastSuccessfulTime` the
/// switch instant; with `eventModeUsed` as well, `eventHandlingNeeded` asks for Event Mode.
/// # Safety
/// Each output pointer NULL or one writable value of its type.
#[no_mangle]
pub unsafe extern "C" fn fmi3DoStep(
    instance: fmi3Instance,
    currentCommunicationPoint: fmi3Float64,
    communicationStepSize: fmi3Float64,
    noSetFMUStatePriorToCurrentPoint: fmi3Boolean,
    eventHandlingNeeded: *mut fmi3Boolean,
    terminateSimulation: *mut fmi3Boolean,
    earlyReturn: *mut fmi3Boolean,
    lastSuccessfulTime: *mut fmi3Float64,
) -> fmi3Status {
    // Nothing is kept for a later fmi3SetFMUState, so the promise changes nothing.
    let _ = noSetFMUStatePriorToCurrentPoint;
    guard3(instance, Function::DoStep, |inst| {
        // SAFETY: FMI 3.0 passes one writable value behind each pointer.
        let event = unsafe { output_pointer(eventHandlingNeeded, "eventHandlingNeeded") }?;
        let terminate = unsafe { output_pointer(terminateSimulation, "terminateSimulation") }?;
        let early = unsafe { output_pointer(earlyReturn, "earlyReturn") }?;
        let last = unsafe { output_pointer(lastSuccessfulTime, "lastSuccessfulTime") }?;
        let outcome = inst.do_step3_body(currentCommunicationPoint, communicationStepSize)?;
        *event = boolean(outcome.event_handling_needed);
        *terminate = boolean(false);
        *early = boolean(outcome.early_return);
        *last = outcome.time;
        Ok(Status::Ok)
    })
}

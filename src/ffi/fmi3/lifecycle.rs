//! Version, logging, instantiation and the lifecycle calls of FMI 3.0 (§2.3.1–§2.3.4).

use super::super::fmu_state::free_states_of;
use super::super::guard::{c_str, input_array, unregister};
use super::super::instantiate::Request;
use super::types::*;
use super::{guard3, CLogger3};
use crate::fmu::{CoSimulationOptions, Flavour, Function, Interface, LogCategory, LogSink, Status};
use std::ffi::c_char;
use std::panic::{catch_unwind, AssertUnwindSafe};

#[no_mangle]
pub extern "C" fn fmi3GetVersion() -> *const c_char {
    c"3.0".as_ptr()
}

/// # Safety
/// Pointer arguments as FMI 3.0 defines them: NULL, or valid for the announced number of
/// elements (strings NUL-terminated) for the duration of the call.
#[no_mangle]
pub unsafe extern "C" fn fmi3SetDebugLogging(
    instance: fmi3Instance,
    loggingOn: fmi3Boolean,
    nCategories: usize,
    categories: *const fmi3String,
) -> fmi3Status {
    guard3(instance, Function::SetDebugLogging, |inst| {
        // SAFETY: FMI 3.0 passes `nCategories` category strings (or NULL with 0).
        let pointers = unsafe { input_array(categories, nCategories, "categories") }?;
        let mut names = Vec::with_capacity(pointers.len());
        for p in pointers {
            // SAFETY: each entry is an fmi3String, NUL-terminated, owned by the importer.
            names.push(unsafe { c_str(*p, "a category name") }?);
        }
        inst.set_debug_logging_body(loggingOn, &names)
    })
}

/// What both instantiation functions were given.
struct Request3 {
    name: fmi3String,
    token: fmi3String,
    logging_on: bool,
    environment: fmi3InstanceEnvironment,
    log_message: fmi3LogMessageCallback,
    flavour: Flavour,
    options: CoSimulationOptions,
}

/// Creates the instance, or NULL after logging the reason (when a logger was given and logging
/// is on); never unwinds into C.
fn instantiate(request: Request3) -> fmi3Instance {
    let function = match request.flavour.interface {
        Interface::ModelExchange => "fmi3InstantiateModelExchange",
        Interface::CoSimulation => "fmi3InstantiateCoSimulation",
    };
    let sink = request.log_message.map(|log_message| {
        Box::new(CLogger3 {
            log_message,
            environment: request.environment,
        }) as Box<dyn LogSink>
    });
    let request = Request {
        function,
        name: request.name,
        key: request.token,
        flavour: Ok(request.flavour),
        options: request.options,
        logging_on: request.logging_on,
        sink,
    };
    // SAFETY: fmi3String arguments are NUL-terminated strings or NULL.
    catch_unwind(AssertUnwindSafe(|| unsafe {
        super::super::instantiate::instantiate(request)
    }))
    .unwrap_or(std::ptr::null_mut())
}

/// # Safety
/// Pointer arguments as FMI 3.0 defines them: NULL, or NUL-terminated strings valid for the
/// duration of the call; `logMessage` NULL or a function of its type.
#[no_mangle]
pub unsafe extern "C" fn fmi3InstantiateModelExchange(
    instanceName: fmi3String,
    instantiationToken: fmi3String,
    resourcePath: fmi3String,
    visible: fmi3Boolean,
    loggingOn: fmi3Boolean,
    instanceEnvironment: fmi3InstanceEnvironment,
    logMessage: fmi3LogMessageCallback,
) -> fmi3Instance {
    // Resources are not needed, and the FMU has no window.
    let _ = (resourcePath, visible);
    instantiate(Request3 {
        name: instanceName,
        token: instantiationToken,
        logging_on: loggingOn,
        environment: instanceEnvironment,
        log_message: logMessage,
        flavour: Flavour::FMI3_ME,
        options: CoSimulationOptions::default(),
    })
}

/// # Safety
/// As [`fmi3InstantiateModelExchange`]; `requiredIntermediateVariables` NULL or
/// `nRequiredIntermediateVariables` value references.
#[no_mangle]
pub unsafe extern "C" fn fmi3InstantiateCoSimulation(
    instanceName: fmi3String,
    instantiationToken: fmi3String,
    resourcePath: fmi3String,
    visible: fmi3Boolean,
    loggingOn: fmi3Boolean,
    eventModeUsed: fmi3Boolean,
    earlyReturnAllowed: fmi3Boolean,
    requiredIntermediateVariables: *const fmi3ValueReference,
    nRequiredIntermediateVariables: usize,
    instanceEnvironment: fmi3InstanceEnvironment,
    logMessage: fmi3LogMessageCallback,
    intermediateUpdate: fmi3IntermediateUpdateCallback,
) -> fmi3Instance {
    // providesIntermediateUpdate = false: the callback is never called, so no variable is
    // required at intermediate points.
    let _ = (
        resourcePath,
        visible,
        requiredIntermediateVariables,
        nRequiredIntermediateVariables,
        intermediateUpdate,
    );
    instantiate(Request3 {
        name: instanceName,
        token: instantiationToken,
        logging_on: loggingOn,
        environment: instanceEnvironment,
        log_message: logMessage,
        flavour: Flavour::FMI3_CS,
        options: CoSimulationOptions {
            event_mode_used: eventModeUsed,
            early_return_allowed: earlyReturnAllowed,
        },
    })
}

/// Scheduled Execution is not offered (no `<ScheduledExecution>` in the description): NULL, and
/// the reason through the logger when one is given.
/// # Safety
/// As [`fmi3InstantiateModelExchange`].
#[no_mangle]
pub unsafe extern "C" fn fmi3InstantiateScheduledExecution(
    instanceName: fmi3String,
    instantiationToken: fmi3String,
    resourcePath: fmi3String,
    visible: fmi3Boolean,
    loggingOn: fmi3Boolean,
    instanceEnvironment: fmi3InstanceEnvironment,
    logMessage: fmi3LogMessageCallback,
    clockUpdate: fmi3ClockUpdateCallback,
    lockPreemption: fmi3LockPreemptionCallback,
    unlockPreemption: fmi3UnlockPreemptionCallback,
) -> fmi3Instance {
    let _ = (
        instanceName,
        instantiationToken,
        resourcePath,
        visible,
        loggingOn,
        clockUpdate,
        lockPreemption,
        unlockPreemption,
    );
    if let Some(log_message) = logMessage {
        let _ = catch_unwind(AssertUnwindSafe(|| {
            CLogger3 {
                log_message,
                environment: instanceEnvironment,
            }
            .log(
                Status::Error,
                LogCategory::Errors,
                "fmi3InstantiateScheduledExecution: this FMU offers Model Exchange and Co-Simulation, not \
                 Scheduled Execution",
            )
        }));
    }
    std::ptr::null_mut()
}

/// Frees the instance and every FMU state it allocated; anything else is ignored.
#[no_mangle]
pub extern "C" fn fmi3FreeInstance(instance: fmi3Instance) {
    if let Some(component) = unregister(instance) {
        free_states_of(instance);
        // Never unwind into C, whatever a destructor does.
        let _ = catch_unwind(AssertUnwindSafe(move || drop(component)));
    }
}

#[no_mangle]
pub extern "C" fn fmi3EnterInitializationMode(
    instance: fmi3Instance,
    toleranceDefined: fmi3Boolean,
    tolerance: fmi3Float64,
    startTime: fmi3Float64,
    stopTimeDefined: fmi3Boolean,
    stopTime: fmi3Float64,
) -> fmi3Status {
    guard3(instance, Function::EnterInitializationMode, |inst| {
        let tolerance = toleranceDefined.then_some(tolerance);
        let stop = stopTimeDefined.then_some(stopTime);
        inst.setup_experiment_body(tolerance, startTime, stop)?;
        inst.enter_initialization_mode_body()
    })
}

#[no_mangle]
pub extern "C" fn fmi3ExitInitializationMode(instance: fmi3Instance) -> fmi3Status {
    guard3(instance, Function::ExitInitializationMode, |inst| {
        inst.exit_initialization_mode_body()
    })
}

#[no_mangle]
pub extern "C" fn fmi3EnterEventMode(instance: fmi3Instance) -> fmi3Status {
    guard3(instance, Function::EnterEventMode, |inst| inst.enter_event_mode_body())
}

#[no_mangle]
pub extern "C" fn fmi3Terminate(instance: fmi3Instance) -> fmi3Status {
    guard3(instance, Function::Terminate, |inst| inst.terminate_body())
}

#[no_mangle]
pub extern "C" fn fmi3Reset(instance: fmi3Instance) -> fmi3Status {
    guard3(instance, Function::Reset, |inst| inst.reset_body())
}

/// fmi3UpdateDiscreteStates: nothing is discrete (docs/model.md §6).
/// # Safety
/// Each pointer NULL or one writable value of its type.
#[no_mangle]
pub unsafe extern "C" fn fmi3UpdateDiscreteStates(
    instance: fmi3Instance,
    discreteStatesNeedUpdate: *mut fmi3Boolean,
    terminateSimulation: *mut fmi3Boolean,
    nominalsOfContinuousStatesChanged: *mut fmi3Boolean,
    valuesOfContinuousStatesChanged: *mut fmi3Boolean,
    nextEventTimeDefined: *mut fmi3Boolean,
    nextEventTime: *mut fmi3Float64,
) -> fmi3Status {
    use super::super::guard::output_pointer;
    guard3(instance, Function::NewDiscreteStates, |inst| {
        // SAFETY: FMI 3.0 passes one writable value behind each pointer.
        let need = unsafe { output_pointer(discreteStatesNeedUpdate, "discreteStatesNeedUpdate") }?;
        let terminate = unsafe { output_pointer(terminateSimulation, "terminateSimulation") }?;
        let nominals =
            unsafe { output_pointer(nominalsOfContinuousStatesChanged, "nominalsOfContinuousStatesChanged") }?;
        let values = unsafe { output_pointer(valuesOfContinuousStatesChanged, "valuesOfContinuousStatesChanged") }?;
        let defined = unsafe { output_pointer(nextEventTimeDefined, "nextEventTimeDefined") }?;
        let next = unsafe { output_pointer(nextEventTime, "nextEventTime") }?;
        let info = inst.new_discrete_states_body()?;
        *need = super::boolean(info.new_discrete_states_needed);
        *terminate = super::boolean(info.terminate_simulation);
        *nominals = super::boolean(info.nominals_changed);
        *values = super::boolean(info.values_changed);
        *defined = super::boolean(info.next_event_time.is_some());
        *next = info.next_event_time.unwrap_or(0.0);
        Ok(Status::Ok)
    })
}

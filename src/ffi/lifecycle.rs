//! Version inquiry, instantiation, logging, and the lifecycle calls of FMI 2.0.4 §2.1.

use super::fmu_state::free_states_of;
use super::guard::{c_str, guard, input_array, register, to_c_string, unregister, CLogger, Component};
use super::types::*;
use crate::fmu::{model_for_instantiation, Function, Instance, Interface, LogCategory, LogSink, Standard, Status};
use std::ffi::c_char;
use std::panic::{catch_unwind, AssertUnwindSafe};

#[no_mangle]
pub extern "C" fn fmi2GetTypesPlatform() -> *const c_char {
    c"default".as_ptr()
}

#[no_mangle]
pub extern "C" fn fmi2GetVersion() -> *const c_char {
    c"2.0".as_ptr()
}

/// # Safety
/// Pointer arguments as FMI 2.0 defines them: NULL, or valid for the announced number of
/// elements (strings NUL-terminated) for the duration of the call.
#[no_mangle]
pub unsafe extern "C" fn fmi2SetDebugLogging(
    c: fmi2Component,
    loggingOn: fmi2Boolean,
    nCategories: usize,
    categories: *const fmi2String,
) -> fmi2Status {
    guard(c, Function::SetDebugLogging, |inst| {
        // SAFETY: FMI 2.0 passes `nCategories` category strings (or NULL with 0).
        let pointers = unsafe { input_array(categories, nCategories, "categories") }?;
        let mut names = Vec::with_capacity(pointers.len());
        for p in pointers {
            // SAFETY: each entry is an fmi2String, NUL-terminated, owned by the importer.
            names.push(unsafe { c_str(*p, "a category name") }?);
        }
        inst.set_debug_logging_body(loggingOn != fmi2False, &names)
    })
}

/// Creates a Model Exchange or Co-Simulation instance of the model whose guid is `fmuGUID`; NULL (after logging
/// the reason, when a logger was given) for anything it cannot serve.
/// # Safety
/// Pointer arguments as FMI 2.0 defines them: NULL, or valid for the announced number of
/// elements (strings NUL-terminated) for the duration of the call.
#[no_mangle]
pub unsafe extern "C" fn fmi2Instantiate(
    instanceName: fmi2String,
    fmuType: fmi2Type,
    fmuGUID: fmi2String,
    fmuResourceLocation: fmi2String,
    functions: *const fmi2CallbackFunctions,
    visible: fmi2Boolean,
    loggingOn: fmi2Boolean,
) -> fmi2Component {
    // Resources are not needed, and the FMU has no window.
    let _ = (fmuResourceLocation, visible);
    let result = catch_unwind(AssertUnwindSafe(|| {
        instantiate(instanceName, fmuType, fmuGUID, functions, loggingOn)
    }));
    result.unwrap_or(std::ptr::null_mut())
}

fn instantiate(
    instance_name: fmi2String,
    fmu_type: fmi2Type,
    guid: fmi2String,
    functions: *const fmi2CallbackFunctions,
    logging_on: fmi2Boolean,
) -> fmi2Component {
    if functions.is_null() || !functions.is_aligned() {
        return std::ptr::null_mut();
    }
    // SAFETY: non-NULL and aligned; FMI 2.0 passes a pointer to an fmi2CallbackFunctions
    // struct valid for the call (and we copy it).
    let callbacks = unsafe { *functions };
    // SAFETY: fmi2String arguments are NUL-terminated strings or NULL.
    let name = unsafe { c_str(instance_name, "instanceName") };
    let logger = callbacks.logger.map(|logger| CLogger {
        logger,
        environment: callbacks.componentEnvironment,
        instance_name: to_c_string(name.as_ref().map(|n| *n).unwrap_or("")),
    });
    let refuse = |logger: &Option<CLogger>, reason: String| {
        if let Some(l) = logger {
            l.send(
                fmi2Status::fmi2Error,
                LogCategory::Errors.name(),
                &format!("fmi2Instantiate: {reason}"),
            );
        }
        std::ptr::null_mut()
    };
    let name = match name {
        Ok(n) if !n.trim().is_empty() => n,
        Ok(_) => return refuse(&logger, "instanceName is blank".into()),
        Err(e) => return refuse(&logger, e.to_string()),
    };
    let interface = match fmu_type {
        fmi2CoSimulation => Interface::CoSimulation,
        fmi2ModelExchange => Interface::ModelExchange,
        other => {
            return refuse(
                &logger,
                format!("fmuType {other} is neither fmi2ModelExchange nor fmi2CoSimulation"),
            )
        }
    };
    // SAFETY: as for instanceName.
    let guid = match unsafe { c_str(guid, "fmuGUID") } {
        Ok(g) => g,
        Err(e) => return refuse(&logger, e.to_string()),
    };
    let model = match model_for_instantiation(Standard::Fmi2, guid) {
        Ok(model) => model,
        Err(why) => return refuse(&logger, why),
    };
    let sink = logger.map(|l| Box::new(l) as Box<dyn LogSink>);
    let mut instance = Instance::new_for(model, interface, sink, logging_on != fmi2False);
    instance.log(Status::Ok, LogCategory::Calls, || {
        format!(
            "fmi2Instantiate: {} instance {name:?} of {}",
            interface.name(),
            model.identifier
        )
    });
    match register(Box::new(Component { instance })) {
        Ok(handle) => handle,
        Err(mut component) => {
            component.instance.log(Status::Error, LogCategory::Errors, || {
                format!(
                    "fmi2Instantiate: {} instances are live, the most this library serves at once; free one first",
                    super::registry::CAPACITY
                )
            });
            std::ptr::null_mut()
        }
    }
}

/// Frees the instance and every FMU state it allocated. Unknown or already freed pointers are
/// ignored (there is nothing to free and no status to return).
#[no_mangle]
pub extern "C" fn fmi2FreeInstance(c: fmi2Component) {
    if let Some(component) = unregister(c) {
        free_states_of(c);
        // Never unwind into C, whatever a destructor does.
        let _ = catch_unwind(AssertUnwindSafe(move || drop(component)));
    }
}

#[no_mangle]
pub extern "C" fn fmi2SetupExperiment(
    c: fmi2Component,
    toleranceDefined: fmi2Boolean,
    tolerance: fmi2Real,
    startTime: fmi2Real,
    stopTimeDefined: fmi2Boolean,
    stopTime: fmi2Real,
) -> fmi2Status {
    guard(c, Function::SetupExperiment, |inst| {
        let tolerance = (toleranceDefined != fmi2False).then_some(tolerance);
        let stop = (stopTimeDefined != fmi2False).then_some(stopTime);
        inst.setup_experiment_body(tolerance, startTime, stop)
    })
}

#[no_mangle]
pub extern "C" fn fmi2EnterInitializationMode(c: fmi2Component) -> fmi2Status {
    guard(c, Function::EnterInitializationMode, |inst| {
        inst.enter_initialization_mode_body()
    })
}

#[no_mangle]
pub extern "C" fn fmi2ExitInitializationMode(c: fmi2Component) -> fmi2Status {
    guard(c, Function::ExitInitializationMode, |inst| {
        inst.exit_initialization_mode_body()
    })
}

#[no_mangle]
pub extern "C" fn fmi2Terminate(c: fmi2Component) -> fmi2Status {
    guard(c, Function::Terminate, |inst| inst.terminate_body())
}

#[no_mangle]
pub extern "C" fn fmi2Reset(c: fmi2Component) -> fmi2Status {
    guard(c, Function::Reset, |inst| inst.reset_body())
}

//! Version inquiry, instantiation, logging, and the lifecycle calls of FMI 2.0.4 §2.1.

use super::fmu_state::free_states_of;
use super::guard::{c_str, guard, input_array, to_c_string, unregister, CLogger};
use super::instantiate::Request;
use super::types::*;
use crate::fmu::{CoSimulationOptions, Flavour, Function, Interface, LogSink, Standard};
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
    let name = unsafe { c_str(instance_name, "instanceName") }.unwrap_or("");
    let sink = callbacks.logger.map(|logger| {
        Box::new(CLogger {
            logger,
            environment: callbacks.componentEnvironment,
            instance_name: to_c_string(name),
        }) as Box<dyn LogSink>
    });
    let interface = match fmu_type {
        fmi2CoSimulation => Ok(Interface::CoSimulation),
        fmi2ModelExchange => Ok(Interface::ModelExchange),
        other => Err(format!(
            "fmuType {other} is neither fmi2ModelExchange nor fmi2CoSimulation"
        )),
    };
    let request = Request {
        function: "fmi2Instantiate",
        name: instance_name,
        key: guid,
        flavour: interface.map(|interface| Flavour {
            standard: Standard::Fmi2,
            interface,
        }),
        options: CoSimulationOptions::default(),
        logging_on: logging_on != fmi2False,
        sink,
    };
    // SAFETY: fmi2String arguments are NUL-terminated strings or NULL.
    unsafe { super::instantiate::instantiate(request) }
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

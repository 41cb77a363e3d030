//! Instantiation, written once for `fmi2Instantiate` and both FMI 3.0 instantiation functions:
//! the checks before an instance exists (instance name, guid or instantiation token), the
//! instance, its registration, and the refusals with their reasons.

use super::guard::{c_str, register, Component};
use crate::fmu::{
    model_for_instantiation, CoSimulationOptions, Flavour, Instance, LogCategory, LogSink, Standard, Status,
};
use std::ffi::{c_char, c_void};

/// What an instantiation function was given, its C strings not yet read.
pub(crate) struct Request {
    /// The C function, for messages.
    pub function: &'static str,
    pub name: *const c_char,
    /// The guid (FMI 2.0) or the instantiation token (FMI 3.0).
    pub key: *const c_char,
    /// Standard and interface, or why the interface asked for is none (FMI 2.0's fmuType).
    pub flavour: Result<Flavour, String>,
    pub options: CoSimulationOptions,
    pub logging_on: bool,
    /// The importer's logger, if it gave one.
    pub sink: Option<Box<dyn LogSink>>,
}

/// The instance's handle, or NULL after logging why: through the importer's logger when it gave
/// one and may be called (FMI 2.0 always reports errors; FMI 3.0.2 §2.3.1: with loggingOn =
/// fmi3False "the logMessage callback function must not be called").
///
/// # Safety
/// `request.name` and `request.key` are NULL or NUL-terminated strings valid for the call.
pub(crate) unsafe fn instantiate(request: Request) -> *mut c_void {
    let Request {
        function,
        name,
        key,
        flavour,
        options,
        logging_on,
        mut sink,
    } = request;
    let standard = flavour.as_ref().map_or(Standard::Fmi2, |f| f.standard);
    let mut refuse = |reason: String| {
        if let (Some(sink), true) = (sink.as_mut(), logging_on || standard == Standard::Fmi2) {
            sink.log(Status::Error, LogCategory::Errors, &format!("{function}: {reason}"));
        }
        std::ptr::null_mut()
    };
    // SAFETY: NUL-terminated or NULL (this function's contract).
    let name = match unsafe { c_str(name, "instanceName") } {
        Ok(n) if !n.trim().is_empty() => n,
        Ok(_) => return refuse("instanceName is blank".into()),
        Err(e) => return refuse(e.to_string()),
    };
    let flavour = match flavour {
        Ok(flavour) => flavour,
        Err(why) => return refuse(why),
    };
    let argument = match standard {
        Standard::Fmi2 => "fmuGUID",
        Standard::Fmi3 => "instantiationToken",
    };
    // SAFETY: as for the name.
    let key = match unsafe { c_str(key, argument) } {
        Ok(k) => k,
        Err(e) => return refuse(e.to_string()),
    };
    let model = match model_for_instantiation(standard, key) {
        Ok(model) => model,
        Err(why) => return refuse(why),
    };
    if let Err(why) = Instance::offered(model, flavour, options) {
        return refuse(why);
    }
    keep_loaded();
    let mut instance = Instance::with(model, flavour, options, sink, logging_on);
    instance.log(Status::Ok, LogCategory::Calls, || {
        format!(
            "{function}: {} instance {name:?} of {}",
            flavour.interface.name(),
            model.identifier
        )
    });
    match register(Box::new(Component { instance })) {
        Ok(handle) => handle,
        Err(mut component) => {
            component.instance.log(Status::Error, LogCategory::Errors, || {
                format!(
                    "{function}: {} instances are live, the most this library serves at once; free one first",
                    super::registry::CAPACITY
                )
            });
            std::ptr::null_mut()
        }
    }
}

/// On Windows, the counterpart of the NODELETE flag the library is linked with on Linux
/// (build.rs): with its first instance the DLL pins itself, so that an importer's FreeLibrary
/// while an instance lives never unloads it, and the table of live instances outlasts a reload
/// (tests/python/test_reload.py, and the cross test's `reload` scenario).
#[cfg(windows)]
fn keep_loaded() {
    static PINNED: std::sync::Once = std::sync::Once::new();
    PINNED.call_once(|| {
        const GET_MODULE_HANDLE_EX_FLAG_PIN: u32 = 0x1;
        const GET_MODULE_HANDLE_EX_FLAG_FROM_ADDRESS: u32 = 0x4;
        #[link(name = "kernel32")]
        extern "system" {
            fn GetModuleHandleExW(flags: u32, name: *const u16, module: *mut *mut c_void) -> i32;
        }
        let mut module = std::ptr::null_mut();
        // SAFETY: with FROM_ADDRESS, `name` is read as an address inside the module to pin (this
        // function's), not as a string; `module` is a valid place for the handle. A failure
        // leaves the DLL as Windows loaded it: nothing to undo.
        unsafe {
            GetModuleHandleExW(
                GET_MODULE_HANDLE_EX_FLAG_PIN | GET_MODULE_HANDLE_EX_FLAG_FROM_ADDRESS,
                keep_loaded as *const u16,
                &mut module,
            )
        };
    });
}

/// Elsewhere the linker's flag does it (build.rs).
#[cfg(not(windows))]
fn keep_loaded() {}

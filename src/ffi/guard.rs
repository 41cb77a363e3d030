//! The one guard every export goes through: null / unknown instance check → catch_unwind →
//! legal-state check → argument conversion → one mapping from error to `fmi2Status`, with the
//! reason logged through the importer's logger. Plus the C logger and pointer conversions.

use super::registry;
use super::types::*;
use crate::fmu::{FmuError, Function, Instance, LogCategory, LogSink, Standard, Status};
use std::ffi::{CStr, CString};
use std::panic::{catch_unwind, AssertUnwindSafe};
use std::sync::atomic::{AtomicUsize, Ordering};

/// What an `fmi2Component` points to.
pub struct Component {
    pub instance: Instance,
}

/// Handles of FMU states: serial numbers that look like aligned addresses to importers that
/// print them.
static NEXT_HANDLE: AtomicUsize = AtomicUsize::new(0x1000);

pub fn next_handle() -> usize {
    NEXT_HANDLE.fetch_add(0x10, Ordering::Relaxed)
}

/// Makes `component` live and returns its handle; gives it back when
/// [`registry::CAPACITY`] instances are live already.
pub fn register(component: Box<Component>) -> Result<fmi2Component, Box<Component>> {
    registry::insert(component).map(|handle| handle as fmi2Component)
}

/// Removes `c` from the live table and returns ownership of its component, if it is live.
pub fn unregister(c: fmi2Component) -> Option<Box<Component>> {
    registry::remove(c as usize)
}

#[inline]
fn component<'a>(c: fmi2Component) -> Option<&'a mut Component> {
    let address = registry::get(c as usize)?;
    // SAFETY: `address` is live (stored by `register`, not yet unregistered). FMI 2.0.4
    // §2.1.5 forbids calling functions of one instance concurrently, so no other reference to
    // this component exists while the call runs.
    Some(unsafe { &mut *address })
}

impl From<Status> for fmi2Status {
    fn from(s: Status) -> fmi2Status {
        match s {
            Status::Ok => fmi2Status::fmi2OK,
            Status::Warning => fmi2Status::fmi2Warning,
            Status::Discard => fmi2Status::fmi2Discard,
            Status::Error => fmi2Status::fmi2Error,
        }
    }
}

fn panic_message(payload: &(dyn std::any::Any + Send)) -> String {
    if let Some(s) = payload.downcast_ref::<&str>() {
        s.to_string()
    } else if let Some(s) = payload.downcast_ref::<String>() {
        s.clone()
    } else {
        "panic with a non-text payload".to_string()
    }
}

/// Runs `body` on the instance behind `c`. `body` converts the C arguments (it runs after the
/// legal-state check) and does the work; errors are logged and mapped in `Instance::run_status`. A
/// panic is caught here and leaves the instance in state Error.
#[inline]
pub fn guard(
    c: fmi2Component,
    function: Function,
    body: impl FnOnce(&mut Instance) -> Result<Status, FmuError>,
) -> fmi2Status {
    guard_in(Standard::Fmi2, c, function, body).into()
}

/// [`guard`] for the functions of `standard`: an instance created through the other standard's
/// functions is refused (with the reason logged), as is a pointer that is no live instance.
#[inline]
pub fn guard_in(
    standard: Standard,
    c: fmi2Component,
    function: Function,
    body: impl FnOnce(&mut Instance) -> Result<Status, FmuError>,
) -> Status {
    let Some(component) = component(c) else {
        // No instance, hence no logger to tell: the status is the only channel.
        return Status::Error;
    };
    if component.instance.flavour().standard != standard {
        return wrong_standard(component, standard, function);
    }
    // Pure arithmetic on the state (it cannot panic), tested here where `function` is a constant.
    let legal = component.instance.is_legal(function);
    match catch_unwind(AssertUnwindSafe(|| {
        component.instance.run_status(function, legal, body)
    })) {
        Ok(status) => status,
        Err(payload) => {
            let message = panic_message(payload.as_ref());
            // Logging calls back into the importer; it must not unwind into C either.
            let _ = catch_unwind(AssertUnwindSafe(|| {
                component.instance.fail_after_panic(function, message)
            }));
            Status::Error
        }
    }
}

#[cold]
#[inline(never)]
fn wrong_standard(component: &mut Component, standard: Standard, function: Function) -> Status {
    let name = function.name(standard);
    let created = component.instance.flavour().name();
    let _ = catch_unwind(AssertUnwindSafe(|| {
        component.instance.log(Status::Error, LogCategory::Errors, || {
            format!("{name}: the instance is an {created} instance; call the functions of its own standard")
        })
    }));
    Status::Error
}

/// A C array the FMU reads: empty for n = 0 (the pointer may then be NULL), else checked for
/// NULL, alignment and size before the slice is formed.
///
/// # Safety
/// If `ptr` is non-NULL it must point to `n` initialized values of `T` that stay valid and
/// unmodified for `'a` (FMI 2.0: arrays of length nvr owned by the importer for the call).
pub unsafe fn input_array<'a, T>(ptr: *const T, n: usize, argument: &'static str) -> Result<&'a [T], FmuError> {
    if n == 0 {
        return Ok(&[]);
    }
    check_array(ptr, n, argument)?;
    // SAFETY: non-NULL, aligned, n·size_of::<T>() ≤ isize::MAX (checked above); validity and
    // lifetime are the caller's contract.
    Ok(unsafe { std::slice::from_raw_parts(ptr, n) })
}

/// A C array the FMU writes.
///
/// # Safety
/// If `ptr` is non-NULL it must point to `n` writable values of `T`, not aliased by any other
/// argument, valid for `'a`.
pub unsafe fn output_array<'a, T>(ptr: *mut T, n: usize, argument: &'static str) -> Result<&'a mut [T], FmuError> {
    if n == 0 {
        return Ok(&mut []);
    }
    check_array(ptr, n, argument)?;
    // SAFETY: as in `input_array`, plus exclusive access by the caller's contract.
    Ok(unsafe { std::slice::from_raw_parts_mut(ptr, n) })
}

fn check_array<T>(ptr: *const T, n: usize, argument: &'static str) -> Result<(), FmuError> {
    if ptr.is_null() {
        return Err(FmuError::NullArgument { argument, length: n });
    }
    if !ptr.is_aligned() {
        return Err(FmuError::Misaligned { argument });
    }
    if n.checked_mul(std::mem::size_of::<T>())
        .is_none_or(|bytes| bytes > isize::MAX as usize)
    {
        return Err(FmuError::TooLong { argument, length: n });
    }
    Ok(())
}

/// A pointer the FMU writes one value through (fmi2GetXXXStatus, size outputs).
///
/// # Safety
/// If `ptr` is non-NULL and aligned it must point to one writable `T` valid for `'a`.
pub unsafe fn output_pointer<'a, T>(ptr: *mut T, argument: &'static str) -> Result<&'a mut T, FmuError> {
    if ptr.is_null() {
        return Err(FmuError::NullArgument { argument, length: 1 });
    }
    if !ptr.is_aligned() {
        return Err(FmuError::Misaligned { argument });
    }
    // SAFETY: non-NULL and aligned; FMI 2.0 passes a pointer to one writable value owned by
    // the importer for the duration of the call.
    Ok(unsafe { &mut *ptr })
}

/// A NUL-terminated C string as UTF-8.
///
/// # Safety
/// If `ptr` is non-NULL it must point to a NUL-terminated string valid for `'a`.
pub unsafe fn c_str<'a>(ptr: fmi2String, argument: &'static str) -> Result<&'a str, FmuError> {
    if ptr.is_null() {
        return Err(FmuError::InvalidArgument(format!("{argument} is NULL")));
    }
    // SAFETY: non-NULL; NUL termination and lifetime are the caller's contract (fmi2String).
    let s = unsafe { CStr::from_ptr(ptr) };
    s.to_str()
        .map_err(|_| FmuError::InvalidArgument(format!("{argument} is not valid UTF-8")))
}

/// Messages as C strings: an interior NUL (impossible in our messages, possible in an
/// instance name echoed back) is replaced rather than truncating the text.
pub fn to_c_string(text: &str) -> CString {
    CString::new(text.replace('\0', "\u{FFFD}")).unwrap_or_default()
}

/// The importer's logger, called as `logger(env, name, status, category, "%s", message)` so
/// that a '%' in a message is never read as a format directive.
pub struct CLogger {
    pub logger: fmi2CallbackLogger,
    pub environment: fmi2ComponentEnvironment,
    pub instance_name: CString,
}

impl CLogger {
    pub fn send(&self, status: fmi2Status, category: &str, message: &str) {
        let category = to_c_string(category);
        let message = to_c_string(message);
        // SAFETY: `logger` is the non-NULL function the importer passed in
        // fmi2CallbackFunctions, of type fmi2CallbackLogger; every string argument is
        // NUL-terminated and lives until the call returns; the format "%s" consumes exactly
        // the one `char*` passed after it.
        unsafe {
            (self.logger)(
                self.environment,
                self.instance_name.as_ptr(),
                status,
                category.as_ptr(),
                c"%s".as_ptr(),
                message.as_ptr(),
            )
        }
    }
}

impl LogSink for CLogger {
    fn log(&mut self, status: Status, category: LogCategory, message: &str) {
        self.send(status.into(), category.name(), message);
    }
}

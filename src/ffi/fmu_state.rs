//! FMU states (FMI 2.0.4 §2.1.8). A handle given to the importer is a serial number under
//! which a [`Snapshot`] is kept in a table here; handles are looked up, never dereferenced,
//! and never reused, so a stale, foreign or garbage handle is refused instead of crashing.

use super::guard::{guard, input_array, next_handle, output_array, output_pointer};
use super::types::*;
use crate::fmu::{FmuError, Function, Snapshot, Status};
use std::collections::BTreeMap;
use std::sync::{Mutex, MutexGuard};

/// Live FMU states: handle → (owning component, state). fmi2FreeInstance frees the states its
/// instance allocated (FMI 2.0.4: it frees "all the allocated memory").
static STATES: Mutex<BTreeMap<usize, (usize, Box<Snapshot>)>> = Mutex::new(BTreeMap::new());

pub(super) fn states() -> MutexGuard<'static, BTreeMap<usize, (usize, Box<Snapshot>)>> {
    // Every update is a single insert/remove/replace: a poisoned map is still consistent.
    STATES.lock().unwrap_or_else(|poisoned| poisoned.into_inner())
}

pub(super) fn store(owner: fmi2Component, snapshot: Snapshot) -> fmi2FMUstate {
    let handle = next_handle();
    states().insert(handle, (owner as usize, Box::new(snapshot)));
    handle as fmi2FMUstate
}

pub(super) fn unknown(handle: fmi2FMUstate) -> FmuError {
    FmuError::StateRefused(format!(
        "{handle:p} is not a live FMU state of this FMU (never allocated by it, or already freed)"
    ))
}

pub(super) fn lookup(handle: fmi2FMUstate) -> Result<Snapshot, FmuError> {
    states()
        .get(&(handle as usize))
        .map(|(_, s)| (**s).clone())
        .ok_or_else(|| unknown(handle))
}

pub(super) fn replace(handle: fmi2FMUstate, snapshot: Snapshot) -> Result<(), FmuError> {
    match states().get_mut(&(handle as usize)) {
        Some((_, s)) => {
            **s = snapshot;
            Ok(())
        }
        None => Err(unknown(handle)),
    }
}

/// Called by fmi2FreeInstance.
pub fn free_states_of(owner: fmi2Component) {
    states().retain(|_, (o, _)| *o != owner as usize);
}

/// Number of live FMU states (for tests of freeing).
pub fn live_state_count() -> usize {
    states().len()
}

/// # Safety
/// Pointer arguments as FMI 2.0 defines them: NULL, or valid for the announced number of
/// elements (strings NUL-terminated) for the duration of the call.
#[no_mangle]
pub unsafe extern "C" fn fmi2GetFMUstate(c: fmi2Component, FMUstate: *mut fmi2FMUstate) -> fmi2Status {
    guard(c, Function::GetFmuState, |inst| {
        // SAFETY: FMI 2.0 passes a pointer to the importer's fmi2FMUstate variable.
        let slot = unsafe { output_pointer(FMUstate, "FMUstate") }?;
        let snapshot = inst.snapshot();
        if slot.is_null() {
            *slot = store(c, snapshot);
        } else {
            // A non-NULL handle is a state returned before: overwrite it (FMI 2.0.4 §2.1.8).
            replace(*slot, snapshot)?;
        }
        Ok(Status::Ok)
    })
}

#[no_mangle]
pub extern "C" fn fmi2SetFMUstate(c: fmi2Component, FMUstate: fmi2FMUstate) -> fmi2Status {
    guard(c, Function::SetFmuState, |inst| {
        let snapshot = lookup(FMUstate)?;
        inst.restore_body(&snapshot)
    })
}

/// # Safety
/// Pointer arguments as FMI 2.0 defines them: NULL, or valid for the announced number of
/// elements (strings NUL-terminated) for the duration of the call.
#[no_mangle]
pub unsafe extern "C" fn fmi2FreeFMUstate(c: fmi2Component, FMUstate: *mut fmi2FMUstate) -> fmi2Status {
    guard(c, Function::FreeFmuState, |_| {
        // SAFETY: as in fmi2GetFMUstate.
        let slot = unsafe { output_pointer(FMUstate, "FMUstate") }?;
        if slot.is_null() {
            return Ok(Status::Ok);
        }
        states().remove(&(*slot as usize)).ok_or_else(|| unknown(*slot))?;
        *slot = std::ptr::null_mut();
        Ok(Status::Ok)
    })
}

/// # Safety
/// Pointer arguments as FMI 2.0 defines them: NULL, or valid for the announced number of
/// elements (strings NUL-terminated) for the duration of the call.
#[no_mangle]
pub unsafe extern "C" fn fmi2SerializedFMUstateSize(
    c: fmi2Component,
    FMUstate: fmi2FMUstate,
    size: *mut usize,
) -> fmi2Status {
    guard(c, Function::SerializedFmuStateSize, |_| {
        // SAFETY: FMI 2.0 passes a pointer to the importer's size_t.
        let size = unsafe { output_pointer(size, "size") }?;
        *size = lookup(FMUstate)?.serialized_len();
        Ok(Status::Ok)
    })
}

/// # Safety
/// Pointer arguments as FMI 2.0 defines them: NULL, or valid for the announced number of
/// elements (strings NUL-terminated) for the duration of the call.
#[no_mangle]
pub unsafe extern "C" fn fmi2SerializeFMUstate(
    c: fmi2Component,
    FMUstate: fmi2FMUstate,
    serializedState: *mut fmi2Byte,
    size: usize,
) -> fmi2Status {
    guard(c, Function::SerializeFmuState, |_| {
        let bytes = lookup(FMUstate)?.to_bytes();
        if size < bytes.len() {
            return Err(FmuError::InvalidArgument(format!(
                "size {size} is less than the {} bytes from fmi2SerializedFMUstateSize",
                bytes.len()
            )));
        }
        // SAFETY: FMI 2.0 passes a buffer of `size` bytes; we write the first bytes.len().
        let out = unsafe { output_array(serializedState.cast::<u8>(), bytes.len(), "serializedState") }?;
        out.copy_from_slice(&bytes);
        Ok(Status::Ok)
    })
}

/// # Safety
/// Pointer arguments as FMI 2.0 defines them: NULL, or valid for the announced number of
/// elements (strings NUL-terminated) for the duration of the call.
#[no_mangle]
pub unsafe extern "C" fn fmi2DeSerializeFMUstate(
    c: fmi2Component,
    serializedState: *const fmi2Byte,
    size: usize,
    FMUstate: *mut fmi2FMUstate,
) -> fmi2Status {
    guard(c, Function::DeSerializeFmuState, |inst| {
        // SAFETY: FMI 2.0 passes `size` bytes (fmi2Byte is a char: same size and alignment as u8).
        let bytes = unsafe { input_array(serializedState.cast::<u8>(), size, "serializedState") }?;
        // SAFETY: as in fmi2GetFMUstate.
        let slot = unsafe { output_pointer(FMUstate, "FMUstate") }?;
        let snapshot = Snapshot::from_bytes(inst.model(), bytes)?;
        // Overwrite a live state passed in; anything else gets a new one.
        if lookup(*slot).is_ok() {
            replace(*slot, snapshot)?;
        } else {
            *slot = store(c, snapshot);
        }
        Ok(Status::Ok)
    })
}

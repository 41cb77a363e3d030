//! FMU states (FMI 2.0.4 §2.1.8). A handle given to the importer is a serial number under
//! which a [`Snapshot`] is kept in a table here; handles are looked up, never dereferenced,
//! and never reused, so a stale, foreign or garbage handle is refused instead of crashing.

use super::guard::{guard, input_array, next_handle, output_array, output_pointer};
use super::types::*;
use crate::fmu::{FmuError, Function, Instance, Snapshot, Status};
use std::collections::BTreeMap;
use std::ffi::c_void;
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

// The work of each FMU-state function, shared by the FMI 2.0 exports below and the FMI 3.0
// ones (`fmi3::states`): the handle types of both standards are `void*`, and their bytes `char`
// (FMI 2.0) or `uint8_t` (FMI 3.0), read here as `u8`.

/// fmi2GetFMUstate / fmi3GetFMUState: a new handle, or the state behind a handle passed in
/// overwritten.
///
/// # Safety
/// `slot` NULL or a pointer to the importer's handle variable.
pub(super) unsafe fn get_state(
    owner: *mut c_void,
    inst: &mut Instance,
    slot: *mut *mut c_void,
) -> Result<Status, FmuError> {
    // SAFETY: the caller's contract.
    let slot = unsafe { output_pointer(slot, "FMUstate") }?;
    let snapshot = inst.snapshot()?;
    if slot.is_null() {
        *slot = store(owner, snapshot);
    } else {
        // A non-NULL handle is a state returned before: overwrite it (FMI 2.0.4 §2.1.8).
        replace(*slot, snapshot)?;
    }
    Ok(Status::Ok)
}

/// fmi2FreeFMUstate / fmi3FreeFMUState.
///
/// # Safety
/// As [`get_state`].
pub(super) unsafe fn free_state(slot: *mut *mut c_void) -> Result<Status, FmuError> {
    // SAFETY: the caller's contract.
    let slot = unsafe { output_pointer(slot, "FMUstate") }?;
    if slot.is_null() {
        return Ok(Status::Ok);
    }
    states().remove(&(*slot as usize)).ok_or_else(|| unknown(*slot))?;
    *slot = std::ptr::null_mut();
    Ok(Status::Ok)
}

/// fmi2SerializedFMUstateSize / fmi3SerializedFMUStateSize; refused by a controller, which has
/// no FMU state, whatever the handle.
///
/// # Safety
/// `size` NULL or one writable size_t.
pub(super) unsafe fn serialized_size(
    inst: &Instance,
    handle: *mut c_void,
    size: *mut usize,
) -> Result<Status, FmuError> {
    inst.check_offered(Function::SerializedFmuStateSize)?;
    // SAFETY: the caller's contract.
    let size = unsafe { output_pointer(size, "size") }?;
    *size = lookup(handle)?.serialized_len();
    Ok(Status::Ok)
}

/// fmi2SerializeFMUstate / fmi3SerializeFMUState (`size_function` names the size call in the
/// message); refused by a controller, as [`serialized_size`].
///
/// # Safety
/// `buffer` NULL or `size` writable bytes.
pub(super) unsafe fn serialize(
    inst: &Instance,
    handle: *mut c_void,
    buffer: *mut u8,
    size: usize,
    size_function: &str,
) -> Result<Status, FmuError> {
    inst.check_offered(Function::SerializeFmuState)?;
    let bytes = lookup(handle)?.to_bytes();
    if size < bytes.len() {
        return Err(FmuError::InvalidArgument(format!(
            "size {size} is less than the {} bytes from {size_function}",
            bytes.len()
        )));
    }
    // SAFETY: a buffer of `size` bytes by the caller's contract; we write the first bytes.len().
    let out = unsafe { output_array(buffer, bytes.len(), "serializedState") }?;
    out.copy_from_slice(&bytes);
    Ok(Status::Ok)
}

/// fmi2DeSerializeFMUstate / fmi3DeserializeFMUState: a live handle passed in is overwritten,
/// anything else gets a new one.
///
/// # Safety
/// `bytes` NULL or `size` readable bytes; `slot` as in [`get_state`].
pub(super) unsafe fn deserialize(
    owner: *mut c_void,
    inst: &mut Instance,
    bytes: *const u8,
    size: usize,
    slot: *mut *mut c_void,
) -> Result<Status, FmuError> {
    // SAFETY: the caller's contract.
    let bytes = unsafe { input_array(bytes, size, "serializedState") }?;
    let slot = unsafe { output_pointer(slot, "FMUstate") }?;
    let snapshot = Snapshot::from_bytes(inst.model(), bytes)?;
    if lookup(*slot).is_ok() {
        replace(*slot, snapshot)?;
    } else {
        *slot = store(owner, snapshot);
    }
    Ok(Status::Ok)
}

/// # Safety
/// Pointer arguments as FMI 2.0 defines them: NULL, or valid for the announced number of
/// elements for the duration of the call.
#[no_mangle]
pub unsafe extern "C" fn fmi2GetFMUstate(c: fmi2Component, FMUstate: *mut fmi2FMUstate) -> fmi2Status {
    // SAFETY: FMI 2.0 passes a pointer to the importer's fmi2FMUstate variable.
    guard(c, Function::GetFmuState, |inst| unsafe { get_state(c, inst, FMUstate) })
}

#[no_mangle]
pub extern "C" fn fmi2SetFMUstate(c: fmi2Component, FMUstate: fmi2FMUstate) -> fmi2Status {
    guard(c, Function::SetFmuState, |inst| {
        let snapshot = lookup(FMUstate)?;
        inst.restore_body(&snapshot)
    })
}

/// # Safety
/// As [`fmi2GetFMUstate`].
#[no_mangle]
pub unsafe extern "C" fn fmi2FreeFMUstate(c: fmi2Component, FMUstate: *mut fmi2FMUstate) -> fmi2Status {
    // SAFETY: as in fmi2GetFMUstate.
    guard(c, Function::FreeFmuState, |_| unsafe { free_state(FMUstate) })
}

/// # Safety
/// As [`fmi2GetFMUstate`].
#[no_mangle]
pub unsafe extern "C" fn fmi2SerializedFMUstateSize(
    c: fmi2Component,
    FMUstate: fmi2FMUstate,
    size: *mut usize,
) -> fmi2Status {
    // SAFETY: FMI 2.0 passes a pointer to the importer's size_t.
    guard(c, Function::SerializedFmuStateSize, |inst| unsafe {
        serialized_size(inst, FMUstate, size)
    })
}

/// # Safety
/// As [`fmi2GetFMUstate`].
#[no_mangle]
pub unsafe extern "C" fn fmi2SerializeFMUstate(
    c: fmi2Component,
    FMUstate: fmi2FMUstate,
    serializedState: *mut fmi2Byte,
    size: usize,
) -> fmi2Status {
    guard(c, Function::SerializeFmuState, |inst| {
        // SAFETY: FMI 2.0 passes a buffer of `size` fmi2Bytes (char: the size and alignment of u8).
        unsafe {
            serialize(
                inst,
                FMUstate,
                serializedState.cast::<u8>(),
                size,
                "fmi2SerializedFMUstateSize",
            )
        }
    })
}

/// # Safety
/// As [`fmi2GetFMUstate`].
#[no_mangle]
pub unsafe extern "C" fn fmi2DeSerializeFMUstate(
    c: fmi2Component,
    serializedState: *const fmi2Byte,
    size: usize,
    FMUstate: *mut fmi2FMUstate,
) -> fmi2Status {
    guard(c, Function::DeSerializeFmuState, |inst| {
        // SAFETY: FMI 2.0 passes `size` bytes and a pointer to the importer's handle variable.
        unsafe { deserialize(c, inst, serializedState.cast::<u8>(), size, FMUstate) }
    })
}

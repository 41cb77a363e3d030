//! FMU states of FMI 3.0 (§2.3.6), kept in the same table as FMI 2.0's (handles looked up,
//! never dereferenced). A state records the standard and interface of its instance, so a state
//! of an FMI 2.0 instance is refused by an FMI 3.0 one with the reason, not misread.

use super::super::fmu_state::{lookup, replace, states, store, unknown};
use super::super::guard::{input_array, output_array, output_pointer};
use super::guard3;
use super::types::*;
use crate::fmu::{FmuError, Function, Snapshot, Status};

/// # Safety
/// `FMUState` NULL or a pointer to the importer's fmi3FMUState variable.
#[no_mangle]
pub unsafe extern "C" fn fmi3GetFMUState(instance: fmi3Instance, FMUState: *mut fmi3FMUState) -> fmi3Status {
    guard3(instance, Function::GetFmuState, |inst| {
        // SAFETY: FMI 3.0 passes a pointer to the importer's fmi3FMUState variable.
        let slot = unsafe { output_pointer(FMUState, "FMUState") }?;
        let snapshot = inst.snapshot();
        if slot.is_null() {
            *slot = store(instance, snapshot);
        } else {
            // A non-NULL handle is a state returned before: overwrite it.
            replace(*slot, snapshot)?;
        }
        Ok(Status::Ok)
    })
}

#[no_mangle]
pub extern "C" fn fmi3SetFMUState(instance: fmi3Instance, FMUState: fmi3FMUState) -> fmi3Status {
    guard3(instance, Function::SetFmuState, |inst| {
        let snapshot = lookup(FMUState)?;
        inst.restore_body(&snapshot)
    })
}

/// # Safety
/// As [`fmi3GetFMUState`].
#[no_mangle]
pub unsafe extern "C" fn fmi3FreeFMUState(instance: fmi3Instance, FMUState: *mut fmi3FMUState) -> fmi3Status {
    guard3(instance, Function::FreeFmuState, |_| {
        // SAFETY: as in fmi3GetFMUState.
        let slot = unsafe { output_pointer(FMUState, "FMUState") }?;
        if slot.is_null() {
            return Ok(Status::Ok);
        }
        states().remove(&(*slot as usize)).ok_or_else(|| unknown(*slot))?;
        *slot = std::ptr::null_mut();
        Ok(Status::Ok)
    })
}

/// # Safety
/// `size` NULL or one writable size_t.
#[no_mangle]
pub unsafe extern "C" fn fmi3SerializedFMUStateSize(
    instance: fmi3Instance,
    FMUState: fmi3FMUState,
    size: *mut usize,
) -> fmi3Status {
    guard3(instance, Function::SerializedFmuStateSize, |_| {
        // SAFETY: FMI 3.0 passes a pointer to the importer's size_t.
        let size = unsafe { output_pointer(size, "size") }?;
        *size = lookup(FMUState)?.serialized_len();
        Ok(Status::Ok)
    })
}

/// # Safety
/// `serializedState` NULL or `size` writable bytes.
#[no_mangle]
pub unsafe extern "C" fn fmi3SerializeFMUState(
    instance: fmi3Instance,
    FMUState: fmi3FMUState,
    serializedState: *mut fmi3Byte,
    size: usize,
) -> fmi3Status {
    guard3(instance, Function::SerializeFmuState, |_| {
        let bytes = lookup(FMUState)?.to_bytes();
        if size < bytes.len() {
            return Err(FmuError::InvalidArgument(format!(
                "size {size} is less than the {} bytes from fmi3SerializedFMUStateSize",
                bytes.len()
            )));
        }
        // SAFETY: FMI 3.0 passes a buffer of `size` bytes; we write the first bytes.len().
        let out = unsafe { output_array(serializedState, bytes.len(), "serializedState") }?;
        out.copy_from_slice(&bytes);
        Ok(Status::Ok)
    })
}

/// # Safety
/// `serializedState` NULL or `size` readable bytes; `FMUState` as in [`fmi3GetFMUState`].
#[no_mangle]
pub unsafe extern "C" fn fmi3DeserializeFMUState(
    instance: fmi3Instance,
    serializedState: *const fmi3Byte,
    size: usize,
    FMUState: *mut fmi3FMUState,
) -> fmi3Status {
    guard3(instance, Function::DeSerializeFmuState, |inst| {
        // SAFETY: FMI 3.0 passes `size` bytes.
        let bytes = unsafe { input_array(serializedState, size, "serializedState") }?;
        // SAFETY: as in fmi3GetFMUState.
        let slot = unsafe { output_pointer(FMUState, "FMUState") }?;
        let snapshot = Snapshot::from_bytes(inst.model(), bytes)?;
        if lookup(*slot).is_ok() {
            replace(*slot, snapshot)?;
        } else {
            *slot = store(instance, snapshot);
        }
        Ok(Status::Ok)
    })
}

//! FMU states of FMI 3.0 (§2.3.6), kept in the same table as FMI 2.0's and served by the same
//! code (`fmu_state`). A state records the standard and interface of its instance, so a state of
//! an FMI 2.0 instance is refused by an FMI 3.0 one with the reason, not misread.

use super::super::fmu_state::{deserialize, free_state, get_state, lookup, serialize, serialized_size};
use super::guard3;
use super::types::*;
use crate::fmu::Function;

/// # Safety
/// `FMUState` NULL or a pointer to the importer's fmi3FMUState variable.
#[no_mangle]
pub unsafe extern "C" fn fmi3GetFMUState(instance: fmi3Instance, FMUState: *mut fmi3FMUState) -> fmi3Status {
    // SAFETY: FMI 3.0 passes a pointer to the importer's fmi3FMUState variable.
    guard3(instance, Function::GetFmuState, |inst| unsafe {
        get_state(instance, inst, FMUState)
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
    // SAFETY: as in fmi3GetFMUState.
    guard3(instance, Function::FreeFmuState, |_| unsafe { free_state(FMUState) })
}

/// # Safety
/// `size` NULL or one writable size_t.
#[no_mangle]
pub unsafe extern "C" fn fmi3SerializedFMUStateSize(
    instance: fmi3Instance,
    FMUState: fmi3FMUState,
    size: *mut usize,
) -> fmi3Status {
    // SAFETY: FMI 3.0 passes a pointer to the importer's size_t.
    guard3(instance, Function::SerializedFmuStateSize, |inst| unsafe {
        serialized_size(inst, FMUState, size)
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
    guard3(instance, Function::SerializeFmuState, |inst| {
        // SAFETY: FMI 3.0 passes a buffer of `size` bytes.
        unsafe { serialize(inst, FMUState, serializedState, size, "fmi3SerializedFMUStateSize") }
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
        // SAFETY: FMI 3.0 passes `size` bytes and a pointer to the importer's handle variable.
        unsafe { deserialize(instance, inst, serializedState, size, FMUState) }
    })
}

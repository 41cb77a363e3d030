//! fmi3Get/Set<type> (FMI 3.0 §2.3.5): Float64 and Int32 (`contact`, `contact_law`) reach the
//! variables; the other types
//! have no variable, so any value reference is refused (by name and type when it names a
//! variable of another type). All variables are scalars: nValues must equal nValueReferences.

use super::super::guard::{input_array, output_array};
use super::guard3;
use super::types::*;
use crate::fmu::{FmuError, Function, Instance, Status};

/// Scalars only: one value per value reference.
fn scalars(n_values: usize, n_value_references: usize) -> Result<(), FmuError> {
    if n_values == n_value_references {
        Ok(())
    } else {
        Err(FmuError::LengthMismatch {
            what: "nValues (every variable is a scalar)",
            length: n_values,
            expected: n_value_references,
        })
    }
}

/// # Safety
/// Pointer arguments as FMI 3.0 defines them: NULL, or valid for the announced number of
/// elements for the duration of the call.
#[no_mangle]
pub unsafe extern "C" fn fmi3GetFloat64(
    instance: fmi3Instance,
    valueReferences: *const fmi3ValueReference,
    nValueReferences: usize,
    values: *mut fmi3Float64,
    nValues: usize,
) -> fmi3Status {
    guard3(instance, Function::GetReal, |inst| {
        scalars(nValues, nValueReferences)?;
        // SAFETY: FMI 3.0 passes `nValueReferences` references and room for `nValues` values.
        let vrs = unsafe { input_array(valueReferences, nValueReferences, "valueReferences") }?;
        let out = unsafe { output_array(values, nValues, "values") }?;
        inst.get_real_body(vrs, out)
    })
}

/// # Safety
/// As [`fmi3GetFloat64`].
#[no_mangle]
pub unsafe extern "C" fn fmi3SetFloat64(
    instance: fmi3Instance,
    valueReferences: *const fmi3ValueReference,
    nValueReferences: usize,
    values: *const fmi3Float64,
    nValues: usize,
) -> fmi3Status {
    guard3(instance, Function::SetReal, |inst| {
        scalars(nValues, nValueReferences)?;
        // SAFETY: as in fmi3GetFloat64.
        let vrs = unsafe { input_array(valueReferences, nValueReferences, "valueReferences") }?;
        let values = unsafe { input_array(values, nValues, "values") }?;
        inst.set_real_body(vrs, values)
    })
}

/// # Safety
/// As [`fmi3GetFloat64`].
#[no_mangle]
pub unsafe extern "C" fn fmi3GetInt32(
    instance: fmi3Instance,
    valueReferences: *const fmi3ValueReference,
    nValueReferences: usize,
    values: *mut fmi3Int32,
    nValues: usize,
) -> fmi3Status {
    guard3(instance, Function::GetInteger, |inst| {
        scalars(nValues, nValueReferences)?;
        // SAFETY: as in fmi3GetFloat64.
        let vrs = unsafe { input_array(valueReferences, nValueReferences, "valueReferences") }?;
        let out = unsafe { output_array(values, nValues, "values") }?;
        inst.get_integer_body(vrs, out)
    })
}

/// # Safety
/// As [`fmi3GetFloat64`].
#[no_mangle]
pub unsafe extern "C" fn fmi3SetInt32(
    instance: fmi3Instance,
    valueReferences: *const fmi3ValueReference,
    nValueReferences: usize,
    values: *const fmi3Int32,
    nValues: usize,
) -> fmi3Status {
    guard3(instance, Function::SetInteger, |inst| {
        scalars(nValues, nValueReferences)?;
        // SAFETY: as in fmi3GetFloat64.
        let vrs = unsafe { input_array(valueReferences, nValueReferences, "valueReferences") }?;
        let values = unsafe { input_array(values, nValues, "values") }?;
        inst.set_integer_body(vrs, values)
    })
}

/// A get or set of a type without variables: the arrays are checked, then every reference is
/// refused (with 0 references the call does nothing and succeeds).
///
/// # Safety
/// `value_references` NULL or `n_value_references` readable value references.
unsafe fn other_type(
    inst: &mut Instance,
    value_references: *const fmi3ValueReference,
    n_value_references: usize,
    type_name: &'static str,
    set: bool,
) -> Result<Status, FmuError> {
    // SAFETY: the caller's contract.
    let vrs = unsafe { input_array(value_references, n_value_references, "valueReferences") }?;
    if set {
        inst.set_untyped_body(vrs, vrs.len(), type_name)
    } else {
        inst.get_untyped_body(vrs, vrs.len(), type_name)
    }
}

/// The typed get and set functions of the types the models have no variable of.
macro_rules! other_type_functions {
    ($($get:ident, $set:ident, $t:ty, $name:literal;)*) => {$(
        /// No variable has this type.
        /// # Safety
        /// As [`fmi3GetFloat64`].
        #[no_mangle]
        pub unsafe extern "C" fn $get(
            instance: fmi3Instance,
            valueReferences: *const fmi3ValueReference,
            nValueReferences: usize,
            values: *mut $t,
            nValues: usize,
        ) -> fmi3Status {
            let _ = values;
            guard3(instance, Function::GetOtherType(stringify!($get)), |inst| {
                scalars(nValues, nValueReferences)?;
                unsafe { other_type(inst, valueReferences, nValueReferences, $name, false) }
            })
        }

        /// No variable has this type.
        /// # Safety
        /// As [`fmi3GetFloat64`].
        #[no_mangle]
        pub unsafe extern "C" fn $set(
            instance: fmi3Instance,
            valueReferences: *const fmi3ValueReference,
            nValueReferences: usize,
            values: *const $t,
            nValues: usize,
        ) -> fmi3Status {
            let _ = values;
            guard3(instance, Function::SetOtherType(stringify!($set)), |inst| {
                scalars(nValues, nValueReferences)?;
                unsafe { other_type(inst, valueReferences, nValueReferences, $name, true) }
            })
        }
    )*};
}

other_type_functions! {
    fmi3GetFloat32, fmi3SetFloat32, fmi3Float32, "Float32";
    fmi3GetInt8, fmi3SetInt8, fmi3Int8, "Int8";
    fmi3GetUInt8, fmi3SetUInt8, fmi3UInt8, "UInt8";
    fmi3GetInt16, fmi3SetInt16, fmi3Int16, "Int16";
    fmi3GetUInt16, fmi3SetUInt16, fmi3UInt16, "UInt16";
    fmi3GetUInt32, fmi3SetUInt32, fmi3UInt32, "UInt32";
    fmi3GetInt64, fmi3SetInt64, fmi3Int64, "Int64";
    fmi3GetUInt64, fmi3SetUInt64, fmi3UInt64, "UInt64";
    fmi3GetBoolean, fmi3SetBoolean, fmi3Boolean, "Boolean";
}

/// # Safety
/// As [`fmi3GetFloat64`].
#[no_mangle]
pub unsafe extern "C" fn fmi3GetString(
    instance: fmi3Instance,
    valueReferences: *const fmi3ValueReference,
    nValueReferences: usize,
    values: *mut fmi3String,
    nValues: usize,
) -> fmi3Status {
    let _ = values;
    guard3(instance, Function::GetString, |inst| {
        scalars(nValues, nValueReferences)?;
        unsafe { other_type(inst, valueReferences, nValueReferences, "String", false) }
    })
}

/// # Safety
/// As [`fmi3GetFloat64`].
#[no_mangle]
pub unsafe extern "C" fn fmi3SetString(
    instance: fmi3Instance,
    valueReferences: *const fmi3ValueReference,
    nValueReferences: usize,
    values: *const fmi3String,
    nValues: usize,
) -> fmi3Status {
    let _ = values;
    guard3(instance, Function::SetString, |inst| {
        scalars(nValues, nValueReferences)?;
        unsafe { other_type(inst, valueReferences, nValueReferences, "String", true) }
    })
}

/// # Safety
/// As [`fmi3GetFloat64`].
#[no_mangle]
pub unsafe extern "C" fn fmi3GetBinary(
    instance: fmi3Instance,
    valueReferences: *const fmi3ValueReference,
    nValueReferences: usize,
    valueSizes: *mut usize,
    values: *mut fmi3Binary,
    nValues: usize,
) -> fmi3Status {
    let _ = (valueSizes, values);
    guard3(instance, Function::GetOtherType("fmi3GetBinary"), |inst| {
        scalars(nValues, nValueReferences)?;
        unsafe { other_type(inst, valueReferences, nValueReferences, "Binary", false) }
    })
}

/// # Safety
/// As [`fmi3GetFloat64`].
#[no_mangle]
pub unsafe extern "C" fn fmi3SetBinary(
    instance: fmi3Instance,
    valueReferences: *const fmi3ValueReference,
    nValueReferences: usize,
    valueSizes: *const usize,
    values: *const fmi3Binary,
    nValues: usize,
) -> fmi3Status {
    let _ = (valueSizes, values);
    guard3(instance, Function::SetOtherType("fmi3SetBinary"), |inst| {
        scalars(nValues, nValueReferences)?;
        unsafe { other_type(inst, valueReferences, nValueReferences, "Binary", true) }
    })
}

/// The exact Jacobian (Model Exchange; Co-Simulation refuses with the reason).
/// # Safety
/// As [`fmi3GetFloat64`].
#[no_mangle]
pub unsafe extern "C" fn fmi3GetDirectionalDerivative(
    instance: fmi3Instance,
    unknowns: *const fmi3ValueReference,
    nUnknowns: usize,
    knowns: *const fmi3ValueReference,
    nKnowns: usize,
    seed: *const fmi3Float64,
    nSeed: usize,
    sensitivity: *mut fmi3Float64,
    nSensitivity: usize,
) -> fmi3Status {
    guard3(instance, Function::GetDirectionalDerivative, |inst| {
        inst.check_directional_derivative_provided()?;
        // SAFETY: FMI 3.0 passes arrays of the announced lengths.
        let unknowns = unsafe { input_array(unknowns, nUnknowns, "unknowns") }?;
        let knowns = unsafe { input_array(knowns, nKnowns, "knowns") }?;
        let seed = unsafe { input_array(seed, nSeed, "seed") }?;
        let out = unsafe { output_array(sensitivity, nSensitivity, "sensitivity") }?;
        inst.get_directional_derivative_body(unknowns, knowns, seed, out)
    })
}

//! The FMI 3.0 functions of features this FMU does not declare: clocks and their intervals and
//! shifts, Scheduled Execution's model partitions, Configuration Mode (no structural
//! parameters), adjoint derivatives, per-element dependencies and fmi3EvaluateDiscreteStates
//! (providesEvaluateDiscreteStates is false). Each is legal in every state and refused with
//! fmi3Error and the reason; none reads or writes through its pointer arguments.

use super::guard3;
use super::types::*;
use crate::fmu::{FmuError, Function};

macro_rules! not_provided {
    ($($name:ident($($arg:ident: $t:ty),*) => $why:literal;)*) => {$(
        #[doc = $why]
        #[no_mangle]
        pub extern "C" fn $name(instance: fmi3Instance, $($arg: $t),*) -> fmi3Status {
            let _ = ($($arg,)*);
            guard3(instance, Function::NotProvided(stringify!($name)), |_| {
                Err(FmuError::Unsupported($why))
            })
        }
    )*};
}

not_provided! {
    fmi3GetClock(valueReferences: *const fmi3ValueReference, nValueReferences: usize, values: *mut fmi3Clock)
        => "the models have no clocks";
    fmi3SetClock(valueReferences: *const fmi3ValueReference, nValueReferences: usize, values: *const fmi3Clock)
        => "the models have no clocks";
    fmi3GetIntervalDecimal(valueReferences: *const fmi3ValueReference, nValueReferences: usize,
        intervals: *mut fmi3Float64, qualifiers: *mut fmi3IntervalQualifier)
        => "the models have no clocks";
    fmi3GetIntervalFraction(valueReferences: *const fmi3ValueReference, nValueReferences: usize,
        counters: *mut fmi3UInt64, resolutions: *mut fmi3UInt64, qualifiers: *mut fmi3IntervalQualifier)
        => "the models have no clocks";
    fmi3GetShiftDecimal(valueReferences: *const fmi3ValueReference, nValueReferences: usize, shifts: *mut fmi3Float64)
        => "the models have no clocks";
    fmi3GetShiftFraction(valueReferences: *const fmi3ValueReference, nValueReferences: usize,
        counters: *mut fmi3UInt64, resolutions: *mut fmi3UInt64)
        => "the models have no clocks";
    fmi3SetIntervalDecimal(valueReferences: *const fmi3ValueReference, nValueReferences: usize,
        intervals: *const fmi3Float64)
        => "the models have no clocks";
    fmi3SetIntervalFraction(valueReferences: *const fmi3ValueReference, nValueReferences: usize,
        counters: *const fmi3UInt64, resolutions: *const fmi3UInt64)
        => "the models have no clocks";
    fmi3SetShiftDecimal(valueReferences: *const fmi3ValueReference, nValueReferences: usize, shifts: *const fmi3Float64)
        => "the models have no clocks";
    fmi3SetShiftFraction(valueReferences: *const fmi3ValueReference, nValueReferences: usize,
        counters: *const fmi3UInt64, resolutions: *const fmi3UInt64)
        => "the models have no clocks";
    fmi3ActivateModelPartition(clockReference: fmi3ValueReference, activationTime: fmi3Float64)
        => "the FMU does not offer Scheduled Execution";
    fmi3EnterConfigurationMode() => "the models have no structural parameters";
    fmi3ExitConfigurationMode() => "the models have no structural parameters";
    fmi3EvaluateDiscreteStates() => "the models have no discrete states (providesEvaluateDiscreteStates is false)";
    fmi3GetAdjointDerivative(unknowns: *const fmi3ValueReference, nUnknowns: usize,
        knowns: *const fmi3ValueReference, nKnowns: usize, seed: *const fmi3Float64, nSeed: usize,
        sensitivity: *mut fmi3Float64, nSensitivity: usize)
        => "adjoint derivatives are not provided (providesAdjointDerivatives is false); fmi3GetDirectionalDerivative gives the Jacobian in Model Exchange";
    fmi3GetNumberOfVariableDependencies(valueReference: fmi3ValueReference, nDependencies: *mut usize)
        => "per-element dependencies are not provided (providesPerElementDependencies is false); the ModelStructure of modelDescription.xml lists them";
    fmi3GetVariableDependencies(dependent: fmi3ValueReference, elementIndicesOfDependent: *mut usize,
        independents: *mut fmi3ValueReference, elementIndicesOfIndependents: *mut usize,
        dependencyKinds: *mut fmi3DependencyKind, nDependencies: usize)
        => "per-element dependencies are not provided (providesPerElementDependencies is false); the ModelStructure of modelDescription.xml lists them";
}

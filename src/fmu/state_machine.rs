//! The FMI 2.0 Co-Simulation state machine (FMI 2.0.4 §4.2.4): the states an instance can be
//! in and, for every function, the states in which calling it is legal.

use std::fmt;

/// The state of an instance. `StepInProgress` and `StepCanceled` are never entered (every step
/// is computed synchronously) and `Fatal` never (instances share nothing), so they are absent.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Phase {
    Instantiated,
    InitializationMode,
    StepComplete,
    StepFailed,
    Terminated,
    Error,
}

impl Phase {
    pub const ALL: [Phase; 6] = [
        Phase::Instantiated,
        Phase::InitializationMode,
        Phase::StepComplete,
        Phase::StepFailed,
        Phase::Terminated,
        Phase::Error,
    ];

    #[inline]
    fn bit(self) -> u8 {
        1 << (self as u8)
    }

    /// Stable numbering for the serialized FMU state.
    pub fn code(self) -> u8 {
        self as u8
    }

    pub fn from_code(code: u8) -> Option<Phase> {
        Phase::ALL.get(code as usize).copied()
    }
}

impl fmt::Display for Phase {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let name = match self {
            Phase::Instantiated => "Instantiated",
            Phase::InitializationMode => "InitializationMode",
            Phase::StepComplete => "StepComplete",
            Phase::StepFailed => "StepFailed",
            Phase::Terminated => "Terminated",
            Phase::Error => "Error",
        };
        f.write_str(name)
    }
}

/// Every FMI 2.0 function that takes an instance.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Function {
    SetDebugLogging,
    FreeInstance,
    SetupExperiment,
    EnterInitializationMode,
    ExitInitializationMode,
    Terminate,
    Reset,
    GetReal,
    GetInteger,
    GetBoolean,
    GetString,
    SetReal,
    SetInteger,
    SetBoolean,
    SetString,
    GetFmuState,
    SetFmuState,
    FreeFmuState,
    SerializedFmuStateSize,
    SerializeFmuState,
    DeSerializeFmuState,
    GetDirectionalDerivative,
    SetRealInputDerivatives,
    GetRealOutputDerivatives,
    DoStep,
    CancelStep,
    GetStatus,
    GetRealStatus,
    GetIntegerStatus,
    GetBooleanStatus,
    GetStringStatus,
    // Model Exchange only: illegal in every state of a Co-Simulation instance.
    EnterEventMode,
    NewDiscreteStates,
    EnterContinuousTimeMode,
    CompletedIntegratorStep,
    SetTime,
    SetContinuousStates,
    GetDerivatives,
    GetEventIndicators,
    GetContinuousStates,
    GetNominalsOfContinuousStates,
}

const I: u8 = 1 << 0;
const M: u8 = 1 << 1;
const C: u8 = 1 << 2;
const F: u8 = 1 << 3;
const T: u8 = 1 << 4;
const E: u8 = 1 << 5;
const ANY: u8 = I | M | C | F | T | E;
/// Not a state: marks the Model Exchange functions, legal in no state of this CS-only FMU.
const MODEL_EXCHANGE: u8 = 1 << 7;

impl Function {
    /// The C name, for messages.
    pub fn c_name(self) -> &'static str {
        use Function::*;
        match self {
            SetDebugLogging => "fmi2SetDebugLogging",
            FreeInstance => "fmi2FreeInstance",
            SetupExperiment => "fmi2SetupExperiment",
            EnterInitializationMode => "fmi2EnterInitializationMode",
            ExitInitializationMode => "fmi2ExitInitializationMode",
            Terminate => "fmi2Terminate",
            Reset => "fmi2Reset",
            GetReal => "fmi2GetReal",
            GetInteger => "fmi2GetInteger",
            GetBoolean => "fmi2GetBoolean",
            GetString => "fmi2GetString",
            SetReal => "fmi2SetReal",
            SetInteger => "fmi2SetInteger",
            SetBoolean => "fmi2SetBoolean",
            SetString => "fmi2SetString",
            GetFmuState => "fmi2GetFMUstate",
            SetFmuState => "fmi2SetFMUstate",
            FreeFmuState => "fmi2FreeFMUstate",
            SerializedFmuStateSize => "fmi2SerializedFMUstateSize",
            SerializeFmuState => "fmi2SerializeFMUstate",
            DeSerializeFmuState => "fmi2DeSerializeFMUstate",
            GetDirectionalDerivative => "fmi2GetDirectionalDerivative",
            SetRealInputDerivatives => "fmi2SetRealInputDerivatives",
            GetRealOutputDerivatives => "fmi2GetRealOutputDerivatives",
            DoStep => "fmi2DoStep",
            CancelStep => "fmi2CancelStep",
            GetStatus => "fmi2GetStatus",
            GetRealStatus => "fmi2GetRealStatus",
            GetIntegerStatus => "fmi2GetIntegerStatus",
            GetBooleanStatus => "fmi2GetBooleanStatus",
            GetStringStatus => "fmi2GetStringStatus",
            EnterEventMode => "fmi2EnterEventMode",
            NewDiscreteStates => "fmi2NewDiscreteStates",
            EnterContinuousTimeMode => "fmi2EnterContinuousTimeMode",
            CompletedIntegratorStep => "fmi2CompletedIntegratorStep",
            SetTime => "fmi2SetTime",
            SetContinuousStates => "fmi2SetContinuousStates",
            GetDerivatives => "fmi2GetDerivatives",
            GetEventIndicators => "fmi2GetEventIndicators",
            GetContinuousStates => "fmi2GetContinuousStates",
            GetNominalsOfContinuousStates => "fmi2GetNominalsOfContinuousStates",
        }
    }

    /// The states in which the call is legal (FMI 2.0.4 Table "Co-Simulation: allowed calls").
    /// Get calls in StepFailed and Error are legal; their values are for debugging.
    #[inline]
    fn mask(self) -> u8 {
        use Function::*;
        match self {
            SetDebugLogging | FreeInstance | Reset => ANY,
            SetupExperiment | EnterInitializationMode => I,
            ExitInitializationMode => M,
            Terminate => C | F,
            GetReal | GetInteger | GetBoolean | GetString => M | C | F | T | E,
            // Which variables may be set in which state is checked per variable.
            SetReal | SetInteger | SetBoolean | SetString => I | M | C,
            GetFmuState
            | SetFmuState
            | FreeFmuState
            | SerializedFmuStateSize
            | SerializeFmuState
            | DeSerializeFmuState => ANY,
            GetDirectionalDerivative => M | C | F | T | E,
            SetRealInputDerivatives => I | M | C,
            GetRealOutputDerivatives => C | F | T | E,
            DoStep => C,
            // Legal only while an asynchronous step is in progress, which never happens here.
            CancelStep => 0,
            GetStatus | GetRealStatus | GetIntegerStatus | GetBooleanStatus | GetStringStatus => C | F | T,
            EnterEventMode
            | NewDiscreteStates
            | EnterContinuousTimeMode
            | CompletedIntegratorStep
            | SetTime
            | SetContinuousStates
            | GetDerivatives
            | GetEventIndicators
            | GetContinuousStates
            | GetNominalsOfContinuousStates => MODEL_EXCHANGE,
        }
    }

    pub fn is_model_exchange_only(self) -> bool {
        self.mask() == MODEL_EXCHANGE
    }

    #[inline]
    pub fn is_legal_in(self, phase: Phase) -> bool {
        self.mask() & phase.bit() != 0
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn masks_match_the_standard_for_the_lifecycle_calls() {
        use Function::*;
        use Phase::*;
        let legal = |f: Function| -> Vec<Phase> { Phase::ALL.into_iter().filter(|p| f.is_legal_in(*p)).collect() };
        assert_eq!(legal(SetupExperiment), vec![Instantiated]);
        assert_eq!(legal(EnterInitializationMode), vec![Instantiated]);
        assert_eq!(legal(ExitInitializationMode), vec![InitializationMode]);
        assert_eq!(legal(DoStep), vec![StepComplete]);
        assert_eq!(legal(Terminate), vec![StepComplete, StepFailed]);
        assert_eq!(legal(Reset), Phase::ALL.to_vec());
        assert_eq!(
            legal(GetReal),
            vec![InitializationMode, StepComplete, StepFailed, Terminated, Error]
        );
        assert_eq!(legal(SetReal), vec![Instantiated, InitializationMode, StepComplete]);
        assert!(legal(CancelStep).is_empty());
        assert!(legal(SetTime).is_empty() && SetTime.is_model_exchange_only());
    }

    #[test]
    fn phase_codes_round_trip() {
        for p in Phase::ALL {
            assert_eq!(Phase::from_code(p.code()), Some(p));
        }
        assert_eq!(Phase::from_code(6), None);
    }
}

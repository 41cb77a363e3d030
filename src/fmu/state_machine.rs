//! The FMI 2.0 state machines of Model Exchange (FMI 2.0.4 §3.2.3) and Co-Simulation (§4.2.4):
//! the states an instance can be in and, for every function and interface, the states in which
//! calling it is legal.

use std::fmt;

/// Which FMI interface an instance serves (the fmuType of fmi2Instantiate).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Interface {
    ModelExchange,
    CoSimulation,
}

impl Interface {
    pub fn name(self) -> &'static str {
        match self {
            Interface::ModelExchange => "Model Exchange",
            Interface::CoSimulation => "Co-Simulation",
        }
    }
}

/// The state of an instance, of either interface: `StepComplete` and `StepFailed` are
/// Co-Simulation's, `EventMode` and `ContinuousTimeMode` Model Exchange's, the others shared.
/// `StepInProgress` and `StepCanceled` are never entered (every step is computed synchronously)
/// and `Fatal` never (instances share nothing), so they are absent.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Phase {
    Instantiated,
    InitializationMode,
    StepComplete,
    StepFailed,
    Terminated,
    Error,
    EventMode,
    ContinuousTimeMode,
}

impl Phase {
    pub const ALL: [Phase; 8] = [
        Phase::Instantiated,
        Phase::InitializationMode,
        Phase::StepComplete,
        Phase::StepFailed,
        Phase::Terminated,
        Phase::Error,
        Phase::EventMode,
        Phase::ContinuousTimeMode,
    ];

    /// Whether an instance of `interface` can be in this state.
    pub fn belongs_to(self, interface: Interface) -> bool {
        match self {
            Phase::StepComplete | Phase::StepFailed => interface == Interface::CoSimulation,
            Phase::EventMode | Phase::ContinuousTimeMode => interface == Interface::ModelExchange,
            Phase::Instantiated | Phase::InitializationMode | Phase::Terminated | Phase::Error => true,
        }
    }

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
            Phase::EventMode => "EventMode",
            Phase::ContinuousTimeMode => "ContinuousTimeMode",
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
const V: u8 = 1 << 6;
const N: u8 = 1 << 7;

/// The states in which a call is legal, for a Model Exchange and a Co-Simulation instance
/// (bits of [`Phase`]; 0: the function belongs to the other interface).
#[derive(Clone, Copy)]
struct Masks {
    model_exchange: u8,
    co_simulation: u8,
}

const fn both(model_exchange: u8, co_simulation: u8) -> Masks {
    Masks {
        model_exchange,
        co_simulation,
    }
}

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

    /// The states in which the call is legal (FMI 2.0.4 §3.2.3 and §4.2.4, "allowed calls").
    /// Get calls in StepFailed and Error are legal; their values are for debugging.
    #[inline]
    fn masks(self) -> Masks {
        use Function::*;
        const ANY: Masks = both(I | M | V | N | T | E, I | M | C | F | T | E);
        match self {
            SetDebugLogging | FreeInstance | Reset => ANY,
            SetupExperiment | EnterInitializationMode => both(I, I),
            ExitInitializationMode => both(M, M),
            Terminate => both(V | N, C | F),
            GetReal | GetInteger | GetBoolean | GetString => both(M | V | N | T | E, M | C | F | T | E),
            // Which variables may be set in which state is checked per variable.
            SetReal => both(I | M | V | N, I | M | C),
            SetInteger | SetBoolean | SetString => both(I | M | V, I | M | C),
            GetFmuState
            | SetFmuState
            | FreeFmuState
            | SerializedFmuStateSize
            | SerializeFmuState
            | DeSerializeFmuState => ANY,
            GetDirectionalDerivative => both(M | V | N | T | E, M | C | F | T | E),
            SetRealInputDerivatives => both(0, I | M | C),
            GetRealOutputDerivatives => both(0, C | F | T | E),
            DoStep => both(0, C),
            // Legal only while an asynchronous step is in progress, which never happens here.
            CancelStep => both(0, 0),
            GetStatus | GetRealStatus | GetIntegerStatus | GetBooleanStatus | GetStringStatus => both(0, C | F | T),
            EnterEventMode => both(V | N, 0),
            NewDiscreteStates | EnterContinuousTimeMode => both(V, 0),
            CompletedIntegratorStep | SetContinuousStates => both(N, 0),
            SetTime => both(V | N, 0),
            GetEventIndicators | GetContinuousStates => both(M | V | N | T | E, 0),
            GetDerivatives => both(V | N | T | E, 0),
            GetNominalsOfContinuousStates => both(I | V | N | T | E, 0),
        }
    }

    /// The interface the function belongs to, if only one (`CancelStep`, legal in no state
    /// entered here, counts as Co-Simulation's).
    pub fn only_for(self) -> Option<Interface> {
        use Function::*;
        match self {
            CancelStep => Some(Interface::CoSimulation),
            _ => match self.masks() {
                Masks { model_exchange: 0, .. } => Some(Interface::CoSimulation),
                Masks { co_simulation: 0, .. } => Some(Interface::ModelExchange),
                _ => None,
            },
        }
    }

    #[inline]
    pub fn is_legal_in(self, interface: Interface, phase: Phase) -> bool {
        let masks = self.masks();
        let mask = match interface {
            Interface::ModelExchange => masks.model_exchange,
            Interface::CoSimulation => masks.co_simulation,
        };
        mask & phase.bit() != 0
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn legal(interface: Interface, f: Function) -> Vec<Phase> {
        Phase::ALL
            .into_iter()
            .filter(|p| f.is_legal_in(interface, *p))
            .collect()
    }

    #[test]
    fn masks_match_the_standard_for_the_lifecycle_calls() {
        use Function::*;
        use Phase::*;
        let cs = |f| legal(Interface::CoSimulation, f);
        assert_eq!(cs(SetupExperiment), vec![Instantiated]);
        assert_eq!(cs(EnterInitializationMode), vec![Instantiated]);
        assert_eq!(cs(ExitInitializationMode), vec![InitializationMode]);
        assert_eq!(cs(DoStep), vec![StepComplete]);
        assert_eq!(cs(Terminate), vec![StepComplete, StepFailed]);
        let every_cs_state: Vec<Phase> = Phase::ALL
            .into_iter()
            .filter(|p| p.belongs_to(Interface::CoSimulation))
            .collect();
        assert_eq!(cs(Reset), every_cs_state);
        assert_eq!(
            cs(GetReal),
            vec![InitializationMode, StepComplete, StepFailed, Terminated, Error]
        );
        assert_eq!(cs(SetReal), vec![Instantiated, InitializationMode, StepComplete]);
        assert!(cs(CancelStep).is_empty());
        assert!(cs(SetTime).is_empty() && SetTime.only_for() == Some(Interface::ModelExchange));
    }

    #[test]
    fn model_exchange_masks_match_the_standard() {
        use Function::*;
        use Phase::*;
        let me = |f| legal(Interface::ModelExchange, f);
        assert_eq!(me(Terminate), vec![EventMode, ContinuousTimeMode]);
        assert_eq!(me(EnterEventMode), vec![EventMode, ContinuousTimeMode]);
        assert_eq!(me(NewDiscreteStates), vec![EventMode]);
        assert_eq!(me(EnterContinuousTimeMode), vec![EventMode]);
        assert_eq!(me(CompletedIntegratorStep), vec![ContinuousTimeMode]);
        assert_eq!(me(SetContinuousStates), vec![ContinuousTimeMode]);
        assert_eq!(me(SetTime), vec![EventMode, ContinuousTimeMode]);
        assert_eq!(
            me(SetReal),
            vec![Instantiated, InitializationMode, EventMode, ContinuousTimeMode]
        );
        assert_eq!(me(SetInteger), vec![Instantiated, InitializationMode, EventMode]);
        assert_eq!(
            me(GetDerivatives),
            vec![Terminated, Error, EventMode, ContinuousTimeMode]
        );
        assert_eq!(
            me(GetNominalsOfContinuousStates),
            vec![Instantiated, Terminated, Error, EventMode, ContinuousTimeMode]
        );
        assert!(me(DoStep).is_empty() && DoStep.only_for() == Some(Interface::CoSimulation));
        assert_eq!(GetReal.only_for(), None);
        // A call legal in a state is legal only in states its interface can be in.
        for f in [GetReal, SetReal, Terminate, GetFmuState, SetTime, DoStep, GetStatus] {
            for interface in [Interface::ModelExchange, Interface::CoSimulation] {
                assert!(legal(interface, f).iter().all(|p| p.belongs_to(interface)), "{f:?}");
            }
        }
    }

    #[test]
    fn phase_codes_round_trip() {
        for p in Phase::ALL {
            assert_eq!(Phase::from_code(p.code()), Some(p));
        }
        assert_eq!(Phase::from_code(8), None);
    }
}

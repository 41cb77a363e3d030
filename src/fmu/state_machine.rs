//! The state machines of Model Exchange and Co-Simulation in FMI 2.0 (FMI 2.0.4 §3.2.3, §4.2.4)
//! and FMI 3.0 (FMI 3.0.2 §3.2, §4.2): the states an instance can be in and, for every function,
//! the states in which calling it is legal for an instance of each standard and interface.

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

/// The version of the standard an instance was created through (fmi2Instantiate or
/// fmi3Instantiate…).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Standard {
    Fmi2,
    Fmi3,
}

/// What an instance serves: a standard and an interface.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct Flavour {
    pub standard: Standard,
    pub interface: Interface,
}

impl Flavour {
    pub const FMI2_CS: Flavour = Flavour {
        standard: Standard::Fmi2,
        interface: Interface::CoSimulation,
    };
    pub const FMI2_ME: Flavour = Flavour {
        standard: Standard::Fmi2,
        interface: Interface::ModelExchange,
    };
    pub const FMI3_CS: Flavour = Flavour {
        standard: Standard::Fmi3,
        interface: Interface::CoSimulation,
    };
    pub const FMI3_ME: Flavour = Flavour {
        standard: Standard::Fmi3,
        interface: Interface::ModelExchange,
    };

    pub fn name(self) -> &'static str {
        match (self.standard, self.interface) {
            (Standard::Fmi2, Interface::ModelExchange) => "FMI 2.0 Model Exchange",
            (Standard::Fmi2, Interface::CoSimulation) => "FMI 2.0 Co-Simulation",
            (Standard::Fmi3, Interface::ModelExchange) => "FMI 3.0 Model Exchange",
            (Standard::Fmi3, Interface::CoSimulation) => "FMI 3.0 Co-Simulation",
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

    /// Whether an instance of `flavour` can be in this state.
    pub fn belongs_to(self, flavour: Flavour) -> bool {
        let co_simulation = flavour.interface == Interface::CoSimulation;
        match self {
            Phase::StepComplete => co_simulation,
            Phase::StepFailed => co_simulation && flavour.standard == Standard::Fmi2,
            Phase::EventMode => !co_simulation || flavour.standard == Standard::Fmi3,
            Phase::ContinuousTimeMode => !co_simulation,
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
    // FMI 3.0 only.
    EnterStepMode,
    GetNumberOfEventIndicators,
    GetNumberOfContinuousStates,
    /// fmi3Get<type> of a type the models have no variable of (the C name).
    GetOtherType(&'static str),
    /// fmi3Set<type> likewise.
    SetOtherType(&'static str),
    /// A function of a feature this FMU does not provide (clocks, configuration mode, adjoint
    /// derivatives, …): legal in every state, refused with the reason (the C name).
    NotProvided(&'static str),
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
    /// The C name in `standard`, for messages.
    pub fn name(self, standard: Standard) -> &'static str {
        match standard {
            Standard::Fmi2 => self.c_name(),
            Standard::Fmi3 => self.fmi3_name(),
        }
    }

    /// The FMI 3.0 C name.
    fn fmi3_name(self) -> &'static str {
        use Function::*;
        match self {
            SetDebugLogging => "fmi3SetDebugLogging",
            FreeInstance => "fmi3FreeInstance",
            SetupExperiment | EnterInitializationMode => "fmi3EnterInitializationMode",
            ExitInitializationMode => "fmi3ExitInitializationMode",
            Terminate => "fmi3Terminate",
            Reset => "fmi3Reset",
            GetReal => "fmi3GetFloat64",
            GetInteger => "fmi3GetInt32",
            GetBoolean => "fmi3GetBoolean",
            GetString => "fmi3GetString",
            SetReal => "fmi3SetFloat64",
            SetInteger => "fmi3SetInt32",
            SetBoolean => "fmi3SetBoolean",
            SetString => "fmi3SetString",
            GetFmuState => "fmi3GetFMUState",
            SetFmuState => "fmi3SetFMUState",
            FreeFmuState => "fmi3FreeFMUState",
            SerializedFmuStateSize => "fmi3SerializedFMUStateSize",
            SerializeFmuState => "fmi3SerializeFMUState",
            DeSerializeFmuState => "fmi3DeserializeFMUState",
            GetDirectionalDerivative => "fmi3GetDirectionalDerivative",
            GetRealOutputDerivatives => "fmi3GetOutputDerivatives",
            DoStep => "fmi3DoStep",
            EnterEventMode => "fmi3EnterEventMode",
            NewDiscreteStates => "fmi3UpdateDiscreteStates",
            EnterContinuousTimeMode => "fmi3EnterContinuousTimeMode",
            CompletedIntegratorStep => "fmi3CompletedIntegratorStep",
            SetTime => "fmi3SetTime",
            SetContinuousStates => "fmi3SetContinuousStates",
            GetDerivatives => "fmi3GetContinuousStateDerivatives",
            GetEventIndicators => "fmi3GetEventIndicators",
            GetContinuousStates => "fmi3GetContinuousStates",
            GetNominalsOfContinuousStates => "fmi3GetNominalsOfContinuousStates",
            EnterStepMode => "fmi3EnterStepMode",
            GetNumberOfEventIndicators => "fmi3GetNumberOfEventIndicators",
            GetNumberOfContinuousStates => "fmi3GetNumberOfContinuousStates",
            GetOtherType(name) | SetOtherType(name) | NotProvided(name) => name,
            // FMI 2.0 only; never called through the FMI 3.0 functions.
            SetRealInputDerivatives
            | CancelStep
            | GetStatus
            | GetRealStatus
            | GetIntegerStatus
            | GetBooleanStatus
            | GetStringStatus => self.c_name(),
        }
    }

    /// The FMI 2.0 C name, for messages.
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
            EnterStepMode => "fmi3EnterStepMode",
            GetNumberOfEventIndicators => "fmi3GetNumberOfEventIndicators",
            GetNumberOfContinuousStates => "fmi3GetNumberOfContinuousStates",
            GetOtherType(name) | SetOtherType(name) | NotProvided(name) => name,
        }
    }

    /// The states in which the call is legal for an instance of `standard`.
    #[inline]
    fn masks(self, standard: Standard) -> Masks {
        match standard {
            Standard::Fmi2 => self.masks2(),
            Standard::Fmi3 => self.masks3(),
        }
    }

    /// FMI 2.0.4 §3.2.3 and §4.2.4, "allowed calls". Get calls in StepFailed and Error are legal;
    /// their values are for debugging.
    #[inline]
    fn masks2(self) -> Masks {
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
            // Condition 8 admits Event Mode "only for a Pure Discrete-Time FMU"; these have
            // continuous states.
            SetTime => both(N, 0),
            GetEventIndicators | GetContinuousStates => both(M | V | N | T | E, 0),
            GetDerivatives => both(V | N | T | E, 0),
            GetNominalsOfContinuousStates => both(I | V | N | T | E, 0),
            EnterStepMode
            | GetNumberOfEventIndicators
            | GetNumberOfContinuousStates
            | GetOtherType(_)
            | SetOtherType(_)
            | NotProvided(_) => both(0, 0),
        }
    }

    /// FMI 3.0.2 §3.2 and §4.2 (Co-Simulation's Step Mode is `StepComplete`; the FMU never
    /// enters Configuration, Reconfiguration or Clock Activation Mode).
    #[inline]
    fn masks3(self) -> Masks {
        use Function::*;
        const ANY: Masks = both(I | M | V | N | T | E, I | M | V | C | T | E);
        const READ: Masks = both(M | V | N | T | E, M | V | C | T | E);
        match self {
            SetDebugLogging | FreeInstance | Reset | NotProvided(_) => ANY,
            GetFmuState
            | SetFmuState
            | FreeFmuState
            | SerializedFmuStateSize
            | SerializeFmuState
            | DeSerializeFmuState => ANY,
            SetupExperiment | EnterInitializationMode => both(I, I),
            ExitInitializationMode => both(M, M),
            Terminate => both(V | N, V | C),
            GetReal | GetInteger | GetBoolean | GetString | GetOtherType(_) | GetDirectionalDerivative => READ,
            // Which variables may be set in which state is checked per variable.
            SetReal => both(I | M | V | N, I | M | V | C),
            SetInteger | SetBoolean | SetString | SetOtherType(_) => both(I | M | V, I | M | V | C),
            GetRealOutputDerivatives => both(0, V | C | T | E),
            DoStep => both(0, C),
            EnterStepMode => both(0, V),
            EnterEventMode => both(N, C),
            NewDiscreteStates => both(V, V),
            EnterContinuousTimeMode => both(V, 0),
            CompletedIntegratorStep | SetContinuousStates => both(N, 0),
            // §3.2.1 lists fmi3SetTime among Continuous-Time Mode's calls only; Event Mode's
            // (§2.3.5) do not include it.
            SetTime => both(N, 0),
            GetEventIndicators | GetContinuousStates | GetDerivatives => both(M | V | N | T | E, 0),
            GetNominalsOfContinuousStates => both(I | M | V | N | T | E, 0),
            GetNumberOfEventIndicators | GetNumberOfContinuousStates => both(I | M | V | N | T | E, 0),
            SetRealInputDerivatives
            | CancelStep
            | GetStatus
            | GetRealStatus
            | GetIntegerStatus
            | GetBooleanStatus
            | GetStringStatus => both(0, 0),
        }
    }

    /// The standard's words behind a refusal of this call in `phase`, where the state table's
    /// bare "not allowed" would leave the importer guessing.
    pub fn rule(self, standard: Standard, phase: Phase) -> Option<&'static str> {
        match (self, standard, phase) {
            (Function::SetTime, Standard::Fmi2, Phase::EventMode) => Some(
                "FMI 2.0.4 §3.2.3 allows it in Event Mode \"only for a Pure Discrete-Time FMU\" (condition 8); \
                 this FMU has continuous states, so time is set in Continuous-Time Mode",
            ),
            (Function::SetTime, Standard::Fmi3, Phase::EventMode) => {
                Some("FMI 3.0.2 §3.2.1 allows it in Continuous-Time Mode only; in Event Mode the time is the event's")
            }
            _ => None,
        }
    }

    /// The interface the function belongs to in `standard`, if only one (`CancelStep`, legal
    /// in no state entered here, counts as Co-Simulation's).
    pub fn only_for(self, standard: Standard) -> Option<Interface> {
        use Function::*;
        match self {
            CancelStep => Some(Interface::CoSimulation),
            _ => match self.masks(standard) {
                Masks {
                    model_exchange: 0,
                    co_simulation: 0,
                } => None,
                Masks { model_exchange: 0, .. } => Some(Interface::CoSimulation),
                Masks { co_simulation: 0, .. } => Some(Interface::ModelExchange),
                _ => None,
            },
        }
    }

    #[inline]
    pub fn is_legal_in(self, flavour: Flavour, phase: Phase) -> bool {
        let masks = self.masks(flavour.standard);
        let mask = match flavour.interface {
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
        legal_in(
            Flavour {
                standard: Standard::Fmi2,
                interface,
            },
            f,
        )
    }

    fn legal_in(flavour: Flavour, f: Function) -> Vec<Phase> {
        Phase::ALL.into_iter().filter(|p| f.is_legal_in(flavour, *p)).collect()
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
            .filter(|p| p.belongs_to(Flavour::FMI2_CS))
            .collect();
        assert_eq!(cs(Reset), every_cs_state);
        assert_eq!(
            cs(GetReal),
            vec![InitializationMode, StepComplete, StepFailed, Terminated, Error]
        );
        assert_eq!(cs(SetReal), vec![Instantiated, InitializationMode, StepComplete]);
        assert!(cs(CancelStep).is_empty());
        assert!(cs(SetTime).is_empty() && SetTime.only_for(Standard::Fmi2) == Some(Interface::ModelExchange));
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
        // Condition 8: Event Mode only for a pure discrete-time FMU.
        assert_eq!(me(SetTime), vec![ContinuousTimeMode]);
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
        assert!(me(DoStep).is_empty() && DoStep.only_for(Standard::Fmi2) == Some(Interface::CoSimulation));
        assert_eq!(GetReal.only_for(Standard::Fmi2), None);
        // A call legal in a state is legal only in states its interface can be in.
        for f in [GetReal, SetReal, Terminate, GetFmuState, SetTime, DoStep, GetStatus] {
            for flavour in [Flavour::FMI2_ME, Flavour::FMI2_CS, Flavour::FMI3_ME, Flavour::FMI3_CS] {
                assert!(
                    legal_in(flavour, f).iter().all(|p| p.belongs_to(flavour)),
                    "{f:?} {flavour:?}"
                );
            }
        }
    }

    #[test]
    fn fmi3_masks_follow_the_standard() {
        use Function::*;
        use Phase::*;
        let cs = |f| legal_in(Flavour::FMI3_CS, f);
        let me = |f| legal_in(Flavour::FMI3_ME, f);
        assert_eq!(cs(DoStep), vec![StepComplete]);
        assert_eq!(cs(EnterStepMode), vec![EventMode]);
        assert_eq!(cs(EnterEventMode), vec![StepComplete]);
        assert_eq!(cs(NewDiscreteStates), vec![EventMode]);
        assert_eq!(cs(Terminate), vec![StepComplete, EventMode]);
        assert_eq!(me(Terminate), vec![EventMode, ContinuousTimeMode]);
        assert_eq!(me(EnterEventMode), vec![ContinuousTimeMode]);
        assert!(cs(SetRealInputDerivatives).is_empty() && cs(GetStatus).is_empty());
        assert_eq!(EnterStepMode.only_for(Standard::Fmi3), Some(Interface::CoSimulation));
        assert_eq!(SetTime.only_for(Standard::Fmi3), Some(Interface::ModelExchange));
        // §3.2.1: fmi3SetTime is among Continuous-Time Mode's calls, not Event Mode's (§2.3.5).
        assert_eq!(me(SetTime), vec![ContinuousTimeMode]);
        assert_eq!(GetReal.name(Standard::Fmi3), "fmi3GetFloat64");
        assert_eq!(GetDerivatives.name(Standard::Fmi3), "fmi3GetContinuousStateDerivatives");
    }

    #[test]
    fn phase_codes_round_trip() {
        for p in Phase::ALL {
            assert_eq!(Phase::from_code(p.code()), Some(p));
        }
        assert_eq!(Phase::from_code(8), None);
    }
}

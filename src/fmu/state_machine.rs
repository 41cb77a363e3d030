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

/// A function's C name and masks in FMI 2.0 and in FMI 3.0.
#[derive(Clone, Copy)]
struct Spec {
    fmi2: (&'static str, Masks),
    fmi3: (&'static str, Masks),
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
        self.in_standard(standard).0
    }

    /// The FMI 2.0 C name, for messages.
    pub fn c_name(self) -> &'static str {
        self.name(Standard::Fmi2)
    }

    /// The states in which the call is legal for an instance of `standard`.
    #[inline]
    fn masks(self, standard: Standard) -> Masks {
        self.in_standard(standard).1
    }

    #[inline]
    fn in_standard(self, standard: Standard) -> (&'static str, Masks) {
        let spec = self.spec();
        match standard {
            Standard::Fmi2 => spec.fmi2,
            Standard::Fmi3 => spec.fmi3,
        }
    }

    /// The one table of the functions: each one's C name and the states it is legal in, in FMI
    /// 2.0 (FMI 2.0.4 §3.2.3 and §4.2.4, "allowed calls") and in FMI 3.0 (FMI 3.0.2 §2.3, §3.2
    /// and §4.2; Co-Simulation's Step Mode is `StepComplete`, and the FMU never enters
    /// Configuration, Reconfiguration or Clock Activation Mode). A function of one standard only
    /// has masks 0 in the other and keeps its own name there. Get calls in StepFailed and Error
    /// are legal; their values are for debugging. Which variables may be set in which state is
    /// checked per variable.
    #[inline]
    fn spec(self) -> Spec {
        use Function::*;
        const ANY2: Masks = both(I | M | V | N | T | E, I | M | C | F | T | E);
        const ANY3: Masks = both(I | M | V | N | T | E, I | M | V | C | T | E);
        const READ2: Masks = both(M | V | N | T | E, M | C | F | T | E);
        const READ3: Masks = both(M | V | N | T | E, M | V | C | T | E);
        const NONE: Masks = both(0, 0);
        let spec = |fmi2, masks2, fmi3, masks3| Spec {
            fmi2: (fmi2, masks2),
            fmi3: (fmi3, masks3),
        };
        // A function of FMI 2.0 only, under its FMI 2.0 name in both.
        let fmi2_only = |name, masks2| spec(name, masks2, name, NONE);
        let fmi3_only = |name, masks3| spec(name, NONE, name, masks3);
        match self {
            SetDebugLogging => spec("fmi2SetDebugLogging", ANY2, "fmi3SetDebugLogging", ANY3),
            FreeInstance => spec("fmi2FreeInstance", ANY2, "fmi3FreeInstance", ANY3),
            SetupExperiment => spec(
                "fmi2SetupExperiment",
                both(I, I),
                "fmi3EnterInitializationMode",
                both(I, I),
            ),
            EnterInitializationMode => spec(
                "fmi2EnterInitializationMode",
                both(I, I),
                "fmi3EnterInitializationMode",
                both(I, I),
            ),
            ExitInitializationMode => spec(
                "fmi2ExitInitializationMode",
                both(M, M),
                "fmi3ExitInitializationMode",
                both(M, M),
            ),
            Terminate => spec("fmi2Terminate", both(V | N, C | F), "fmi3Terminate", both(V | N, V | C)),
            Reset => spec("fmi2Reset", ANY2, "fmi3Reset", ANY3),
            GetReal => spec("fmi2GetReal", READ2, "fmi3GetFloat64", READ3),
            GetInteger => spec("fmi2GetInteger", READ2, "fmi3GetInt32", READ3),
            GetBoolean => spec("fmi2GetBoolean", READ2, "fmi3GetBoolean", READ3),
            GetString => spec("fmi2GetString", READ2, "fmi3GetString", READ3),
            SetReal => spec(
                "fmi2SetReal",
                both(I | M | V | N, I | M | C),
                "fmi3SetFloat64",
                both(I | M | V | N, I | M | V | C),
            ),
            SetInteger => spec(
                "fmi2SetInteger",
                both(I | M | V, I | M | C),
                "fmi3SetInt32",
                both(I | M | V, I | M | V | C),
            ),
            SetBoolean => spec(
                "fmi2SetBoolean",
                both(I | M | V, I | M | C),
                "fmi3SetBoolean",
                both(I | M | V, I | M | V | C),
            ),
            SetString => spec(
                "fmi2SetString",
                both(I | M | V, I | M | C),
                "fmi3SetString",
                both(I | M | V, I | M | V | C),
            ),
            GetFmuState => spec("fmi2GetFMUstate", ANY2, "fmi3GetFMUState", ANY3),
            SetFmuState => spec("fmi2SetFMUstate", ANY2, "fmi3SetFMUState", ANY3),
            FreeFmuState => spec("fmi2FreeFMUstate", ANY2, "fmi3FreeFMUState", ANY3),
            SerializedFmuStateSize => spec("fmi2SerializedFMUstateSize", ANY2, "fmi3SerializedFMUStateSize", ANY3),
            SerializeFmuState => spec("fmi2SerializeFMUstate", ANY2, "fmi3SerializeFMUState", ANY3),
            DeSerializeFmuState => spec("fmi2DeSerializeFMUstate", ANY2, "fmi3DeserializeFMUState", ANY3),
            GetDirectionalDerivative => spec(
                "fmi2GetDirectionalDerivative",
                READ2,
                "fmi3GetDirectionalDerivative",
                READ3,
            ),
            SetRealInputDerivatives => fmi2_only("fmi2SetRealInputDerivatives", both(0, I | M | C)),
            GetRealOutputDerivatives => spec(
                "fmi2GetRealOutputDerivatives",
                both(0, C | F | T | E),
                "fmi3GetOutputDerivatives",
                both(0, V | C | T | E),
            ),
            DoStep => spec("fmi2DoStep", both(0, C), "fmi3DoStep", both(0, C)),
            // Legal only while an asynchronous step is in progress, which never happens here.
            CancelStep => fmi2_only("fmi2CancelStep", NONE),
            GetStatus => fmi2_only("fmi2GetStatus", both(0, C | F | T)),
            GetRealStatus => fmi2_only("fmi2GetRealStatus", both(0, C | F | T)),
            GetIntegerStatus => fmi2_only("fmi2GetIntegerStatus", both(0, C | F | T)),
            GetBooleanStatus => fmi2_only("fmi2GetBooleanStatus", both(0, C | F | T)),
            GetStringStatus => fmi2_only("fmi2GetStringStatus", both(0, C | F | T)),
            EnterEventMode => spec("fmi2EnterEventMode", both(V | N, 0), "fmi3EnterEventMode", both(N, C)),
            NewDiscreteStates => spec(
                "fmi2NewDiscreteStates",
                both(V, 0),
                "fmi3UpdateDiscreteStates",
                both(V, V),
            ),
            EnterContinuousTimeMode => spec(
                "fmi2EnterContinuousTimeMode",
                both(V, 0),
                "fmi3EnterContinuousTimeMode",
                both(V, 0),
            ),
            CompletedIntegratorStep => spec(
                "fmi2CompletedIntegratorStep",
                both(N, 0),
                "fmi3CompletedIntegratorStep",
                both(N, 0),
            ),
            SetContinuousStates => spec(
                "fmi2SetContinuousStates",
                both(N, 0),
                "fmi3SetContinuousStates",
                both(N, 0),
            ),
            // FMI 2.0.4 condition 8 admits Event Mode "only for a Pure Discrete-Time FMU"; these
            // have continuous states. FMI 3.0.2 §3.2.1 lists fmi3SetTime among Continuous-Time
            // Mode's calls only; Event Mode's (§2.3.5) do not include it.
            SetTime => spec("fmi2SetTime", both(N, 0), "fmi3SetTime", both(N, 0)),
            GetEventIndicators => spec(
                "fmi2GetEventIndicators",
                both(M | V | N | T | E, 0),
                "fmi3GetEventIndicators",
                both(M | V | N | T | E, 0),
            ),
            GetContinuousStates => spec(
                "fmi2GetContinuousStates",
                both(M | V | N | T | E, 0),
                "fmi3GetContinuousStates",
                both(M | V | N | T | E, 0),
            ),
            // FMI 2.0.4 §3.2.3's table marks both in Initialization Mode too.
            GetDerivatives => spec(
                "fmi2GetDerivatives",
                both(M | V | N | T | E, 0),
                "fmi3GetContinuousStateDerivatives",
                both(M | V | N | T | E, 0),
            ),
            GetNominalsOfContinuousStates => spec(
                "fmi2GetNominalsOfContinuousStates",
                both(I | M | V | N | T | E, 0),
                "fmi3GetNominalsOfContinuousStates",
                both(I | M | V | N | T | E, 0),
            ),
            EnterStepMode => fmi3_only("fmi3EnterStepMode", both(0, V)),
            GetNumberOfEventIndicators => fmi3_only("fmi3GetNumberOfEventIndicators", both(I | M | V | N | T | E, 0)),
            GetNumberOfContinuousStates => fmi3_only("fmi3GetNumberOfContinuousStates", both(I | M | V | N | T | E, 0)),
            GetOtherType(name) => fmi3_only(name, READ3),
            SetOtherType(name) => fmi3_only(name, both(I | M | V, I | M | V | C)),
            NotProvided(name) => fmi3_only(name, ANY3),
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
            vec![InitializationMode, Terminated, Error, EventMode, ContinuousTimeMode]
        );
        assert_eq!(
            me(GetNominalsOfContinuousStates),
            vec![
                Instantiated,
                InitializationMode,
                Terminated,
                Error,
                EventMode,
                ContinuousTimeMode
            ]
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

//! Every C function in every state of the FMI 2.0 state machines, through the C ABI, against
//! the standard's tables of allowed calls written out here independently of
//! `src/fmu/state_machine.rs`: Co-Simulation (FMI 2.0.4 §4.2.4) and Model Exchange (§3.2.3), the
//! latter on every model (their continuous states differ in number).
//! StepFailed, which this FMU never enters by itself, is reached through an FMU state. An
//! illegal call must return fmi2Error, log "not allowed in state X" (or, for a function of the
//! other interface, "belongs to FMI for ...") and leave the instance in state Error; a legal one
//! must do its work.
//!
//! The Co-Simulation tables cover the controller too ([`CONTROLLER`], docs/model.md §9), with its
//! own rows where it refuses a call the state table allows: the FMU-state calls (it has none),
//! input and output derivatives; it never enters StepFailed (no FMU state to reach it through).

use crate::robustness_common::*;
use backlash_fmu::ffi::*;
use backlash_fmu::fmu::MODELS;
use std::ptr::{null, null_mut};

const OK: fmi2Status = fmi2Status::fmi2OK;
const ERROR: fmi2Status = fmi2Status::fmi2Error;
const DISCARD: fmi2Status = fmi2Status::fmi2Discard;

const PHASES: [&str; 6] = [
    "Instantiated",
    "InitializationMode",
    "StepComplete",
    "StepFailed",
    "Terminated",
    "Error",
];

fn in_phase(model: usize, phase: &str) -> Fmu {
    match phase {
        "Instantiated" => Fmu::new(model),
        "InitializationMode" => {
            let f = Fmu::new(model);
            assert_eq!(fmi2EnterInitializationMode(f.c), OK);
            f
        }
        "StepComplete" => Fmu::initialized(model, None),
        "StepFailed" => in_step_failed(model),
        "Terminated" => {
            let f = Fmu::initialized(model, None);
            assert_eq!(fmi2Terminate(f.c), OK);
            f
        }
        "Error" => {
            // From StepComplete, so that the values of a simulation are there to be read.
            let f = Fmu::initialized(model, None);
            assert_eq!(fmi2EnterInitializationMode(f.c), ERROR);
            f
        }
        _ => unreachable!(),
    }
}

type Call = fn(&Fmu) -> fmi2Status;

/// The value reference of the plant's variable `plant`, or of the controller's `controller`: a
/// variable of the same kind in each.
fn vr(f: &Fmu, plant: &str, controller: &str) -> [u32; 1] {
    [f.vr(if f.model.is_controller() { controller } else { plant })]
}

/// The controller's own answer to a call the table allows (docs/model.md §9): refused, naming the
/// flag of its description that says it is not offered.
fn controller_refusal(function: &str) -> Option<&'static str> {
    match function {
        "fmi2GetFMUstate"
        | "fmi2SetFMUstate"
        | "fmi2SerializedFMUstateSize"
        | "fmi2SerializeFMUstate"
        | "fmi2DeSerializeFMUstate" => Some("canGetAndSetFMUstate = false"),
        "fmi2SetRealInputDerivatives" => Some("canInterpolateInputs = false"),
        "fmi2GetRealOutputDerivatives" => Some("maxOutputDerivativeOrder = 0"),
        _ => None,
    }
}

/// (function, call with valid arguments, legal in [I, M, C, F, T, E], status when legal).
/// The masks are the "x" columns of the Co-Simulation table of FMI 2.0.4 §4.2.4; StepInProgress
/// and StepCanceled are never entered by a synchronous FMU. Each call takes its variables from
/// the instance's model (a plant's or the controller's), and any FMU state from a shaft.
#[rustfmt::skip]
fn table() -> Vec<(&'static str, Call, [bool; 6], fmi2Status)> {
    const ALL: [bool; 6] = [true; 6];
    const NONE: [bool; 6] = [false; 6];
    // SAFETY (every entry): pointers to locals or statics of the announced length.
    unsafe {
        vec![
            ("fmi2SetDebugLogging", |f| fmi2SetDebugLogging(f.c, 1, 1, [c"logCalls".as_ptr()].as_ptr()), ALL, OK),
            ("fmi2SetupExperiment", |f| fmi2SetupExperiment(f.c, 1, 1e-6, 0.0, 1, 10.0), [true, false, false, false, false, false], OK),
            ("fmi2EnterInitializationMode", |f| fmi2EnterInitializationMode(f.c), [true, false, false, false, false, false], OK),
            ("fmi2ExitInitializationMode", |f| fmi2ExitInitializationMode(f.c), [false, true, false, false, false, false], OK),
            ("fmi2Terminate", |f| fmi2Terminate(f.c), [false, false, true, true, false, false], OK),
            ("fmi2Reset", |f| fmi2Reset(f.c), ALL, OK),
            ("fmi2GetReal", |f| fmi2GetReal(f.c, vr(f, "theta_m", "tau_m").as_ptr(), 1, [0.0].as_mut_ptr()), [false, true, true, true, true, true], OK),
            ("fmi2GetInteger", |f| fmi2GetInteger(f.c, vr(f, "contact", "reference").as_ptr(), 1, [0].as_mut_ptr()), [false, true, true, true, true, true], OK),
            ("fmi2GetBoolean", |f| fmi2GetBoolean(f.c, null(), 0, null_mut()), [false, true, true, true, true, true], OK),
            ("fmi2GetString", |f| fmi2GetString(f.c, null(), 0, null_mut()), [false, true, true, true, true, true], OK),
            ("fmi2SetReal", |f| fmi2SetReal(f.c, vr(f, "tau_m", "omega_m").as_ptr(), 1, [0.5].as_ptr()), [true, true, true, false, false, false], OK),
            ("fmi2SetInteger", |f| fmi2SetInteger(f.c, null(), 0, null()), [true, true, true, false, false, false], OK),
            ("fmi2SetBoolean", |f| fmi2SetBoolean(f.c, null(), 0, null()), [true, true, true, false, false, false], OK),
            ("fmi2SetString", |f| fmi2SetString(f.c, null(), 0, null()), [true, true, true, false, false, false], OK),
            ("fmi2GetFMUstate", |f| {
                let mut s = null_mut();
                let status = fmi2GetFMUstate(f.c, &mut s);
                fmi2FreeFMUstate(f.c, &mut s);
                status
            }, ALL, OK),
            ("fmi2SetFMUstate", |f| {
                // A state of the same model taken from another instance in StepComplete.
                let donor = Fmu::initialized(0, None);
                let mut s = null_mut();
                assert_eq!(fmi2GetFMUstate(donor.c, &mut s), OK);
                fmi2SetFMUstate(f.c, s)
            }, ALL, OK),
            ("fmi2FreeFMUstate", |f| {
                if f.model.is_controller() {
                    // No state of its own to free: freeing none is ignored.
                    return fmi2FreeFMUstate(f.c, &mut null_mut());
                }
                let donor = Fmu::new(0);
                let mut s = null_mut();
                assert_eq!(fmi2GetFMUstate(donor.c, &mut s), OK);
                fmi2FreeFMUstate(f.c, &mut s)
            }, ALL, OK),
            ("fmi2SerializedFMUstateSize", |f| {
                let donor = Fmu::new(0);
                let mut s = null_mut();
                assert_eq!(fmi2GetFMUstate(donor.c, &mut s), OK);
                fmi2SerializedFMUstateSize(f.c, s, &mut 0)
            }, ALL, OK),
            ("fmi2SerializeFMUstate", |f| {
                let donor = Fmu::new(0);
                let mut s = null_mut();
                assert_eq!(fmi2GetFMUstate(donor.c, &mut s), OK);
                fmi2SerializeFMUstate(f.c, s, [0; 4096].as_mut_ptr(), 4096)
            }, ALL, OK),
            ("fmi2DeSerializeFMUstate", |f| {
                let bytes = serialized(&Fmu::new(0));
                fmi2DeSerializeFMUstate(f.c, bytes.as_ptr().cast(), bytes.len(), &mut null_mut())
            }, ALL, OK),
            ("fmi2GetDirectionalDerivative", |f| {
                fmi2GetDirectionalDerivative(f.c, vr(f, "omega_m", "tau_m").as_ptr(), 1, vr(f, "tau_m", "omega_m").as_ptr(), 1, [1.0].as_ptr(), [0.0].as_mut_ptr())
            }, [false, true, true, true, true, true], ERROR),
            ("fmi2SetRealInputDerivatives", |f| {
                fmi2SetRealInputDerivatives(f.c, vr(f, "tau_m", "omega_m").as_ptr(), 1, [1].as_ptr(), [0.5].as_ptr())
            }, [true, true, true, false, false, false], OK),
            ("fmi2GetRealOutputDerivatives", |f| {
                fmi2GetRealOutputDerivatives(f.c, vr(f, "omega_m", "tau_m").as_ptr(), 1, [1].as_ptr(), [0.0].as_mut_ptr())
            }, [false, false, true, true, true, true], OK),
            ("fmi2DoStep", |f| fmi2DoStep(f.c, 0.0, 1e-3, 1), [false, false, true, false, false, false], OK),
            ("fmi2CancelStep", |f| fmi2CancelStep(f.c), NONE, OK),
            ("fmi2GetStatus", |f| fmi2GetStatus(f.c, fmi2DoStepStatus, &mut fmi2Status::fmi2Error), [false, false, true, true, true, false], OK),
            ("fmi2GetRealStatus", |f| fmi2GetRealStatus(f.c, fmi2LastSuccessfulTime, &mut 0.0), [false, false, true, true, true, false], OK),
            ("fmi2GetIntegerStatus", |f| fmi2GetIntegerStatus(f.c, fmi2DoStepStatus, &mut 0), [false, false, true, true, true, false], DISCARD),
            ("fmi2GetBooleanStatus", |f| fmi2GetBooleanStatus(f.c, fmi2Terminated, &mut 0), [false, false, true, true, true, false], OK),
            ("fmi2GetStringStatus", |f| fmi2GetStringStatus(f.c, fmi2PendingStatus, &mut null()), [false, false, true, true, true, false], DISCARD),
            ("fmi2EnterEventMode", |f| fmi2EnterEventMode(f.c), NONE, OK),
            ("fmi2NewDiscreteStates", |f| fmi2NewDiscreteStates(f.c, null_mut()), NONE, OK),
            ("fmi2EnterContinuousTimeMode", |f| fmi2EnterContinuousTimeMode(f.c), NONE, OK),
            ("fmi2CompletedIntegratorStep", |f| fmi2CompletedIntegratorStep(f.c, 1, &mut 0, &mut 0), NONE, OK),
            ("fmi2SetTime", |f| fmi2SetTime(f.c, 0.0), NONE, OK),
            ("fmi2SetContinuousStates", |f| fmi2SetContinuousStates(f.c, [0.0; 4].as_ptr(), 4), NONE, OK),
            ("fmi2GetDerivatives", |f| fmi2GetDerivatives(f.c, [0.0; 4].as_mut_ptr(), 4), NONE, OK),
            ("fmi2GetEventIndicators", |f| fmi2GetEventIndicators(f.c, [0.0; 1].as_mut_ptr(), 0), NONE, OK),
            ("fmi2GetContinuousStates", |f| fmi2GetContinuousStates(f.c, [0.0; 4].as_mut_ptr(), 4), NONE, OK),
            ("fmi2GetNominalsOfContinuousStates", |f| fmi2GetNominalsOfContinuousStates(f.c, [0.0; 4].as_mut_ptr(), 4), NONE, OK),
        ]
    }
}

/// On a plant and on the controller, with the controller's own rows ([`controller_refusal`]) and
/// no StepFailed column for it.
#[test]
fn every_call_in_every_state_follows_the_standard_table() {
    let table = table();
    assert_eq!(table.len(), 40, "every FMI 2.0 function that takes an instance");
    let mut checked = 0;
    for ((name, call, legal, when_legal), model) in table.iter().flat_map(|row| [(row, SHAFT), (row, CONTROLLER)]) {
        let model_exchange = legal == &[false; 6] && *name != "fmi2CancelStep";
        let controller = model == CONTROLLER;
        for (phase, legal) in PHASES.iter().zip(legal) {
            if controller && *phase == "StepFailed" {
                continue;
            }
            let f = in_phase(model, phase);
            let before = f.log_len();
            let context = format!("{name} in {phase} ({})", f.model.identifier);
            if let (true, true, Some(reason)) = (controller, *legal, controller_refusal(name)) {
                // Its own row: refused with the reason, nothing changed (where values are
                // readable: not in Instantiated), and then in state Error.
                let status = if *phase == "Instantiated" {
                    f.refuses(reason, |_| call(&f))
                } else {
                    f.refuses_changing_nothing(reason, |_| call(&f))
                };
                assert_eq!(status, ERROR, "{context}");
                f.refuses("not allowed in state Error", |c| fmi2EnterInitializationMode(c));
                f.reset_and_check();
                checked += 1;
                continue;
            }
            let status = call(&f);
            if *legal {
                assert_eq!(status, *when_legal, "{context}: {:?}", f.entries().get(before..));
                if *when_legal == OK {
                    assert!(
                        f.entries()[before..].iter().all(|e| e.category != "logErrors"),
                        "{context}: {:?}",
                        &f.entries()[before..]
                    );
                }
            } else {
                let reason = if model_exchange {
                    "belongs to FMI for Model Exchange; this instance was instantiated for Co-Simulation".to_string()
                } else {
                    format!("{name} is not allowed in state {phase}")
                };
                f.assert_refused(status, before, &reason);
                assert_eq!(status, ERROR, "{context}");
                // Now in state Error: a call legal only in Instantiated says so.
                let before = f.log_len();
                let s = fmi2EnterInitializationMode(f.c);
                f.assert_refused(s, before, "not allowed in state Error");
            }
            checked += 1;
        }
    }
    assert_eq!(checked, 240 + 200);
    fresh_instance_works(SHAFT);
    fresh_instance_works(CONTROLLER);
}

/// On a plant and on the controller (no FMU state to go with it, no StepFailed).
#[test]
fn an_instance_can_be_freed_in_every_state_and_is_gone_after() {
    for phase in PHASES {
        let f = in_phase(BELT, phase);
        let c = f.c;
        // An FMU state the instance owns goes with it.
        let mut s = null_mut();
        // SAFETY: pointer to a local.
        assert_eq!(unsafe { fmi2GetFMUstate(c, &mut s) }, OK);
        drop(f);
        assert_eq!(fmi2Reset(c), ERROR, "{phase}: a freed instance answered");
        let other = Fmu::new(BELT);
        other.refuses("not a live FMU state", |o| fmi2SetFMUstate(o, s));
    }
    for phase in PHASES.into_iter().filter(|phase| *phase != "StepFailed") {
        let f = in_phase(CONTROLLER, phase);
        let c = f.c;
        drop(f);
        assert_eq!(fmi2Reset(c), ERROR, "{phase}: a freed controller answered");
        assert_eq!(
            fmi2DoStep(c, 0.0, 1e-3, 1),
            ERROR,
            "{phase}: a freed controller stepped"
        );
    }
    fresh_instance_works(BELT);
    fresh_instance_works(CONTROLLER);
}

/// The controller has no FMU state: fmi2Reset alone leads it out of Error (its own rows).
#[test]
fn error_is_left_only_by_reset_or_an_fmu_state() {
    let f = in_phase(CONTROLLER, "Error");
    f.refuses_changing_nothing("canGetAndSetFMUstate = false", |c| {
        let mut s = null_mut();
        // SAFETY: pointer to a local.
        unsafe { fmi2GetFMUstate(c, &mut s) }
    });
    f.refuses("not allowed in state Error", |c| fmi2DoStep(c, 0.0, 1e-3, 1));
    f.reset_and_check();

    // fmi2Reset leads back to Instantiated.
    let f = in_phase(SHAFT, "Error");
    f.reset_and_check();
    // fmi2SetFMUstate with a state saved before the error continues from there.
    let f = Fmu::initialized(SHAFT, None);
    assert_eq!(fmi2DoStep(f.c, 0.0, 0.01, 1), OK);
    let saved = serialized(&f);
    assert_eq!(fmi2DoStep(f.c, 0.0, 0.01, 1), ERROR, "wrong communication point");
    assert_eq!(load(&f, &saved), (OK, OK));
    assert_eq!(fmi2DoStep(f.c, 0.01, 0.01, 1), OK);
    f.assert_all_finite("after leaving Error through an FMU state");
    let reference = Fmu::initialized(SHAFT, None);
    assert_eq!(fmi2DoStep(reference.c, 0.0, 0.01, 1), OK);
    assert_eq!(fmi2DoStep(reference.c, 0.01, 0.01, 1), OK);
    // The restored state is the reference's after its first step, stepped by the same code.
    let bits = |f: &Fmu| f.all_values().1.iter().map(|(_, x)| x.to_bits()).collect::<Vec<_>>();
    assert_eq!(bits(&f), bits(&reference));
}

// ---- Model Exchange (FMI 2.0.4 §3.2.3) ----

/// The states of a Model Exchange instance; "Error" is entered twice in the test, from Event
/// Mode (a simulation to read) and before initialization (none yet).
const ME_PHASES: [&str; 6] = [
    "Instantiated",
    "InitializationMode",
    "EventMode",
    "ContinuousTimeMode",
    "Terminated",
    "Error",
];

/// The states in which the table is checked: the six above, and Error entered from
/// Instantiated, with the legality of Error.
const ME_COLUMNS: [(&str, usize); 7] = [
    ("Instantiated", 0),
    ("InitializationMode", 1),
    ("EventMode", 2),
    ("ContinuousTimeMode", 3),
    ("Terminated", 4),
    ("Error", 5),
    ("Error before initialization", 5),
];

/// The continuous states of `model` the table's fmi2SetContinuousStates sets, and the donor's
/// states (a web span's tension 30 N).
fn table_states(model: usize) -> Vec<f64> {
    states(model, [1e-4, 0.2, -1e-4, 0.1], 30.0)
}

fn in_me_phase(model: usize, phase: &str) -> Fmu {
    match phase {
        "Instantiated" => Fmu::new_model_exchange(model),
        "InitializationMode" => {
            let f = Fmu::new_model_exchange(model);
            assert_eq!(fmi2EnterInitializationMode(f.c), OK);
            f
        }
        "EventMode" => Fmu::me_initialized(model, None),
        "ContinuousTimeMode" => Fmu::me_continuous(model),
        "Terminated" => {
            let f = Fmu::me_continuous(model);
            assert_eq!(fmi2Terminate(f.c), OK);
            f
        }
        "Error" => {
            let f = Fmu::me_initialized(model, None);
            assert_eq!(fmi2EnterInitializationMode(f.c), ERROR);
            f
        }
        "Error before initialization" => {
            let f = Fmu::new_model_exchange(model);
            assert_eq!(fmi2ExitInitializationMode(f.c), ERROR);
            f
        }
        _ => unreachable!("{phase}"),
    }
}

/// What a legal call must have done, checked right after it with further calls.
type Effect = fn(&Fmu, &str);

/// A call of one function on the instance passed, with valid arguments for its model.
type MeCall = fn(&Fmu) -> fmi2Status;

struct MeCase {
    name: &'static str,
    call: MeCall,
    /// Legal in [Instantiated, InitializationMode, EventMode, ContinuousTimeMode, Terminated, Error].
    legal: [bool; 6],
    when_legal: fmi2Status,
    effect: Option<Effect>,
}

/// An ME instance of `model` in Continuous-Time Mode at t = 0.3 with the states
/// [`table_states`]: the source of the FMU state the table's fmi2SetFMUstate loads.
fn me_donor(model: usize) -> Fmu {
    let donor = Fmu::me_continuous(model);
    assert_eq!(fmi2SetTime(donor.c, 0.3), OK);
    assert_eq!(donor.set_continuous_states(&table_states(model)), OK);
    donor
}

fn bits(x: &[f64]) -> Vec<u64> {
    x.iter().map(|x| x.to_bits()).collect()
}

/// The variables `name_of` each state variable of `f`'s model (itself, or its derivative), read
/// one by one by name, in the order of the continuous states.
fn read_by_name(f: &Fmu, name_of: fn(&str) -> String) -> Vec<f64> {
    state_names(f.model_index())
        .iter()
        .map(|state| f.get_real(&name_of(state)).1)
        .collect()
}

/// The Model Exchange table of FMI 2.0.4 §3.2.3 ("x": the call is allowed in that state), one
/// row per function in the order of [`table`], with the effect a legal call must have.
#[rustfmt::skip]
fn me_table() -> Vec<MeCase> {
    const ALL: [bool; 6] = [true; 6];
    const NONE: [bool; 6] = [false; 6];
    // I, M, V (Event Mode), N (Continuous-Time Mode), T, E.
    const I: [bool; 6] = [true, false, false, false, false, false];
    const M: [bool; 6] = [false, true, false, false, false, false];
    const V: [bool; 6] = [false, false, true, false, false, false];
    const N: [bool; 6] = [false, false, false, true, false, false];
    const V_N: [bool; 6] = [false, false, true, true, false, false];
    const READ: [bool; 6] = [false, true, true, true, true, true];
    fn case(name: &'static str, call: MeCall, legal: [bool; 6], when_legal: fmi2Status, effect: Option<Effect>) -> MeCase {
        MeCase { name, call, legal, when_legal, effect }
    }
    // SAFETY (every entry): pointers to locals or statics of the announced length.
    unsafe {
        vec![
            case("fmi2SetDebugLogging", |f| fmi2SetDebugLogging(f.c, 1, 1, [c"logCalls".as_ptr()].as_ptr()), ALL, OK, None),
            // Start time 0.5: an earlier time is refused afterwards.
            case("fmi2SetupExperiment", |f| fmi2SetupExperiment(f.c, 1, 1e-6, 0.5, 1, 10.0), I, OK, Some(|f, _| {
                assert_eq!(fmi2EnterInitializationMode(f.c), OK);
                assert_eq!(fmi2ExitInitializationMode(f.c), OK);
                assert_eq!(fmi2EnterContinuousTimeMode(f.c), OK);
                f.refuses("start time 0.5", |c| fmi2SetTime(c, 0.25));
            })),
            case("fmi2EnterInitializationMode", |f| fmi2EnterInitializationMode(f.c), I, OK, Some(|f, _| {
                assert_eq!(f.get_real("theta_m"), (OK, 0.0));
                f.refuses("not allowed in state InitializationMode", |c| fmi2EnterEventMode(c));
            })),
            case("fmi2ExitInitializationMode", |f| fmi2ExitInitializationMode(f.c), M, OK, Some(|f, _| {
                // Event Mode: the event iteration, then Continuous-Time Mode.
                let mut info = event_info();
                assert_eq!(fmi2NewDiscreteStates(f.c, &mut info), OK);
                assert_eq!(info.newDiscreteStatesNeeded, fmi2False);
                assert_eq!(fmi2EnterContinuousTimeMode(f.c), OK);
                assert_eq!(fmi2CompletedIntegratorStep(f.c, 1, &mut 1, &mut 1), OK);
            })),
            case("fmi2Terminate", |f| fmi2Terminate(f.c), V_N, OK, Some(|f, _| {
                f.assert_all_finite("after fmi2Terminate");
                assert_eq!(f.derivatives().0, OK);
                f.refuses("not allowed in state Terminated", |c| fmi2EnterEventMode(c));
            })),
            case("fmi2Reset", |f| fmi2Reset(f.c), ALL, OK, Some(|f, _| {
                f.refuses("not allowed in state Instantiated", |c| fmi2GetReal(c, [f.vr("theta_m")].as_ptr(), 1, [0.0].as_mut_ptr()));
                f.reset_and_check();
            })),
            case("fmi2GetReal", |f| fmi2GetReal(f.c, [f.vr("theta_m")].as_ptr(), 1, [0.0].as_mut_ptr()), READ, OK, Some(|f, _| {
                f.assert_all_finite("fmi2GetReal of every variable");
            })),
            case("fmi2GetInteger", |f| fmi2GetInteger(f.c, [f.vr("contact")].as_ptr(), 1, [0].as_mut_ptr()), READ, OK, None),
            case("fmi2GetBoolean", |f| fmi2GetBoolean(f.c, null(), 0, null_mut()), READ, OK, None),
            case("fmi2GetString", |f| fmi2GetString(f.c, null(), 0, null_mut()), READ, OK, None),
            case("fmi2SetReal", |f| fmi2SetReal(f.c, [f.vr("tau_m")].as_ptr(), 1, [0.5].as_ptr()), [true, true, true, true, false, false], OK, Some(|f, phase| {
                if phase == "Instantiated" {
                    assert_eq!(fmi2EnterInitializationMode(f.c), OK);
                }
                assert_eq!(f.get_real("tau_m"), (OK, 0.5));
                // der(omega_m) = (tau_m - b_m omega_m - psi) / J_m, from rest at theta = 0.
                // (0.5 − b_m·0 − 0)/J_m: the FMU's division of the same numbers, the rest exact zeros.
                assert_eq!(f.get_real("der(omega_m)"), (OK, 0.5 / f.get_real("J_m").1));
            })),
            case("fmi2SetInteger", |f| fmi2SetInteger(f.c, null(), 0, null()), [true, true, true, false, false, false], OK, None),
            case("fmi2SetBoolean", |f| fmi2SetBoolean(f.c, null(), 0, null()), [true, true, true, false, false, false], OK, None),
            case("fmi2SetString", |f| fmi2SetString(f.c, null(), 0, null()), [true, true, true, false, false, false], OK, None),
            case("fmi2GetFMUstate", |f| {
                let mut s = null_mut();
                let status = fmi2GetFMUstate(f.c, &mut s);
                fmi2FreeFMUstate(f.c, &mut s);
                status
            }, ALL, OK, None),
            case("fmi2SetFMUstate", |f| {
                let donor = me_donor(f.model_index());
                let mut s = null_mut();
                assert_eq!(fmi2GetFMUstate(donor.c, &mut s), OK);
                fmi2SetFMUstate(f.c, s)
            }, ALL, OK, Some(|f, _| {
                // Now the donor's: Continuous-Time Mode with its states.
                assert_eq!(f.continuous_states(), (OK, table_states(f.model_index())));
                assert_eq!(fmi2CompletedIntegratorStep(f.c, 1, &mut 1, &mut 1), OK);
                let donor = me_donor(f.model_index());
                // The same bound state advanced to the same time by the same code.
                assert_eq!(f.get_real("bound"), donor.get_real("bound"));
            })),
            case("fmi2FreeFMUstate", |f| {
                let donor = Fmu::new_model_exchange(f.model_index());
                let mut s = null_mut();
                assert_eq!(fmi2GetFMUstate(donor.c, &mut s), OK);
                fmi2FreeFMUstate(f.c, &mut s)
            }, ALL, OK, None),
            case("fmi2SerializedFMUstateSize", |f| {
                let donor = Fmu::new_model_exchange(f.model_index());
                let mut s = null_mut();
                assert_eq!(fmi2GetFMUstate(donor.c, &mut s), OK);
                fmi2SerializedFMUstateSize(f.c, s, &mut 0)
            }, ALL, OK, None),
            case("fmi2SerializeFMUstate", |f| {
                let donor = Fmu::new_model_exchange(f.model_index());
                let mut s = null_mut();
                assert_eq!(fmi2GetFMUstate(donor.c, &mut s), OK);
                fmi2SerializeFMUstate(f.c, s, [0; 4096].as_mut_ptr(), 4096)
            }, ALL, OK, None),
            case("fmi2DeSerializeFMUstate", |f| {
                let bytes = serialized(&me_donor(f.model_index()));
                fmi2DeSerializeFMUstate(f.c, bytes.as_ptr().cast(), bytes.len(), &mut null_mut())
            }, ALL, OK, None),
            case("fmi2GetDirectionalDerivative", |f| {
                fmi2GetDirectionalDerivative(f.c, [f.vr("der(omega_m)")].as_ptr(), 1, [f.vr("tau_m")].as_ptr(), 1, [1.0].as_ptr(), [0.0].as_mut_ptr())
            }, READ, OK, Some(|f, _| {
                // d der(omega_m) / d tau_m = 1/J_m in every mode.
                let mut dv = [f64::NAN];
                let s = fmi2GetDirectionalDerivative(f.c, [f.vr("der(omega_m)")].as_ptr(), 1, [f.vr("tau_m")].as_ptr(), 1, [2.0].as_ptr(), dv.as_mut_ptr());
                assert_eq!(s, OK);
                // The FMU's (1/J_m)·2 equals 2/J_m exactly: scaling by a power of two commutes with
                // rounding.
                assert_eq!(dv[0], 2.0 / f.get_real("J_m").1);
            })),
            case("fmi2SetRealInputDerivatives", |f| {
                fmi2SetRealInputDerivatives(f.c, [f.vr("tau_m")].as_ptr(), 1, [1].as_ptr(), [0.5].as_ptr())
            }, NONE, OK, None),
            case("fmi2GetRealOutputDerivatives", |f| {
                fmi2GetRealOutputDerivatives(f.c, [f.vr("omega_m")].as_ptr(), 1, [1].as_ptr(), [0.0].as_mut_ptr())
            }, NONE, OK, None),
            case("fmi2DoStep", |f| fmi2DoStep(f.c, 0.0, 1e-3, 1), NONE, OK, None),
            case("fmi2CancelStep", |f| fmi2CancelStep(f.c), NONE, OK, None),
            case("fmi2GetStatus", |f| fmi2GetStatus(f.c, fmi2DoStepStatus, &mut fmi2Status::fmi2Error), NONE, OK, None),
            case("fmi2GetRealStatus", |f| fmi2GetRealStatus(f.c, fmi2LastSuccessfulTime, &mut 0.0), NONE, OK, None),
            case("fmi2GetIntegerStatus", |f| fmi2GetIntegerStatus(f.c, fmi2DoStepStatus, &mut 0), NONE, OK, None),
            case("fmi2GetBooleanStatus", |f| fmi2GetBooleanStatus(f.c, fmi2Terminated, &mut 0), NONE, OK, None),
            case("fmi2GetStringStatus", |f| fmi2GetStringStatus(f.c, fmi2PendingStatus, &mut null()), NONE, OK, None),
            case("fmi2EnterEventMode", |f| fmi2EnterEventMode(f.c), V_N, OK, Some(|f, _| {
                let mut info = event_info();
                assert_eq!(fmi2NewDiscreteStates(f.c, &mut info), OK);
                let x = table_states(f.model_index());
                f.refuses("not allowed in state EventMode", |c| fmi2SetContinuousStates(c, x.as_ptr(), x.len()));
            })),
            case("fmi2NewDiscreteStates", |f| {
                let mut info = event_info();
                let s = fmi2NewDiscreteStates(f.c, &mut info);
                if s == OK {
                    // No discrete states, no time events: nothing to iterate, nothing changed.
                    assert_eq!(
                        [info.newDiscreteStatesNeeded, info.terminateSimulation, info.nominalsOfContinuousStatesChanged,
                         info.valuesOfContinuousStatesChanged, info.nextEventTimeDefined],
                        [fmi2False; 5]
                    );
                }
                s
            }, V, OK, None),
            case("fmi2EnterContinuousTimeMode", |f| fmi2EnterContinuousTimeMode(f.c), V, OK, Some(|f, _| {
                assert_eq!(f.set_continuous_states(&table_states(f.model_index())), OK);
                f.refuses("not allowed in state ContinuousTimeMode", |c| fmi2NewDiscreteStates(c, &mut event_info()));
            })),
            case("fmi2CompletedIntegratorStep", |f| {
                let (mut enter, mut terminate) = (fmi2True, fmi2True);
                let s = fmi2CompletedIntegratorStep(f.c, 1, &mut enter, &mut terminate);
                if s == OK {
                    assert_eq!((enter, terminate), (fmi2False, fmi2False));
                }
                s
            }, N, OK, None),
            // Event Mode: condition 8, "only for a Pure Discrete-Time FMU"; this one has states.
            case("fmi2SetTime", |f| fmi2SetTime(f.c, 0.3), N, OK, Some(|f, _| {
                // The bounds follow time: those of an instance set to 0.3, not those at 0 (= 0).
                let (s, bound) = f.get_real("bound");
                assert_eq!(s, OK);
                assert!(bound > 0.0);
                // Both bring the bound from the start to 0.3 by the same advance.
                assert_eq!(bound.to_bits(), me_donor(f.model_index()).get_real("bound").1.to_bits());
            })),
            case("fmi2SetContinuousStates", |f| {
                let x = table_states(f.model_index());
                fmi2SetContinuousStates(f.c, x.as_ptr(), x.len())
            }, N, OK, Some(|f, _| {
                let x = table_states(f.model_index());
                assert_eq!(bits(&f.continuous_states().1), bits(&x));
                assert_eq!(bits(&read_by_name(f, |state| state.to_string())), bits(&x));
                // theta' = omega.
                let (s, dx) = f.derivatives();
                assert_eq!(s, OK);
                assert_eq!((dx[0], dx[2]), (x[1], x[3]));
            })),
            // The table: "x" in Initialization Mode too (the row of fmi2GetEventIndicators alike).
            case("fmi2GetDerivatives", |f| fmi2GetDerivatives(f.c, vec![0.0; f.nx()].as_mut_ptr(), f.nx()), [false, true, true, true, true, true], OK, Some(|f, _| {
                let (s, dx) = f.derivatives();
                assert_eq!(s, OK);
                assert_eq!(bits(&dx), bits(&read_by_name(f, |state| format!("der({state})"))));
            })),
            case("fmi2GetEventIndicators", |f| fmi2GetEventIndicators(f.c, vec![0.0; f.ni()].as_mut_ptr(), f.ni()), READ, OK, Some(|f, _| {
                // [u - g, u + g] with u = r_m theta_m - r_L theta_L, and g > 0 (a gearbox's first
                // stage: u_1 = theta_m - n_1 theta_i).
                let (s, z) = f.event_indicators();
                assert_eq!(s, OK);
                let u = match f.model.is_geared() {
                    true => f.get_real("theta_m").1 - f.get_value("n_1").1 * f.get_real("theta_i").1,
                    false => {
                        let (r_m, r_l) = transmission(f.model, |name| f.get_value(name).1);
                        r_m * f.get_real("theta_m").1 - r_l * f.get_real("theta_L").1
                    }
                };
                assert!(z[0] < z[1], "{z:?}");
                assert!(((z[0] + z[1]) / 2.0 - u).abs() <= 1e-15, "{z:?}, u = {u}");
            })),
            case("fmi2GetContinuousStates", |f| fmi2GetContinuousStates(f.c, vec![0.0; f.nx()].as_mut_ptr(), f.nx()), READ, OK, Some(|f, _| {
                let (s, x) = f.continuous_states();
                assert_eq!(s, OK);
                assert_eq!(bits(&x), bits(&read_by_name(f, |state| state.to_string())));
            })),
            // The table: "x" in every state but before instantiation (and 7 in Error).
            case("fmi2GetNominalsOfContinuousStates", |f| fmi2GetNominalsOfContinuousStates(f.c, vec![0.0; f.nx()].as_mut_ptr(), f.nx()), [true, true, true, true, true, true], OK, Some(|f, _| {
                let (s, n) = f.nominals();
                assert_eq!(s, OK);
                assert!(n.iter().all(|x| x.is_finite() && *x > 0.0), "{n:?}");
            })),
        ]
    }
}

/// Model Exchange: the plants only (the controller has no Model Exchange, refused at instantiation).
#[test]
fn every_call_in_every_model_exchange_state_follows_the_standard_table() {
    let table = me_table();
    assert_eq!(table.len(), 40, "every FMI 2.0 function that takes an instance");
    let names: Vec<_> = table.iter().map(|c| c.name).collect();
    let cs_names: Vec<_> = self::table().iter().map(|c| c.0).collect();
    assert_eq!(names, cs_names, "the same functions as the Co-Simulation table");
    let mut checked = 0;
    let mut effects = 0;
    for (model, case) in (0..MODELS.len()).flat_map(|model| table.iter().map(move |case| (model, case))) {
        let co_simulation = case.legal == [false; 6];
        for (phase, column) in ME_COLUMNS {
            let legal = case.legal[column];
            let f = in_me_phase(model, phase);
            let before = f.log_len();
            let status = (case.call)(&f);
            let context = format!(
                "{} in {phase} (Model Exchange, {})",
                case.name, MODELS[model].identifier
            );
            if legal {
                assert_eq!(status, case.when_legal, "{context}: {:?}", f.entries().get(before..));
                assert!(
                    f.entries()[before..].iter().all(|e| e.category != "logErrors"),
                    "{context}: {:?}",
                    &f.entries()[before..]
                );
                if let Some(effect) = case.effect {
                    effect(&f, phase);
                    effects += 1;
                }
            } else {
                let reason = if co_simulation {
                    format!(
                        "{} belongs to FMI for Co-Simulation; this instance was instantiated for Model Exchange",
                        case.name
                    )
                } else {
                    format!("{} is not allowed in state {}", case.name, ME_PHASES[column])
                };
                f.assert_refused(status, before, &reason);
                assert_eq!(status, ERROR, "{context}");
                // Now in state Error: a call legal only in Instantiated says so.
                f.refuses("not allowed in state Error", |c| fmi2EnterInitializationMode(c));
                // The values stay readable (for debugging) and finite.
                f.assert_all_finite(&format!("{context}, then in state Error"));
            }
            checked += 1;
        }
    }
    assert_eq!(checked, 280 * MODELS.len());
    // Every legal call with an effect to check was checked in every state it is legal in.
    let expected: usize = table
        .iter()
        .filter(|c| c.effect.is_some())
        .map(|c| ME_COLUMNS.iter().filter(|(_, k)| c.legal[*k]).count())
        .sum();
    assert_eq!(effects, expected * MODELS.len());
    assert!(expected > 60, "{expected}");
    fresh_instances_of_every_model_work();
}

/// Model Exchange: the plants only (the controller has no Model Exchange, refused at instantiation).
#[test]
fn model_exchange_instances_move_through_their_states_as_the_standard_draws_them() {
    for model in 0..MODELS.len() {
        let f = Fmu::new_model_exchange(model);
        // Instantiated -> InitializationMode -> EventMode.
        assert_eq!(fmi2SetupExperiment(f.c, 0, 0.0, 0.0, 0, 0.0), OK);
        assert_eq!(fmi2EnterInitializationMode(f.c), OK);
        assert_eq!(fmi2ExitInitializationMode(f.c), OK);
        // EventMode <-> ContinuousTimeMode, many times, with time moving forwards and, within
        // the last integrator step, backwards.
        for k in 0..5 {
            let mut info = event_info();
            // SAFETY: pointer to a local.
            assert_eq!(unsafe { fmi2NewDiscreteStates(f.c, &mut info) }, OK);
            assert_eq!(fmi2EnterContinuousTimeMode(f.c), OK);
            assert_eq!(fmi2SetTime(f.c, 0.1 * k as f64 + 0.05), OK);
            // SAFETY: pointers to locals.
            assert_eq!(unsafe { fmi2CompletedIntegratorStep(f.c, 1, &mut 1, &mut 1) }, OK);
            assert_eq!(fmi2SetTime(f.c, 0.1 * k as f64 + 0.02), OK, "back within the step");
            assert_eq!(fmi2SetTime(f.c, 0.1 * k as f64 + 0.05), OK);
            let x: Vec<f64> = table_states(model).iter().map(|x| x * k as f64).collect();
            assert_eq!(f.set_continuous_states(&x), OK);
            assert_eq!(f.set_real("tau_L", k as f64), OK, "an input in Continuous-Time Mode");
            f.assert_all_finite(&format!("round {k}"));
            // Event Mode is entered from Continuous-Time Mode and from Event Mode itself.
            assert_eq!(fmi2EnterEventMode(f.c), OK);
            assert_eq!(fmi2EnterEventMode(f.c), OK);
        }
        // Terminate from Event Mode; from Continuous-Time Mode it is covered by the table.
        assert_eq!(fmi2Terminate(f.c), OK);
        f.assert_all_finite("Terminated");
        f.refuses("not allowed in state Terminated", |c| fmi2Terminate(c));
        // Reset leads back to Instantiated, from which everything starts again.
        f.reset_and_check();
    }
}

/// The rules of FMI 2.0.4 on time and states that the state table does not show, on every
/// model, each with its sentence (Model Exchange: the plants only; the controller has none).
#[test]
fn model_exchange_time_and_states_follow_the_text_beside_the_table() {
    for model in 0..MODELS.len() {
        // §3.2.2: "After fmi2CompletedIntegratorStep is called, it is still allowed to go back in
        // time (calling fmi2SetTime) [...]. However, it is not allowed to go back in time over the
        // previous fmi2CompletedIntegratorStep or the previous fmi2EnterEventMode call."
        let completed = |f: &Fmu, t: f64| {
            assert_eq!(fmi2SetTime(f.c, t), OK);
            // SAFETY: pointers to locals.
            assert_eq!(unsafe { fmi2CompletedIntegratorStep(f.c, 1, &mut 1, &mut 1) }, OK);
        };
        let f = Fmu::me_continuous(model);
        completed(&f, 0.01);
        completed(&f, 0.02);
        assert_eq!(fmi2SetTime(f.c, 0.015), OK, "back within the last step");
        assert_eq!(fmi2SetTime(f.c, 0.01), OK, "back to the previous step");
        f.refuses(
            "time 0.005 is before 0.01, the time of the second-last completed integrator step: FMI 2.0.4 §3.2.2",
            |c| fmi2SetTime(c, 0.005),
        );
        f.reset_and_check();
        // §3.2.3: "As soon as an event occurred (fmi2EnterEventMode was called), going back in
        // time is forbidden".
        let f = Fmu::me_continuous(model);
        assert_eq!(fmi2SetTime(f.c, 0.04), OK);
        assert_eq!(fmi2EnterEventMode(f.c), OK);
        // SAFETY: pointer to a local.
        assert_eq!(unsafe { fmi2NewDiscreteStates(f.c, &mut event_info()) }, OK);
        assert_eq!(fmi2EnterContinuousTimeMode(f.c), OK);
        assert_eq!(fmi2SetTime(f.c, 0.04), OK, "the event's time itself");
        f.refuses("time 0.03 is before 0.04, the time of the last event", |c| {
            fmi2SetTime(c, 0.03)
        });
        f.reset_and_check();
        // The table, fmi2SetTime in Event Mode, condition 8: "only for a Pure Discrete-Time FMU".
        let f = Fmu::me_initialized(model, None);
        f.refuses("only for a Pure Discrete-Time FMU", |c| fmi2SetTime(c, 0.0));
        f.reset_and_check();
        // An FMU state keeps how far back the time may go: restored after a step at 0.02 it
        // refuses 0.005 again, and a state from before the steps allows it.
        let f = Fmu::me_continuous(model);
        let early = serialized(&f);
        completed(&f, 0.01);
        completed(&f, 0.02);
        let late = serialized(&f);
        assert_eq!(load(&f, &early), (OK, OK));
        assert_eq!(fmi2SetTime(f.c, 0.005), OK, "before any completed step");
        assert_eq!(load(&f, &late), (OK, OK));
        f.refuses("time 0.005 is before 0.01", |c| fmi2SetTime(c, 0.005));
        f.reset_and_check();
        // Condition 5, fmi2SetReal in Continuous-Time Mode: "for a variable with causality =
        // "input" and variability = "continuous", and for a continuous-time state variable"; in
        // Event Mode (condition 4) inputs and tunable parameters only.
        let (by_name, by_vector) = (Fmu::me_continuous(model), Fmu::me_continuous(model));
        let mut x = by_vector.continuous_states().1;
        x[0] = 2e-4;
        assert_eq!(by_name.set_real("theta_m", 2e-4), OK);
        assert_eq!(by_vector.set_continuous_states(&x), OK);
        assert_eq!(bits(&by_name.continuous_states().1), bits(&x));
        assert_eq!(bits(&by_name.derivatives().1), bits(&by_vector.derivatives().1));
        assert_eq!(by_name.event_indicators(), by_vector.event_indicators());
        let events = Fmu::me_initialized(model, None);
        events.refuses("condition 4", |_| events.set_real("theta_m", 2e-4));
    }
    fresh_instances_of_every_model_work();
}

#[test]
fn calls_of_the_other_interface_are_refused_with_the_reason() {
    // fmi2DoStep on a Model Exchange instance, fmi2SetTime on a Co-Simulation one, in the state
    // where the call would be legal for its own interface.
    let me = Fmu::me_continuous(BELT);
    me.refuses(
        "fmi2DoStep belongs to FMI for Co-Simulation; this instance was instantiated for Model Exchange",
        |c| fmi2DoStep(c, 0.0, 1e-3, 1),
    );
    me.reset_and_check();
    let cs = Fmu::initialized(BELT, None);
    cs.refuses(
        "fmi2SetTime belongs to FMI for Model Exchange; this instance was instantiated for Co-Simulation",
        |c| fmi2SetTime(c, 0.0),
    );
    cs.reset_and_check();
    // The controller, Co-Simulation only, alike (each function of the other interface in every
    // state: the table above).
    let pi = Fmu::initialized(CONTROLLER, None);
    pi.refuses_changing_nothing(
        "fmi2SetTime belongs to FMI for Model Exchange; this instance was instantiated for Co-Simulation",
        |c| fmi2SetTime(c, 0.0),
    );
    pi.reset_and_check();
    // FMU states do not cross interfaces either (the refusal changes nothing but the state).
    let me = Fmu::me_continuous(BELT);
    let cs = Fmu::initialized(BELT, None);
    let from_me = serialized(&me);
    let from_cs = serialized(&cs);
    let refused = |f: &Fmu, bytes: &[u8], reason: &str| {
        let mut s = null_mut();
        // SAFETY: `bytes` has the announced length; `s` is a local.
        assert_eq!(
            unsafe { fmi2DeSerializeFMUstate(f.c, bytes.as_ptr().cast(), bytes.len(), &mut s) },
            OK
        );
        f.refuses(reason, |c| fmi2SetFMUstate(c, s));
    };
    refused(
        &me,
        &from_cs,
        "it was taken from a Co-Simulation instance; this instance serves Model Exchange",
    );
    refused(
        &cs,
        &from_me,
        "it was taken from a Model Exchange instance; this instance serves Co-Simulation",
    );
    me.reset_and_check();
    cs.reset_and_check();
}

/// Model Exchange: the plants only (the controller has no Model Exchange, refused at instantiation).
#[test]
fn a_model_exchange_instance_can_be_freed_in_every_state_and_is_gone_after() {
    for (phase, _) in ME_COLUMNS {
        let f = in_me_phase(BELT, phase);
        let c = f.c;
        let mut s = null_mut();
        // SAFETY: pointer to a local.
        assert_eq!(unsafe { fmi2GetFMUstate(c, &mut s) }, OK);
        drop(f);
        assert_eq!(fmi2Reset(c), ERROR, "{phase}: a freed instance answered");
        assert_eq!(fmi2SetTime(c, 0.0), ERROR, "{phase}: a freed instance answered");
        let other = Fmu::new_model_exchange(BELT);
        other.refuses("not a live FMU state", |o| fmi2SetFMUstate(o, s));
    }
    fresh_me_instance_works(BELT);
}

/// Model Exchange: the plants only (the controller has no Model Exchange, refused at instantiation).
#[test]
fn model_exchange_error_is_left_only_by_reset_or_an_fmu_state() {
    let f = in_me_phase(SHAFT, "Error");
    f.refuses("not allowed in state Error", |c| fmi2EnterEventMode(c));
    f.refuses("not allowed in state Error", |c| fmi2SetTime(c, 0.0));
    f.reset_and_check();
    // An FMU state saved in Continuous-Time Mode continues from there, bit for bit.
    let x = table_states(SHAFT);
    let f = Fmu::me_continuous(SHAFT);
    assert_eq!(fmi2SetTime(f.c, 0.2), OK);
    assert_eq!(f.set_continuous_states(&x), OK);
    let saved = serialized(&f);
    f.refuses("not allowed in state ContinuousTimeMode", |c| {
        fmi2ExitInitializationMode(c)
    });
    // SAFETY: x.len() values.
    f.refuses("not allowed in state Error", |c| unsafe {
        fmi2SetContinuousStates(c, x.as_ptr(), x.len())
    });
    assert_eq!(load(&f, &saved), (OK, OK));
    assert_eq!(f.continuous_states(), (OK, x.clone()));
    let reference = Fmu::me_continuous(SHAFT);
    assert_eq!(fmi2SetTime(reference.c, 0.2), OK);
    assert_eq!(reference.set_continuous_states(&x), OK);
    for g in [&f, &reference] {
        assert_eq!(fmi2SetTime(g.c, 0.25), OK);
        assert_eq!(
            g.set_continuous_states(&x.iter().map(|x| 2.0 * x).collect::<Vec<_>>()),
            OK
        );
        g.assert_all_finite("after leaving Error through an FMU state");
    }
    let values = |f: &Fmu| f.all_values().1.iter().map(|(_, x)| x.to_bits()).collect::<Vec<_>>();
    assert_eq!(values(&f), values(&reference));
    assert_eq!(f.derivatives(), reference.derivatives());
}

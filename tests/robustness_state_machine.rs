//! Every C function in every state of the FMI 2.0 Co-Simulation state machine, through the C
//! ABI, against the standard's table of allowed calls (FMI 2.0.4 §4.2.4) written out here
//! independently of `src/fmu/state_machine.rs`. StepFailed, which this FMU never enters by
//! itself, is reached through an FMU state. An illegal call must return fmi2Error, log
//! "not allowed in state X" and leave the instance in state Error; a legal one must do its
//! work.
#![cfg(all(target_os = "linux", any(target_arch = "x86_64", target_arch = "aarch64")))]

mod robustness_common;

use backlash_fmu::ffi::*;
use backlash_fmu::fmu::MODELS;
use robustness_common::*;
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

type Call = fn(fmi2Component) -> fmi2Status;

fn vr(name: &str) -> [u32; 1] {
    [MODELS[0].vr(name)]
}

/// (function, call with valid arguments, legal in [I, M, C, F, T, E], status when legal).
/// The masks are the "x" columns of the Co-Simulation table of FMI 2.0.4 §4.2.4; StepInProgress
/// and StepCanceled are never entered by a synchronous FMU.
#[rustfmt::skip]
fn table() -> Vec<(&'static str, Call, [bool; 6], fmi2Status)> {
    const ALL: [bool; 6] = [true; 6];
    const NONE: [bool; 6] = [false; 6];
    // SAFETY (every entry): pointers to locals or statics of the announced length.
    unsafe {
        vec![
            ("fmi2SetDebugLogging", |c| fmi2SetDebugLogging(c, 1, 1, [c"logCalls".as_ptr()].as_ptr()), ALL, OK),
            ("fmi2SetupExperiment", |c| fmi2SetupExperiment(c, 1, 1e-6, 0.0, 1, 10.0), [true, false, false, false, false, false], OK),
            ("fmi2EnterInitializationMode", |c| fmi2EnterInitializationMode(c), [true, false, false, false, false, false], OK),
            ("fmi2ExitInitializationMode", |c| fmi2ExitInitializationMode(c), [false, true, false, false, false, false], OK),
            ("fmi2Terminate", |c| fmi2Terminate(c), [false, false, true, true, false, false], OK),
            ("fmi2Reset", |c| fmi2Reset(c), ALL, OK),
            ("fmi2GetReal", |c| fmi2GetReal(c, vr("theta_m").as_ptr(), 1, [0.0].as_mut_ptr()), [false, true, true, true, true, true], OK),
            ("fmi2GetInteger", |c| fmi2GetInteger(c, vr("contact").as_ptr(), 1, [0].as_mut_ptr()), [false, true, true, true, true, true], OK),
            ("fmi2GetBoolean", |c| fmi2GetBoolean(c, null(), 0, null_mut()), [false, true, true, true, true, true], OK),
            ("fmi2GetString", |c| fmi2GetString(c, null(), 0, null_mut()), [false, true, true, true, true, true], OK),
            ("fmi2SetReal", |c| fmi2SetReal(c, vr("tau_m").as_ptr(), 1, [0.5].as_ptr()), [true, true, true, false, false, false], OK),
            ("fmi2SetInteger", |c| fmi2SetInteger(c, null(), 0, null()), [true, true, true, false, false, false], OK),
            ("fmi2SetBoolean", |c| fmi2SetBoolean(c, null(), 0, null()), [true, true, true, false, false, false], OK),
            ("fmi2SetString", |c| fmi2SetString(c, null(), 0, null()), [true, true, true, false, false, false], OK),
            ("fmi2GetFMUstate", |c| {
                let mut s = null_mut();
                let status = fmi2GetFMUstate(c, &mut s);
                fmi2FreeFMUstate(c, &mut s);
                status
            }, ALL, OK),
            ("fmi2SetFMUstate", |c| {
                // A state of the same model taken from another instance in StepComplete.
                let donor = Fmu::initialized(0, None);
                let mut s = null_mut();
                assert_eq!(fmi2GetFMUstate(donor.c, &mut s), OK);
                fmi2SetFMUstate(c, s)
            }, ALL, OK),
            ("fmi2FreeFMUstate", |c| {
                let donor = Fmu::new(0);
                let mut s = null_mut();
                assert_eq!(fmi2GetFMUstate(donor.c, &mut s), OK);
                fmi2FreeFMUstate(c, &mut s)
            }, ALL, OK),
            ("fmi2SerializedFMUstateSize", |c| {
                let donor = Fmu::new(0);
                let mut s = null_mut();
                assert_eq!(fmi2GetFMUstate(donor.c, &mut s), OK);
                fmi2SerializedFMUstateSize(c, s, &mut 0)
            }, ALL, OK),
            ("fmi2SerializeFMUstate", |c| {
                let donor = Fmu::new(0);
                let mut s = null_mut();
                assert_eq!(fmi2GetFMUstate(donor.c, &mut s), OK);
                fmi2SerializeFMUstate(c, s, [0; 4096].as_mut_ptr(), 4096)
            }, ALL, OK),
            ("fmi2DeSerializeFMUstate", |c| {
                let bytes = serialized(&Fmu::new(0));
                fmi2DeSerializeFMUstate(c, bytes.as_ptr().cast(), bytes.len(), &mut null_mut())
            }, ALL, OK),
            ("fmi2GetDirectionalDerivative", |c| {
                fmi2GetDirectionalDerivative(c, vr("omega_m").as_ptr(), 1, vr("tau_m").as_ptr(), 1, [1.0].as_ptr(), [0.0].as_mut_ptr())
            }, [false, true, true, true, true, true], ERROR),
            ("fmi2SetRealInputDerivatives", |c| {
                fmi2SetRealInputDerivatives(c, vr("tau_m").as_ptr(), 1, [1].as_ptr(), [0.5].as_ptr())
            }, [true, true, true, false, false, false], OK),
            ("fmi2GetRealOutputDerivatives", |c| {
                fmi2GetRealOutputDerivatives(c, vr("omega_m").as_ptr(), 1, [1].as_ptr(), [0.0].as_mut_ptr())
            }, [false, false, true, true, true, true], OK),
            ("fmi2DoStep", |c| fmi2DoStep(c, 0.0, 1e-3, 1), [false, false, true, false, false, false], OK),
            ("fmi2CancelStep", |c| fmi2CancelStep(c), NONE, OK),
            ("fmi2GetStatus", |c| fmi2GetStatus(c, fmi2DoStepStatus, &mut fmi2Status::fmi2Error), [false, false, true, true, true, false], OK),
            ("fmi2GetRealStatus", |c| fmi2GetRealStatus(c, fmi2LastSuccessfulTime, &mut 0.0), [false, false, true, true, true, false], OK),
            ("fmi2GetIntegerStatus", |c| fmi2GetIntegerStatus(c, fmi2DoStepStatus, &mut 0), [false, false, true, true, true, false], DISCARD),
            ("fmi2GetBooleanStatus", |c| fmi2GetBooleanStatus(c, fmi2Terminated, &mut 0), [false, false, true, true, true, false], OK),
            ("fmi2GetStringStatus", |c| fmi2GetStringStatus(c, fmi2PendingStatus, &mut null()), [false, false, true, true, true, false], DISCARD),
            ("fmi2EnterEventMode", |c| fmi2EnterEventMode(c), NONE, OK),
            ("fmi2NewDiscreteStates", |c| fmi2NewDiscreteStates(c, null_mut()), NONE, OK),
            ("fmi2EnterContinuousTimeMode", |c| fmi2EnterContinuousTimeMode(c), NONE, OK),
            ("fmi2CompletedIntegratorStep", |c| fmi2CompletedIntegratorStep(c, 1, &mut 0, &mut 0), NONE, OK),
            ("fmi2SetTime", |c| fmi2SetTime(c, 0.0), NONE, OK),
            ("fmi2SetContinuousStates", |c| fmi2SetContinuousStates(c, [0.0; 4].as_ptr(), 4), NONE, OK),
            ("fmi2GetDerivatives", |c| fmi2GetDerivatives(c, [0.0; 4].as_mut_ptr(), 4), NONE, OK),
            ("fmi2GetEventIndicators", |c| fmi2GetEventIndicators(c, [0.0; 1].as_mut_ptr(), 0), NONE, OK),
            ("fmi2GetContinuousStates", |c| fmi2GetContinuousStates(c, [0.0; 4].as_mut_ptr(), 4), NONE, OK),
            ("fmi2GetNominalsOfContinuousStates", |c| fmi2GetNominalsOfContinuousStates(c, [0.0; 4].as_mut_ptr(), 4), NONE, OK),
        ]
    }
}

#[test]
fn every_call_in_every_state_follows_the_standard_table() {
    let table = table();
    assert_eq!(table.len(), 40, "every FMI 2.0 function that takes an instance");
    let mut checked = 0;
    for (name, call, legal, when_legal) in &table {
        let model_exchange = legal == &[false; 6] && *name != "fmi2CancelStep";
        for (phase, legal) in PHASES.iter().zip(legal) {
            let f = in_phase(0, phase);
            let before = f.log_len();
            let status = call(f.c);
            let context = format!("{name} in {phase}");
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
                    "Model Exchange".to_string()
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
    assert_eq!(checked, 240);
    fresh_instance_works(SHAFT);
}

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
    fresh_instance_works(BELT);
}

#[test]
fn error_is_left_only_by_reset_or_an_fmu_state() {
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
    let bits = |f: &Fmu| f.all_values().1.iter().map(|(_, x)| x.to_bits()).collect::<Vec<_>>();
    assert_eq!(bits(&f), bits(&reference));
}

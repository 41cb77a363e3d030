//! Misuse of every C function's arguments: NULL instances, NULL arrays and out-pointers,
//! unknown or mistyped value references, variables that cannot be set now, non-finite and
//! out-of-range values, bad step sizes and communication points, bad fmi2Instantiate
//! arguments. Each refusal must be fmi2Error/fmi2Discard with its reason logged through the
//! importer's logger, must change nothing, and a fresh instance must work normally after.
#![cfg(all(target_os = "linux", any(target_arch = "x86_64", target_arch = "aarch64")))]

mod robustness_common;

use backlash_fmu::ffi::*;
use backlash_fmu::fmu::MODELS;
use robustness_common::*;
use std::ffi::CString;
use std::ptr::{null, null_mut};

const OK: fmi2Status = fmi2Status::fmi2OK;
const ERROR: fmi2Status = fmi2Status::fmi2Error;

/// Every function that takes an instance, called on `c` with otherwise valid arguments.
fn every_instance_function() -> Vec<(&'static str, Box<dyn Fn(fmi2Component) -> fmi2Status>)> {
    let vr = [MODELS[0].vr("tau_m")];
    let out_vr = [MODELS[0].vr("omega_m")];
    // SAFETY (all closures): every pointer is a live local or static of the announced length.
    unsafe {
        vec![
            (
                "fmi2SetDebugLogging",
                Box::new(|c| fmi2SetDebugLogging(c, 1, 0, null())),
            ),
            (
                "fmi2SetupExperiment",
                Box::new(|c| fmi2SetupExperiment(c, 0, 0.0, 0.0, 0, 0.0)),
            ),
            (
                "fmi2EnterInitializationMode",
                Box::new(|c| fmi2EnterInitializationMode(c)),
            ),
            (
                "fmi2ExitInitializationMode",
                Box::new(|c| fmi2ExitInitializationMode(c)),
            ),
            ("fmi2Terminate", Box::new(|c| fmi2Terminate(c))),
            ("fmi2Reset", Box::new(|c| fmi2Reset(c))),
            (
                "fmi2GetReal",
                Box::new(move |c| fmi2GetReal(c, vr.as_ptr(), 1, [0.0].as_mut_ptr())),
            ),
            (
                "fmi2GetInteger",
                Box::new(move |c| fmi2GetInteger(c, vr.as_ptr(), 1, [0].as_mut_ptr())),
            ),
            (
                "fmi2GetBoolean",
                Box::new(move |c| fmi2GetBoolean(c, vr.as_ptr(), 1, [0].as_mut_ptr())),
            ),
            (
                "fmi2GetString",
                Box::new(move |c| fmi2GetString(c, vr.as_ptr(), 1, [null()].as_mut_ptr())),
            ),
            (
                "fmi2SetReal",
                Box::new(move |c| fmi2SetReal(c, vr.as_ptr(), 1, [1.0].as_ptr())),
            ),
            (
                "fmi2SetInteger",
                Box::new(move |c| fmi2SetInteger(c, vr.as_ptr(), 1, [1].as_ptr())),
            ),
            (
                "fmi2SetBoolean",
                Box::new(move |c| fmi2SetBoolean(c, vr.as_ptr(), 1, [1].as_ptr())),
            ),
            (
                "fmi2SetString",
                Box::new(move |c| fmi2SetString(c, vr.as_ptr(), 1, [c"x".as_ptr()].as_ptr())),
            ),
            ("fmi2GetFMUstate", Box::new(|c| fmi2GetFMUstate(c, &mut null_mut()))),
            ("fmi2SetFMUstate", Box::new(|c| fmi2SetFMUstate(c, null_mut()))),
            ("fmi2FreeFMUstate", Box::new(|c| fmi2FreeFMUstate(c, &mut null_mut()))),
            (
                "fmi2SerializedFMUstateSize",
                Box::new(|c| fmi2SerializedFMUstateSize(c, null_mut(), &mut 0)),
            ),
            (
                "fmi2SerializeFMUstate",
                Box::new(|c| fmi2SerializeFMUstate(c, null_mut(), [0; 8].as_mut_ptr(), 8)),
            ),
            (
                "fmi2DeSerializeFMUstate",
                Box::new(|c| fmi2DeSerializeFMUstate(c, [0; 8].as_ptr(), 8, &mut null_mut())),
            ),
            (
                "fmi2GetDirectionalDerivative",
                Box::new(move |c| {
                    fmi2GetDirectionalDerivative(
                        c,
                        out_vr.as_ptr(),
                        1,
                        vr.as_ptr(),
                        1,
                        [1.0].as_ptr(),
                        [0.0].as_mut_ptr(),
                    )
                }),
            ),
            (
                "fmi2SetRealInputDerivatives",
                Box::new(move |c| fmi2SetRealInputDerivatives(c, vr.as_ptr(), 1, [1].as_ptr(), [0.5].as_ptr())),
            ),
            (
                "fmi2GetRealOutputDerivatives",
                Box::new(move |c| {
                    fmi2GetRealOutputDerivatives(c, out_vr.as_ptr(), 1, [1].as_ptr(), [0.0].as_mut_ptr())
                }),
            ),
            ("fmi2DoStep", Box::new(|c| fmi2DoStep(c, 0.0, 1e-3, 1))),
            ("fmi2CancelStep", Box::new(|c| fmi2CancelStep(c))),
            (
                "fmi2GetStatus",
                Box::new(|c| fmi2GetStatus(c, fmi2DoStepStatus, &mut fmi2Status::fmi2OK)),
            ),
            (
                "fmi2GetRealStatus",
                Box::new(|c| fmi2GetRealStatus(c, fmi2LastSuccessfulTime, &mut 0.0)),
            ),
            (
                "fmi2GetIntegerStatus",
                Box::new(|c| fmi2GetIntegerStatus(c, fmi2DoStepStatus, &mut 0)),
            ),
            (
                "fmi2GetBooleanStatus",
                Box::new(|c| fmi2GetBooleanStatus(c, fmi2Terminated, &mut 0)),
            ),
            (
                "fmi2GetStringStatus",
                Box::new(|c| fmi2GetStringStatus(c, fmi2PendingStatus, &mut null())),
            ),
            ("fmi2EnterEventMode", Box::new(|c| fmi2EnterEventMode(c))),
            (
                "fmi2NewDiscreteStates",
                Box::new(|c| fmi2NewDiscreteStates(c, null_mut())),
            ),
            (
                "fmi2EnterContinuousTimeMode",
                Box::new(|c| fmi2EnterContinuousTimeMode(c)),
            ),
            (
                "fmi2CompletedIntegratorStep",
                Box::new(|c| fmi2CompletedIntegratorStep(c, 1, &mut 0, &mut 0)),
            ),
            ("fmi2SetTime", Box::new(|c| fmi2SetTime(c, 0.0))),
            (
                "fmi2SetContinuousStates",
                Box::new(|c| fmi2SetContinuousStates(c, [0.0; 4].as_ptr(), 4)),
            ),
            (
                "fmi2GetDerivatives",
                Box::new(|c| fmi2GetDerivatives(c, [0.0; 4].as_mut_ptr(), 4)),
            ),
            (
                "fmi2GetEventIndicators",
                Box::new(|c| fmi2GetEventIndicators(c, [0.0; 4].as_mut_ptr(), 4)),
            ),
            (
                "fmi2GetContinuousStates",
                Box::new(|c| fmi2GetContinuousStates(c, [0.0; 4].as_mut_ptr(), 4)),
            ),
            (
                "fmi2GetNominalsOfContinuousStates",
                Box::new(|c| fmi2GetNominalsOfContinuousStates(c, [0.0; 4].as_mut_ptr(), 4)),
            ),
        ]
    }
}

#[test]
fn a_null_freed_or_foreign_instance_is_refused_by_every_function() {
    let freed = Fmu::new(SHAFT);
    let stale = freed.c;
    drop(freed);
    let mut local = 0u64;
    let foreign = &mut local as *mut u64 as fmi2Component;
    let calls = every_instance_function();
    assert_eq!(calls.len(), 40, "every FMI 2.0 function that takes an instance");
    for (name, call) in &calls {
        for c in [null_mut(), stale, foreign, usize::MAX as fmi2Component] {
            // No instance means no logger: the status is the only channel.
            assert_eq!(call(c), ERROR, "{name} on {c:p}");
        }
    }
    // Freeing what is not an instance is ignored.
    fmi2FreeInstance(null_mut());
    fmi2FreeInstance(stale);
    fmi2FreeInstance(foreign);
    assert_eq!(local, 0, "a foreign pointer was written through");
    fresh_instance_works(SHAFT);
}

/// A fresh initialized instance for each refused call (a refusal puts it in state Error).
fn refused_in_step_complete(reason: &str, call: impl FnOnce(fmi2Component) -> fmi2Status) {
    let f = Fmu::initialized(SHAFT, None);
    let before = f.all_values().1;
    f.refuses(reason, call);
    // The refusal changed no value (fmi2GetXXX stays legal in state Error).
    let after = f.all_values();
    assert_eq!(after.0, OK);
    assert_eq!(
        before.iter().map(|(_, x)| x.to_bits()).collect::<Vec<_>>(),
        after.1.iter().map(|(_, x)| x.to_bits()).collect::<Vec<_>>()
    );
    f.reset_and_check();
}

#[test]
fn null_arrays_and_out_pointers_with_a_positive_length_are_refused() {
    let vr = [MODELS[0].vr("tau_m")];
    let out = [MODELS[0].vr("omega_m")];
    let vr = vr.as_ptr();
    let out = out.as_ptr();
    let n = 1;
    // (what, reason, call): each call passes exactly one NULL where n > 0 values are announced.
    type Call = Box<dyn Fn(fmi2Component) -> fmi2Status>;
    // SAFETY (all closures): the non-NULL pointers point to live values of the announced length.
    let cases: Vec<(&str, &str, Call)> = unsafe {
        vec![
            (
                "SetDebugLogging categories",
                "categories is NULL",
                Box::new(|c| fmi2SetDebugLogging(c, 1, 2, null())),
            ),
            (
                "SetDebugLogging category entry",
                "category name is NULL",
                Box::new(|c| fmi2SetDebugLogging(c, 1, 2, [c"logCalls".as_ptr(), null()].as_ptr())),
            ),
            (
                "GetReal vr",
                "vr is NULL",
                Box::new(move |c| fmi2GetReal(c, null(), n, [0.0].as_mut_ptr())),
            ),
            (
                "GetReal value",
                "value is NULL",
                Box::new(move |c| fmi2GetReal(c, vr, n, null_mut())),
            ),
            (
                "GetInteger vr",
                "vr is NULL",
                Box::new(move |c| fmi2GetInteger(c, null(), n, [0].as_mut_ptr())),
            ),
            (
                "GetInteger value",
                "value is NULL",
                Box::new(move |c| fmi2GetInteger(c, vr, n, null_mut())),
            ),
            (
                "GetBoolean vr",
                "vr is NULL",
                Box::new(move |c| fmi2GetBoolean(c, null(), n, [0].as_mut_ptr())),
            ),
            (
                "GetBoolean value",
                "value is NULL",
                Box::new(move |c| fmi2GetBoolean(c, vr, n, null_mut())),
            ),
            (
                "GetString vr",
                "vr is NULL",
                Box::new(move |c| fmi2GetString(c, null(), n, [null()].as_mut_ptr())),
            ),
            (
                "GetString value",
                "value is NULL",
                Box::new(move |c| fmi2GetString(c, vr, n, null_mut())),
            ),
            (
                "SetReal vr",
                "vr is NULL",
                Box::new(move |c| fmi2SetReal(c, null(), n, [0.0].as_ptr())),
            ),
            (
                "SetReal value",
                "value is NULL",
                Box::new(move |c| fmi2SetReal(c, vr, n, null())),
            ),
            (
                "SetInteger vr",
                "vr is NULL",
                Box::new(move |c| fmi2SetInteger(c, null(), n, [0].as_ptr())),
            ),
            (
                "SetInteger value",
                "value is NULL",
                Box::new(move |c| fmi2SetInteger(c, vr, n, null())),
            ),
            (
                "SetBoolean vr",
                "vr is NULL",
                Box::new(move |c| fmi2SetBoolean(c, null(), n, [0].as_ptr())),
            ),
            (
                "SetBoolean value",
                "value is NULL",
                Box::new(move |c| fmi2SetBoolean(c, vr, n, null())),
            ),
            (
                "SetString vr",
                "vr is NULL",
                Box::new(move |c| fmi2SetString(c, null(), n, [null()].as_ptr())),
            ),
            (
                "SetString value",
                "value is NULL",
                Box::new(move |c| fmi2SetString(c, vr, n, null())),
            ),
            (
                "SetRealInputDerivatives vr",
                "vr is NULL",
                Box::new(move |c| fmi2SetRealInputDerivatives(c, null(), n, [1].as_ptr(), [0.0].as_ptr())),
            ),
            (
                "SetRealInputDerivatives order",
                "order is NULL",
                Box::new(move |c| fmi2SetRealInputDerivatives(c, vr, n, null(), [0.0].as_ptr())),
            ),
            (
                "SetRealInputDerivatives value",
                "value is NULL",
                Box::new(move |c| fmi2SetRealInputDerivatives(c, vr, n, [1].as_ptr(), null())),
            ),
            (
                "GetRealOutputDerivatives vr",
                "vr is NULL",
                Box::new(move |c| fmi2GetRealOutputDerivatives(c, null(), n, [1].as_ptr(), [0.0].as_mut_ptr())),
            ),
            (
                "GetRealOutputDerivatives order",
                "order is NULL",
                Box::new(move |c| fmi2GetRealOutputDerivatives(c, out, n, null(), [0.0].as_mut_ptr())),
            ),
            (
                "GetRealOutputDerivatives value",
                "value is NULL",
                Box::new(move |c| fmi2GetRealOutputDerivatives(c, out, n, [1].as_ptr(), null_mut())),
            ),
            (
                "GetStatus",
                "value is NULL",
                Box::new(|c| fmi2GetStatus(c, fmi2DoStepStatus, null_mut())),
            ),
            (
                "GetRealStatus",
                "value is NULL",
                Box::new(|c| fmi2GetRealStatus(c, fmi2LastSuccessfulTime, null_mut())),
            ),
            (
                "GetIntegerStatus",
                "value is NULL",
                Box::new(|c| fmi2GetIntegerStatus(c, fmi2DoStepStatus, null_mut())),
            ),
            (
                "GetBooleanStatus",
                "value is NULL",
                Box::new(|c| fmi2GetBooleanStatus(c, fmi2Terminated, null_mut())),
            ),
            (
                "GetStringStatus",
                "value is NULL",
                Box::new(|c| fmi2GetStringStatus(c, fmi2PendingStatus, null_mut())),
            ),
            (
                "GetFMUstate",
                "FMUstate is NULL",
                Box::new(|c| fmi2GetFMUstate(c, null_mut())),
            ),
            (
                "FreeFMUstate",
                "FMUstate is NULL",
                Box::new(|c| fmi2FreeFMUstate(c, null_mut())),
            ),
            (
                "SerializedFMUstateSize",
                "size is NULL",
                Box::new(|c| {
                    let mut s = null_mut();
                    assert_eq!(fmi2GetFMUstate(c, &mut s), OK);
                    fmi2SerializedFMUstateSize(c, s, null_mut())
                }),
            ),
            (
                "SerializeFMUstate",
                "serializedState is NULL",
                Box::new(|c| {
                    let mut s = null_mut();
                    assert_eq!(fmi2GetFMUstate(c, &mut s), OK);
                    fmi2SerializeFMUstate(c, s, null_mut(), 1 << 16)
                }),
            ),
            (
                "DeSerializeFMUstate bytes",
                "serializedState is NULL",
                Box::new(|c| fmi2DeSerializeFMUstate(c, null(), 300, &mut null_mut())),
            ),
            (
                "DeSerializeFMUstate out",
                "FMUstate is NULL",
                Box::new(|c| fmi2DeSerializeFMUstate(c, [0; 300].as_ptr(), 300, null_mut())),
            ),
            (
                "GetDirectionalDerivative",
                "not provided",
                Box::new(|c| fmi2GetDirectionalDerivative(c, null(), 1, null(), 1, null(), null_mut())),
            ),
            (
                "GetDerivatives",
                "Model Exchange",
                Box::new(|c| fmi2GetDerivatives(c, null_mut(), 4)),
            ),
            (
                "SetContinuousStates",
                "Model Exchange",
                Box::new(|c| fmi2SetContinuousStates(c, null(), 4)),
            ),
            (
                "GetEventIndicators",
                "Model Exchange",
                Box::new(|c| fmi2GetEventIndicators(c, null_mut(), 1)),
            ),
            (
                "GetContinuousStates",
                "Model Exchange",
                Box::new(|c| fmi2GetContinuousStates(c, null_mut(), 4)),
            ),
            (
                "GetNominalsOfContinuousStates",
                "Model Exchange",
                Box::new(|c| fmi2GetNominalsOfContinuousStates(c, null_mut(), 4)),
            ),
            (
                "NewDiscreteStates",
                "Model Exchange",
                Box::new(|c| fmi2NewDiscreteStates(c, null_mut())),
            ),
            (
                "CompletedIntegratorStep",
                "Model Exchange",
                Box::new(|c| fmi2CompletedIntegratorStep(c, 0, null_mut(), null_mut())),
            ),
        ]
    };
    for (what, reason, call) in cases {
        eprintln!("{what}");
        refused_in_step_complete(reason, call);
    }
    fresh_instance_works(SHAFT);
}

#[test]
fn zero_length_null_arrays_are_accepted() {
    let f = Fmu::initialized(BELT, None);
    // SAFETY: n = 0: no element is read or written.
    unsafe {
        assert_eq!(fmi2GetReal(f.c, null(), 0, null_mut()), OK);
        assert_eq!(fmi2GetInteger(f.c, null(), 0, null_mut()), OK);
        assert_eq!(fmi2GetBoolean(f.c, null(), 0, null_mut()), OK);
        assert_eq!(fmi2GetString(f.c, null(), 0, null_mut()), OK);
        assert_eq!(fmi2SetReal(f.c, null(), 0, null()), OK);
        assert_eq!(fmi2SetInteger(f.c, null(), 0, null()), OK);
        assert_eq!(fmi2SetBoolean(f.c, null(), 0, null()), OK);
        assert_eq!(fmi2SetString(f.c, null(), 0, null()), OK);
        assert_eq!(fmi2SetRealInputDerivatives(f.c, null(), 0, null(), null()), OK);
        assert_eq!(fmi2GetRealOutputDerivatives(f.c, null(), 0, null(), null_mut()), OK);
        assert_eq!(fmi2SetDebugLogging(f.c, 0, 0, null()), OK);
    }
    assert!(
        f.entries().iter().all(|e| e.category != "logErrors"),
        "{:?}",
        f.entries()
    );
    f.assert_all_finite("after empty calls");
    assert_eq!(fmi2DoStep(f.c, 0.0, 1e-3, 1), OK);
    f.reset_and_check();
}

#[test]
fn unknown_and_mistyped_value_references_are_refused() {
    let m = &MODELS[SHAFT];
    let known: Vec<u32> = m.variables.iter().map(|v| v.vr).collect();
    let unknown = [0, 25, 1000, u32::MAX].into_iter().filter(|vr| !known.contains(vr));
    for vr in unknown {
        let v = [vr];
        // SAFETY (all calls): arrays of length 1.
        unsafe {
            refused_in_step_complete("not a variable", |c| fmi2GetReal(c, v.as_ptr(), 1, [0.0].as_mut_ptr()));
            refused_in_step_complete("not a variable", |c| fmi2SetReal(c, v.as_ptr(), 1, [0.0].as_ptr()));
            refused_in_step_complete("not a variable", |c| fmi2GetInteger(c, v.as_ptr(), 1, [0].as_mut_ptr()));
            refused_in_step_complete("not a variable", |c| fmi2SetInteger(c, v.as_ptr(), 1, [0].as_ptr()));
            refused_in_step_complete("not a variable", |c| fmi2GetBoolean(c, v.as_ptr(), 1, [0].as_mut_ptr()));
            refused_in_step_complete("not a variable", |c| fmi2SetBoolean(c, v.as_ptr(), 1, [0].as_ptr()));
            refused_in_step_complete("not a variable", |c| {
                fmi2GetString(c, v.as_ptr(), 1, [null()].as_mut_ptr())
            });
            refused_in_step_complete("not a variable", |c| fmi2SetString(c, v.as_ptr(), 1, [null()].as_ptr()));
            refused_in_step_complete("not a variable", |c| {
                fmi2SetRealInputDerivatives(c, v.as_ptr(), 1, [1].as_ptr(), [0.0].as_ptr())
            });
            refused_in_step_complete("not a variable", |c| {
                fmi2GetRealOutputDerivatives(c, v.as_ptr(), 1, [1].as_ptr(), [0.0].as_mut_ptr())
            });
        }
    }
    let contact = [m.vr("contact")];
    let theta = [m.vr("theta_m")];
    let tau = [m.vr("tau_m")];
    // SAFETY (all calls): arrays of length 1.
    unsafe {
        refused_in_step_complete("not Integer", |c| {
            fmi2GetInteger(c, theta.as_ptr(), 1, [0].as_mut_ptr())
        });
        refused_in_step_complete("not Real", |c| fmi2GetReal(c, contact.as_ptr(), 1, [0.0].as_mut_ptr()));
        refused_in_step_complete("not Real", |c| fmi2SetReal(c, contact.as_ptr(), 1, [1.0].as_ptr()));
        refused_in_step_complete("not Boolean", |c| fmi2GetBoolean(c, tau.as_ptr(), 1, [0].as_mut_ptr()));
        refused_in_step_complete("not Boolean", |c| fmi2SetBoolean(c, tau.as_ptr(), 1, [1].as_ptr()));
        refused_in_step_complete("not String", |c| {
            fmi2GetString(c, tau.as_ptr(), 1, [null()].as_mut_ptr())
        });
        refused_in_step_complete("not String", |c| {
            fmi2SetString(c, tau.as_ptr(), 1, [c"1".as_ptr()].as_ptr())
        });
        refused_in_step_complete("not Integer", |c| fmi2SetInteger(c, tau.as_ptr(), 1, [1].as_ptr()));
        // contact is an Integer, but a calculated output.
        refused_in_step_complete("output computed by the FMU", |c| {
            fmi2SetInteger(c, contact.as_ptr(), 1, [1].as_ptr())
        });
        // A bad reference after good ones: nothing is stored (checked by the helper).
        let mixed = [m.vr("tau_m"), m.vr("tau_L"), 1000];
        refused_in_step_complete("not a variable", |c| {
            fmi2SetReal(c, mixed.as_ptr(), 3, [5.0, 6.0, 7.0].as_ptr())
        });
    }
    fresh_instance_works(SHAFT);
}

#[test]
fn variables_that_cannot_be_set_now_are_refused() {
    for model in [SHAFT, BELT] {
        let m = &MODELS[model];
        let in_step_complete = |name: &str, reason: &str| {
            let f = Fmu::initialized(model, None);
            let (_, old) = f.get_real(name);
            f.refuses(reason, |_| f.set_real(name, 1.5));
            assert_eq!(f.get_real(name).1.to_bits(), old.to_bits(), "{name} changed");
            f.reset_and_check();
        };
        for v in m.variables {
            use backlash_fmu::fmu::variables::Causality::*;
            match (v.causality, v.is_initial_state(), v.name) {
                (_, _, "contact") => {}
                (Input, ..) => {}
                (Output, true, _) => in_step_complete(v.name, "initial state"),
                (Output, false, _) => in_step_complete(v.name, "output computed by the FMU"),
                (Parameter, ..) => in_step_complete(v.name, "fixed parameter"),
                (CalculatedParameter, ..) => in_step_complete(v.name, "calculatedParameter"),
                (Local, ..) => in_step_complete(v.name, "state derivative"),
            }
        }
        // Before initialization the calculated quantities are refused too.
        let f = Fmu::new(model);
        f.refuses("calculatedParameter", |_| f.set_real("bound_sup", 1.0));
        let f = Fmu::new(model);
        f.refuses("output computed", |_| f.set_real("psi", 1.0));
        // After fmi2Terminate nothing can be set.
        let f = Fmu::initialized(model, None);
        assert_eq!(fmi2Terminate(f.c), OK);
        f.refuses("not allowed in state Terminated", |_| f.set_real("tau_m", 1.0));
        f.reset_and_check();
    }
}

/// The settable Real variables and values outside their range.
fn bad_values(range: backlash_fmu::fmu::variables::Range) -> Vec<f64> {
    use backlash_fmu::fmu::variables::Range::*;
    let mut v = vec![f64::NAN, -f64::NAN, f64::INFINITY, f64::NEG_INFINITY];
    match range {
        Finite => {}
        NonNegative => v.extend([-1e-300, -1.0, -f64::MAX]),
        Positive => v.extend([0.0, -0.0, -1e-300, -1.0]),
    }
    v
}

#[test]
fn non_finite_and_out_of_range_values_never_reach_the_instance() {
    for model in [SHAFT, BELT] {
        let m = &MODELS[model];
        for v in m.variables.iter().filter(|v| v.start.is_some()) {
            for x in bad_values(v.range) {
                // Before, during and (inputs only) after initialization.
                for phase in 0..3 {
                    let f = match phase {
                        0 => Fmu::new(model),
                        1 => {
                            let f = Fmu::new(model);
                            assert_eq!(fmi2EnterInitializationMode(f.c), OK);
                            f
                        }
                        _ if v.causality == backlash_fmu::fmu::variables::Causality::Input => {
                            Fmu::initialized(model, None)
                        }
                        _ => continue,
                    };
                    f.refuses(&format!("value {x} refused for {}", v.name), |_| f.set_real(v.name, x));
                    // Still the start value; every variable still readable and finite.
                    if phase > 0 {
                        assert_eq!(f.get_real(v.name).1, v.start.unwrap(), "{}", v.name);
                        f.assert_all_finite(&format!("after {} = {x}", v.name));
                    }
                }
            }
        }
        // Input derivatives: only finite slopes.
        for x in [f64::NAN, f64::INFINITY, f64::NEG_INFINITY] {
            let f = Fmu::initialized(model, None);
            let vr = [f.vr("tau_L")];
            // SAFETY: arrays of length 1.
            f.refuses("refused for tau_L", |c| unsafe {
                fmi2SetRealInputDerivatives(c, vr.as_ptr(), 1, [1].as_ptr(), [x].as_ptr())
            });
            f.reset_and_check();
        }
    }
    fresh_instance_works(BELT);
}

#[test]
fn input_ramps_that_overflow_are_refused_not_stored() {
    let f = Fmu::initialized(SHAFT, None);
    let vr = [f.vr("tau_m")];
    // SAFETY: arrays of length 1.
    let s = unsafe { fmi2SetRealInputDerivatives(f.c, vr.as_ptr(), 1, [1].as_ptr(), [f64::MAX].as_ptr()) };
    assert_eq!(s, OK);
    let mut t = 0.0;
    for _ in 0..4 {
        let before = f.log_len();
        match fmi2DoStep(f.c, t, 1.0, 1) {
            OK => t += 1.0,
            s => {
                f.assert_refused(s, before, "");
                break;
            }
        }
        f.assert_all_finite(&format!("t = {t}"));
    }
    f.assert_all_finite("end");
    assert!(t < 4.0, "a ramp of slope f64::MAX cannot stay finite for 4 s");
    f.reset_and_check();
}

#[test]
fn bad_step_sizes_and_communication_points_are_refused() {
    for h in [0.0, -0.0, -1e-3, -1e-300, f64::NAN, f64::INFINITY, f64::NEG_INFINITY] {
        refused_in_step_complete("communicationStepSize", |c| fmi2DoStep(c, 0.0, h, 1));
    }
    refused_in_step_complete("exceeds", |c| fmi2DoStep(c, 0.0, 1e300, 1));
    for t in [0.5, -0.5, 1e-3, f64::NAN, f64::INFINITY, f64::NEG_INFINITY] {
        refused_in_step_complete("currentCommunicationPoint", |c| fmi2DoStep(c, t, 1e-3, 1));
    }

    // A tiny step is a step: at t = 0 it is representable and moves time exactly.
    let f = Fmu::initialized(SHAFT, None);
    assert_eq!(fmi2DoStep(f.c, 0.0, 1e-300, 1), OK);
    assert_eq!(f.time(), 1e-300);
    f.assert_all_finite("after h = 1e-300");
    assert_eq!(fmi2DoStep(f.c, 1e-300, 1.0 - 1e-300, 1), OK);
    assert_eq!(f.time(), 1.0);
    // At t = 1 it is below the resolution of time: refused rather than a step that does nothing.
    f.refuses("resolution", |c| fmi2DoStep(c, 1.0, 1e-300, 1));
    f.assert_all_finite("after a refused tiny step");
    f.reset_and_check();

    // Stop time: a step ending on it is fine, one beyond it is refused.
    let f = Fmu::initialized(BELT, Some(0.01));
    f.refuses("stopTime", |c| fmi2DoStep(c, 0.0, 0.02, 1));
    let f = Fmu::initialized(BELT, Some(0.01));
    assert_eq!(fmi2DoStep(f.c, 0.0, 0.01, 1), OK);
    f.refuses("stopTime", |c| fmi2DoStep(c, 0.01, 1e-6, 1));
    f.assert_all_finite("after stepping past the stop time");
    f.reset_and_check();

    // fmi2SetupExperiment: non-finite times, stop before start.
    for (start, stop) in [
        (f64::NAN, 1.0),
        (f64::INFINITY, 1.0),
        (0.0, f64::NAN),
        (0.0, -1.0),
        (1.0, 0.5),
    ] {
        let f = Fmu::new(SHAFT);
        let reason = if start.is_finite() { "stopTime" } else { "startTime" };
        f.refuses(reason, |c| fmi2SetupExperiment(c, 0, 0.0, start, 1, stop));
        f.reset_and_check();
    }
    fresh_instance_works(SHAFT);
}

#[test]
fn status_queries_that_have_no_answer_are_discarded_with_a_reason() {
    let f = Fmu::initialized(SHAFT, None);
    // SAFETY: pointers to locals.
    unsafe {
        for kind in [fmi2PendingStatus, fmi2LastSuccessfulTime, fmi2Terminated] {
            let s = f.refuses("not", |c| fmi2GetStatus(c, kind, &mut fmi2Status::fmi2OK));
            assert_eq!(s, fmi2Status::fmi2Discard);
        }
        let s = f.refuses("Integer", |c| fmi2GetIntegerStatus(c, fmi2DoStepStatus, &mut 0));
        assert_eq!(s, fmi2Status::fmi2Discard);
        let s = f.refuses("pending", |c| fmi2GetStringStatus(c, fmi2PendingStatus, &mut null()));
        assert_eq!(s, fmi2Status::fmi2Discard);
        // fmi2Discard leaves the instance usable.
        assert_eq!(fmi2DoStep(f.c, 0.0, 1e-3, 1), OK);
        // A status kind outside the enum.
        f.refuses("not an fmi2StatusKind", |c| fmi2GetRealStatus(c, 17, &mut 0.0));
    }
    f.reset_and_check();
}

#[test]
fn instantiate_refuses_bad_arguments_with_a_reason() {
    let log: Box<Log> = Box::default();
    let cb = callbacks(&*log);
    let shaft = CString::new(MODELS[0].guid).unwrap();
    let count = || log.lock().unwrap().len();
    let refuse = |reason: &str, c: fmi2Component| {
        assert!(c.is_null(), "instantiated despite {reason}");
        let entries = log.lock().unwrap();
        let last = entries.last().expect("a logged reason");
        assert_eq!(
            (last.status, last.category.as_str(), last.format.as_str()),
            (ERROR, "logErrors", "%s")
        );
        assert!(last.message.contains(reason), "{reason:?} not in {:?}", last.message);
    };
    let ok = fmi2CoSimulation;
    // SAFETY: every pointer is NULL or a live NUL-terminated string / the live struct `cb`.
    unsafe {
        let i = |name, ty, guid| fmi2Instantiate(name, ty, guid, c"file:///x".as_ptr(), &cb, 0, 0);
        refuse("instanceName is NULL", i(null(), ok, shaft.as_ptr()));
        refuse("blank", i(c"".as_ptr(), ok, shaft.as_ptr()));
        refuse("blank", i(c" \t\n".as_ptr(), ok, shaft.as_ptr()));
        refuse("not valid UTF-8", i(c"\xff\xfe".as_ptr(), ok, shaft.as_ptr()));
        refuse("fmuGUID is NULL", i(c"a".as_ptr(), ok, null()));
        refuse("fmuGUID", i(c"a".as_ptr(), ok, c"".as_ptr()));
        refuse("fmuGUID", i(c"a".as_ptr(), ok, c"{not-a-guid}".as_ptr()));
        let padded = CString::new(format!(" {}", MODELS[0].guid)).unwrap();
        refuse("fmuGUID", i(c"a".as_ptr(), ok, padded.as_ptr()));
        refuse("neither", i(c"a".as_ptr(), 2, shaft.as_ptr()));
        refuse("neither", i(c"a".as_ptr(), -1, shaft.as_ptr()));
        let n = count();
        // No callbacks: nothing to log through, just NULL.
        assert!(fmi2Instantiate(c"a".as_ptr(), ok, shaft.as_ptr(), null(), null(), 0, 0).is_null());
        assert_eq!(count(), n);

        // Resource locations are not used: any URI (or none) is fine.
        for uri in [
            c"file:///tmp/a%20b/c%25d/%E2%82%AC/resources".as_ptr(),
            c"file:///tmp/with space/and%/resources".as_ptr(),
            c"".as_ptr(),
            null(),
        ] {
            let c = fmi2Instantiate(c"uri".as_ptr(), ok, shaft.as_ptr(), uri, &cb, 1, 1);
            assert!(!c.is_null());
            fmi2FreeInstance(c);
        }

        // A NULL logger: no logging and no crash, also when a call fails.
        let quiet = fmi2CallbackFunctions { logger: None, ..cb };
        let c = fmi2Instantiate(c"quiet".as_ptr(), ok, shaft.as_ptr(), null(), &quiet, 0, 1);
        assert!(!c.is_null());
        assert_eq!(fmi2DoStep(c, 0.0, 1.0, 1), ERROR);
        assert_eq!(fmi2SetReal(c, null(), 3, null()), ERROR);
        assert_eq!(fmi2Reset(c), OK);
        assert_eq!(fmi2EnterInitializationMode(c), OK);
        assert_eq!(fmi2ExitInitializationMode(c), OK);
        assert_eq!(fmi2DoStep(c, 0.0, 1e-3, 1), OK);
        fmi2FreeInstance(c);
        let m = count();
        assert!(fmi2Instantiate(null(), ok, shaft.as_ptr(), null(), &quiet, 0, 1).is_null());
        assert_eq!(count(), m, "nothing reaches the other logger");
    }
    fresh_instance_works(SHAFT);
    fresh_instance_works(BELT);
}

#[test]
fn debug_logging_refuses_unknown_categories() {
    let f = Fmu::new(BELT);
    // SAFETY: arrays of the announced length, NUL-terminated strings.
    f.refuses("unknown log category", |c| unsafe {
        fmi2SetDebugLogging(c, 1, 2, [c"logCalls".as_ptr(), c"logEverything".as_ptr()].as_ptr())
    });
    f.reset_and_check();
}

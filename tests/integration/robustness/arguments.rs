//! Misuse of every C function's arguments: NULL instances, NULL arrays and out-pointers,
//! unknown or mistyped value references, variables that cannot be set now, non-finite and
//! out-of-range values, bad step sizes and communication points, bad fmi2Instantiate
//! arguments; for Model Exchange, state, derivative, nominal and indicator vectors of the wrong
//! length, non-finite or overflowing states, times that are not finite or lie before the start
//! time, bad seeds and references of fmi2GetDirectionalDerivative. Each refusal must be
//! fmi2Error/fmi2Discard with its reason logged through the importer's logger, must change
//! nothing, and a fresh instance must work normally after.
//!
//! The Co-Simulation tables cover the controller too ([`CONTROLLER`], docs/model.md §9), with its
//! own rows where it answers otherwise: no FMU state, no input or output derivatives, one step
//! size (its sample period), no Model Exchange, and its own variables.

use crate::robustness_common::*;
use backlash_fmu::ffi::*;
use backlash_fmu::fmu::variables::{Causality, VarType, Variable};
use backlash_fmu::fmu::{served, ModelInfo, MODELS};
use std::ffi::CString;
use std::ptr::{null, null_mut};

const OK: fmi2Status = fmi2Status::fmi2OK;
const ERROR: fmi2Status = fmi2Status::fmi2Error;

/// A call of one C function on the instance passed.
type InstanceCall = Box<dyn Fn(fmi2Component) -> fmi2Status>;

/// Every function that takes an instance, called on `c` with otherwise valid arguments.
fn every_instance_function() -> Vec<(&'static str, InstanceCall)> {
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
    // Freed instances of every model, Co-Simulation and Model Exchange (each is freed as it
    // drops), and of the controller, Co-Simulation only.
    let stale: Vec<fmi2Component> = (0..MODELS.len())
        .flat_map(|model| [Fmu::new(model), Fmu::me_continuous(model)])
        .chain([Fmu::initialized(CONTROLLER, None)])
        .map(|freed| freed.c)
        .collect();
    let mut local = 0u64;
    let foreign = &mut local as *mut u64 as fmi2Component;
    let calls = every_instance_function();
    assert_eq!(calls.len(), 40, "every FMI 2.0 function that takes an instance");
    for (name, call) in &calls {
        let invalid = [null_mut(), foreign, usize::MAX as fmi2Component];
        for &c in invalid.iter().chain(&stale) {
            // No instance means no logger: the status is the only channel.
            assert_eq!(call(c), ERROR, "{name} on {c:p}");
        }
    }
    // Freeing what is not an instance is ignored.
    fmi2FreeInstance(null_mut());
    for &c in &stale {
        fmi2FreeInstance(c);
    }
    fmi2FreeInstance(foreign);
    assert_eq!(local, 0, "a foreign pointer was written through");
    fresh_instance_works(SHAFT);
    fresh_instance_works(CONTROLLER);
}

/// The first variable of `model` with `causality`: an input and an output to pass to the calls
/// that take one (a plant's τ_m and θ_m, the controller's ω_m and τ_m).
fn first(model: &ModelInfo, causality: Causality) -> &'static Variable {
    model
        .variables
        .iter()
        .find(|v| v.causality == causality)
        .unwrap_or_else(|| panic!("{} has no {causality:?}", model.identifier))
}

/// On a plant and on the controller: the NULL is refused before any reference is looked up, so
/// both answer alike, but for the FMU-state rows of the controller, which has none to pass (its
/// own rows: fmi2SerializedFMUstateSize and fmi2SerializeFMUstate refused as not provided).
#[test]
fn null_arrays_and_out_pointers_with_a_positive_length_are_refused() {
    for model in [SHAFT, CONTROLLER] {
        null_arrays_and_out_pointers_are_refused(model);
    }
    fresh_instance_works(SHAFT);
    fresh_instance_works(CONTROLLER);
}

fn null_arrays_and_out_pointers_are_refused(model: usize) {
    let m = model_at(model);
    let vr = [first(m, Causality::Input).vr];
    let out = [first(m, Causality::Output).vr];
    let (vr, out) = (vr.as_ptr(), out.as_ptr());
    let n = 1;
    let controller = m.is_controller();
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
                if controller {
                    "canGetAndSetFMUstate = false"
                } else {
                    "size is NULL"
                },
                Box::new(move |c| {
                    let mut s = null_mut();
                    if !controller {
                        assert_eq!(fmi2GetFMUstate(c, &mut s), OK);
                    }
                    fmi2SerializedFMUstateSize(c, s, null_mut())
                }),
            ),
            (
                "SerializeFMUstate",
                if controller {
                    "canGetAndSetFMUstate = false"
                } else {
                    "serializedState is NULL"
                },
                Box::new(move |c| {
                    let mut s = null_mut();
                    if !controller {
                        assert_eq!(fmi2GetFMUstate(c, &mut s), OK);
                    }
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
        eprintln!("{what} ({})", m.identifier);
        refused_in_step_complete(model, reason, call);
    }
}

/// On a plant and on the controller, which refuses the input and output derivatives it does not
/// offer whatever their length (its own rows: canInterpolateInputs = false,
/// maxOutputDerivativeOrder = 0).
#[test]
fn zero_length_null_arrays_are_accepted() {
    for model in [BELT, CONTROLLER] {
        let f = Fmu::initialized(model, None);
        let controller = f.model.is_controller();
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
            if !controller {
                assert_eq!(fmi2SetRealInputDerivatives(f.c, null(), 0, null(), null()), OK);
                assert_eq!(fmi2GetRealOutputDerivatives(f.c, null(), 0, null(), null_mut()), OK);
            }
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
    // SAFETY (both calls): n = 0: no element is read or written.
    refused_in_step_complete(CONTROLLER, "canInterpolateInputs = false", |c| unsafe {
        fmi2SetRealInputDerivatives(c, null(), 0, null(), null())
    });
    refused_in_step_complete(CONTROLLER, "maxOutputDerivativeOrder = 0", |c| unsafe {
        fmi2GetRealOutputDerivatives(c, null(), 0, null(), null_mut())
    });
    fresh_instance_works(CONTROLLER);
}

/// On a plant and on the controller, each with its own variables: the controller's Integer is
/// the parameter `reference`, its Reals the inputs ω_m and T, the output τ_m and parameters.
#[test]
fn unknown_and_mistyped_value_references_are_refused() {
    // (model, an Integer, a Real output, two Real inputs)
    let cases = [
        (SHAFT, "contact", "theta_m", ["tau_m", "tau_L"]),
        (CONTROLLER, "reference", "tau_m", ["omega_m", "T"]),
    ];
    for (model, integer, output, inputs) in cases {
        let m = model_at(model);
        let known: Vec<u32> = m.variables.iter().map(|v| v.vr).collect();
        let unknown = [0, 25, 1000, u32::MAX].into_iter().filter(|vr| !known.contains(vr));
        let refused =
            |reason: &str, call: &dyn Fn(fmi2Component) -> fmi2Status| refused_in_step_complete(model, reason, call);
        for vr in unknown {
            let v = [vr];
            // SAFETY (all calls): arrays of length 1.
            unsafe {
                refused("not a variable", &|c| fmi2GetReal(c, v.as_ptr(), 1, [0.0].as_mut_ptr()));
                refused("not a variable", &|c| fmi2SetReal(c, v.as_ptr(), 1, [0.0].as_ptr()));
                refused("not a variable", &|c| {
                    fmi2GetInteger(c, v.as_ptr(), 1, [0].as_mut_ptr())
                });
                refused("not a variable", &|c| fmi2SetInteger(c, v.as_ptr(), 1, [0].as_ptr()));
                refused("not a variable", &|c| {
                    fmi2GetBoolean(c, v.as_ptr(), 1, [0].as_mut_ptr())
                });
                refused("not a variable", &|c| fmi2SetBoolean(c, v.as_ptr(), 1, [0].as_ptr()));
                refused("not a variable", &|c| {
                    fmi2GetString(c, v.as_ptr(), 1, [null()].as_mut_ptr())
                });
                refused("not a variable", &|c| {
                    fmi2SetString(c, v.as_ptr(), 1, [null()].as_ptr())
                });
                if !m.is_controller() {
                    refused("not a variable", &|c| {
                        fmi2SetRealInputDerivatives(c, v.as_ptr(), 1, [1].as_ptr(), [0.0].as_ptr())
                    });
                    refused("not a variable", &|c| {
                        fmi2GetRealOutputDerivatives(c, v.as_ptr(), 1, [1].as_ptr(), [0.0].as_mut_ptr())
                    });
                }
            }
        }
        let integer = [m.vr(integer)];
        let output = [m.vr(output)];
        let input = [m.vr(inputs[0])];
        // SAFETY (all calls): arrays of length 1.
        unsafe {
            refused("not Integer", &|c| {
                fmi2GetInteger(c, output.as_ptr(), 1, [0].as_mut_ptr())
            });
            refused("not Real", &|c| fmi2GetReal(c, integer.as_ptr(), 1, [0.0].as_mut_ptr()));
            refused("not Real", &|c| fmi2SetReal(c, integer.as_ptr(), 1, [1.0].as_ptr()));
            refused("not Boolean", &|c| {
                fmi2GetBoolean(c, input.as_ptr(), 1, [0].as_mut_ptr())
            });
            refused("not Boolean", &|c| fmi2SetBoolean(c, input.as_ptr(), 1, [1].as_ptr()));
            refused("not String", &|c| {
                fmi2GetString(c, input.as_ptr(), 1, [null()].as_mut_ptr())
            });
            refused("not String", &|c| {
                fmi2SetString(c, input.as_ptr(), 1, [c"1".as_ptr()].as_ptr())
            });
            refused("not Integer", &|c| fmi2SetInteger(c, input.as_ptr(), 1, [1].as_ptr()));
            if !m.is_controller() {
                // contact is an Integer, but a calculated output.
                refused("output computed by the FMU", &|c| {
                    fmi2SetInteger(c, integer.as_ptr(), 1, [1].as_ptr())
                });
            }
            // A bad reference after good ones: nothing is stored (checked by the helper).
            let mixed = [m.vr(inputs[0]), m.vr(inputs[1]), 1000];
            refused("not a variable", &|c| {
                fmi2SetReal(c, mixed.as_ptr(), 3, [5.0, 6.0, 7.0].as_ptr())
            });
        }
        fresh_instance_works(model);
    }
}

/// On every model the library serves: the plants, and the controller, whose output τ_m has a
/// start value (held until the first step ends) and whose Integer parameter is `reference`.
#[test]
fn variables_that_cannot_be_set_now_are_refused() {
    for (model, m) in served().enumerate() {
        let in_step_complete = |name: &str, reason: &str| {
            let f = Fmu::initialized(model, None);
            let (_, old) = f.get_real(name);
            f.refuses(reason, |_| f.set_real(name, 1.5));
            assert_eq!(f.get_real(name).1.to_bits(), old.to_bits(), "{name} changed");
            f.reset_and_check();
        };
        for v in m.variables {
            use backlash_fmu::fmu::variables::Causality::*;
            match (v.causality, v.is_initial_state(), v.ty) {
                // The Integer parameters (contact_law, reference), by fmi2SetInteger.
                (Parameter, _, VarType::Integer) => {
                    let f = Fmu::initialized(model, None);
                    f.refuses("fixed parameter", |_| f.set_integer(v.name, 2));
                    assert_eq!(f.get_integer(v.name), (OK, v.start.unwrap() as i32), "{}", v.name);
                    f.reset_and_check();
                }
                (_, _, VarType::Integer) => {}
                (Input, ..) => {}
                (Output, true, _) => in_step_complete(v.name, "initial state"),
                (Output, false, _) => in_step_complete(v.name, "output computed by the FMU"),
                (Parameter, ..) => in_step_complete(v.name, "fixed parameter"),
                (CalculatedParameter, ..) => in_step_complete(v.name, "calculatedParameter"),
                (Local, ..) if v.derivative_of.is_some() => in_step_complete(v.name, "state derivative"),
                (Local, ..) => in_step_complete(v.name, "computed by the FMU from the state"),
            }
        }
        // Before initialization the calculated quantities are refused too (a controller has none).
        if !m.is_controller() {
            let f = Fmu::new(model);
            f.refuses("calculatedParameter", |_| f.set_real("bound_sup", 1.0));
            let f = Fmu::new(model);
            f.refuses("output computed", |_| f.set_real("psi", 1.0));
        }
        // After fmi2Terminate nothing can be set, not even an input.
        let f = Fmu::initialized(model, None);
        assert_eq!(fmi2Terminate(f.c), OK);
        f.refuses("not allowed in state Terminated", |_| {
            f.set_real(first(m, Causality::Input).name, 1.0)
        });
        f.reset_and_check();
    }
}

/// Values outside the range of a settable Real variable.
fn bad_values(range: backlash_fmu::fmu::variables::Range) -> Vec<f64> {
    use backlash_fmu::fmu::variables::Range::*;
    let mut v = vec![f64::NAN, -f64::NAN, f64::INFINITY, f64::NEG_INFINITY];
    match range {
        Finite => {}
        NonNegative => v.extend([-1e-300, -1.0, -f64::MAX]),
        Positive => v.extend([0.0, -0.0, -1e-300, -1.0]),
        AtLeastOne => v.extend([1.0 - f64::EPSILON / 2.0, 0.0, -1.0]),
        Integers { .. } => unreachable!("an Integer is set by fmi2SetInteger"),
    }
    v
}

/// Values outside the range of a settable Integer variable (`contact_law`).
fn bad_integers(range: backlash_fmu::fmu::variables::Range) -> Vec<i32> {
    use backlash_fmu::fmu::variables::Range::*;
    match range {
        Integers { min, max } => vec![min - 1, max + 1, 0, -1, i32::MIN, i32::MAX],
        other => unreachable!("{other:?} is a Real's range"),
    }
}

/// On every model the library serves, each with its own ranges (the controller's: `h > 0`,
/// `t_ramp > 0`, `frequency >= 0`, `t_hold >= 0`, `reference` 1 to 3); the controller takes no
/// input derivatives at all (its own rows: refused naming canInterpolateInputs = false, finite or
/// not).
#[test]
fn non_finite_and_out_of_range_values_never_reach_the_instance() {
    for (model, m) in served().enumerate() {
        for v in m
            .variables
            .iter()
            .filter(|v| v.start.is_some() && v.ty == VarType::Integer)
        {
            // The ranges of the descriptions (docs/model.md §4, §9).
            let range = match v.name {
                "contact_law" => "1 or 2",
                "reference" => "an integer from 1 to 3",
                other => unreachable!("an Integer {other} with a start value"),
            };
            for x in bad_integers(v.range) {
                for phase in 0..2 {
                    let f = Fmu::new(model);
                    if phase == 1 {
                        assert_eq!(fmi2EnterInitializationMode(f.c), OK);
                    }
                    let reason = format!("value {x} refused for {}: it must be {range}", v.name);
                    f.refuses(&reason, |_| f.set_integer(v.name, x));
                    if phase > 0 {
                        assert_eq!(f.get_integer(v.name), (OK, v.start.unwrap() as i32), "{}", v.name);
                        f.assert_all_finite(&format!("after {} = {x}", v.name));
                    }
                }
            }
        }
        for v in m
            .variables
            .iter()
            .filter(|v| v.start.is_some() && v.ty == VarType::Real)
        {
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
        // Input derivatives: only finite slopes, for every input.
        let inputs = m
            .variables
            .iter()
            .filter(|v| v.causality == backlash_fmu::fmu::variables::Causality::Input);
        for v in inputs {
            let (slopes, reason) = if m.is_controller() {
                (
                    vec![f64::NAN, f64::INFINITY, 0.5],
                    "canInterpolateInputs = false".to_string(),
                )
            } else {
                (
                    vec![f64::NAN, f64::INFINITY, f64::NEG_INFINITY],
                    format!("refused for {}", v.name),
                )
            };
            for x in slopes {
                let vr = [v.vr];
                // SAFETY: arrays of length 1.
                refused_in_step_complete(model, &reason, |c| unsafe {
                    fmi2SetRealInputDerivatives(c, vr.as_ptr(), 1, [1].as_ptr(), [x].as_ptr())
                });
            }
        }
        fresh_instance_works(model);
    }
}

/// The plants only: the controller takes no input derivatives (refused in
/// `non_finite_and_out_of_range_values_never_reach_the_instance`).
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

/// On a plant and on the controller, whose every step must last its sample period `h` (1 ms by
/// default) to 1e-9 relative (docs/model.md §9; its own rows: any other size, tiny or huge, is
/// refused naming the period).
#[test]
fn bad_step_sizes_and_communication_points_are_refused() {
    for model in [SHAFT, CONTROLLER] {
        for h in [0.0, -0.0, -1e-3, -1e-300, f64::NAN, f64::INFINITY, f64::NEG_INFINITY] {
            refused_in_step_complete(model, "communicationStepSize", |c| fmi2DoStep(c, 0.0, h, 1));
        }
        // The controller's steps are 1 ms long (its default h), so 1e-3 is a valid size for both.
        for t in [0.5, -0.5, 1e-3, f64::NAN, f64::INFINITY, f64::NEG_INFINITY] {
            refused_in_step_complete(model, "currentCommunicationPoint", |c| fmi2DoStep(c, t, 1e-3, 1));
        }
    }
    refused_in_step_complete(SHAFT, "exceeds", |c| fmi2DoStep(c, 0.0, 1e300, 1));

    // The controller: a step of any other size than its period is refused with the period named.
    let period = model_at(CONTROLLER).by_name("h").and_then(|v| v.start).unwrap();
    assert_eq!(
        period, 1e-3,
        "the controller's default sample period (docs/model.md §9)"
    );
    for h in [1e300, 1e-300, 2e-3, 5e-4, 1e-3 * (1.0 + 1e-8), 1e-3 * (1.0 - 1e-8)] {
        let reason = format!("communicationStepSize {h} is not the sample period h = 0.001");
        refused_in_step_complete(CONTROLLER, &reason, |c| fmi2DoStep(c, 0.0, h, 1));
    }
    // Within 1e-9 relative of h (a master's clock in integer nanoseconds, or summed step by step):
    // a sample, taken.
    let f = Fmu::initialized(CONTROLLER, None);
    let (t1, t2) = (1e-3 * (1.0 + 1e-10), 2_000_000.0 / 1e9);
    assert_eq!(fmi2DoStep(f.c, 0.0, t1, 1), OK);
    assert_eq!(fmi2DoStep(f.c, t1, t2 - t1, 1), OK);
    assert_eq!(f.time(), t2);
    // Another size after good steps: refused, and the held torque stays.
    f.refuses_changing_nothing("is not the sample period h = 0.001", |c| fmi2DoStep(c, t2, 2e-3, 1));
    f.reset_and_check();

    // A tiny step is a step: at t = 0 it is representable and moves time exactly. The FMU's
    // time is currentCommunicationPoint + h, so exact here: 0 + 1e-300 = 1e-300, and
    // 1e-300 + fl(1 − 1e-300) = 1e-300 + 1 rounds to 1 (1e-300 is far below half an ulp of 1).
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
    // The controller: ten samples of 1 ms end on a stop time of 10 ms; the eleventh is refused.
    let f = Fmu::initialized(CONTROLLER, Some(0.01));
    for k in 0..10 {
        assert_eq!(fmi2DoStep(f.c, f.time(), 1e-3, 1), OK, "sample {k}");
    }
    f.refuses_changing_nothing("stopTime", |c| fmi2DoStep(c, f.time(), 1e-3, 1));
    f.reset_and_check();

    // fmi2SetupExperiment: non-finite times, stop before start.
    for (start, stop) in [
        (f64::NAN, 1.0),
        (f64::INFINITY, 1.0),
        (0.0, f64::NAN),
        (0.0, -1.0),
        (1.0, 0.5),
    ] {
        for model in [SHAFT, CONTROLLER] {
            let f = Fmu::new(model);
            let reason = if start.is_finite() { "stopTime" } else { "startTime" };
            f.refuses(reason, |c| fmi2SetupExperiment(c, 0, 0.0, start, 1, stop));
            f.reset_and_check();
        }
    }
    fresh_instance_works(SHAFT);
    fresh_instance_works(CONTROLLER);
}

/// On a plant and on the controller alike.
#[test]
fn status_queries_that_have_no_answer_are_discarded_with_a_reason() {
    for model in [SHAFT, CONTROLLER] {
        status_queries_are_discarded(model);
    }
}

fn status_queries_are_discarded(model: usize) {
    let f = Fmu::initialized(model, None);
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
    let controller = CString::new(model_at(CONTROLLER).guid).unwrap();
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
        // The controller is Co-Simulation only: its description declares no Model Exchange.
        refuse(
            "BacklashController is a controller: Co-Simulation only, its description declares no Model Exchange",
            i(c"a".as_ptr(), fmi2ModelExchange, controller.as_ptr()),
        );
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
        // The controller alike: a step of another size than its period, refused in silence.
        let c = fmi2Instantiate(c"quiet".as_ptr(), ok, controller.as_ptr(), null(), &quiet, 0, 1);
        assert!(!c.is_null());
        assert_eq!(fmi2EnterInitializationMode(c), OK);
        assert_eq!(fmi2ExitInitializationMode(c), OK);
        assert_eq!(fmi2DoStep(c, 0.0, 2e-3, 1), ERROR);
        assert_eq!(fmi2Reset(c), OK);
        assert_eq!(fmi2EnterInitializationMode(c), OK);
        assert_eq!(fmi2ExitInitializationMode(c), OK);
        assert_eq!(fmi2DoStep(c, 0.0, 1e-3, 1), OK);
        fmi2FreeInstance(c);
        let m = count();
        assert!(fmi2Instantiate(null(), ok, shaft.as_ptr(), null(), &quiet, 0, 1).is_null());
        let me = fmi2ModelExchange;
        assert!(fmi2Instantiate(c"me".as_ptr(), me, controller.as_ptr(), null(), &quiet, 0, 1).is_null());
        assert_eq!(count(), m, "nothing reaches the other logger");
    }
    for model in 0..served().count() {
        fresh_instance_works(model);
    }
}

/// On a plant and on the controller alike.
#[test]
fn debug_logging_refuses_unknown_categories() {
    for model in [BELT, CONTROLLER] {
        let f = Fmu::new(model);
        // SAFETY: arrays of the announced length, NUL-terminated strings.
        f.refuses("unknown log category", |c| unsafe {
            fmi2SetDebugLogging(c, 1, 2, [c"logCalls".as_ptr(), c"logEverything".as_ptr()].as_ptr())
        });
        f.reset_and_check();
    }
}

// ---- Model Exchange ----

/// Continuous states of `model` away from rest, inside the gap of every model (u = 2e-5 rad on
/// the shaft), and for a web span a tension of 20 N.
fn x_at_work(model: usize) -> Vec<f64> {
    states(model, [3e-5, 0.2, 1e-5, 0.1], 20.0)
}

/// Everything a Model Exchange instance shows, as bits: every variable, the continuous states,
/// the event indicators and the nominals (all readable in Event, Continuous-Time and Error mode).
/// Two observations of one unchanged instance are the same arithmetic by construction (the same
/// code on the same stored values), so they are compared bit for bit.
fn observe(f: &Fmu) -> Vec<u64> {
    let (s, values) = f.all_values();
    assert_eq!(s, OK, "{:?}", f.entries().last());
    let mut bits: Vec<u64> = values.iter().map(|(_, x)| x.to_bits()).collect();
    let (s, x) = f.continuous_states();
    assert_eq!(s, OK);
    let (s2, z) = f.event_indicators();
    assert_eq!(s2, OK);
    let (s3, n) = f.nominals();
    assert_eq!(s3, OK);
    bits.extend(x.iter().chain(&z).chain(&n).map(|x| x.to_bits()));
    bits
}

/// A Model Exchange instance of `model` at t = 0.2 with the states [`x_at_work`] and τ_m = 1.5, in
/// Continuous-Time Mode or (`event_mode`) back in Event Mode.
fn me_at_work(model: usize, event_mode: bool) -> Fmu {
    let f = Fmu::me_continuous(model);
    assert_eq!(fmi2SetTime(f.c, 0.2), OK);
    assert_eq!(f.set_continuous_states(&x_at_work(model)), OK);
    assert_eq!(f.set_real("tau_m", 1.5), OK);
    if event_mode {
        assert_eq!(fmi2EnterEventMode(f.c), OK);
    }
    f.assert_all_finite("at work");
    f
}

/// A refused Model Exchange call, on a fresh instance at work: the reason is logged, nothing the
/// instance shows changed, and fmi2Reset gives a working instance.
#[track_caller]
fn refused_in_me(model: usize, event_mode: bool, reason: &str, call: impl FnOnce(fmi2Component) -> fmi2Status) {
    let f = me_at_work(model, event_mode);
    let before = observe(&f);
    let status = f.refuses(reason, call);
    assert_eq!(status, ERROR);
    assert_eq!(observe(&f), before, "the refused call changed a value ({reason})");
    f.reset_and_check();
}

/// After a call that may have pushed the instance to the edge of f64: every read either
/// succeeds with [`admissible`] values (finite but for bound_sup and bound_T_sup) or is refused
/// with a reason that names an overflow; never a NaN.
#[track_caller]
fn reads_are_finite_or_refused(f: &Fmu, context: &str) {
    let check = |what: &str, status: fmi2Status, before: usize, values: &[f64]| {
        if status == OK {
            assert!(
                values.iter().all(|x| admissible(what, *x)),
                "{context}: {what} = {values:?}"
            );
        } else {
            f.assert_refused(status, before, "overflow");
        }
    };
    let n = f.log_len();
    let (s, x) = f.continuous_states();
    check("continuous states", s, n, &x);
    let n = f.log_len();
    let (s, dx) = f.derivatives();
    check("derivatives", s, n, &dx);
    let n = f.log_len();
    let (s, z) = f.event_indicators();
    check("event indicators", s, n, &z);
    let n = f.log_len();
    let (s, nominal) = f.nominals();
    check("nominals", s, n, &nominal);
    for v in f.model.variables.iter().filter(|v| v.ty == VarType::Real) {
        let n = f.log_len();
        let (s, x) = f.get_real(v.name);
        assert!(!x.is_nan() || s != OK, "{context}: {} is NaN", v.name);
        check(v.name, s, n, &[x]);
    }
}

/// Model Exchange: the plants only (the controller has no Model Exchange, refused at instantiation).
#[test]
fn model_exchange_null_arrays_and_out_pointers_are_refused() {
    for model in 0..MODELS.len() {
        null_arrays_and_out_pointers_are_refused_in_me(model);
    }
    fresh_me_instance_works(SHAFT);
}

fn null_arrays_and_out_pointers_are_refused_in_me(model: usize) {
    let m = &MODELS[model];
    let unknown = [m.vr("der(omega_m)")];
    let known = [m.vr("tau_m")];
    let (unknown, known) = (unknown.as_ptr(), known.as_ptr());
    let nx = nx(model);
    let x_null = format!("argument x is NULL but {nx} values were announced");
    let derivatives_null = format!("argument derivatives is NULL but {nx} values");
    let n_i = crate::robustness_common::ni(model);
    let indicators_null = format!("argument eventIndicators is NULL but {n_i} values");
    let nominals_null = format!("argument x_nominal is NULL but {nx} values");
    type Call = Box<dyn Fn(fmi2Component) -> fmi2Status>;
    // (event mode?, reason, call): each call passes one NULL where values are announced.
    // SAFETY (all closures): the non-NULL pointers point to live values of the announced length.
    let cases: Vec<(bool, &str, Call)> = unsafe {
        vec![
            (
                false,
                &x_null,
                Box::new(move |c| fmi2SetContinuousStates(c, null(), nx)),
            ),
            (
                false,
                &x_null,
                Box::new(move |c| fmi2GetContinuousStates(c, null_mut(), nx)),
            ),
            (
                true,
                &x_null,
                Box::new(move |c| fmi2GetContinuousStates(c, null_mut(), nx)),
            ),
            (
                false,
                &derivatives_null,
                Box::new(move |c| fmi2GetDerivatives(c, null_mut(), nx)),
            ),
            (
                true,
                &derivatives_null,
                Box::new(move |c| fmi2GetDerivatives(c, null_mut(), nx)),
            ),
            (
                false,
                &indicators_null,
                Box::new(move |c| fmi2GetEventIndicators(c, null_mut(), n_i)),
            ),
            (
                false,
                &nominals_null,
                Box::new(move |c| fmi2GetNominalsOfContinuousStates(c, null_mut(), nx)),
            ),
            (
                true,
                "argument fmi2eventInfo is NULL",
                Box::new(|c| fmi2NewDiscreteStates(c, null_mut())),
            ),
            (
                false,
                "argument enterEventMode is NULL",
                Box::new(|c| fmi2CompletedIntegratorStep(c, 1, null_mut(), &mut 0)),
            ),
            (
                false,
                "argument terminateSimulation is NULL",
                Box::new(|c| fmi2CompletedIntegratorStep(c, 0, &mut 0, null_mut())),
            ),
            (
                false,
                "argument vUnknown_ref is NULL",
                Box::new(move |c| {
                    fmi2GetDirectionalDerivative(c, null(), 1, known, 1, [1.0].as_ptr(), [0.0].as_mut_ptr())
                }),
            ),
            (
                true,
                "argument vKnown_ref is NULL",
                Box::new(move |c| {
                    fmi2GetDirectionalDerivative(c, unknown, 1, null(), 1, [1.0].as_ptr(), [0.0].as_mut_ptr())
                }),
            ),
            (
                false,
                "argument dvKnown is NULL",
                Box::new(move |c| fmi2GetDirectionalDerivative(c, unknown, 1, known, 1, null(), [0.0].as_mut_ptr())),
            ),
            (
                false,
                "argument dvUnknown is NULL",
                Box::new(move |c| fmi2GetDirectionalDerivative(c, unknown, 1, known, 1, [1.0].as_ptr(), null_mut())),
            ),
            // Value references of fmi2GetReal / fmi2SetReal in Continuous-Time Mode.
            (
                false,
                "argument vr is NULL",
                Box::new(|c| fmi2SetReal(c, null(), 1, [1.0].as_ptr())),
            ),
            (
                false,
                "argument value is NULL",
                Box::new(move |c| fmi2GetReal(c, known, 1, null_mut())),
            ),
        ]
    };
    let count = cases.len();
    for (event_mode, reason, call) in cases {
        refused_in_me(model, event_mode, reason, call);
    }
    assert_eq!(count, 16);
}

/// Model Exchange: the plants only (the controller has no Model Exchange, refused at instantiation).
#[test]
fn model_exchange_vectors_of_the_wrong_length_are_refused_and_left_unwritten() {
    for model in 0..MODELS.len() {
        let expected = nx(model);
        let x_at_work = x_at_work(model);
        for nx in [0, 1, expected - 1, expected + 1, 1000] {
            let reason = |what: &str| format!("{what}: {nx} values given, {expected} expected");
            let x: Vec<f64> = (0..nx).map(|i| x_at_work[i % expected]).collect();
            // SAFETY (all calls): buffers of length nx (NULL for nx = 0, where nothing is read).
            unsafe {
                let input = if nx == 0 { null() } else { x.as_ptr() };
                refused_in_me(model, false, &reason("continuous states"), |c| {
                    fmi2SetContinuousStates(c, input, nx)
                });
                type Getter = unsafe extern "C" fn(fmi2Component, *mut f64, usize) -> fmi2Status;
                let getters: [(&str, Getter, bool); 3] = [
                    ("continuous states", fmi2GetContinuousStates, true),
                    ("derivatives", fmi2GetDerivatives, false),
                    (
                        "nominals of the continuous states",
                        fmi2GetNominalsOfContinuousStates,
                        true,
                    ),
                ];
                for (what, get, in_event_mode) in getters {
                    let mut out = vec![7.0; nx];
                    let ptr = if nx == 0 { null_mut() } else { out.as_mut_ptr() };
                    refused_in_me(model, in_event_mode, &reason(what), |c| get(c, ptr, nx));
                    assert!(
                        out.iter().all(|x| *x == 7.0),
                        "{what} wrote into a refused buffer: {out:?}"
                    );
                }
            }
        }
        for ni in [0, 1, 2, 5, 7, 100] {
            let mut out = vec![7.0; ni];
            let ptr = if ni == 0 { null_mut() } else { out.as_mut_ptr() };
            // SAFETY: a buffer of length ni.
            refused_in_me(
                model,
                false,
                &format!(
                    "event indicators: {ni} values given, {} expected",
                    crate::robustness_common::ni(model)
                ),
                |c| unsafe { fmi2GetEventIndicators(c, ptr, ni) },
            );
            assert!(out.iter().all(|x| *x == 7.0), "{out:?}");
        }
    }
    fresh_me_instance_works(BELT);
}

/// Model Exchange: the plants only (the controller has no Model Exchange, refused at instantiation).
#[test]
fn model_exchange_non_finite_states_and_times_never_reach_the_instance() {
    for (model, m) in MODELS.iter().enumerate() {
        let x_at_work = x_at_work(model);
        // Each state in turn non-finite, the others valid: nothing is stored (all or nothing).
        for (i, name) in state_names(model).iter().enumerate() {
            for bad in [f64::NAN, -f64::NAN, f64::INFINITY, f64::NEG_INFINITY] {
                let mut x: Vec<f64> = x_at_work.iter().map(|x| 3.0 * x).collect();
                x[i] = bad;
                let reason = format!("continuous state {} ({name}) is", i + 1);
                refused_in_me(model, false, &reason, |c| unsafe {
                    // SAFETY: x.len() values.
                    fmi2SetContinuousStates(c, x.as_ptr(), x.len())
                });
                let f = me_at_work(model, false);
                f.refuses("states must be finite", |_| f.set_continuous_states(&x));
                assert_eq!(f.continuous_states(), (OK, x_at_work.clone()), "a state was stored");
            }
        }
        // Finite states whose force overflows are refused too.
        let huge = states(model, [f64::MAX, 0.0, -f64::MAX, 0.0], 0.0);
        refused_in_me(model, false, "the continuous states overflow", |c| unsafe {
            // SAFETY: huge.len() values.
            fmi2SetContinuousStates(c, huge.as_ptr(), huge.len())
        });
        // Finite states at the edge of f64: accepted or refused, never a NaN read after. A web
        // span's tension too, where there is one.
        let mut edges: Vec<Vec<f64>> = [
            [0.0, f64::MAX, 0.0, 0.0],
            [0.0, 0.0, 0.0, -f64::MAX],
            [1e300, 1e300, 1e300, 1e300],
            [5e-324, -5e-324, f64::MIN_POSITIVE, 0.0],
            [1e-3, 1e150, -1e-3, -1e150],
        ]
        .into_iter()
        .map(|edge| states(model, edge, 0.0))
        .collect();
        if m.web {
            for tension in [f64::MAX, -1e300, 5e-324, 1e150] {
                edges.push(states(model, [3e-5, 0.2, 1e-5, 0.1], tension));
            }
            edges.push(states(model, [1e300; 4], -1e300));
        }
        for edge in edges {
            let f = me_at_work(model, false);
            let before = f.log_len();
            let s = f.set_continuous_states(&edge);
            if s == OK {
                assert_eq!(f.continuous_states(), (OK, edge.clone()));
            } else {
                f.assert_refused(s, before, "overflow");
                assert_eq!(f.continuous_states(), (OK, x_at_work.clone()));
            }
            reads_are_finite_or_refused(&f, &format!("{} states {edge:?}", m.identifier));
            f.reset_and_check();
        }

        // fmi2SetTime: non-finite times, and times before the start time.
        for t in [f64::NAN, f64::INFINITY, f64::NEG_INFINITY, -1e-300, -1.0, -f64::MAX] {
            let reason = format!("time {t} must be finite and >= the start time 0");
            refused_in_me(model, false, &reason, |c| fmi2SetTime(c, t));
            // FMI 2.0.4 §3.2.3, condition 8: no fmi2SetTime at all in Event Mode here.
            refused_in_me(model, true, "fmi2SetTime is not allowed in state EventMode", |c| {
                fmi2SetTime(c, t)
            });
        }
        let f = Fmu::new_model_exchange(model);
        assert_eq!(fmi2SetupExperiment(f.c, 0, 0.0, 1.0, 1, 2.0), OK);
        assert_eq!(fmi2EnterInitializationMode(f.c), OK);
        assert_eq!(fmi2ExitInitializationMode(f.c), OK);
        assert_eq!(fmi2EnterContinuousTimeMode(f.c), OK);
        let before = observe(&f);
        for t in [1.0, 1.5, 1.0] {
            assert_eq!(fmi2SetTime(f.c, t), OK, "t = {t}");
        }
        // Bit for bit: back at elapsed time 0 the bounds restart from their reset state (a
        // bound is a function of elapsed time alone), and the rest never moved.
        assert_eq!(
            observe(&f),
            before,
            "back at the start time, the values are those at the start"
        );
        let just_before = f64::from_bits(1f64.to_bits() - 1);
        f.refuses(
            &format!("time {just_before} must be finite and >= the start time 1 of the experiment"),
            |c| fmi2SetTime(c, just_before),
        );
        assert_eq!(observe(&f), before);
        f.reset_and_check();
        // -0 is the start time 0.
        let f = me_at_work(model, false);
        assert_eq!(fmi2SetTime(f.c, -0.0), OK);
        f.assert_all_finite("t = -0");
    }
    fresh_me_instance_works(SHAFT);
}

/// Model Exchange: the plants only (the controller has no Model Exchange, refused at instantiation).
#[test]
fn model_exchange_directional_derivatives_refuse_bad_seeds_and_references() {
    for (model, m) in MODELS.iter().enumerate() {
        let web = m.web;
        let vr = |name: &str| crate::robustness_common::named(m, name);
        let identifier = m.identifier;
        // (reason, unknowns, knowns, seeds)
        type Case = (String, Vec<u32>, Vec<u32>, Vec<f64>);
        let cases: Vec<Case> = vec![
            (
                "value NaN refused for tau_m: it must be a finite seed".into(),
                vec![vr("der(omega_m)")],
                vec![vr("theta_m"), vr("tau_m")],
                vec![1.0, f64::NAN],
            ),
            (
                "value inf refused for theta_m: it must be a finite seed".into(),
                vec![vr("der(omega_m)")],
                vec![vr("theta_m")],
                vec![f64::INFINITY],
            ),
            (
                "value -inf refused for omega_L".into(),
                vec![vr("psi")],
                vec![vr("omega_L")],
                vec![f64::NEG_INFINITY],
            ),
            (
                "value NaN refused for tau_L".into(),
                vec![vr("der(omega_L)")],
                vec![vr("tau_L")],
                vec![-f64::NAN],
            ),
            (
                format!("value reference 1000 is not a variable of {identifier}"),
                vec![vr("der(omega_m)"), 1000],
                vec![vr("tau_m")],
                vec![1.0],
            ),
            (
                format!("value reference 1000 is not a variable of {identifier}"),
                vec![vr("der(omega_m)")],
                vec![vr("tau_m"), 1000],
                vec![1.0, 1.0],
            ),
            (
                format!("value reference 4294967295 is not a variable of {identifier}"),
                vec![u32::MAX],
                vec![vr("tau_m")],
                vec![1.0],
            ),
            (
                format!("variable {} (value reference", m.by_vr(vr("contact")).unwrap().name),
                vec![vr("contact")],
                vec![vr("tau_m")],
                vec![1.0],
            ),
            (
                format!("variable {} (value reference", m.by_vr(vr("contact")).unwrap().name),
                vec![vr("der(theta_m)")],
                vec![vr("contact")],
                vec![1.0],
            ),
        ];
        let mut cases = cases;
        if web {
            // The span's state and inputs are knowns: their seeds must be finite too.
            for (known, seed) in [("T", f64::NAN), ("v_in", f64::INFINITY), ("T_in", f64::NEG_INFINITY)] {
                cases.push((
                    format!("value {seed} refused for {known}"),
                    vec![vr("der(T)")],
                    vec![vr(known)],
                    vec![seed],
                ));
            }
        }
        // Knowns that are neither continuous states nor inputs.
        let mut not_knowns = vec![
            "J_m",
            "Delta",
            "psi",
            "der(theta_m)",
            "der(omega_L)",
            "bound",
            "bound_paper",
            "bound_sup",
        ];
        // Unknowns that are neither state derivatives nor outputs.
        let mut not_unknowns = vec!["tau_m", "tau_L", "J_L", "Kp", "bound_sup"];
        if web {
            not_knowns.extend(["der(T)", "bound_T", "bound_T_sup", "EA", "Kp_T"]);
            not_unknowns.extend(["v_in", "T_in", "L_w", "Ki_T", "bound_T_sup"]);
        }
        // (A gearbox has no bound_paper: docs/model.md §10.)
        not_knowns.retain(|name| m.by_name(name).is_some() || m.by_name(&format!("{name}_1")).is_some());
        for name in not_knowns {
            let shown = m.by_vr(vr(name)).unwrap().name;
            cases.push((
                format!("{shown} is not a known of the Jacobian: the knowns are the continuous states and the inputs"),
                vec![vr("der(omega_m)")],
                vec![vr("theta_m"), vr(name)],
                vec![1.0, 1.0],
            ));
        }
        for name in not_unknowns {
            cases.push((
                format!(
                    "{name} is not an unknown of the Jacobian: the unknowns are the state derivatives and the outputs"
                ),
                vec![vr("der(omega_m)"), vr(name)],
                vec![vr("tau_m")],
                vec![1.0],
            ));
        }
        for (reason, unknowns, knowns, seeds) in &cases {
            for event_mode in [false, true] {
                let mut out = vec![7.0; unknowns.len()];
                // SAFETY: arrays of the announced lengths.
                refused_in_me(model, event_mode, reason, |c| unsafe {
                    fmi2GetDirectionalDerivative(
                        c,
                        unknowns.as_ptr(),
                        unknowns.len(),
                        knowns.as_ptr(),
                        knowns.len(),
                        seeds.as_ptr(),
                        out.as_mut_ptr(),
                    )
                });
                assert!(out.iter().all(|x| *x == 7.0), "{reason}: {out:?}");
            }
        }
        // Finite seeds whose sum overflows: refused with a reason or finite, never NaN with OK.
        let f = me_at_work(model, false);
        let mut unknowns = vec![
            "der(theta_m)",
            "der(omega_m)",
            "der(theta_L)",
            "der(omega_L)",
            "psi",
            "theta_m",
            "bound",
        ];
        let mut knowns = vec![
            ("theta_m", f64::MAX),
            ("theta_m", f64::MAX),
            ("omega_L", -f64::MAX),
            ("tau_m", f64::MAX),
        ];
        if web {
            unknowns.extend(["der(T)", "T", "bound_T"]);
            knowns.extend([("T", f64::MAX), ("v_in", -f64::MAX), ("T_in", f64::MAX)]);
        }
        let unknowns: Vec<u32> = unknowns.into_iter().map(vr).collect();
        let (knowns, seeds): (Vec<u32>, Vec<f64>) = knowns.into_iter().map(|(name, seed)| (vr(name), seed)).unzip();
        let mut out = vec![f64::NAN; unknowns.len()];
        let before = f.log_len();
        // SAFETY: arrays of the announced lengths.
        let s = unsafe {
            fmi2GetDirectionalDerivative(
                f.c,
                unknowns.as_ptr(),
                unknowns.len(),
                knowns.as_ptr(),
                knowns.len(),
                seeds.as_ptr(),
                out.as_mut_ptr(),
            )
        };
        if s == OK {
            assert!(out.iter().all(|x| x.is_finite()), "{out:?}");
        } else {
            f.assert_refused(s, before, "overflow");
        }
        reads_are_finite_or_refused(&f, "after huge seeds");
        f.reset_and_check();
        // Zero-length calls are fine; a legal call keeps the instance at work.
        let f = me_at_work(model, true);
        // SAFETY: n = 0: nothing is read or written.
        assert_eq!(
            unsafe { fmi2GetDirectionalDerivative(f.c, null(), 0, null(), 0, null(), null_mut()) },
            OK
        );
        let mut dv = [f64::NAN; 4];
        // SAFETY: arrays of the announced lengths.
        let s = unsafe {
            fmi2GetDirectionalDerivative(
                f.c,
                [vr("theta_m"), vr("bound"), vr("u_minus_g"), vr("u_plus_g")].as_ptr(),
                4,
                [vr("theta_m"), vr("tau_L")].as_ptr(),
                2,
                [0.5, 3.0].as_ptr(),
                dv.as_mut_ptr(),
            )
        };
        assert_eq!(s, OK);
        // d theta_m = the theta_m seed; the bound depends on time alone; u = r_m theta_m - r_L theta_L
        // moves with theta_m (r_m = 1 on the shaft). All exact: the seed passed through (0 + 0.5),
        // the literal 0, and u_minus_g and u_plus_g both `Plant::transmission` of the same
        // seeds (on the shaft 1·0.5 − 1·0 = 0.5).
        assert_eq!(dv[..2], [0.5, 0.0]);
        assert_eq!(dv[2], dv[3]);
        if model == SHAFT {
            assert_eq!(dv[2], 0.5);
        } else {
            assert!(dv[2] > 0.0, "{dv:?}");
        }
        if web {
            // The span, L_w T' = EA (R_w ω_L − v_in) + v_ref (T_in − T) (docs/model.md §8): its
            // rate in each of its knowns, T by the seed T, and bound_T on time alone.
            let p = |name: &str| f.get_real(name).1;
            let (r_w, l_w, ea, v_ref) = (p("R_w"), p("L_w"), p("EA"), p("v_ref"));
            for (known, rate) in [
                ("T", -v_ref / l_w),
                ("omega_L", ea * r_w / l_w),
                ("v_in", -ea / l_w),
                ("T_in", v_ref / l_w),
                ("tau_m", 0.0),
            ] {
                let mut dv = [f64::NAN; 3];
                // SAFETY: arrays of the announced lengths.
                let s = unsafe {
                    fmi2GetDirectionalDerivative(
                        f.c,
                        [vr("der(T)"), vr("T"), vr("bound_T")].as_ptr(),
                        3,
                        [vr(known)].as_ptr(),
                        1,
                        [2.0].as_ptr(),
                        dv.as_mut_ptr(),
                    )
                };
                assert_eq!(s, OK, "{known}");
                // d(T) is the seed passed through (0 + 2) and d(bound_T) the literal 0: exact.
                let want = [2.0 * rate, if known == "T" { 2.0 } else { 0.0 }, 0.0];
                assert!(
                    (dv[0] - want[0]).abs() <= 1e-14 * want[0].abs() && dv[1..] == want[1..],
                    "d(der(T), T, bound_T)/d{known}: {dv:?}, expected {want:?}"
                );
            }
        }
        assert_eq!(fmi2EnterContinuousTimeMode(f.c), OK);
        f.reset_and_check();
    }
    fresh_me_instance_works(SHAFT);
}

/// fmi2SetReal of the continuous-time state `name` in Continuous-Time Mode (FMI 2.0.4 §3.2.3,
/// condition 5) does what fmi2SetContinuousStates with the other entries unchanged does: both
/// build the plant's state from the same vector by the same function, so every value the
/// instances show is the same bit for bit. A non-finite or overflowing value is refused and
/// changes nothing.
fn a_state_set_by_reference_is_a_state_set(model: usize, name: &str) {
    let k = state_names(model).iter().position(|s| *s == name).expect("a state");
    let (by_name, by_vector) = (me_at_work(model, false), me_at_work(model, false));
    let mut x = x_at_work(model);
    x[k] = -4.0e-3;
    assert_eq!(by_name.set_real(name, x[k]), OK);
    assert_eq!(by_vector.set_continuous_states(&x), OK);
    assert_eq!(observe(&by_name), observe(&by_vector), "{name}");
    assert_eq!(by_name.continuous_states(), (OK, x), "{name}");
    for bad in [f64::NAN, f64::INFINITY, f64::NEG_INFINITY] {
        let f = me_at_work(model, false);
        let before = observe(&f);
        f.refuses(&format!("value {bad} refused for {name}"), |_| f.set_real(name, bad));
        assert_eq!(observe(&f), before, "{name} = {bad}");
    }
    // A huge finite state: accepted unless its force overflows (refused, nothing changed),
    // then every read is finite or refused as an overflow.
    let f = me_at_work(model, false);
    let before = observe(&f);
    let log = f.log_len();
    match f.set_real(name, f64::MAX) {
        OK => reads_are_finite_or_refused(&f, &format!("{name} = f64::MAX")),
        status => {
            f.assert_refused(status, log, "overflow");
            assert_eq!(observe(&f), before, "{name} = f64::MAX");
        }
    }
}

/// Model Exchange: the plants only (the controller has no Model Exchange, refused at instantiation).
#[test]
fn model_exchange_variables_that_cannot_be_set_now_are_refused() {
    use backlash_fmu::fmu::variables::Causality::*;
    for (model, m) in MODELS.iter().enumerate() {
        for event_mode in [true, false] {
            for v in m.variables.iter().filter(|v| v.ty == VarType::Real) {
                let reason = match (v.causality, v.is_initial_state()) {
                    (Input, _) => None,
                    // FMI 2.0.4 §3.2.3: in Event Mode "for a variable with causality = "input", or
                    // (causality = "parameter" and variability = "tunable")" (condition 4).
                    (Output, true) if event_mode => Some("inputs and tunable parameters only (condition 4)"),
                    // Condition 5, Continuous-Time Mode: "… and for a continuous-time state
                    // variable": below.
                    (Output, true) => {
                        a_state_set_by_reference_is_a_state_set(model, v.name);
                        continue;
                    }
                    (Output, false) => Some("output computed by the FMU"),
                    (Parameter, _) => Some("fixed parameter"),
                    (CalculatedParameter, _) => Some("calculatedParameter"),
                    // der(...) and the event indicators (u_minus_g, ..., cap_lower).
                    (Local, _) if v.name.starts_with("der(") => Some("state derivative, computed by the FMU"),
                    (Local, _) => Some("computed by the FMU"),
                };
                match reason {
                    Some(reason) => refused_in_me(model, event_mode, reason, |c| unsafe {
                        // SAFETY: arrays of length 1.
                        fmi2SetReal(c, [v.vr].as_ptr(), 1, [1.5].as_ptr())
                    }),
                    None => {
                        // An input: set, and seen in the derivatives at once.
                        let f = me_at_work(model, event_mode);
                        let (_, before) = f.derivatives();
                        assert_eq!(f.set_real(v.name, -4.0), OK);
                        assert_eq!(f.get_real(v.name), (OK, -4.0));
                        let (s, after) = f.derivatives();
                        assert_eq!(s, OK);
                        assert_ne!(before, after, "{} changed no derivative", v.name);
                        // Non-finite inputs are refused, and nothing else changes.
                        for bad in [f64::NAN, f64::INFINITY, f64::NEG_INFINITY] {
                            let f = me_at_work(model, event_mode);
                            let before = observe(&f);
                            f.refuses(&format!("value {bad} refused for {}", v.name), |_| {
                                f.set_real(v.name, bad)
                            });
                            assert_eq!(observe(&f), before);
                        }
                        // All or nothing: a valid input before a refused variable is not stored.
                        let both = [v.vr, m.vr("J_m")];
                        refused_in_me(model, event_mode, "fixed parameter", |c| unsafe {
                            // SAFETY: arrays of length 2.
                            fmi2SetReal(c, both.as_ptr(), 2, [9.0, 1.0].as_ptr())
                        });
                        // Huge finite inputs: accepted (finite), and then every read is finite
                        // or refused as an overflow.
                        let f = me_at_work(model, event_mode);
                        assert_eq!(f.set_real(v.name, f64::MAX), OK);
                        reads_are_finite_or_refused(&f, &format!("{} = f64::MAX", v.name));
                        f.reset_and_check();
                    }
                }
            }
            // The Integers: contact is a calculated output, contact_law a fixed parameter; in
            // Continuous-Time Mode no Integer can be set at all.
            for (name, in_event_mode) in [
                ("contact", "output computed by the FMU"),
                ("contact_law", "fixed parameter"),
            ] {
                let vr = [crate::robustness_common::named(m, name)];
                let reason = if event_mode {
                    in_event_mode
                } else {
                    "fmi2SetInteger is not allowed in state ContinuousTimeMode"
                };
                refused_in_me(model, event_mode, reason, |c| unsafe {
                    // SAFETY: arrays of length 1.
                    fmi2SetInteger(c, vr.as_ptr(), 1, [1].as_ptr())
                });
            }
        }
    }
    fresh_me_instance_works(BELT);
}

/// fmi2SetTime accepts any finite time from the start time on; the bounds are then brought to
/// that time when read (Model Exchange: the plants only; the controller has no bounds and no
/// Model Exchange). That must not take unbounded work: a far time is refused with a reason,
/// or the read answers promptly. (Each time runs in its own thread, so that a hang fails the
/// test instead of stalling the suite; a hung thread is left behind until the process exits.)
#[test]
fn model_exchange_far_times_are_refused_or_answered_promptly() {
    let limit = std::time::Duration::from_secs(5);
    // One at a time, each against its own deadline: the first read of the bounds after the far
    // time takes up to 0.8 s of work on the shaft and the belt and 1.9 s on the web line (measured
    // with the test profile), too much for all cases at once on two cores.
    let cases = [
        (SHAFT, 1e3),
        (BELT, 1e3),
        (WEB, 1e3),
        (SHAFT, 1e6),
        (BELT, 1e6),
        (WEB, 1e6),
        (BELT, 1e300),
        (WEB, 1e300),
    ];
    let mut slow = Vec::new();
    for (model, t) in cases {
        let (tx, rx) = std::sync::mpsc::channel();
        std::thread::spawn(move || {
            let f = Fmu::me_initialized(model, None);
            let before = f.log_len();
            let s = fmi2SetTime(f.c, t);
            if s != OK {
                f.assert_refused(s, before, "time");
            } else {
                // Every bound that follows time: the web span's too, where there is one.
                for name in ["bound", "bound_paper", "bound_T"] {
                    if f.model.by_name(name).is_some() {
                        let before = f.log_len();
                        let (s, bound) = f.get_real(name);
                        if s == OK {
                            assert!(bound.is_finite(), "{name} = {bound}");
                        } else {
                            f.assert_refused(s, before, "");
                            break;
                        }
                    }
                }
            }
            let _ = tx.send(());
        });
        let identifier = MODELS[model].identifier;
        match rx.recv_timeout(limit) {
            Ok(()) => {}
            Err(std::sync::mpsc::RecvTimeoutError::Timeout) => slow.push((identifier, t)),
            Err(e) => panic!("{identifier} at t = {t}: the call panicked ({e})"),
        }
    }
    assert!(
        slow.is_empty(),
        "fmi2SetTime(t) accepted, then fmi2GetReal(bound) did not return within {limit:?} for {slow:?}: \
         the bound is advanced in steps of at most max_step up to t"
    );
}

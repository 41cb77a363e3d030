//! Every lifecycle call in every reachable state, against the FMI 2.0.4 Co-Simulation table
//! of allowed calls, written out here independently of `src/fmu/state_machine.rs`.

use backlash_fmu::fmu::{FmuError, Instance, Phase, StatusKind, MODELS};

fn in_phase(phase: Phase) -> Instance {
    let mut inst = Instance::new(&MODELS[0], None, false);
    match phase {
        Phase::Instantiated => {}
        Phase::InitializationMode => {
            inst.enter_initialization_mode().unwrap();
        }
        Phase::StepComplete | Phase::Terminated => {
            inst.enter_initialization_mode().unwrap();
            inst.exit_initialization_mode().unwrap();
            if phase == Phase::Terminated {
                inst.terminate().unwrap();
            }
        }
        Phase::Error => {
            inst.exit_initialization_mode().unwrap_err();
        }
        Phase::StepFailed => unreachable!("never entered: steps either complete or fail with fmi2Error"),
    }
    assert_eq!(inst.phase(), phase);
    inst
}

type Call = fn(&mut Instance) -> Result<(), FmuError>;

#[test]
fn allowed_calls_match_the_standard_table() {
    use Phase::*;
    let phases = [Instantiated, InitializationMode, StepComplete, Terminated, Error];
    // (call, legal in I, M, C, T, E): FMI 2.0.4 §4.2.4, "x" columns of the Co-Simulation table.
    let table: [(&str, Call, [bool; 5]); 13] = [
        (
            "fmi2SetupExperiment",
            |i| i.setup_experiment(None, 0.0, None).map(drop),
            [true, false, false, false, false],
        ),
        (
            "fmi2EnterInitializationMode",
            |i| i.enter_initialization_mode().map(drop),
            [true, false, false, false, false],
        ),
        (
            "fmi2ExitInitializationMode",
            |i| i.exit_initialization_mode().map(drop),
            [false, true, false, false, false],
        ),
        (
            "fmi2Terminate",
            |i| i.terminate().map(drop),
            [false, false, true, false, false],
        ),
        ("fmi2Reset", |i| i.reset().map(drop), [true; 5]),
        (
            "fmi2GetReal",
            |i| i.get_real(&[], &mut []).map(drop),
            [false, true, true, true, true],
        ),
        (
            "fmi2SetReal",
            |i| i.set_real(&[], &[]).map(drop),
            [true, true, true, false, false],
        ),
        ("fmi2GetFMUstate", |i| i.get_fmu_state().map(drop), [true; 5]),
        (
            "fmi2SetRealInputDerivatives",
            |i| i.set_real_input_derivatives(&[], &[], &[]).map(drop),
            [true, true, true, false, false],
        ),
        (
            "fmi2GetRealOutputDerivatives",
            |i| i.get_real_output_derivatives(&[], &[], &mut []).map(drop),
            [false, false, true, true, true],
        ),
        (
            "fmi2DoStep",
            |i| i.do_step(i.time(), 0.01).map(drop),
            [false, false, true, false, false],
        ),
        (
            "fmi2GetStatus",
            |i| i.get_status(StatusKind::DoStepStatus).map(drop),
            [false, false, true, true, false],
        ),
        (
            "fmi2SetDebugLogging",
            |i| i.set_debug_logging(true, &[]).map(drop),
            [true; 5],
        ),
    ];
    for (name, call, legal) in table {
        for (phase, legal) in phases.iter().zip(legal) {
            let mut inst = in_phase(*phase);
            let illegal = matches!(call(&mut inst), Err(FmuError::IllegalCall { .. }));
            assert_eq!(illegal, !legal, "{name} in {phase}");
            if illegal {
                assert_eq!(inst.phase(), Error, "an illegal call enters Error");
            }
        }
    }
}

#[test]
fn cancel_step_is_never_legal() {
    let mut inst = in_phase(Phase::StepComplete);
    assert!(matches!(
        inst.cancel_step().unwrap_err(),
        FmuError::IllegalCall {
            function: "fmi2CancelStep",
            ..
        }
    ));
}

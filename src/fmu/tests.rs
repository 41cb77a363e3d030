//! Unit tests of the instance: state machine, per-variable set rules, refusals, FMU states.

use super::*;
use crate::fmu::logging::Collected;
use crate::fmu::state_machine::Interface;

fn shaft() -> (Instance, Collected) {
    let log = Collected::default();
    let inst = Instance::new(&MODELS[0], Some(Box::new(log.clone())), false);
    (inst, log)
}

fn vr(inst: &Instance, name: &str) -> u32 {
    inst.model().vr(name)
}

fn initialized() -> (Instance, Collected) {
    let (mut inst, log) = shaft();
    inst.setup_experiment(None, 0.0, None).unwrap();
    inst.enter_initialization_mode().unwrap();
    inst.exit_initialization_mode().unwrap();
    (inst, log)
}

fn messages(log: &Collected) -> Vec<String> {
    log.0.borrow().iter().map(|(_, _, m)| m.clone()).collect()
}

#[test]
fn illegal_call_is_refused_logged_and_enters_error() {
    let (mut inst, log) = shaft();
    let err = inst.do_step(0.0, 0.1).unwrap_err();
    assert_eq!(
        err,
        FmuError::IllegalCall {
            function: "fmi2DoStep",
            phase: Phase::Instantiated,
            rule: None,
        }
    );
    assert_eq!(inst.phase(), Phase::Error);
    assert!(messages(&log)[0].contains("fmi2DoStep is not allowed in state Instantiated"));
    // From Error only reset, free, logging, FMU states and (debug) gets are legal.
    assert!(inst.enter_initialization_mode().is_err());
    inst.reset().unwrap();
    assert_eq!(inst.phase(), Phase::Instantiated);
}

#[test]
fn lifecycle_moves_through_the_states() {
    let (mut inst, _) = shaft();
    inst.setup_experiment(Some(1e-6), 1.5, Some(3.0)).unwrap();
    inst.enter_initialization_mode().unwrap();
    assert_eq!(inst.phase(), Phase::InitializationMode);
    inst.exit_initialization_mode().unwrap();
    assert_eq!(inst.phase(), Phase::StepComplete);
    assert_eq!(inst.time(), 1.5);
    inst.do_step(1.5, 0.5).unwrap();
    assert_eq!(inst.time(), 2.0);
    inst.terminate().unwrap();
    assert_eq!(inst.phase(), Phase::Terminated);
    assert!(inst.do_step(2.0, 0.5).is_err());
}

#[test]
fn refused_values_never_reach_the_instance() {
    let (mut inst, log) = shaft();
    let (j_m, delta, tau) = (vr(&inst, "J_m"), vr(&inst, "Delta"), vr(&inst, "tau_m"));
    for (v, bad) in [
        (j_m, 0.0),
        (j_m, -1.0),
        (j_m, f64::NAN),
        (delta, -1e-9),
        (tau, f64::INFINITY),
        (tau, f64::NAN),
    ] {
        inst.reset().unwrap();
        // A valid value listed first is not stored either: the call is all or nothing.
        let err = inst.set_real(&[tau, v], &[7.0, bad]).unwrap_err();
        assert!(matches!(err, FmuError::ValueRefused { .. }), "{err}");
        inst.reset().unwrap();
        inst.enter_initialization_mode().unwrap();
        let mut out = [0.0; 2];
        inst.get_real(&[tau, j_m], &mut out).unwrap();
        assert_eq!(out, [0.0, 2.28]);
    }
    assert!(messages(&log)
        .iter()
        .any(|m| m.contains("refused for J_m") && m.contains("> 0")));
}

#[test]
fn set_rules_follow_causality_and_state() {
    let (mut inst, _) = shaft();
    let psi = vr(&inst, "psi");
    let sup = vr(&inst, "bound_sup");
    let err = inst.set_real(&[psi], &[1.0]).unwrap_err();
    assert!(matches!(err, FmuError::NotSettable { name: "psi", .. }));
    inst.reset().unwrap();
    assert!(matches!(
        inst.set_real(&[sup], &[1.0]).unwrap_err(),
        FmuError::NotSettable { name: "bound_sup", .. }
    ));

    let (mut inst, _) = initialized();
    inst.set_real(&[vr(&inst, "tau_m")], &[1.0]).unwrap();
    for name in ["J_m", "k", "Delta", "Kp", "theta_m", "omega_L"] {
        let (mut inst, _) = initialized();
        let err = inst.set_real(&[vr(&inst, name)], &[1.0]).unwrap_err();
        assert!(
            matches!(
                err,
                FmuError::NotSettable {
                    phase: Phase::StepComplete,
                    ..
                }
            ),
            "{name}: {err}"
        );
    }
}

#[test]
fn unknown_reference_and_wrong_type_are_refused() {
    let (mut inst, _) = initialized();
    let mut out = [0.0];
    assert!(matches!(
        inst.get_real(&[999], &mut out).unwrap_err(),
        FmuError::UnknownValueReference { vr: 999, .. }
    ));
    let (mut inst, _) = initialized();
    let contact = vr(&inst, "contact");
    assert!(matches!(
        inst.get_real(&[contact], &mut out).unwrap_err(),
        FmuError::WrongType { name: "contact", .. }
    ));
    let (mut inst, _) = initialized();
    let mut ints = [0];
    assert!(matches!(
        inst.get_integer(&[vr(&inst, "psi")], &mut ints).unwrap_err(),
        FmuError::WrongType { .. }
    ));
    let (mut inst, _) = initialized();
    assert!(matches!(
        inst.get_boolean(&[vr(&inst, "psi")], &mut ints).unwrap_err(),
        FmuError::WrongType { .. }
    ));
    let (mut inst, _) = initialized();
    inst.get_boolean(&[], &mut []).unwrap();
    inst.get_string(&[], 0).unwrap();
}

#[test]
fn invalid_parameters_are_named_at_exit_initialization() {
    let (mut inst, _) = shaft();
    // J_m > 0 is checked at set time; a magnitude the plant cannot integrate only at build time.
    inst.set_real(&[vr(&inst, "J_m"), vr(&inst, "k")], &[1e-300, 1e300])
        .unwrap();
    inst.enter_initialization_mode().unwrap();
    let err = inst.exit_initialization_mode().unwrap_err();
    assert!(matches!(err, FmuError::Parameter(_)), "{err}");
    assert!(err.to_string().contains("J_m = 1e-300"), "{err}");
    assert_eq!(inst.phase(), Phase::Error);
}

#[test]
fn step_arguments_are_checked() {
    for (t, h, what) in [
        (0.0, 0.0, "must be finite and > 0"),
        (0.0, -1.0, "must be finite and > 0"),
        (0.0, f64::NAN, "must be finite and > 0"),
        (0.0, f64::INFINITY, "must be finite and > 0"),
        (0.1, 0.1, "differs from the FMU's time"),
        (f64::NAN, 0.1, "not finite"),
        (0.0, 1e9, "exceeds"),
    ] {
        let (mut inst, _) = initialized();
        let err = inst.do_step(t, h).unwrap_err();
        assert!(err.to_string().contains(what), "{t} {h}: {err}");
    }
    let (mut inst, _) = shaft();
    inst.setup_experiment(None, 0.0, Some(1.0)).unwrap();
    inst.enter_initialization_mode().unwrap();
    inst.exit_initialization_mode().unwrap();
    inst.do_step(0.0, 1.0).unwrap();
    assert!(inst.do_step(1.0, 0.1).unwrap_err().to_string().contains("stopTime"));
}

#[test]
fn status_queries() {
    let (mut inst, _) = initialized();
    inst.do_step(0.0, 0.25).unwrap();
    assert_eq!(inst.get_status(StatusKind::DoStepStatus).unwrap(), Status::Ok);
    assert_eq!(inst.get_real_status(StatusKind::LastSuccessfulTime).unwrap(), 0.25);
    assert!(!inst.get_boolean_status(StatusKind::Terminated).unwrap());
    // Unavailable status is fmi2Discard and leaves the state alone.
    let err = inst.get_status(StatusKind::PendingStatus).unwrap_err();
    assert_eq!(err.status(), Status::Discard);
    assert_eq!(inst.phase(), Phase::StepComplete);
    assert!(inst.cancel_step().is_err());
}

#[test]
fn debug_logging_filters_categories() {
    let (mut inst, log) = shaft();
    assert!(inst.set_debug_logging(true, &["logNothing"]).is_err());
    inst.reset().unwrap();
    inst.set_debug_logging(false, &[]).unwrap();
    assert!(inst.do_step(0.0, 1.0).is_err());
    assert_eq!(
        messages(&log).len(),
        1,
        "only the unknown-category error: errors were switched off"
    );
    inst.reset().unwrap();
    inst.set_debug_logging(true, &["logCalls"]).unwrap();
    inst.enter_initialization_mode().unwrap();
    assert!(messages(&log)
        .last()
        .unwrap()
        .contains("fmi2EnterInitializationMode -> OK"));
}

#[test]
fn fmu_state_round_trip_in_every_reachable_phase() {
    let (mut inst, _) = shaft();
    let tau = vr(&inst, "tau_m");
    inst.set_real(&[tau], &[3.0]).unwrap();
    let before_init = inst.get_fmu_state().unwrap();
    inst.enter_initialization_mode().unwrap();
    inst.exit_initialization_mode().unwrap();
    inst.do_step(0.0, 0.3).unwrap();
    let stepped = inst.get_fmu_state().unwrap();
    for snap in [&before_init, &stepped] {
        let bytes = inst.serialize_fmu_state(snap).unwrap();
        assert_eq!(bytes.len(), snap.serialized_len());
        let back = inst.deserialize_fmu_state(&bytes).unwrap();
        assert_eq!(&back, snap);
    }
    inst.set_fmu_state(&before_init).unwrap();
    assert_eq!(inst.phase(), Phase::Instantiated);
    inst.set_fmu_state(&stepped).unwrap();
    assert_eq!((inst.phase(), inst.time()), (Phase::StepComplete, 0.3));
}

#[test]
fn a_state_of_the_other_model_is_refused() {
    let (mut shaft, _) = shaft();
    let mut belt = Instance::new(&MODELS[1], None, false);
    let snap = belt.get_fmu_state().unwrap();
    let bytes = belt.serialize_fmu_state(&snap).unwrap();
    let err = shaft.deserialize_fmu_state(&bytes).unwrap_err();
    assert!(err.to_string().contains("BacklashShaft"), "{err}");
    let (mut shaft, _) = self::shaft();
    assert!(shaft.set_fmu_state(&snap).is_err());
}

fn model_exchange(model: usize) -> Instance {
    let mut inst = Instance::new_for(&MODELS[model], Interface::ModelExchange, None, false);
    inst.setup_experiment(None, 0.5, None).unwrap();
    inst.enter_initialization_mode().unwrap();
    inst.exit_initialization_mode().unwrap();
    inst
}

fn read(inst: &mut Instance, name: &str) -> f64 {
    let mut out = [0.0];
    inst.get_real(&[vr(inst, name)], &mut out).unwrap();
    out[0]
}

#[test]
fn model_exchange_lifecycle_and_refusals() {
    let mut inst = model_exchange(0);
    assert_eq!(inst.phase(), Phase::EventMode);
    let info = inst.new_discrete_states().unwrap();
    assert!(!info.new_discrete_states_needed && info.next_event_time.is_none());
    inst.enter_continuous_time_mode().unwrap();
    assert_eq!(inst.phase(), Phase::ContinuousTimeMode);
    inst.set_time(0.7).unwrap();
    inst.set_continuous_states(&[0.01, 0.2, 0.0, -0.1]).unwrap();
    let mut z = [0.0; 4];
    inst.get_continuous_states(&mut z).unwrap();
    assert_eq!(z, [0.01, 0.2, 0.0, -0.1]);
    assert_eq!(inst.completed_integrator_step().unwrap(), (false, false));
    // Co-Simulation calls are refused with the reason.
    let err = inst.do_step(0.7, 0.1).unwrap_err();
    assert!(err.to_string().contains("belongs to FMI for Co-Simulation"), "{err}");
    // Wrong lengths, non-finite states and times before the start are refused.
    for bad in [&[0.0; 3][..], &[0.0, f64::NAN, 0.0, 0.0], &[f64::INFINITY; 4]] {
        let mut inst = model_exchange(0);
        inst.enter_continuous_time_mode().unwrap();
        assert!(inst.set_continuous_states(bad).is_err());
        assert_eq!(inst.phase(), Phase::Error);
    }
    for bad in [f64::NAN, 0.4, f64::INFINITY] {
        let mut inst = model_exchange(0);
        assert!(inst.set_time(bad).is_err(), "time {bad}");
    }
    // And a Co-Simulation instance refuses the Model Exchange calls.
    let (mut cs, _) = initialized();
    let err = cs.set_time(0.1).unwrap_err();
    assert!(err.to_string().contains("belongs to FMI for Model Exchange"), "{err}");
}

/// The bounds are functions of time − startTime alone: any path of fmi2SetTime calls, forwards
/// or backwards, gives the Co-Simulation value at that time (stepped there in steps of 0.01 s).
#[test]
fn model_exchange_bounds_follow_time_both_ways_and_match_co_simulation() {
    for model in [0, 1] {
        let mut me = model_exchange(model);
        me.enter_continuous_time_mode().unwrap();
        let mut cs = Instance::new(&MODELS[model], None, false);
        cs.setup_experiment(None, 0.5, None).unwrap();
        cs.enter_initialization_mode().unwrap();
        cs.exit_initialization_mode().unwrap();
        let h = MODELS[model].default_experiment.step_size;
        let mut cs_at = Vec::new();
        let mut t = 0.5;
        for k in 1..=40 {
            cs.do_step(t, h).unwrap();
            t = 0.5 + k as f64 * h;
            cs_at.push((t, read(&mut cs, "bound"), read(&mut cs, "bound_paper")));
        }
        for &index in &[39usize, 5, 20, 0, 39, 38, 10] {
            let (t, bound, paper) = cs_at[index];
            me.set_time(t).unwrap();
            let (b, p) = (read(&mut me, "bound"), read(&mut me, "bound_paper"));
            assert!((b - bound).abs() <= 1e-12 * bound, "{model} t {t}: {b} vs {bound}");
            assert!((p - paper).abs() <= 1e-12 * paper, "{model} t {t}: {p} vs {paper}");
        }
    }
}

#[test]
fn model_exchange_states_do_not_cross_interfaces() {
    let mut me = model_exchange(0);
    me.enter_continuous_time_mode().unwrap();
    me.set_continuous_states(&[0.01, 0.2, 0.0, -0.1]).unwrap();
    let snap = me.get_fmu_state().unwrap();
    let bytes = me.serialize_fmu_state(&snap).unwrap();
    // Into another Model Exchange instance: restored exactly, state machine included.
    let mut other = Instance::new_for(&MODELS[0], Interface::ModelExchange, None, false);
    let restored = other.deserialize_fmu_state(&bytes).unwrap();
    other.set_fmu_state(&restored).unwrap();
    assert_eq!(other.phase(), Phase::ContinuousTimeMode);
    let (mut a, mut b) = ([0.0; 4], [0.0; 4]);
    me.get_derivatives(&mut a).unwrap();
    other.get_derivatives(&mut b).unwrap();
    // The same state, restored bit for bit, through the same vector field.
    assert_eq!(a, b);
    // Into a Co-Simulation instance: refused with the reason.
    let (mut cs, _) = shaft();
    let snap = cs.deserialize_fmu_state(&bytes).unwrap();
    let err = cs.set_fmu_state(&snap).unwrap_err();
    assert!(
        err.to_string().contains("taken from a Model Exchange instance"),
        "{err}"
    );
}

/// A loop that never settles (no damping, no controller): a bound read far from the start is
/// refused with the reason after a bounded amount of work, not computed for ever.
#[test]
fn model_exchange_bound_far_out_on_an_undamped_loop_is_refused_promptly() {
    let mut inst = Instance::new_for(&MODELS[0], Interface::ModelExchange, None, false);
    let (b_m, b_l) = (vr(&inst, "b_m"), vr(&inst, "b_L"));
    inst.set_real(&[b_m, b_l], &[0.0, 0.0]).unwrap();
    inst.setup_experiment(None, 0.0, None).unwrap();
    inst.enter_initialization_mode().unwrap();
    inst.exit_initialization_mode().unwrap_or_else(|e| panic!("{e}"));
    inst.enter_continuous_time_mode().unwrap();
    inst.set_time(1e300).unwrap();
    let started = std::time::Instant::now();
    let mut out = [0.0];
    let err = inst.get_real(&[vr(&inst, "bound")], &mut out).unwrap_err();
    assert!(err.to_string().contains("out of reach"), "{err}");
    assert!(
        started.elapsed() < std::time::Duration::from_secs(20),
        "{:?}",
        started.elapsed()
    );
}

/// The input lines' order is one: each slot's symbol is mapped to that slot, and is named as
/// docs/model.md §4 and §8 name the inputs.
#[test]
fn input_slots_are_the_symbols_order() {
    use crate::fmu::adapter::{input_name, Source, INPUT_SYMBOLS};
    for (slot, symbol) in INPUT_SYMBOLS.iter().enumerate() {
        assert_eq!(symbol.source(), Source::Input(slot));
    }
    let names: Vec<&str> = (0..INPUT_SYMBOLS.len()).map(input_name).collect();
    assert_eq!(names, ["tau_m", "tau_L", "v_in", "T_in"]);
}

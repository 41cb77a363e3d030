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

// ---- the damper in the compliant member: d / D_b and the Integer parameter contact_law ----

/// A fresh instance of `model` of `standard` (Co-Simulation), with its log (on: FMI 3.0 logs
/// nothing otherwise).
fn instance_of(model: usize, standard: Standard) -> (Instance, Collected) {
    let log = Collected::default();
    let flavour = Flavour {
        standard,
        interface: Interface::CoSimulation,
    };
    let inst = Instance::with(
        &MODELS[model],
        flavour,
        CoSimulationOptions::default(),
        Some(Box::new(log.clone())),
        true,
    );
    (inst, log)
}

fn read_integer(inst: &mut Instance, name: &str) -> i32 {
    let mut out = [0];
    inst.get_integer(&[vr(inst, name)], &mut out).unwrap();
    out[0]
}

/// The damping parameter of each model: the shaft's `d`, a belt's `D_b` (the web line's too).
const DAMPING: [(&str, &str, &str); 3] = [
    ("d", "N.m.s/rad", "RotationalDampingConstant"),
    ("D_b", "N.s/m", "TranslationalDampingConstant"),
    ("D_b", "N.s/m", "TranslationalDampingConstant"),
];

#[test]
fn the_descriptions_list_the_damper_contact_law_and_ten_event_indicators() {
    use crate::fmu::variables::{Causality, Initial, Range, VarType, Variability};
    for (model, (damping, unit, quantity)) in MODELS.iter().zip(DAMPING) {
        let id = model.identifier;
        let d = model
            .by_name(damping)
            .unwrap_or_else(|| panic!("{id} has no {damping}"));
        assert_eq!(
            (d.vr, d.ty, d.causality, d.variability, d.initial),
            (
                42,
                VarType::Real,
                Causality::Parameter,
                Variability::Fixed,
                Initial::Exact
            ),
            "{id}"
        );
        assert_eq!(
            (d.start, d.range, d.unit, d.quantity),
            (Some(0.0), Range::NonNegative, unit, quantity),
            "{id}"
        );
        let law = model.by_name("contact_law").unwrap();
        assert_eq!(
            (law.vr, law.ty, law.causality, law.variability, law.initial, law.start),
            (
                43,
                VarType::Integer,
                Causality::Parameter,
                Variability::Fixed,
                Initial::Exact,
                Some(1.0)
            ),
            "{id}"
        );
        assert_eq!(law.range, Range::Integers { min: 1, max: 2 }, "{id}");
        assert!(
            law.description.contains("1: Modelica ElastoBacklash") && law.description.contains("2: ElastoBacklash2")
        );
        for (vr, name) in [
            (44, "force_upper"),
            (45, "force_lower"),
            (46, "cap_upper"),
            (47, "cap_lower"),
        ] {
            let v = model.by_name(name).unwrap();
            assert_eq!(
                (v.vr, v.ty, v.causality, v.variability),
                (vr, VarType::Real, Causality::Local, Variability::Continuous),
                "{id} {name}"
            );
        }

        // As the FMI 2.0 and 3.0 descriptions write them.
        let text2 = model_description::xml::model_description(id);
        let doc = roxmltree::Document::parse(&text2).unwrap();
        assert_eq!(
            doc.root_element().attribute("numberOfEventIndicators"),
            Some("10"),
            "{id}"
        );
        let scalar = |name: &str| {
            let v = doc
                .descendants()
                .find(|n| n.has_tag_name("ScalarVariable") && n.attribute("name") == Some(name))
                .unwrap_or_else(|| panic!("{id}: no {name}"));
            v.children().find(|n| n.is_element()).unwrap()
        };
        let typed = scalar("contact_law");
        assert_eq!(typed.tag_name().name(), "Integer");
        fn attributes<'a>(n: roxmltree::Node<'a, '_>) -> [Option<&'a str>; 3] {
            [n.attribute("min"), n.attribute("max"), n.attribute("start")]
        }
        assert_eq!(attributes(typed), [Some("1"), Some("2"), Some("1")], "{id}");
        let typed = scalar(damping);
        assert_eq!(typed.tag_name().name(), "Real");
        assert_eq!(attributes(typed), [Some("0.0"), None, Some("0.0")], "{id}");
        assert_eq!(typed.attribute("unit"), Some(unit));
        assert_eq!(attributes(scalar("contact"))[..2], [Some("-1"), Some("1")], "{id}");

        let text3 = model_description::xml3::model_description(id);
        let doc3 = roxmltree::Document::parse(&text3).unwrap();
        let law = doc3
            .descendants()
            .find(|n| n.attribute("name") == Some("contact_law"))
            .unwrap();
        assert_eq!(law.tag_name().name(), "Int32");
        assert_eq!(
            [
                law.attribute("causality"),
                law.attribute("variability"),
                law.attribute("start")
            ],
            [Some("parameter"), Some("fixed"), Some("1")]
        );
        assert_eq!([law.attribute("min"), law.attribute("max")], [Some("1"), Some("2")]);
        let indicators: Vec<&str> = doc3
            .descendants()
            .filter(|n| n.has_tag_name("EventIndicator"))
            .map(|n| n.attribute("valueReference").unwrap())
            .collect();
        assert_eq!(
            indicators,
            ["28", "29", "44", "45", "46", "47", "54", "55", "56", "57"],
            "{id}"
        );
    }
}

#[test]
fn contact_law_admits_1_and_2_only_in_both_standards() {
    for standard in [Standard::Fmi2, Standard::Fmi3] {
        for model in 0..MODELS.len() {
            for bad in [3, 0, -1] {
                let (mut inst, log) = instance_of(model, standard);
                let law = vr(&inst, "contact_law");
                // All or nothing: the admissible value before it is not stored either.
                let err = inst.set_integer(&[law, law], &[2, bad]).unwrap_err();
                assert_eq!(err.status(), Status::Error);
                let reason = err.to_string();
                assert!(
                    reason.contains("contact_law")
                        && reason.contains(&format!("value {bad} "))
                        && reason.contains("1 or 2"),
                    "{reason}"
                );
                assert!(
                    messages(&log).iter().any(|m| m.contains(&reason)),
                    "{:?}",
                    messages(&log)
                );
                assert_eq!(inst.phase(), Phase::Error);
                // Gets are legal in Error: the start value is still there.
                assert_eq!(read_integer(&mut inst, "contact_law"), 1);
            }
            let (mut inst, _) = instance_of(model, standard);
            let law = vr(&inst, "contact_law");
            inst.set_integer(&[law], &[2]).unwrap();
            inst.enter_initialization_mode().unwrap();
            assert_eq!(read_integer(&mut inst, "contact_law"), 2);
            inst.set_integer(&[law], &[1]).unwrap();
            assert_eq!(read_integer(&mut inst, "contact_law"), 1);
        }
    }
}

/// contact_law follows the rules of the fixed Real parameters, and the Real get and set refuse
/// it by its type (and the Integer ones a Real).
#[test]
fn contact_law_is_a_fixed_integer_parameter() {
    for standard in [Standard::Fmi2, Standard::Fmi3] {
        let (mut inst, _) = instance_of(0, standard);
        let (law, d, contact) = (vr(&inst, "contact_law"), vr(&inst, "d"), vr(&inst, "contact"));
        inst.enter_initialization_mode().unwrap();
        inst.set_integer(&[law], &[2]).unwrap();
        inst.exit_initialization_mode().unwrap();
        assert_eq!(read_integer(&mut inst, "contact_law"), 2);
        let err = inst.set_integer(&[law], &[1]).unwrap_err();
        assert!(
            matches!(
                err,
                FmuError::NotSettable {
                    name: "contact_law",
                    phase: Phase::StepComplete,
                    ..
                }
            ),
            "{err}"
        );
        assert!(err.to_string().contains("fixed parameter"), "{err}");

        let (mut inst, _) = instance_of(0, standard);
        let err = inst.set_real(&[law], &[2.0]).unwrap_err();
        assert!(
            matches!(
                err,
                FmuError::WrongType {
                    name: "contact_law",
                    ..
                }
            ),
            "{err}"
        );
        let (mut inst, _) = instance_of(0, standard);
        inst.enter_initialization_mode().unwrap();
        assert!(matches!(
            inst.get_real(&[law], &mut [0.0]).unwrap_err(),
            FmuError::WrongType {
                name: "contact_law",
                ..
            }
        ));
        let (mut inst, _) = instance_of(0, standard);
        assert!(matches!(
            inst.set_integer(&[d], &[1]).unwrap_err(),
            FmuError::WrongType { name: "d", .. }
        ));
        let (mut inst, _) = instance_of(0, standard);
        assert!(matches!(
            inst.set_integer(&[contact], &[1]).unwrap_err(),
            FmuError::NotSettable { name: "contact", .. }
        ));
        let (mut inst, _) = instance_of(0, standard);
        assert!(matches!(
            inst.set_integer(&[law], &[]).unwrap_err(),
            FmuError::LengthMismatch { .. }
        ));
    }
}

/// A negative or non-finite damping is refused when it is set, naming the parameter; the plant
/// refuses it by name too, should one reach it.
#[test]
fn a_negative_or_nan_damping_is_refused_by_its_name() {
    for (model, (damping, _, _)) in DAMPING.iter().enumerate() {
        for bad in [-1.0, f64::NAN, f64::INFINITY] {
            let (mut inst, log) = instance_of(model, Standard::Fmi2);
            let err = inst.set_real(&[vr(&inst, damping)], &[bad]).unwrap_err();
            assert!(
                matches!(err, FmuError::ValueRefused { name, .. } if name == *damping),
                "{err}"
            );
            assert!(err.to_string().contains(">= 0"), "{err}");
            assert!(messages(&log)
                .iter()
                .any(|m| m.contains(&format!("refused for {damping}"))));
        }
        let mut values = crate::fmu::adapter::start_values(&MODELS[model]);
        values[MODELS[model].by_name(damping).unwrap().symbol.index()] = -1.0;
        let err =
            crate::physics::Plant::new(crate::fmu::adapter::plant_params(&MODELS[model], &values).expect("a plant"))
                .unwrap_err();
        assert!(err.to_string().contains(damping), "{err}");
        // A valid one is taken, and initialization goes through.
        let (mut inst, _) = instance_of(model, Standard::Fmi2);
        inst.set_real(&[vr(&inst, damping)], &[0.5]).unwrap();
        inst.set_integer(&[vr(&inst, "contact_law")], &[2]).unwrap();
        inst.enter_initialization_mode().unwrap();
        inst.exit_initialization_mode()
            .unwrap_or_else(|e| panic!("{damping}: {e}"));
        assert_eq!(read(&mut inst, damping), 0.5);
    }
}

/// An FMU state keeps contact_law (and the damping): get/set, serialize/deserialize; a state
/// whose contact_law is neither 1 nor 2 is refused.
#[test]
fn fmu_states_carry_contact_law() {
    for standard in [Standard::Fmi2, Standard::Fmi3] {
        let (mut inst, _) = instance_of(1, standard);
        let (law, d_b) = (vr(&inst, "contact_law"), vr(&inst, "D_b"));
        inst.set_integer(&[law], &[2]).unwrap();
        inst.set_real(&[d_b], &[3.0]).unwrap();
        let before_init = inst.get_fmu_state().unwrap();
        inst.enter_initialization_mode().unwrap();
        inst.exit_initialization_mode().unwrap();
        let running = inst.get_fmu_state().unwrap();
        for snap in [&before_init, &running] {
            let bytes = inst.serialize_fmu_state(snap).unwrap();
            let (mut other, _) = instance_of(1, standard);
            let back = other.deserialize_fmu_state(&bytes).unwrap();
            assert_eq!(&back, snap);
            other.set_fmu_state(&back).unwrap();
            if other.phase() == Phase::Instantiated {
                other.enter_initialization_mode().unwrap();
            }
            assert_eq!(read_integer(&mut other, "contact_law"), 2);
            assert_eq!(read(&mut other, "D_b"), 3.0);
        }
        inst.reset().unwrap();
        inst.enter_initialization_mode().unwrap();
        assert_eq!(read_integer(&mut inst, "contact_law"), 1);
        inst.set_fmu_state(&running).unwrap();
        assert_eq!(read_integer(&mut inst, "contact_law"), 2);

        for bad in [3.0, 0.0, 1.5] {
            let mut snap = running.clone();
            snap.values[Symbol::ContactLaw.index()] = bad;
            let bytes = snap.to_bytes();
            let err = inst.deserialize_fmu_state(&bytes).unwrap_err();
            assert!(err.to_string().contains(&format!("contact_law = {bad}")), "{err}");
            let (mut other, _) = instance_of(1, standard);
            let err = other.set_fmu_state(&snap).unwrap_err();
            assert!(err.to_string().contains("contact_law"), "{err}");
        }
    }
}

/// With a damper the indicators and their Jacobian rows are those of the physics: the values
/// through get_real and fmi2GetEventIndicators, the rows through the directional derivative.
#[test]
fn the_damper_indicators_and_their_jacobian_rows() {
    for law in [1, 2] {
        let mut inst = Instance::new_for(&MODELS[0], Interface::ModelExchange, None, false);
        inst.set_real(&[vr(&inst, "d"), vr(&inst, "Delta")], &[2.0, 1e-3])
            .unwrap();
        inst.set_integer(&[vr(&inst, "contact_law")], &[law]).unwrap();
        inst.setup_experiment(None, 0.0, None).unwrap();
        inst.enter_initialization_mode().unwrap();
        inst.exit_initialization_mode().unwrap();
        inst.enter_continuous_time_mode().unwrap();
        let z = [0.004, 0.3, 0.001, -0.2];
        inst.set_continuous_states(&z).unwrap();
        let (u, du) = (z[0] - z[2], z[1] - z[3]);
        let (k, d, g) = (200.0, 2.0, 1e-3);
        let cap = |x: f64| if law == 1 { x } else { 1.0 };
        let expected = [
            u - g,
            u + g,
            k * (u - g) + d * du,
            k * (u + g) + d * du,
            cap(d * du - k * (u - g)),
            cap(d * du - k * (u + g)),
        ];
        let mut indicators = [0.0; 10];
        inst.get_event_indicators(&mut indicators).unwrap();
        let names = [
            "u_minus_g",
            "u_plus_g",
            "force_upper",
            "force_lower",
            "cap_upper",
            "cap_lower",
        ];
        for ((name, x), e) in names.iter().zip(indicators).zip(expected) {
            assert!(
                (x - e).abs() <= 1e-12 * e.abs().max(1.0),
                "law {law} {name}: {x} vs {e}"
            );
            assert_eq!(read(&mut inst, name), x, "{name}");
        }
        // Each row against the seed: J v = the indicator's change along v.
        let states: Vec<u32> = ["theta_m", "omega_m", "theta_L", "omega_L"]
            .iter()
            .map(|n| vr(&inst, n))
            .collect();
        let unknowns: Vec<u32> = names.iter().map(|n| vr(&inst, n)).collect();
        let seed = [0.5, -1.5, 0.25, 2.0];
        let mut rows = [0.0; 6];
        inst.get_directional_derivative(&unknowns, &states, &seed, &mut rows)
            .unwrap();
        let (dv, ddv) = (seed[0] - seed[2], seed[1] - seed[3]);
        let slope = [
            dv,
            dv,
            k * dv + d * ddv,
            k * dv + d * ddv,
            if law == 1 { d * ddv - k * dv } else { 0.0 },
            if law == 1 { d * ddv - k * dv } else { 0.0 },
        ];
        for ((name, x), e) in names.iter().zip(rows).zip(slope) {
            assert!(
                (x - e).abs() <= 1e-12 * e.abs().max(1.0),
                "law {law} {name}: {x} vs {e}"
            );
        }
    }
    // Without a damper the four damper indicators are 1 and their rows 0, and so are the four
    // of friction without friction (docs/model.md §12).
    let mut inst = model_exchange(0);
    inst.enter_continuous_time_mode().unwrap();
    let mut indicators = [0.0; 10];
    inst.get_event_indicators(&mut indicators).unwrap();
    assert_eq!(indicators[2..], [1.0; 8]);
}

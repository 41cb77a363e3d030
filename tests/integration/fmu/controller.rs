//! BacklashController through the library's Rust API (docs/model.md §9): the sampled PI's law
//! worked by hand, its timing (each sample's torque out after the step, the reference on the
//! controller's own count of samples), and its refusals (another step size, Model Exchange,
//! Event Mode, FMU states, input and output derivatives, an overflowing sample).

use backlash_fmu::fmu::{
    CoSimulationOptions, Flavour, FmuError, Instance, Interface, Phase, Standard, Status, CONTROLLERS,
};

fn controller(standard: Standard, params: &[(&str, f64)], reference: i32) -> Instance {
    let model = &CONTROLLERS[0];
    let flavour = Flavour {
        standard,
        interface: Interface::CoSimulation,
    };
    let mut inst = Instance::with(model, flavour, CoSimulationOptions::default(), None, false);
    for (name, value) in params {
        inst.set_real(&[model.vr(name)], &[*value]).unwrap();
    }
    inst.set_integer(&[model.vr("reference")], &[reference]).unwrap();
    inst.setup_experiment(None, 0.0, None).unwrap();
    inst.enter_initialization_mode().unwrap();
    assert_eq!(inst.exit_initialization_mode().unwrap(), Status::Ok);
    inst
}

fn torque(inst: &mut Instance) -> f64 {
    let mut out = [f64::NAN];
    inst.get_real(&[inst.model().vr("tau_m")], &mut out).unwrap();
    out[0]
}

fn measure(inst: &mut Instance, omega_m: f64, tension: f64) {
    let model = inst.model();
    inst.set_real(&[model.vr("omega_m"), model.vr("T")], &[omega_m, tension])
        .unwrap();
}

/// Step reference 1, Kp = 2, Ki = 3, h = 0.5 (binary fractions: every value below is exact).
/// Sample 0: e = 1 - 0.5 = 0.5, u_0 = 1, x_c = 0.25; sample 1: e = 1 - 0.25 = 0.75,
/// u_1 = 1.5 + 0.75 = 2.25, x_c = 0.625; sample 2: e = 1 - 1 = 0, u_2 = 1.875.
#[test]
fn each_sample_torque_is_out_after_its_step_worked_by_hand() {
    for standard in [Standard::Fmi2, Standard::Fmi3] {
        let params = [
            ("Kp", 2.0),
            ("Ki", 3.0),
            ("h", 0.5),
            ("amplitude", 1.0),
            ("tau_m", 0.125),
        ];
        let mut inst = controller(standard, &params, 1);
        // Before the first step ends: tau_m's start value, as set.
        measure(&mut inst, 0.5, 0.0);
        assert_eq!(torque(&mut inst), 0.125);
        inst.do_step(0.0, 0.5).unwrap();
        assert_eq!(torque(&mut inst), 1.0);
        // A new input changes nothing until the next sample: no direct feedthrough.
        measure(&mut inst, 0.25, 0.0);
        assert_eq!(torque(&mut inst), 1.0);
        inst.do_step(0.5, 0.5).unwrap();
        assert_eq!(torque(&mut inst), 2.25);
        measure(&mut inst, 1.0, 0.0);
        inst.do_step(1.0, 0.5).unwrap();
        assert_eq!(torque(&mut inst), 1.875);
        assert_eq!(inst.time(), 1.5);
    }
}

/// The tension loop trims the speed reference (step reference 0): T_ref = 10, T = 6, Kp_T = 0.5,
/// Ki_T = 1, Kp = 2, Ki = 0 (so u = 2 e), h = 0.5. Sample 0: e_T = 4, e = 0 + 2 + 0 - 1 = 1, u = 2,
/// x_T = 2; sample 1: e = 2 + 2 - 1 = 3, u = 6.
#[test]
fn the_tension_loop_trims_the_speed_reference_worked_by_hand() {
    let params = [
        ("Kp", 2.0),
        ("Ki", 0.0),
        ("Kp_T", 0.5),
        ("Ki_T", 1.0),
        ("T_ref", 10.0),
        ("h", 0.5),
        ("amplitude", 0.0),
    ];
    let mut inst = controller(Standard::Fmi2, &params, 1);
    measure(&mut inst, 1.0, 6.0);
    inst.do_step(0.0, 0.5).unwrap();
    assert_eq!(torque(&mut inst), 2.0);
    inst.do_step(0.5, 0.5).unwrap();
    assert_eq!(torque(&mut inst), 6.0);
}

/// The references at the samples, through u = Kp r with omega_m = 0 and Ki = 0: the trapezoid
/// (amplitude 4, ramp 2 s, hold 1 s) at t = k h, h = 0.5, worked by hand; the sine at its own
/// count of samples k h, whatever the communication points the importer passes (a clock summed
/// step by step drifts from k h).
#[test]
fn the_references_are_read_at_the_controllers_own_sample_times() {
    let mut inst = controller(
        Standard::Fmi2,
        &[
            ("Kp", 1.0),
            ("Ki", 0.0),
            ("h", 0.5),
            ("amplitude", 4.0),
            ("t_ramp", 2.0),
            ("t_hold", 1.0),
        ],
        2,
    );
    let mut seen = Vec::new();
    for k in 0..12 {
        inst.do_step(f64::from(k) * 0.5, 0.5).unwrap();
        seen.push(torque(&mut inst));
    }
    assert_eq!(seen, [0.0, 1.0, 2.0, 3.0, 4.0, 4.0, 4.0, 3.0, 2.0, 1.0, 0.0, 0.0]);

    let (h, f, a) = (0.1, 1.25, 2.0);
    let mut inst = controller(
        Standard::Fmi3,
        &[("Kp", 1.0), ("Ki", 0.0), ("h", h), ("amplitude", a), ("frequency", f)],
        3,
    );
    let mut t = 0.0;
    for k in 0..50 {
        inst.do_step(t, h).unwrap();
        t += h;
        let sample_time = f64::from(k) * h;
        let expected = a * (2.0 * std::f64::consts::PI * f * sample_time).sin();
        // |r| <= 2; the argument is below 8 pi, so sin is evaluated to an ulp or two of it.
        assert!((torque(&mut inst) - expected).abs() <= 1e-14, "sample {k}");
    }
    // The summed clock drifted away from 50 h; the controller kept its own count.
    assert_ne!(t, 50.0 * h);
}

#[test]
fn a_step_of_another_size_is_refused_with_the_reason() {
    let mut inst = controller(Standard::Fmi2, &[("h", 1e-3)], 1);
    let err = inst.do_step(0.0, 2e-3).unwrap_err();
    assert!(err.to_string().contains("is not the sample period h = 0.001"), "{err}");
    assert_eq!(inst.phase(), Phase::Error);
    // A master's clock in integer nanoseconds: within 1e-9 relative of h, taken.
    let mut inst = controller(Standard::Fmi2, &[("h", 1e-3)], 1);
    let (t1, t2) = (1_000_000.0 / 1e9, 2_000_000.0 / 1e9);
    inst.do_step(0.0, t1).unwrap();
    inst.do_step(t1, t2 - t1).unwrap();
}

#[test]
fn what_a_controller_does_not_offer_is_refused_naming_the_flag() {
    let model = &CONTROLLERS[0];
    let fmi3_cs = Flavour {
        standard: Standard::Fmi3,
        interface: Interface::CoSimulation,
    };
    let me = Flavour {
        standard: Standard::Fmi2,
        interface: Interface::ModelExchange,
    };
    let why = Instance::offered(model, me, CoSimulationOptions::default()).unwrap_err();
    assert!(why.contains("Co-Simulation only"), "{why}");
    let events = CoSimulationOptions {
        event_mode_used: true,
        early_return_allowed: false,
    };
    let why = Instance::offered(model, fmi3_cs, events).unwrap_err();
    assert!(why.contains("hasEventMode = false"), "{why}");
    assert!(Instance::offered(model, fmi3_cs, CoSimulationOptions::default()).is_ok());

    let mut inst = controller(Standard::Fmi2, &[], 3);
    let not_provided = |e: FmuError, flag: &str| assert!(e.to_string().contains(flag), "{e}");
    not_provided(inst.get_fmu_state().unwrap_err(), "canGetAndSetFMUstate = false");
    inst.reset().unwrap();
    let mut inst = controller(Standard::Fmi2, &[], 3);
    let vr = inst.model().vr("omega_m");
    not_provided(
        inst.set_real_input_derivatives(&[vr], &[1], &[1.0]).unwrap_err(),
        "canInterpolateInputs = false",
    );
    let mut inst = controller(Standard::Fmi2, &[], 3);
    let vr = inst.model().vr("tau_m");
    not_provided(
        inst.get_real_output_derivatives(&[vr], &[1], &mut [0.0]).unwrap_err(),
        "maxOutputDerivativeOrder = 0",
    );
}

#[test]
fn an_overflowing_sample_is_refused_and_changes_nothing() {
    let mut inst = controller(Standard::Fmi2, &[("Kp", 1e300), ("Ki", 0.0), ("h", 1.0)], 1);
    measure(&mut inst, -1e300, 0.0);
    let err = inst.do_step(0.0, 1.0).unwrap_err();
    assert!(matches!(err, FmuError::Overflow(_)), "{err}");
    assert_eq!(inst.time(), 0.0);
    let mut out = [f64::NAN];
    // Gets stay legal in Error: the torque is the one held before.
    inst.get_real(&[inst.model().vr("tau_m")], &mut out).unwrap();
    assert_eq!(out[0], 0.0);
}

/// fmi2Reset returns the controller to its start: a rerun gives the same torques bit for bit.
#[test]
fn reset_and_rerun_give_the_same_torques() {
    let run = |inst: &mut Instance| -> Vec<u64> {
        let mut out = Vec::new();
        for k in 0..20 {
            measure(inst, 0.01 * f64::from(k), 0.0);
            inst.do_step(f64::from(k) * 1e-3, 1e-3).unwrap();
            out.push(torque(inst).to_bits());
        }
        out
    };
    let params = [("Kp", 40.0), ("Ki", 180.0), ("amplitude", 0.05), ("frequency", 1.4)];
    let mut inst = controller(Standard::Fmi2, &params, 3);
    let first = run(&mut inst);
    inst.reset().unwrap();
    for (name, value) in params {
        inst.set_real(&[inst.model().vr(name)], &[value]).unwrap();
    }
    inst.setup_experiment(None, 0.0, None).unwrap();
    inst.enter_initialization_mode().unwrap();
    inst.exit_initialization_mode().unwrap();
    assert_eq!(run(&mut inst), first);
}

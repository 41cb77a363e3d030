//! Bearing friction with stiction through the FMU (docs/model.md §12), against closed forms
//! written here: a motor that coasts to a stop inside the gap (FMI 3.0 returns early at the
//! stop), one that breaks away under a torque ramp (the instant read from the logged switch);
//! FMU states that continue bit for bit from a stuck body; the bounds +∞ with the reason
//! logged; Model Exchange refused with the reason.

use backlash_fmu::fmu::{Collected, FmuError, Instance, Interface, LogCategory, ModelInfo, MODELS};

fn shaft() -> &'static ModelInfo {
    &MODELS[0]
}

fn set(inst: &mut Instance, values: &[(&str, f64)]) {
    let vrs: Vec<u32> = values.iter().map(|(n, _)| inst.model().vr(n)).collect();
    let x: Vec<f64> = values.iter().map(|(_, x)| *x).collect();
    inst.set_real(&vrs, &x).unwrap();
}

fn get(inst: &mut Instance, names: &[&str]) -> Vec<f64> {
    let vrs: Vec<u32> = names.iter().map(|n| inst.model().vr(n)).collect();
    let mut out = vec![0.0; names.len()];
    inst.get_real(&vrs, &mut out).unwrap();
    out
}

fn sliding(inst: &mut Instance) -> [i32; 2] {
    let vrs = [inst.model().vr("sliding_m"), inst.model().vr("sliding_L")];
    let mut out = [9; 2];
    inst.get_integer(&vrs, &mut out).unwrap();
    out
}

/// An initialized Co-Simulation instance of the shaft with `values`, logging into `log`.
fn initialized(interface: Interface, values: &[(&str, f64)], log: &Collected) -> Result<Instance, FmuError> {
    let mut inst = Instance::new_for(shaft(), interface, Some(Box::new(log.clone())), true);
    set(&mut inst, values);
    inst.setup_experiment(None, 0.0, None)?;
    inst.enter_initialization_mode()?;
    inst.exit_initialization_mode()?;
    Ok(inst)
}

/// The paper's motor (J_m 2.28, b_m 0.05) free inside a gap of 1 rad, the load at rest.
const COAST: [(&str, f64); 6] = [
    ("Delta", 1.0),
    ("omega_m", 0.2),
    ("tau_c_m", 0.5),
    ("tau_c_L", 0.1),
    ("peak_L", 1.2),
    ("tau_m", 0.0),
];

/// J ω′ = −b ω − τ_c from ω_0 > 0: ω = (ω_0 + τ_c/b) e^{−b t/J} − τ_c/b stops at
/// t* = (J/b) ln(1 + b ω_0/τ_c), after θ* = (J/b)(ω_0 + τ_c/b)(1 − e^{−b t*/J}) − τ_c t*/b.
fn coast_stop(j: f64, b: f64, omega0: f64, tau_c: f64) -> (f64, f64) {
    let t = j / b * (b * omega0 / tau_c).ln_1p();
    let decay = b * omega0 / tau_c / (1.0 + b * omega0 / tau_c); // 1 − e^{−b t*/J}
    (t, j / b * (omega0 + tau_c / b) * decay - tau_c / b * t)
}

#[test]
fn a_coasting_motor_stops_where_the_closed_form_says_and_sticks() {
    let log = Collected::default();
    let mut inst = initialized(Interface::CoSimulation, &COAST, &log).unwrap();
    assert_eq!(sliding(&mut inst), [1, 0], "the motor slides, the load at rest sticks");
    let (t_stop, theta_stop) = coast_stop(2.28, 0.05, 0.2, 0.5);
    // Steps of 10 ms; the stop is located inside one of them.
    let h = 0.01;
    let mut t = 0.0;
    while t < 1.5 {
        inst.do_step(t, h).unwrap();
        t += h;
    }
    let [theta_m, omega_m, theta_l] = get(&mut inst, &["theta_m", "omega_m", "theta_L"])[..] else {
        unreachable!()
    };
    assert_eq!(omega_m, 0.0, "stuck: at rest exactly");
    assert_eq!(theta_l, 0.0, "the stuck load does not move");
    assert_eq!(sliding(&mut inst), [0, 0]);
    // θ* is the difference of two terms near 9.1 and 9.0: a few ulps of 9 of cancellation.
    assert!((theta_m - theta_stop).abs() <= 1e-13, "{theta_m} vs {theta_stop}");
    let reported: Vec<f64> = log
        .0
        .borrow()
        .iter()
        .filter(|(_, c, m)| *c == LogCategory::ContactEvents && m.starts_with("friction switch of the motor"))
        .map(|(_, _, m)| switch_time(m))
        .collect();
    assert_eq!(reported.len(), 1, "one stop: {reported:?}");
    // t* to round-off of its logarithm and of the stepper's location on a time grid of 10 ms.
    assert!(
        (reported[0] - t_stop).abs() <= 1e-12 * t_stop,
        "{} vs {t_stop}",
        reported[0]
    );
}

/// The `t = …` of a logged switch.
fn switch_time(message: &str) -> f64 {
    let at = message.find("t = ").expect("a time") + 4;
    let rest = &message[at..];
    rest[..rest.find(' ').unwrap()].parse().unwrap()
}

#[test]
fn a_ramp_breaks_the_stuck_motor_away_at_peak_times_tau_c() {
    let log = Collected::default();
    let (tau_c, peak, rate) = (0.2, 1.5, 0.5);
    let values = [("Delta", 1.0), ("tau_c_m", tau_c), ("peak_m", peak)];
    let mut inst = initialized(Interface::CoSimulation, &values, &log).unwrap();
    assert_eq!(sliding(&mut inst)[0], 0, "at rest without torque: stuck");
    let vr = inst.model().vr("tau_m");
    inst.set_real_input_derivatives(&[vr], &[1], &[rate]).unwrap();
    let h = 0.05;
    let mut t = 0.0;
    while t < 0.8 {
        inst.do_step(t, h).unwrap();
        t += h;
    }
    assert_eq!(sliding(&mut inst)[0], 1, "broken away forward");
    let reported: Vec<f64> = log
        .0
        .borrow()
        .iter()
        .filter(|(_, _, m)| m.starts_with("friction switch of the motor"))
        .map(|(_, _, m)| switch_time(m))
        .collect();
    // τ_m = rate t reaches peak τ_c at t = peak τ_c / rate; the ramp's time is accumulated
    // over 12 steps of 0.05 s (a few ulps of 0.6).
    let expected = peak * tau_c / rate;
    assert_eq!(reported.len(), 1, "{reported:?}");
    assert!((reported[0] - expected).abs() <= 1e-12, "{} vs {expected}", reported[0]);
    // Past the breakaway the motor slides: J ω′ = τ_m − b ω − τ_c, ω > 0.
    assert!(get(&mut inst, &["omega_m"])[0] > 0.0);
}

#[test]
fn an_fmu_state_taken_while_stuck_continues_bit_for_bit() {
    let log = Collected::default();
    let mut inst = initialized(Interface::CoSimulation, &COAST, &log).unwrap();
    let names = ["theta_m", "omega_m", "theta_L", "omega_L", "psi"];
    let mut t = 0.0;
    for _ in 0..100 {
        inst.do_step(t, 0.01).unwrap();
        t += 0.01;
    }
    assert_eq!(sliding(&mut inst), [0, 0]);
    let bytes = {
        let snapshot = inst.get_fmu_state().unwrap();
        inst.serialize_fmu_state(&snapshot).unwrap()
    };
    // A reversing torque: above the motor's breakaway (0.5), then below.
    let run = |inst: &mut Instance| {
        let mut out = Vec::new();
        let mut t = 1.0;
        for k in 0..200 {
            set(inst, &[("tau_m", if k < 100 { 0.8 } else { -0.8 })]);
            inst.do_step(t, 0.01).unwrap();
            t += 0.01;
            let mut row = get(inst, &names);
            row.extend(sliding(inst).map(f64::from));
            out.push(row);
        }
        out
    };
    let first = run(&mut inst);
    let snapshot = inst.deserialize_fmu_state(&bytes).unwrap();
    inst.set_fmu_state(&snapshot).unwrap();
    let second = run(&mut inst);
    assert_eq!(first, second);
    assert!(first.iter().any(|row| row[5] == 1.0) && first.iter().any(|row| row[5] == -1.0));
}

#[test]
fn with_friction_the_bounds_are_infinite_and_the_reason_is_logged() {
    let log = Collected::default();
    let mut inst = initialized(Interface::CoSimulation, &COAST, &log).unwrap();
    inst.do_step(0.0, 0.1).unwrap();
    let [bound, bound_sup] = get(&mut inst, &["bound", "bound_sup"])[..] else {
        unreachable!()
    };
    assert_eq!((bound, bound_sup), (f64::INFINITY, f64::INFINITY));
    let said = log
        .0
        .borrow()
        .iter()
        .any(|(_, _, m)| m.contains("bound_sup") && m.contains("Coulomb friction"));
    assert!(said, "{:?}", log.0.borrow());
}

#[test]
fn model_exchange_refuses_friction_with_the_reason() {
    let log = Collected::default();
    let err = initialized(Interface::ModelExchange, &COAST, &log)
        .err()
        .expect("refused");
    assert!(err.to_string().contains("Co-Simulation only"), "{err}");
    // Without friction Model Exchange initializes as before.
    assert!(initialized(Interface::ModelExchange, &[("tau_c_m", 0.0)], &Collected::default()).is_ok());
}

/// FMI 3.0 with early return stops at the stop of the coasting motor, at the closed form's t*.
#[cfg(all(target_os = "linux", any(target_arch = "x86_64", target_arch = "aarch64")))]
#[test]
fn fmi3_returns_early_at_the_stop() {
    use super::fmi3_ffi::{Fmu3, OK3};
    use backlash_fmu::ffi::fmi3::{fmi3EnterInitializationMode, fmi3ExitInitializationMode, fmi3Status};
    let fmu = Fmu3::co_simulation(0, false, true);
    let (names, values): (Vec<&str>, Vec<f64>) = COAST.iter().copied().unzip();
    assert_eq!(fmu.set(&names, &values), OK3);
    assert_eq!(fmi3EnterInitializationMode(fmu.c, false, 0.0, 0.0, false, 0.0), OK3);
    // A warning: the bounds are +∞ with friction.
    assert_eq!(fmi3ExitInitializationMode(fmu.c), fmi3Status::fmi3Warning);
    let (t_stop, _) = coast_stop(2.28, 0.05, 0.2, 0.5);
    // Communication points every 10 ms; after an early return the step goes on to the next.
    let (mut t, mut k) = (0.0, 1);
    let mut stops = Vec::new();
    while k <= 150 {
        let target = k as f64 * 0.01;
        let (status, _, early, last) = fmu.step(t, target - t);
        assert_eq!(status, OK3, "at t = {t}: {:?}", fmu.log.lock().unwrap().last());
        if early {
            stops.push(last);
        } else {
            k += 1;
        }
        t = last;
    }
    assert_eq!(stops.len(), 1, "{stops:?}");
    assert!((stops[0] - t_stop).abs() <= 1e-12 * t_stop, "{} vs {t_stop}", stops[0]);
}

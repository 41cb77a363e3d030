//! Bearing friction with stiction through the FMU (docs/model.md §12), against closed forms
//! written here: a motor that coasts to a stop inside the gap (FMI 3.0 returns early at the
//! stop), one that breaks away under a torque ramp (the instant read from the logged switch);
//! FMU states that continue bit for bit from a stuck body; the bound with each body's friction
//! term against a quadrature of the loop's exponential, and +∞ on the web line; Model Exchange under an importer written here (the stop and the breakaway as events,
//! the stuck body held), and its Jacobian in the held modes against central differences.

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

/// The bound with friction (docs/model.md §10, §12): the frictionless drive's bound plus each
/// body's 2 peak tau_c ∫_0^t |L e^{A s} E_b| ds, E_b = 1/J_b at its speed, L the load speed, A
/// the loop of §3; the integral here by Simpson's rule on e^{A s} from nalgebra's exponential.
/// The web line with friction: +∞ with the reason logged.
#[test]
fn with_friction_the_bound_adds_each_bodys_term() {
    use backlash_fmu::physics::closed_loop::closed_loop;
    use backlash_fmu::physics::{PiGains, Plant, PlantParams};
    use nalgebra::{SMatrix, SVector};
    let (kp, ki, t_end) = (42.7, 179.2, 0.5);
    let friction = [("tau_c_m", 0.5), ("peak_m", 1.2), ("tau_c_L", 0.1), ("peak_L", 1.5)];
    let gains = [("Kp", kp), ("Ki", ki)];
    let run = |values: &[(&str, f64)]| {
        let log = Collected::default();
        let mut inst = initialized(Interface::CoSimulation, values, &log).unwrap();
        let mut t = 0.0;
        while t < t_end - 1e-9 {
            inst.do_step(t, 0.01).unwrap();
            t += 0.01;
        }
        let out = get(&mut inst, &["bound", "bound_sup"]);
        (out[0], out[1], log)
    };
    let (plain, plain_sup, _) = run(&gains);
    let mut with: Vec<(&str, f64)> = gains.to_vec();
    with.extend(friction);
    let (bound, sup, log) = run(&with);
    let warned = log.0.borrow().iter().any(|(_, _, m)| m.contains("+inf"));
    assert!(!warned, "{:?}", log.0.borrow());
    // The friction's part from the loop's matrix exponential, by Simpson's rule with n and 2n
    // panels: |h_b| has kinks where h_b changes sign, so the rule converges about as n⁻²; the
    // difference of the two, times 4, bounds the finer one's error.
    let plant = Plant::new(PlantParams::paper_rig(0.775e-3)).unwrap();
    let a: SMatrix<f64, 5, 5> = closed_loop(&plant, PiGains { kp, ki });
    let p = plant.params();
    let l1 = |column: SVector<f64, 5>, n: usize| {
        let ds = t_end / n as f64;
        let h = |s: f64| ((a * s).exp() * column)[3].abs();
        let inner: f64 = (1..n)
            .map(|i| if i % 2 == 1 { 4.0 } else { 2.0 } * h(i as f64 * ds))
            .sum();
        ds / 3.0 * (h(0.0) + inner + h(t_end))
    };
    let mut e_m = SVector::<f64, 5>::zeros();
    e_m[1] = 1.0 / p.j_m;
    let mut e_l = SVector::<f64, 5>::zeros();
    e_l[3] = 1.0 / p.j_l;
    let part_of = |n: usize| 2.0 * 1.2 * 0.5 * l1(e_m, n) + 2.0 * 1.5 * 0.1 * l1(e_l, n);
    let (coarse, expected) = (part_of(10_000), part_of(20_000));
    let resolution = 4.0 * (expected - coarse).abs() + 1e-12 * expected;
    let part = bound - plain;
    assert!(
        (part - expected).abs() <= resolution,
        "{part} vs {expected} (resolution {resolution:e})"
    );
    assert!(sup >= plain_sup + part * (1.0 - 1e-12), "{sup} vs {plain_sup} + {part}");

    // The web line with friction: +∞, with the reason.
    let web = MODELS.iter().find(|m| m.identifier == "BacklashWeb").unwrap();
    let log = Collected::default();
    let mut inst = Instance::new_for(web, Interface::CoSimulation, Some(Box::new(log.clone())), true);
    set(&mut inst, &[("tau_c_L", 0.01)]);
    inst.setup_experiment(None, 0.0, None).unwrap();
    inst.enter_initialization_mode().unwrap();
    inst.exit_initialization_mode().unwrap();
    let vrs = [web.vr("bound"), web.vr("bound_sup"), web.vr("bound_T")];
    let mut out = [0.0; 3];
    inst.get_real(&vrs, &mut out).unwrap();
    assert_eq!(out, [f64::INFINITY; 3]);
    let said = log
        .0
        .borrow()
        .iter()
        .any(|(_, _, m)| m.contains("bound_T_sup") && m.contains("web line"));
    assert!(said, "{:?}", log.0.borrow());
}

/// FMI 3.0 with early return stops at the stop of the coasting motor, at the closed form's t*.
#[cfg(all(target_os = "linux", any(target_arch = "x86_64", target_arch = "aarch64")))]
#[test]
fn fmi3_returns_early_at_the_stop() {
    use super::fmi3_ffi::{Fmu3, OK3};
    use backlash_fmu::ffi::fmi3::{fmi3EnterInitializationMode, fmi3ExitInitializationMode};
    let fmu = Fmu3::co_simulation(0, false, true);
    let (names, values): (Vec<&str>, Vec<f64>) = COAST.iter().copied().unzip();
    assert_eq!(fmu.set(&names, &values), OK3);
    assert_eq!(fmi3EnterInitializationMode(fmu.c, false, 0.0, 0.0, false, 0.0), OK3);
    assert_eq!(fmi3ExitInitializationMode(fmu.c), OK3);
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

/// A Model Exchange importer written here: classical Runge–Kutta steps of `h`, every event
/// indicator watched for a sign change, the crossing bisected to 1e-13 s, then Event Mode (the
/// law of stiction applied by fmi2NewDiscreteStates) and on. `tau_m(t)` is set at every
/// evaluation. Returns the event times.
fn model_exchange_run(inst: &mut Instance, tau_m: &dyn Fn(f64) -> f64, h: f64, end: f64) -> Vec<f64> {
    let n = 4;
    let vr = inst.model().vr("tau_m");
    let rates = |inst: &mut Instance, t: f64, x: &[f64]| {
        inst.set_time(t).unwrap();
        inst.set_real(&[vr], &[tau_m(t)]).unwrap();
        inst.set_continuous_states(x).unwrap();
        let mut dx = vec![0.0; n];
        inst.get_derivatives(&mut dx).unwrap();
        dx
    };
    let rk4 = |inst: &mut Instance, t: f64, x: &[f64], h: f64| {
        let k1 = rates(inst, t, x);
        let at = |k: &[f64], c: f64| -> Vec<f64> { x.iter().zip(k).map(|(a, b)| a + c * b).collect() };
        let k2 = rates(inst, t + h / 2.0, &at(&k1, h / 2.0));
        let k3 = rates(inst, t + h / 2.0, &at(&k2, h / 2.0));
        let k4 = rates(inst, t + h, &at(&k3, h));
        (0..n)
            .map(|i| x[i] + h / 6.0 * (k1[i] + 2.0 * k2[i] + 2.0 * k3[i] + k4[i]))
            .collect::<Vec<f64>>()
    };
    let indicators = |inst: &mut Instance, t: f64, x: &[f64]| {
        rates(inst, t, x);
        let mut g = vec![0.0; 10];
        inst.get_event_indicators(&mut g).unwrap();
        g
    };
    inst.new_discrete_states().unwrap();
    inst.enter_continuous_time_mode().unwrap();
    let mut x = vec![0.0; n];
    inst.get_continuous_states(&mut x).unwrap();
    let (mut t, mut events) = (0.0, Vec::new());
    while t < end - 1e-12 {
        let before = indicators(inst, t, &x);
        let step = h.min(end - t);
        let next = rk4(inst, t, &x, step);
        let crossed = |g: &[f64]| before.iter().zip(g).any(|(a, b)| a * b < 0.0);
        if !crossed(&indicators(inst, t + step, &next)) {
            (t, x) = (t + step, next);
            inst.completed_integrator_step().unwrap();
            continue;
        }
        let (mut lo, mut hi) = (0.0, step);
        while hi - lo > 1e-13 {
            let mid = (lo + hi) / 2.0;
            let at = rk4(inst, t, &x, mid);
            match crossed(&indicators(inst, t + mid, &at)) {
                true => hi = mid,
                false => lo = mid,
            }
        }
        x = rk4(inst, t, &x, hi);
        t += hi;
        rates(inst, t, &x);
        inst.enter_event_mode().unwrap();
        if inst.new_discrete_states().unwrap().values_changed {
            inst.get_continuous_states(&mut x).unwrap();
        }
        inst.enter_continuous_time_mode().unwrap();
        events.push(t);
    }
    rates(inst, t, &x);
    events
}

#[test]
fn model_exchange_sees_the_stop_and_holds_the_stuck_motor() {
    let log = Collected::default();
    let mut inst = initialized(Interface::ModelExchange, &COAST, &log).unwrap();
    let events = model_exchange_run(&mut inst, &|_| 0.0, 1e-3, 1.5);
    let (t_stop, theta_stop) = coast_stop(2.28, 0.05, 0.2, 0.5);
    // One event, the stop, within the bisection's 1e-13 s and the Runge–Kutta error (h⁴ times
    // (b/J)⁴, far below it).
    assert_eq!(events.len(), 1, "{events:?}");
    assert!((events[0] - t_stop).abs() <= 1e-11, "{} vs {t_stop}", events[0]);
    let [theta_m, omega_m] = get(&mut inst, &["theta_m", "omega_m"])[..] else {
        unreachable!()
    };
    assert_eq!(omega_m, 0.0, "set at rest in Event Mode and held there");
    // θ* within the speed at the located instant times the bisection's bracket.
    assert!((theta_m - theta_stop).abs() <= 1e-11, "{theta_m} vs {theta_stop}");
    assert_eq!(sliding(&mut inst), [0, 0]);
}

#[test]
fn model_exchange_sees_the_breakaway_under_a_ramp() {
    let log = Collected::default();
    let (tau_c, peak, rate, b, j) = (0.2, 1.5, 0.5, 0.05, 2.28);
    let values = [("Delta", 1.0), ("tau_c_m", tau_c), ("peak_m", peak)];
    let mut inst = initialized(Interface::ModelExchange, &values, &log).unwrap();
    let events = model_exchange_run(&mut inst, &|t| rate * t, 1e-3, 0.8);
    let t_b = peak * tau_c / rate;
    assert_eq!(events.len(), 1, "{events:?}");
    assert!((events[0] - t_b).abs() <= 1e-11, "{} vs {t_b}", events[0]);
    assert_eq!(sliding(&mut inst)[0], 1);
    // J ω′ = r t − b ω − τ_c from ω(t_b) = 0: ω = A t + B − (A t_b + B) e^{−b (t − t_b)/J} with
    // A = r/b, B = −(τ_c + J r/b)/b.
    let (a, bb) = (rate / b, -(tau_c + j * rate / b) / b);
    let t = 0.8;
    let expected = a * t + bb - (a * t_b + bb) * (-(b / j) * (t - t_b)).exp();
    let omega = get(&mut inst, &["omega_m"])[0];
    // Runge–Kutta's error over 200 steps of 1 ms and the event's location: far below 1e-10 of
    // a speed of 0.009 rad/s; the closed form cancels A t + B against its exponential term.
    assert!((omega - expected).abs() <= 1e-10, "{omega} vs {expected}");
}

/// Model Exchange's directional derivatives in the held friction modes (the motor sliding, the
/// load stuck; then both stuck) against central differences of the derivatives and the event
/// indicators, the modes held while the states move (they change only in Event Mode).
#[test]
fn the_jacobian_holds_in_the_friction_modes() {
    let values = [
        ("Delta", 1e-3),
        ("theta_m", 2e-3),
        ("omega_m", 0.3),
        ("tau_c_m", 0.5),
        ("tau_c_L", 0.4),
        ("peak_L", 1.3),
        ("tau_m", 0.7),
    ];
    let mut inst = initialized(Interface::ModelExchange, &values, &Collected::default()).unwrap();
    inst.new_discrete_states().unwrap();
    inst.enter_continuous_time_mode().unwrap();
    assert_eq!(
        sliding(&mut inst),
        [1, 0],
        "the motor slides, the load at rest sticks (|tau_h| = 0.2 < 0.52)"
    );
    let knowns = ["theta_m", "omega_m", "theta_L", "omega_L", "tau_m", "tau_L"];
    let unknowns = [
        "der(omega_m)",
        "der(omega_L)",
        "stop_m",
        "breakaway_m",
        "stop_L",
        "breakaway_L",
    ];
    let kv: Vec<u32> = knowns.iter().map(|n| inst.model().vr(n)).collect();
    let uv: Vec<u32> = unknowns.iter().map(|n| inst.model().vr(n)).collect();
    let mut x = vec![0.0; 4];
    inst.get_continuous_states(&mut x).unwrap();
    let base_inputs = get(&mut inst, &["tau_m", "tau_L"]);
    let read = |inst: &mut Instance, x: &[f64], inputs: &[f64]| {
        inst.set_continuous_states(x).unwrap();
        set(inst, &[("tau_m", inputs[0]), ("tau_L", inputs[1])]);
        get(inst, &unknowns)
    };
    for (k, name) in knowns.iter().enumerate() {
        let mut seed = vec![0.0; knowns.len()];
        seed[k] = 1.0;
        let mut exact = vec![0.0; unknowns.len()];
        inst.set_continuous_states(&x).unwrap();
        set(&mut inst, &[("tau_m", base_inputs[0]), ("tau_L", base_inputs[1])]);
        inst.get_directional_derivative(&uv, &kv, &seed, &mut exact).unwrap();
        // Every unknown is affine in the knowns inside the modes held: a central difference of
        // step e is exact but for round-off, about 1e-16 of the values over 2e (5e-10 of them
        // for e = 1e-7); 1e-8 leaves a margin of 20.
        let e = 1e-7;
        let moved = |sign: f64| {
            let (mut xs, mut us) = (x.clone(), base_inputs.clone());
            match k {
                0..=3 => xs[k] += sign * e,
                _ => us[k - 4] += sign * e,
            }
            (xs, us)
        };
        let (xp, up) = moved(1.0);
        let (xm, um) = moved(-1.0);
        let plus = read(&mut inst, &xp, &up);
        let minus = read(&mut inst, &xm, &um);
        for (i, unknown) in unknowns.iter().enumerate() {
            let fd = (plus[i] - minus[i]) / (2.0 * e);
            let scale = plus[i].abs().max(minus[i].abs()).max(1.0);
            assert!(
                (fd - exact[i]).abs() <= 1e-8 * scale,
                "d{unknown}/d{name}: exact {} vs difference {fd}",
                exact[i]
            );
        }
        inst.set_continuous_states(&x).unwrap();
    }
    // The stuck load's acceleration row is 0; the sliding motor's stop indicator is its speed.
    let mut exact = vec![0.0; 2];
    let rows = [inst.model().vr("der(omega_L)"), inst.model().vr("stop_m")];
    inst.get_directional_derivative(&rows, &kv, &[1.0, 1.0, 1.0, 1.0, 1.0, 1.0], &mut exact)
        .unwrap();
    assert_eq!(exact, [0.0, 1.0]);
}

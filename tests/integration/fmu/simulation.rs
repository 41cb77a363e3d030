//! Stepping through the FMU against independent computations: the closed-form solution of the
//! backlash-free, undamped shaft (docs/model.md §1 with Δ = 0), the free-flight contact time, ramp
//! inputs, bit-identical reruns after fmi2Reset, and the bounds read after any steps. (A serialized
//! FMU state continuing bit for bit: `crate::fmu_state::rust_api`.)

use backlash_fmu::fmu::{Collected, Instance, LogCategory, Status, MODELS};

const J_M: f64 = 2.28;
const J_L: f64 = 2.55;
const K: f64 = 200.0;

pub(crate) fn shaft(params: &[(&str, f64)], log: Option<Collected>, logging_on: bool) -> Instance {
    let model = &MODELS[0];
    let mut inst = Instance::new(model, log.map(|l| Box::new(l) as _), logging_on);
    for (name, value) in params {
        inst.set_real(&[model.vr(name)], &[*value]).unwrap();
    }
    inst.setup_experiment(None, 0.0, None).unwrap();
    inst.enter_initialization_mode().unwrap();
    inst
}

fn get(inst: &mut Instance, names: &[&str]) -> Vec<f64> {
    let vrs: Vec<u32> = names.iter().map(|n| inst.model().vr(n)).collect();
    let mut out = vec![0.0; names.len()];
    inst.get_real(&vrs, &mut out).unwrap();
    out
}

fn close(actual: f64, expected: f64, scale: f64, what: &str) {
    assert!(
        (actual - expected).abs() <= 1e-11 * scale,
        "{what}: {actual} vs {expected}"
    );
}

#[test]
fn backlash_free_undamped_shaft_follows_the_closed_form_solution() {
    let log = Collected::default();
    let mut inst = shaft(&[("Delta", 0.0), ("b_m", 0.0), ("b_L", 0.0)], Some(log.clone()), false);
    // Undamped: h never decays, so bound_sup is +inf with a warning (docs/model.md §4).
    assert_eq!(inst.exit_initialization_mode().unwrap(), Status::Warning);
    assert!(log
        .0
        .borrow()
        .iter()
        .any(|(s, c, m)| *s == Status::Warning && *c == LogCategory::Warnings && m.contains("bound_sup = +inf")));
    assert_eq!(get(&mut inst, &["bound_sup"])[0], f64::INFINITY);

    let tau = 1.5;
    inst.set_real(&[inst.model().vr("tau_m")], &[tau]).unwrap();
    let w = (K * (1.0 / J_M + 1.0 / J_L)).sqrt();
    let c = K * tau / (J_L * J_M * w * w);
    let h = 0.037;
    let mut t = 0.0;
    for _ in 0..100 {
        inst.do_step(t, h).unwrap();
        t += h;
        let u = tau / (J_M * w * w) * (1.0 - (w * t).cos());
        let du = tau / (J_M * w) * (w * t).sin();
        let omega_l = c * (t - (w * t).sin() / w);
        let theta_l = c * (t * t / 2.0 - (1.0 - (w * t).cos()) / (w * w));
        let y = get(&mut inst, &["theta_m", "omega_m", "theta_L", "omega_L", "psi"]);
        let scale = 1.0 + theta_l.abs();
        close(y[0], theta_l + u, scale, "theta_m");
        close(y[1], omega_l + du, scale, "omega_m");
        close(y[2], theta_l, scale, "theta_L");
        close(y[3], omega_l, scale, "omega_L");
        close(y[4], K * u, K * scale, "psi");

        let vrs: Vec<u32> = ["theta_m", "omega_m", "theta_L", "omega_L", "psi"]
            .iter()
            .map(|n| inst.model().vr(n))
            .collect();
        let mut d = [0.0; 5];
        inst.get_real_output_derivatives(&vrs, &[1; 5], &mut d).unwrap();
        close(d[0], omega_l + du, scale, "d theta_m");
        close(d[1], (tau - K * u) / J_M, scale, "d omega_m");
        close(d[2], omega_l, scale, "d theta_L");
        close(d[3], K * u / J_L, scale, "d omega_L");
        close(d[4], K * du, K * scale, "d psi");
    }
}

#[test]
fn a_ramp_set_once_continues_over_later_steps() {
    let mut inst = shaft(&[("Delta", 0.0), ("b_m", 0.0), ("b_L", 0.0)], None, false);
    let tau_m = inst.model().vr("tau_m");
    let r = 0.8;
    inst.set_real_input_derivatives(&[tau_m], &[1], &[r]).unwrap();
    inst.exit_initialization_mode().unwrap();
    let w = (K * (1.0 / J_M + 1.0 / J_L)).sqrt();
    let mut t = 0.0;
    for _ in 0..40 {
        inst.do_step(t, 0.05).unwrap();
        t += 0.05;
        // u'' + w² u = r t / J_m from rest.
        let u = r / (J_M * w * w) * (t - (w * t).sin() / w);
        let y = get(&mut inst, &["psi", "tau_m"]);
        close(y[0], K * u, K, "psi");
        close(y[1], r * t, 1.0, "tau_m moves along its line");
    }
    // Order 2 is refused: inputs are interpolated linearly.
    assert!(inst.set_real_input_derivatives(&[tau_m], &[2], &[1.0]).is_err());
}

#[test]
fn the_first_contact_is_logged_at_the_free_flight_time() {
    let log = Collected::default();
    let delta = 0.775e-3;
    let mut inst = shaft(&[("b_m", 0.0), ("b_L", 0.0), ("tau_m", 1.5)], Some(log.clone()), false);
    inst.set_debug_logging(true, &["logContactEvents"]).unwrap();
    inst.exit_initialization_mode().unwrap();
    let mut t = 0.0;
    for _ in 0..10 {
        inst.do_step(t, 0.01).unwrap();
        t += 0.01;
    }
    // In the gap the motor accelerates alone: theta_m = tau t²/(2 J_m) reaches Delta at t*.
    let t_star = (2.0 * delta * J_M / 1.5_f64).sqrt();
    let events: Vec<String> = log
        .0
        .borrow()
        .iter()
        .filter(|(_, c, _)| *c == LogCategory::ContactEvents)
        .map(|(_, _, m)| m.clone())
        .collect();
    let first = events.first().expect("a contact switch was logged");
    assert!(first.contains("Free -> Positive"), "{first}");
    let logged: f64 = first
        .split("t = ")
        .nth(1)
        .unwrap()
        .split(' ')
        .next()
        .unwrap()
        .parse()
        .unwrap();
    assert!((logged - t_star).abs() < 1e-12, "{logged} vs {t_star}");
    let mut contact = [0];
    inst.get_integer(&[inst.model().vr("contact")], &mut contact).unwrap();
    assert_eq!(contact, [1]);
}

/// Outputs after each of `steps` steps with a varying torque, as bits. Two runs compared bit
/// for bit are the same arithmetic by construction: the same library code (in one process, so
/// the same libm) on the same parameters, state and inputs; fmi2Reset rebuilds the start state
/// from the same values, and an FMU state carries its f64 words byte for byte.
pub(crate) fn run(inst: &mut Instance, steps: usize) -> Vec<u64> {
    let names = [
        "theta_m",
        "omega_m",
        "theta_L",
        "omega_L",
        "psi",
        "bound",
        "bound_paper",
    ];
    let mut bits = Vec::new();
    let mut t = inst.time();
    for _ in 0..steps {
        let tau = 4.0 * (18.0 * t).sin();
        inst.set_real(&[inst.model().vr("tau_m")], &[tau]).unwrap();
        inst.do_step(t, 0.05).unwrap();
        t += 0.05;
        bits.extend(get(inst, &names).iter().map(|x| x.to_bits()));
        let mut contact = [0];
        inst.get_integer(&[inst.model().vr("contact")], &mut contact).unwrap();
        bits.push(contact[0] as u64);
    }
    bits
}

#[test]
fn reset_reruns_bit_identically() {
    let mut inst = shaft(&[("Kp", 20.0), ("Ki", 5.0)], None, false);
    inst.exit_initialization_mode().unwrap();
    let first = run(&mut inst, 60);
    inst.reset().unwrap();
    for (name, value) in [("Kp", 20.0), ("Ki", 5.0)] {
        inst.set_real(&[inst.model().vr(name)], &[value]).unwrap();
    }
    inst.setup_experiment(None, 0.0, None).unwrap();
    inst.enter_initialization_mode().unwrap();
    inst.exit_initialization_mode().unwrap();
    assert_eq!(run(&mut inst, 60), first);
}

#[test]
fn bound_rates_match_central_differences() {
    let mut inst = shaft(&[("Kp", 20.0), ("Ki", 5.0)], None, false);
    inst.exit_initialization_mode().unwrap();
    let (vb, vp) = (inst.model().vr("bound"), inst.model().vr("bound_paper"));
    let delta = 1e-5;
    inst.do_step(0.0, 0.7 - delta).unwrap();
    let before = get(&mut inst, &["bound", "bound_paper"]);
    inst.do_step(0.7 - delta, delta).unwrap();
    let mut rate = [0.0; 2];
    inst.get_real_output_derivatives(&[vb, vp], &[1, 1], &mut rate).unwrap();
    inst.do_step(0.7, delta).unwrap();
    let after = get(&mut inst, &["bound", "bound_paper"]);
    for i in 0..2 {
        let central = (after[i] - before[i]) / (2.0 * delta);
        assert!(
            (rate[i] - central).abs() <= 1e-6 * central.abs().max(1e-12),
            "{i}: {} vs {central}",
            rate[i]
        );
    }
    assert!(rate[0] > 0.0);
}

/// Co-Simulation steps advance the plant only; the bounds follow when read (docs/model.md §3).
/// Read after every step they are, bit for bit, the library's bound advanced step by step; read
/// every tenth step, or first after an FMU state taken in between, they agree with it to
/// round-off; the shaft under a reversing torque, so that the plant switches too.
#[test]
fn bounds_read_after_any_steps_are_the_bound_advanced_over_them() {
    use backlash_fmu::physics::{Plant, PlantParams, SpeedErrorBound};
    let pi = crate::support::rigs::fmu_gains("BacklashShaft");
    let gains = [("Kp", pi.kp), ("Ki", pi.ki)];
    let mut direct = SpeedErrorBound::new(&Plant::new(PlantParams::paper_rig(0.775e-3)).unwrap(), pi).unwrap();
    let (mut every, mut tenth) = (shaft(&gains, None, false), shaft(&gains, None, false));
    every.exit_initialization_mode().unwrap();
    tenth.exit_initialization_mode().unwrap();
    let h = 0.013;
    let names = ["bound", "bound_paper"];
    let mut saved = None;
    for k in 0..300 {
        let tau = if (k / 20) % 2 == 0 { 3.0 } else { -3.0 };
        for inst in [&mut every, &mut tenth] {
            inst.set_real(&[inst.model().vr("tau_m")], &[tau]).unwrap();
            inst.do_step(k as f64 * h, h).unwrap();
        }
        direct.advance(h).unwrap();
        let b = get(&mut every, &names);
        // Bit for bit by construction: the instance builds the same SpeedErrorBound (the
        // shaft's start values are paper_rig(0.775e-3)'s) and, read after every step, catches
        // up by its lag 0 + h = h in one `advance(h)`, the call made on `direct`.
        assert_eq!(b[0].to_bits(), direct.bound().to_bits(), "bound after step {k}");
        assert_eq!(
            b[1].to_bits(),
            direct.bound_paper().to_bits(),
            "bound_paper after step {k}"
        );
        if k == 154 {
            // Taken with the bounds 5 steps behind: the state keeps that.
            let state = tenth.get_fmu_state().unwrap();
            saved = Some((tenth.serialize_fmu_state(&state).unwrap(), b.clone()));
        }
        if k % 10 == 9 {
            let c = get(&mut tenth, &names);
            for (x, y) in c.iter().zip(&b) {
                assert!(
                    (x - y).abs() <= 1e-13 * y.abs(),
                    "read every tenth step, after {k}: {x} vs {y}"
                );
            }
        }
    }
    let (bytes, at_save) = saved.unwrap();
    let mut other = shaft(&gains, None, false);
    other.exit_initialization_mode().unwrap();
    let restored = other.deserialize_fmu_state(&bytes).unwrap();
    other.set_fmu_state(&restored).unwrap();
    let c = get(&mut other, &names);
    for (x, y) in c.iter().zip(&at_save) {
        assert!(
            (x - y).abs() <= 1e-13 * y.abs(),
            "restored with the bounds behind: {x} vs {y}"
        );
    }
}

/// Unread, the bounds lag behind by the steps taken, and are brought along within the step that
/// makes them lag by the longest step accepted; an FMU state records the lag.
#[test]
fn unread_bounds_are_brought_along_once_they_lag_by_the_longest_step() {
    use backlash_fmu::fmu::adapter::default_plant_params;
    use backlash_fmu::physics::{max_step, Plant};
    let belt = &MODELS[1];
    let longest = max_step(&Plant::new(default_plant_params(belt.identifier)).unwrap());
    let mut inst = Instance::new(belt, None, false);
    inst.setup_experiment(None, 0.0, None).unwrap();
    inst.enter_initialization_mode().unwrap();
    inst.exit_initialization_mode().unwrap();
    let h = 0.5 * longest;
    let lag = |inst: &mut Instance| inst.get_fmu_state().unwrap().physics.unwrap().bounds_behind;
    let mut lags = Vec::new();
    for k in 0..3 {
        inst.do_step(k as f64 * h, h).unwrap();
        lags.push(lag(&mut inst));
    }
    // Exact: the lag sums step lengths, 0 + h = h and h + h = 2 h exactly, and catching up
    // sets it to 0.
    assert_eq!(lags, [h, 0.0, h]);
    // Read, they catch up.
    let bound = get(&mut inst, &["bound"])[0];
    assert!(bound > 0.0 && lag(&mut inst) == 0.0, "bound {bound}");
}

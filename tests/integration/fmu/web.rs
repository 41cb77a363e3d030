//! BacklashWeb through the FMU's Rust API (docs/model.md §8): Co-Simulation with ramped torques,
//! upstream speed and tension against the independent reference of support/web_reference.rs;
//! Model Exchange's vector field and Jacobian against the equations written out here; output
//! derivatives of T and bound_T; its inputs refused by name. (Its FMU states that continue bit
//! for bit: `crate::fmu_state::rust_api`.)

use crate::support::reference::RefEvent;
use crate::support::rigs::web_line;
use crate::support::web_reference::{WebInputs, WebReference};
use backlash_fmu::fmu::{Collected, Instance, Interface, LogCategory, ModelInfo, MODELS};

fn web() -> &'static ModelInfo {
    MODELS
        .iter()
        .find(|m| m.identifier == "BacklashWeb")
        .expect("the web line")
}

fn vrs(model: &ModelInfo, names: &[&str]) -> Vec<u32> {
    names.iter().map(|n| model.vr(n)).collect()
}

pub(crate) fn get(inst: &mut Instance, names: &[&str]) -> Vec<f64> {
    let mut out = vec![0.0; names.len()];
    inst.get_real(&vrs(inst.model(), names), &mut out).unwrap();
    out
}

fn set(inst: &mut Instance, values: &[(&str, f64)]) {
    let names: Vec<&str> = values.iter().map(|(n, _)| *n).collect();
    let x: Vec<f64> = values.iter().map(|(_, x)| *x).collect();
    inst.set_real(&vrs(inst.model(), &names), &x).unwrap();
}

/// A web line instance in Initialization Mode with `values` set.
pub(crate) fn instance(interface: Interface, values: &[(&str, f64)], log: Option<Collected>) -> Instance {
    let mut inst = Instance::new_for(web(), interface, log.map(|l| Box::new(l) as _), true);
    set(&mut inst, values);
    inst.setup_experiment(None, 0.0, None).unwrap();
    inst.enter_initialization_mode().unwrap();
    inst
}

/// Inputs and their slopes over one step, as an importer sets them: values, then
/// fmi2SetRealInputDerivatives.
pub(crate) fn apply(inst: &mut Instance, i: &WebInputs) {
    set(
        inst,
        &[
            ("tau_m", i.tau_m),
            ("tau_L", i.tau_l),
            ("v_in", i.v_in),
            ("T_in", i.t_in),
        ],
    );
    let vr = vrs(inst.model(), &["tau_m", "tau_L", "v_in", "T_in"]);
    inst.set_real_input_derivatives(&vr, &[1; 4], &[i.dtau_m, i.dtau_l, i.dv_in, i.dt_in])
        .unwrap();
}

/// Ramped torques, upstream speed and tension around line speed: the gear crosses its gap.
pub(crate) fn ramps(steps: usize, h: f64) -> Vec<WebInputs> {
    let w = 2.0 * std::f64::consts::PI / 0.05;
    (0..steps)
        .map(|k| {
            let t = k as f64 * h;
            let phase = (w * t).sin();
            WebInputs {
                tau_m: 0.42 + 0.4 * phase,
                dtau_m: 0.4 * w * (w * t).cos(),
                tau_l: -0.1,
                dtau_l: 0.1,
                v_in: 2.0 + 0.01 * phase,
                dv_in: -0.05,
                t_in: 50.0 + 5.0 * phase,
                dt_in: 30.0,
            }
        })
        .collect()
}

const OUTPUTS: [&str; 5] = ["theta_m", "omega_m", "theta_L", "omega_L", "T"];

#[test]
fn co_simulation_follows_the_independent_reference_through_all_four_inputs() {
    let params = web_line(5e-5);
    let reference = WebReference::new(&params);
    // At line speed (R_w ω_L = v_in) and upstream tension.
    let omega_l = 2.0 / 0.05;
    let omega_m = omega_l * reference.form.r_l / reference.form.r_m;
    let z = [0.0, omega_m, 0.0, omega_l];
    let mut inst = instance(
        Interface::CoSimulation,
        &[("omega_m", omega_m), ("omega_L", omega_l), ("T", 50.0)],
        None,
    );
    inst.exit_initialization_mode().unwrap();
    let mut state = reference.state(z, 50.0);
    let (h, mut t) = (2e-3, 0.0);
    let mut events: Vec<RefEvent> = Vec::new();
    let mut worst = [0.0f64; 5];
    let mut scale = [f64::MIN_POSITIVE; 5];
    for inputs in ramps(150, h) {
        apply(&mut inst, &inputs);
        inst.do_step(t, h).unwrap();
        reference.step(&mut state, t, &inputs, h, &mut events);
        t += h;
        let got = get(&mut inst, &OUTPUTS);
        let s = WebReference::sample(&state);
        let want = [s[0], s[1], s[2], s[3], s[5]];
        for k in 0..5 {
            worst[k] = worst[k].max((got[k] - want[k]).abs());
            scale[k] = scale[k].max(want[k].abs());
        }
    }
    let relative: Vec<f64> = worst.iter().zip(scale).map(|(w, s)| w / s).collect();
    println!(
        "{} switches; relative errors θ_m ω_m θ_L ω_L T: {relative:?}",
        events.len()
    );
    assert!(
        events.len() >= 20,
        "the gear crosses its gap: {} switches",
        events.len()
    );
    assert!(relative.iter().all(|e| *e <= 1e-9), "{relative:?}");
}

/// Every output and output derivative after each of `steps` steps, as bits.
pub(crate) fn trace(inst: &mut Instance, t0: f64, steps: usize) -> Vec<u64> {
    let outputs = ["omega_m", "omega_L", "T", "psi", "bound", "bound_paper", "bound_T"];
    let vr = vrs(inst.model(), &outputs);
    let mut bits = Vec::new();
    let h = 1e-3;
    for k in 0..steps {
        inst.do_step(t0 + k as f64 * h, h).unwrap();
        let mut x = vec![0.0; vr.len()];
        inst.get_real(&vr, &mut x).unwrap();
        let mut dx = vec![0.0; vr.len()];
        inst.get_real_output_derivatives(&vr, &vec![1; vr.len()], &mut dx)
            .unwrap();
        bits.extend(x.iter().chain(&dx).map(|v| v.to_bits()));
    }
    bits
}

#[test]
fn model_exchange_vector_field_jacobian_and_nominals_are_the_equations() {
    let params = web_line(5e-5);
    let f = WebReference::new(&params).form;
    let span = params.web.unwrap();
    let mut inst = instance(Interface::ModelExchange, &[], None);
    inst.exit_initialization_mode().unwrap();
    inst.new_discrete_states().unwrap();
    inst.enter_continuous_time_mode().unwrap();
    let (tau_m, tau_l, v_in, t_in) = (0.3, -0.2, 1.9, 40.0);
    set(
        &mut inst,
        &[("tau_m", tau_m), ("tau_L", tau_l), ("v_in", v_in), ("T_in", t_in)],
    );
    // In contact on the positive flank: u = 3 g.
    let theta_m = 3.0 * f.g / f.r_m;
    let x = [theta_m, 90.0, 0.0, 38.0, 55.0];
    inst.set_time(0.01).unwrap();
    inst.set_continuous_states(&x).unwrap();

    let mut dx = [0.0; 5];
    inst.get_derivatives(&mut dx).unwrap();
    let u = f.r_m * x[0] - f.r_l * x[2];
    let psi = f.k * (u - f.g);
    let want = [
        x[1],
        (tau_m - f.b_m * x[1] - f.r_m * psi) / f.j_m,
        x[3],
        (tau_l - f.b_l * x[3] + f.r_l * psi - span.r_w * x[4]) / f.j_l,
        (span.ea * (span.r_w * x[3] - v_in) + span.v_ref * (t_in - x[4])) / span.l_w,
    ];
    for k in 0..5 {
        assert!(
            (dx[k] - want[k]).abs() <= 1e-12 * want[k].abs().max(1.0),
            "{k}: {} vs {}",
            dx[k],
            want[k]
        );
    }

    // ∂/∂ of der(omega_L), der(T) with respect to T, ω_L, v_in, T_in, one seed at a time.
    let unknowns = vrs(web(), &["der(omega_L)", "der(T)"]);
    let exact = [
        ("T", [-span.r_w / f.j_l, -span.v_ref / span.l_w]),
        ("omega_L", [-f.b_l / f.j_l, span.ea * span.r_w / span.l_w]),
        ("v_in", [0.0, -span.ea / span.l_w]),
        ("T_in", [0.0, span.v_ref / span.l_w]),
    ];
    for (known, want) in exact {
        let mut got = [0.0; 2];
        inst.get_directional_derivative(&unknowns, &[web().vr(known)], &[1.0], &mut got)
            .unwrap();
        for k in 0..2 {
            assert!(
                (got[k] - want[k]).abs() <= 1e-12 * want[k].abs().max(1e-300),
                "∂{k}/∂{known}: {got:?} vs {want:?}"
            );
        }
    }

    // T's nominal: the tension that balances on the roller the belt force of a gap's stretch.
    let mut nominals = [0.0; 5];
    inst.get_nominals_of_continuous_states(&mut nominals).unwrap();
    let t_nominal = f.k * f.g * f.r_l / span.r_w;
    assert!(
        (nominals[4] / t_nominal - 1.0).abs() < 1e-12,
        "{} vs {t_nominal}",
        nominals[4]
    );
    // Four states are the drive train's count, not the web line's.
    assert!(inst.set_continuous_states(&x[..4]).is_err());
}

#[test]
fn output_derivatives_of_t_and_bound_t_are_their_rates() {
    let gains = [("Kp", 0.178805), ("Ki", 57.61789), ("Kp_T", 0.01), ("Ki_T", 0.05)];
    let mut inst = instance(Interface::CoSimulation, &gains, None);
    inst.exit_initialization_mode().unwrap();
    let inputs = WebInputs {
        tau_m: 0.05,
        v_in: 0.3,
        t_in: 20.0,
        ..WebInputs::default()
    };
    apply(&mut inst, &inputs);
    let h = 1e-3;
    for k in 0..30 {
        inst.do_step(k as f64 * h, h).unwrap();
    }
    let names = ["T", "bound_T", "omega_L"];
    let vr = vrs(web(), &names);
    let mut rates = [0.0; 3];
    inst.get_real_output_derivatives(&vr, &[1; 3], &mut rates).unwrap();
    let before = get(&mut inst, &names);
    let span = web_line(5e-5).web.unwrap();
    // L_w T' = EA (R_w ω_L − v_in) + v_ref (T_in − T) from the outputs.
    let dt = (span.ea * (span.r_w * before[2] - 0.3) + span.v_ref * (20.0 - before[0])) / span.l_w;
    assert!((rates[0] - dt).abs() <= 1e-10 * dt.abs(), "dT/dt {} vs {dt}", rates[0]);
    // bound_T over a tiny step.
    let delta = 1e-7;
    inst.do_step(30.0 * h, delta).unwrap();
    let after = get(&mut inst, &names);
    let slope = (after[1] - before[1]) / delta;
    assert!(
        rates[1] > 0.0 && (rates[1] - slope).abs() <= 1e-5 * rates[1],
        "d bound_T/dt {} vs {slope}",
        rates[1]
    );
}

#[test]
fn bad_web_inputs_are_refused_by_name() {
    let log = Collected::default();
    let mut inst = instance(Interface::CoSimulation, &[], Some(log.clone()));
    inst.exit_initialization_mode().unwrap();
    let last = |log: &Collected| {
        let entries = log.0.borrow();
        let reason = entries.iter().rev().find(|(_, c, _)| *c == LogCategory::Errors);
        reason.map(|(_, _, m)| m.clone()).unwrap_or_default()
    };
    for (name, value) in [("v_in", f64::NAN), ("T_in", f64::INFINITY)] {
        assert!(inst.set_real(&[web().vr(name)], &[value]).is_err());
        let message = last(&log);
        assert!(message.contains(name), "{message}");
        inst.reset().unwrap();
        inst.setup_experiment(None, 0.0, None).unwrap();
        inst.enter_initialization_mode().unwrap();
        inst.exit_initialization_mode().unwrap();
    }
    // An input line that leaves f64 within the step is refused before stepping, by name.
    inst.set_real_input_derivatives(&[web().vr("T_in")], &[1], &[1e308])
        .unwrap();
    set(&mut inst, &[("T_in", 1e308)]);
    assert!(inst.do_step(0.0, 10.0).is_err());
    let message = last(&log);
    assert!(message.contains("T_in"), "{message}");
    // Finite upstream values whose motion leaves f64 within the step: refused, naming the inputs.
    let mut inst = instance(Interface::CoSimulation, &[], Some(log.clone()));
    inst.exit_initialization_mode().unwrap();
    set(&mut inst, &[("v_in", 1e300)]);
    assert!(inst.do_step(0.0, 1e-3).is_err());
    let message = last(&log);
    assert!(
        message.contains("v_in = 1e300") && message.contains("overflows"),
        "{message}"
    );
    // The drive trains have no such inputs.
    let belt = MODELS.iter().find(|m| m.identifier == "BacklashBelt").unwrap();
    assert!(belt.by_name("v_in").is_none() && belt.by_vr(30).is_none());
}

/// With the speed loop open the tension PI cannot act (it trims the speed reference): its gains
/// change neither bound, and the integrator x_T leaves the suprema finite.
#[test]
fn tension_gains_without_a_speed_loop_change_no_bound() {
    let bounds = |tension: &[(&str, f64)]| {
        let mut inst = instance(Interface::CoSimulation, tension, None);
        inst.exit_initialization_mode().unwrap();
        for k in 0..50 {
            inst.do_step(k as f64 * 1e-3, 1e-3).unwrap();
        }
        get(
            &mut inst,
            &["bound_T", "bound", "bound_paper", "bound_T_sup", "bound_sup"],
        )
    };
    let without = bounds(&[]);
    let with = bounds(&[("Kp_T", 0.01), ("Ki_T", 0.05)]);
    assert!(without.iter().all(|x| x.is_finite() && *x > 0.0), "{without:?}");
    // Bit for bit by construction: with Kp = Ki = 0 the tension gains enter `web_loop` only
    // multiplied by a speed gain (0·Kp_T, 0·Ki_T: the same zeros as with Kp_T = Ki_T = 0), and
    // neither `web_loop` nor `Reduced::web` wires x_T in with the speed loop open; so both
    // instances build identical matrices and run the same arithmetic on them.
    assert_eq!(with, without);
}

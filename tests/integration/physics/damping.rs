//! The damper in the compliant member (docs/model.md §1, "Damping in the compliant member"):
//! the stepper's own consistency (the same trajectory whatever the step size, every switch on a
//! surface of the law), the force never pulling, and the damped stepper's limit D → 0 against the
//! undamped one, which is a separate code path. The comparison with an independent reference is
//! in tests/python/test_damping.py.

use backlash_fmu::physics::{
    ContactLaw, ContactMode, Damping, Geometry, Inputs, Plant, PlantParams, PlantState, Stepper, SwitchEvent,
};

/// The paper's rig (docs/model.md §4) with a damper of contact damping ratio `zeta`:
/// D = 2 ζ sqrt(K J_eff), J_eff = 1/(r_m²/J_m + r_L²/J_L).
fn shaft(delta: f64, zeta: f64, law: ContactLaw) -> PlantParams {
    let p = PlantParams::paper_rig(delta);
    let k = 200.0;
    let j_eff = 1.0 / (1.0 / p.j_m + 1.0 / p.j_l);
    PlantParams {
        damping: Damping {
            d: 2.0 * zeta * (k * j_eff).sqrt(),
            law,
        },
        ..p
    }
}

/// A geared belt drive (r_m = 0.1 m, r_L = 0.12 m) with a damper of ratio `zeta`.
fn belt(delta: f64, zeta: f64, law: ContactLaw) -> PlantParams {
    let (j_m, j_l, k_b, r_m, r_l) = (2.28, 2.55, 2.0e4, 0.1, 0.08 * 0.075 / 0.05);
    let j_eff = 1.0 / (r_m * r_m / j_m + r_l * r_l / j_l);
    PlantParams {
        j_m,
        j_l,
        b_m: 0.05,
        b_l: 0.05,
        geometry: Geometry::Belt {
            k_b,
            r_1: r_m,
            r_2: 0.08,
            r_g1: 0.05,
            r_g2: 0.075,
            delta,
        },
        damping: Damping {
            d: 2.0 * zeta * (k_b * j_eff).sqrt(),
            law,
        },
        web: None,
    }
}

/// A reversing motor torque held over steps of `h`: ±amplitude, switching sign every `period`/2.
fn torque(t: f64, amplitude: f64, period: f64) -> f64 {
    if (t / period).fract() < 0.5 {
        amplitude
    } else {
        -amplitude
    }
}

struct Run {
    states: Vec<PlantState>,
    switches: Vec<(f64, SwitchEvent)>,
}

/// `steps` steps of `h` from rest, the torque held over each `hold` (a multiple of h).
fn run(params: PlantParams, h: f64, steps: usize, hold: f64, amplitude: f64, period: f64) -> Run {
    let plant = Plant::new(params).unwrap();
    let mut stepper = Stepper::new(plant);
    let mut state = PlantState::new(&plant, 0.0, 0.0, 0.0, 0.0);
    let mut states = vec![state];
    let mut switches = Vec::new();
    for n in 0..steps {
        let t = n as f64 * h;
        let held = (t / hold + 1e-9).floor() * hold;
        let inputs = Inputs::held(torque(held, amplitude, period), 0.0);
        stepper
            .step(&mut state, &inputs, h, &mut |e| switches.push((t, e)))
            .unwrap_or_else(|e| panic!("step {n}: {e}"));
        states.push(state);
    }
    Run { states, switches }
}

fn laws() -> [ContactLaw; 2] {
    [ContactLaw::ElastoBacklash, ContactLaw::ElastoBacklash2]
}

/// Exact stepping: the trajectory does not depend on the step size. Steps of 10 ms and of 1 ms
/// under the same 10 ms holds meet at every 10 ms point to round-off, times the growth of errors
/// over the run (the motion is stable: 1e-10 of each quantity's amplitude).
#[test]
fn the_trajectory_does_not_depend_on_the_step_size() {
    for law in laws() {
        for (label, params, amplitude) in [
            ("shaft", shaft(2.69e-3, 0.5, law), 6.0),
            ("shaft, zeta 0.05", shaft(2.69e-3, 0.05, law), 6.0),
            ("belt", belt(2.0e-3, 0.5, law), 6.0),
            ("shaft without gap", shaft(0.0, 0.5, law), 6.0),
        ] {
            let coarse = run(params, 1e-2, 300, 1e-2, amplitude, 0.6);
            let fine = run(params, 1e-3, 3000, 1e-2, amplitude, 0.6);
            assert_eq!(coarse.switches.len(), fine.switches.len(), "{label} {law:?}: switches");
            assert!(coarse.switches.len() >= 8, "{label} {law:?}: too few switches to test");
            let amp = |f: fn(&PlantState) -> f64| coarse.states.iter().map(|s| f(s).abs()).fold(0.0, f64::max);
            let scales = [amp(|s| s.u), amp(|s| s.du), amp(|s| s.omega_l), amp(|s| s.theta_l)];
            for (n, a) in coarse.states.iter().enumerate() {
                let b = &fine.states[10 * n];
                for (i, (x, y)) in [(a.u, b.u), (a.du, b.du), (a.omega_l, b.omega_l), (a.theta_l, b.theta_l)]
                    .into_iter()
                    .enumerate()
                {
                    assert!(
                        (x - y).abs() <= 1e-10 * scales[i],
                        "{label} {law:?} at t = {}: entry {i} {x} vs {y}",
                        n as f64 * 1e-2
                    );
                }
            }
        }
    }
}

/// Every switch is a crossing of a surface of the law, into the mode the law prescribes, and
/// the force never pulls: ψ has the sign of the mode's flank, and `contact` is its sign.
#[test]
fn the_force_never_pulls_and_every_switch_is_a_surface_of_the_law() {
    for law in laws() {
        for params in [shaft(2.69e-3, 0.5, law), belt(2.0e-3, 1.5, law), shaft(0.0, 0.5, law)] {
            let plant = Plant::new(params).unwrap();
            let r = run(params, 1e-3, 3000, 1e-2, 6.0, 0.6);
            let mut kinds = std::collections::BTreeSet::new();
            for (_, e) in &r.switches {
                kinds.insert(format!("{:?}->{:?}", e.from, e.to));
                assert_ne!(e.from, e.to);
                if law == ContactLaw::ElastoBacklash2 {
                    assert!(!matches!(
                        e.to,
                        ContactMode::CappedNegative | ContactMode::CappedPositive
                    ));
                }
            }
            // Contact lost by the force reaching 0 with u still past the flank.
            assert!(kinds.iter().any(|k| k.contains("->Slack")), "{law:?}: {kinds:?}");
            if law == ContactLaw::ElastoBacklash {
                assert!(kinds.iter().any(|k| k.contains("->Capped")), "{law:?}: {kinds:?}");
            }
            for s in &r.states {
                let psi = plant.force(s.u, s.du);
                let contact = backlash_fmu::physics::contact_indicator(s, &plant);
                assert!(psi * s.mode.side() >= 0.0, "{law:?}: psi = {psi} in {:?}", s.mode);
                assert_eq!(
                    contact as f64,
                    psi.signum() * (psi != 0.0) as i32 as f64,
                    "{law:?}: {:?}",
                    s.mode
                );
            }
        }
    }
}

/// The damped stepper (its own modes and surfaces) with a tiny damper against the undamped one:
/// the motions differ by O(D), here 1e-9 of K's scale.
#[test]
fn a_vanishing_damper_gives_the_undamped_plant() {
    for law in laws() {
        let damped = shaft(2.69e-3, 1e-9, law);
        let undamped = PlantParams::paper_rig(2.69e-3);
        let a = run(damped, 1e-2, 300, 1e-2, 6.0, 0.6);
        let b = run(undamped, 1e-2, 300, 1e-2, 6.0, 0.6);
        let scale = b.states.iter().map(|s| s.du.abs()).fold(0.0, f64::max);
        for (x, y) in a.states.iter().zip(&b.states) {
            assert!((x.du - y.du).abs() <= 1e-6 * scale, "{law:?}: {} vs {}", x.du, y.du);
        }
    }
}

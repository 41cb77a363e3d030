//! `Stepper::step` across many contact switches, against the independent Taylor reference
//! (support/reference.rs, validated in physics::reference to ~1e-13): states within 1e-9
//! relative to the amplitude of each quantity, and the same switches (number, direction) at
//! the same times within 1e-10 s. Also grazing touches that begin and end inside one step
//! (docs/model.md §2), several switches per step, and step sizes from 1 ns to 10 s; and the FMU's quiet
//! path (`Stepper::quiet_step`) against `Stepper::step`.

use crate::support::closed_form::single_inertia_increment;
use crate::support::harness::{compare_run, compare_steps, sine_schedule, square_wave_schedule};
use crate::support::reference::{GenericForm, Reference};
use crate::support::rigs::belt;
use backlash_fmu::physics::{Inputs, Plant, PlantParams, PlantState, Stepper};

const TOL_STATE: f64 = 1e-9;
const TOL_TIME: f64 = 1e-10;

/// The paper's gaps (docs/model.md §4): 1.55, 3.56, 5.38 mm, read as Δ = gap/2 and as Δ = gap.
const PAPER_DELTAS: [f64; 4] = [0.775e-3, 1.78e-3, 3.56e-3, 5.38e-3];

#[test]
fn paper_rig_square_wave_torque_small_steps() {
    for delta in PAPER_DELTAS {
        let params = PlantParams::paper_rig(delta);
        let sched = square_wave_schedule(5.0, 1.3, 1e-3, 3000, 0.5);
        let c = compare_run(&params, [0.0; 4], &sched);
        assert!(
            c.ref_events.len() >= 8,
            "too few switches to test anything: {}",
            c.ref_events.len()
        );
        c.assert_agrees(TOL_STATE, TOL_TIME, &format!("rig Δ = {delta}, square wave, h = 1e-3"));
    }
}

#[test]
fn paper_rig_reversing_torque_communication_steps() {
    for delta in [1.78e-3, 5.38e-3] {
        let params = PlantParams::paper_rig(delta);
        for (label, sched) in [
            ("square wave, h = 0.05", square_wave_schedule(5.0, 1.7, 0.05, 200, -0.3)),
            ("sine ZOH, h = 0.05", sine_schedule(4.0, 2.3, 0.05, 200, 0.2, false)),
            ("sine FOH, h = 0.05", sine_schedule(4.0, 2.3, 0.05, 200, 0.2, true)),
            ("sine FOH, h = 0.31", sine_schedule(4.0, 2.3, 0.31, 40, 0.0, true)),
        ] {
            let c = compare_run(&params, [0.0, 0.3, 0.0, -0.1], &sched);
            assert!(
                c.ref_events.len() >= 8,
                "{label}: too few switches: {}",
                c.ref_events.len()
            );
            c.assert_agrees(TOL_STATE, TOL_TIME, &format!("rig Δ = {delta}, {label}"));
        }
    }
}

#[test]
fn bouncing_in_the_gap_gives_many_switches_per_long_step() {
    // No torque, a relative speed: the teeth bounce flank to flank (elastic contact, docs/model.md §5),
    // tens of switches inside each 1–10 s step.
    for delta in [1.78e-3, 5.38e-3] {
        let params = PlantParams::paper_rig(delta);
        for h in [1.0, 2.5, 10.0] {
            let steps = (20.0 / h) as usize;
            let sched: Vec<_> = (0..steps)
                .map(|i| (Inputs::held(if i % 2 == 0 { 0.0 } else { 0.4 }, 0.0), h))
                .collect();
            let c = compare_run(&params, [0.0, 0.5, 0.0, -0.5], &sched);
            let per_step = c.ref_events.len() as f64 / steps as f64;
            assert!(per_step >= 5.0 * h, "h = {h}: only {per_step} switches per step");
            c.assert_agrees(TOL_STATE, TOL_TIME, &format!("rig Δ = {delta}, bouncing, h = {h}"));
        }
    }
}

#[test]
fn belt_geometry_with_reversing_torque() {
    for delta in [1e-4, 5e-4] {
        let params = belt(delta);
        for (label, sched) in [
            ("square wave, h = 1e-3", square_wave_schedule(0.3, 0.4, 1e-3, 2000, 0.0)),
            ("sine FOH, h = 0.05", sine_schedule(0.3, 0.7, 0.05, 100, -0.5, true)),
            ("square wave, h = 2", square_wave_schedule(0.3, 4.0, 2.0, 5, 0.0)),
        ] {
            let c = compare_run(&params, [0.0, 1.0, 0.0, 0.0], &sched);
            assert!(
                c.ref_events.len() >= 8,
                "{label}: too few switches: {}",
                c.ref_events.len()
            );
            c.assert_agrees(TOL_STATE, TOL_TIME, &format!("belt Δ = {delta}, {label}"));
        }
    }
}

#[test]
fn each_step_is_exact_to_round_off() {
    // Local error: the reference restarts from the stepper's state at every step, so what is
    // measured is the error made within one step (docs/model.md §2: exact up to round-off), not its
    // growth along a trajectory whose switches amplify earlier differences.
    let cases: Vec<(&str, PlantParams, Vec<(Inputs, f64)>)> = vec![
        (
            "rig Δ = 1.78 mm, square wave, h = 1e-3",
            PlantParams::paper_rig(1.78e-3),
            square_wave_schedule(5.0, 1.3, 1e-3, 3000, 0.5),
        ),
        (
            "rig Δ = 5.38 mm, sine FOH, h = 0.05",
            PlantParams::paper_rig(5.38e-3),
            sine_schedule(4.0, 2.3, 0.05, 200, 0.2, true),
        ),
        (
            "belt Δ = 0.1 mm, square wave, h = 1e-3",
            belt(1e-4),
            square_wave_schedule(0.3, 0.4, 1e-3, 2000, 0.0),
        ),
        (
            "belt Δ = 0.5 mm, sine FOH, h = 0.05",
            belt(5e-4),
            sine_schedule(0.3, 0.7, 0.05, 100, -0.5, true),
        ),
    ];
    for (label, params, sched) in cases {
        let c = compare_steps(&params, [0.0, 1.0, 0.0, 0.0], &sched);
        c.assert_agrees(1e-12, 1e-12, &format!("local error, {label}"));
    }
}

#[test]
fn tiny_and_huge_steps() {
    // Start just short of contact (u = g − 5e-10, u' = 1e-3): the contact begins inside the
    // stream of 1 ns steps; then 1 µs steps, then 10 s steps.
    let params = PlantParams::paper_rig(1.78e-3);
    let g = 1.78e-3;
    let mut sched = vec![(Inputs::held(0.0, 0.0), 1e-9); 1000];
    sched.extend(vec![(Inputs::held(1.0, 0.0), 1e-6); 1000]);
    sched.extend(vec![(Inputs::held(-1.0, 0.0), 1e-3); 200]);
    sched.extend(vec![(Inputs::held(0.0, 0.0), 10.0); 2]);
    let init = [g - 5e-10, 1e-3, 0.0, 0.0];
    let c = compare_run(&params, init, &sched);
    let first = c.ref_events.first().copied();
    eprintln!("first switch {first:?}");
    assert!(
        first.is_some_and(|e| e.t < 1e-6),
        "the first contact should fall inside the 1 ns steps"
    );
    c.assert_agrees(TOL_STATE, TOL_TIME, "rig, steps 1 ns … 10 s");
}

/// One step of `h` from u0 with u' = v0 and motor deceleration `acc` (τ_m = −acc·J_m):
/// returns the stepper's switches (offset, from, to) and the comparison with the reference.
fn graze(params: &PlantParams, u0: f64, v0: f64, acc: f64, h: f64) -> Vec<(f64, i32, i32)> {
    let plant = Plant::new(*params).unwrap();
    let mut stepper = Stepper::new(plant);
    let mut st = PlantState::new(&plant, u0, v0, 0.0, 0.0);
    let mut events = Vec::new();
    let inputs = Inputs::held(-acc * params.j_m, 0.0);
    let n = stepper
        .step(&mut st, &inputs, h, &mut |e| {
            events.push((e.offset, e.from.as_i32(), e.to.as_i32()))
        })
        .unwrap();
    assert_eq!(n, events.len());
    let c = compare_run(params, [u0, v0, 0.0, 0.0], &[(inputs, h)]);
    c.assert_agrees(TOL_STATE, TOL_TIME, &format!("graze from u0 = {u0:e}, h = {h}"));
    events
}

#[test]
fn grazing_touch_inside_one_step_is_found_exactly() {
    // b = 0: in the gap u'' = −a, u peaks at g + ε at t* = v0/a. The touch is a contact
    // q'' + Ω² q = −a from q' = √(2aε): it lasts 2 atan(√(2aε) Ω/a)/Ω. v0²/(2a) is a power
    // of two, so the ε realised in u0 is computed exactly.
    let g = 1.78e-3;
    let params = PlantParams {
        b_m: 0.0,
        b_l: 0.0,
        ..PlantParams::paper_rig(g)
    };
    let f = GenericForm::from_params(&params);
    let omega = (f.k * (1.0 / f.j_m + 1.0 / f.j_l)).sqrt();
    let (acc, v0) = (1.0, 0.0625);
    for eps_wanted in [1e-6 * g, 1e-9 * g, 1e-12 * g] {
        let u0 = (g + eps_wanted) - v0 * v0 / (2.0 * acc);
        let eps = (u0 + v0 * v0 / (2.0 * acc)) - g;
        let v_in = (2.0 * acc * eps).sqrt();
        let t_in = (v0 - v_in) / acc;
        let t_out = t_in + 2.0 * (v_in * omega / acc).atan() / omega;
        // u reaches −g at t ≈ 0.147: the steps end before, or (h = 1) only the first two
        // switches are the touch.
        for h in [0.1, 0.14, 1.0] {
            let mut events = graze(&params, u0, v0, acc, h);
            events.retain(|e| e.0 < 0.14);
            eprintln!("ε = {eps:.2e}, h = {h}: {events:?}, exact entry {t_in}, exit {t_out}");
            assert_eq!(events.len(), 2, "ε = {eps:e}, h = {h}: switches {events:?}");
            assert_eq!((events[0].1, events[0].2, events[1].1, events[1].2), (0, 1, 1, 0));
            let (e_in, e_out) = ((events[0].0 - t_in).abs(), (events[1].0 - t_out).abs());
            assert!(
                e_in <= TOL_TIME && e_out <= TOL_TIME,
                "ε = {eps:e}: entry off by {e_in:e} s, exit by {e_out:e} s"
            );
        }
    }
}

#[test]
fn grazing_touch_with_damping_matches_the_reference() {
    // b > 0: the free flight is the closed form of each inertia alone; its peak of u (where
    // ω_m = ω_L) is placed at g + ε. u does not act on the free flight, so the shift is exact.
    let g = 3.56e-3;
    let params = PlantParams::paper_rig(g);
    let f = GenericForm::from_params(&params);
    let (acc, v0) = (1.0, 0.08);
    let rel = |t: f64| {
        let (dm, wm) = single_inertia_increment(f.j_m, f.b_m, v0, -acc * f.j_m, 0.0, t);
        (dm, wm) // θ_L, ω_L stay 0: no load torque, load at rest
    };
    let (mut lo, mut hi) = (0.0, 1.0);
    while hi - lo > 1e-16 {
        let mid = 0.5 * (lo + hi);
        if rel(mid).1 > 0.0 {
            lo = mid
        } else {
            hi = mid
        }
    }
    let rise = rel(lo).0;
    let reference = Reference::new(&params);
    for eps in [1e-6 * g, 1e-9 * g, 1e-12 * g] {
        let u0 = (g + eps) - rise;
        // The reference confirms a touch, then the stepper must see the same two switches.
        let mut rs = reference.state(u0, v0, 0.0, 0.0);
        let mut ref_events = Vec::new();
        reference.step(
            &mut rs,
            0.0,
            &Inputs::held(-acc * f.j_m, 0.0),
            0.15,
            &mut ref_events,
            None,
        );
        assert_eq!(ref_events.len(), 2, "reference: {ref_events:?}");
        let events = graze(&params, u0, v0, acc, 0.15);
        eprintln!("damped graze ε = {eps:.1e}: stepper {events:?}, reference {ref_events:?}");
        assert_eq!(events.len(), 2);
    }
}

/// `Stepper::quiet_step`, the event-free step the FMU tries first, against `Stepper::step`:
/// wherever it takes a step it gives the same state bit for bit (but for the sign of a zero:
/// the contract in `Stepper::quiet_step`'s documentation); it declines every step that holds a
/// contact switch, a step size other than the last one and a step of several pieces; and it
/// takes most one-piece steps of a run (else the FMU would not be fast).
#[test]
fn the_quiet_step_is_the_step_or_declines() {
    // (label, plant, schedule, whether its steps are one piece long)
    for (label, params, sched, one_piece) in [
        (
            "rig Δ = 1.78 mm, square wave, h = 1e-3",
            PlantParams::paper_rig(1.78e-3),
            square_wave_schedule(5.0, 1.3, 1e-3, 3000, 0.5),
            true,
        ),
        (
            "belt Δ = 0.1 mm, square wave, h = 1e-3",
            belt(1e-4),
            square_wave_schedule(0.3, 0.4, 1e-3, 2000, 0.0),
            true,
        ),
        (
            "rig Δ = 5.38 mm, sine FOH, h = 0.05",
            PlantParams::paper_rig(5.38e-3),
            sine_schedule(4.0, 2.3, 0.05, 200, 0.2, true),
            false,
        ),
    ] {
        let plant = Plant::new(params).unwrap();
        let mut stepper = Stepper::new(plant);
        let mut state = PlantState::new(&plant, 0.0, 1.0, 0.0, 0.0);
        let (mut taken, mut switching, mut declined_switching) = (0, 0, 0);
        for (i, (inputs, h)) in sched.iter().enumerate() {
            let quiet = stepper.quiet_step(&state, inputs, *h);
            let switches = stepper.step(&mut state, inputs, *h, &mut |_| {}).unwrap();
            if switches > 0 {
                switching += 1;
                declined_switching += usize::from(quiet.is_none());
            }
            if let Some(q) = quiet {
                taken += 1;
                assert_eq!(switches, 0, "{label}: quiet step {i} over a switch");
                assert_eq!(q.mode, state.mode, "{label}: step {i}");
                for (a, b) in [
                    (q.theta_m, state.theta_m),
                    (q.omega_m, state.omega_m),
                    (q.theta_l, state.theta_l),
                    (q.omega_l, state.omega_l),
                    (q.u, state.u),
                    (q.du, state.du),
                ] {
                    // Same arithmetic by construction, so the same bits on any machine: both
                    // run `step`'s one-piece path (the same cached kernel and
                    // `PieceKernel::sums_inline` on the same operands in the same order, then
                    // `clear` and `finish_piece`). `step` forms the piece-start inputs as
                    // τ + τ̇·0, τ but for the sign of a zero: a zero may differ in sign only.
                    assert!(
                        a.to_bits() == b.to_bits() || (a == 0.0 && b == 0.0),
                        "{label}: step {i}: {a} vs {b}"
                    );
                }
            }
        }
        assert!(
            switching >= 4,
            "{label}: too few switching steps to test anything: {switching}"
        );
        assert_eq!(declined_switching, switching, "{label}");
        if one_piece {
            assert!(
                taken >= sched.len() * 3 / 4,
                "{label}: the quiet path took only {taken} of {} steps",
                sched.len()
            );
            // Another step size than the last one: declined.
            let (inputs, h) = sched[0];
            assert!(stepper.quiet_step(&state, &inputs, h * 0.5).is_none(), "{label}");
        } else {
            assert_eq!(taken, 0, "{label}: steps of several pieces");
        }
    }
}

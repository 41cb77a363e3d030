//! The web line of docs/model.md §8 stepped exactly and bounded: against the independent
//! reference of support/web_reference.rs (its own matrices and Taylor integrator), against the
//! belt drive when the web is decoupled, twin lines under PI loops against bound_T(t) and
//! bound(t), the vector field against its equations, and its parameters refused by name.

use crate::support::reference::RefEvent;
use crate::support::rigs::{belt_damped, web_line};
use crate::support::web_reference::{WebInputs, WebReference};
use backlash_fmu::physics::{Damping, Geometry, Inputs, ParamError, Plant, PlantParams, PlantState, Stepper, WebSpan};

/// [θ_m, ω_m, θ_L, ω_L, u, T] of the crate's state.
fn sample(s: &PlantState) -> [f64; 6] {
    [s.theta_m, s.omega_m, s.theta_l, s.omega_l, s.u, s.tension]
}

/// The crate's inputs for the reference's: the span's forcing from v_in and T_in.
fn crate_inputs(plant: &Plant, i: &WebInputs) -> Inputs {
    let web = plant.web().expect("a web line");
    Inputs {
        tau_m: i.tau_m,
        tau_l: i.tau_l,
        dtau_m: i.dtau_m,
        dtau_l: i.dtau_l,
        span: web.forcing(i.v_in, i.t_in),
        dspan: web.forcing(i.dv_in, i.dt_in),
    }
}

/// Errors relative to the amplitude of each kind over the run: angles to max |θ|, speeds to
/// max |ω|, u to max(|u|, g), T to max |T|.
fn relative_errors(got: &[[f64; 6]], want: &[[f64; 6]], g: f64) -> [f64; 4] {
    let amplitude = |idx: &[usize]| {
        want.iter()
            .flat_map(|w| idx.iter().map(move |&k| w[k].abs()))
            .fold(f64::MIN_POSITIVE, f64::max)
    };
    let kinds: [(&[usize], f64); 4] = [
        (&[0, 2], amplitude(&[0, 2])),
        (&[1, 3], amplitude(&[1, 3])),
        (&[4], amplitude(&[4]).max(g)),
        (&[5], amplitude(&[5])),
    ];
    kinds.map(|(idx, scale)| {
        got.iter()
            .zip(want)
            .flat_map(|(a, b)| idx.iter().map(move |&k| (a[k] - b[k]).abs() / scale))
            .fold(0.0, f64::max)
    })
}

/// Both solutions of one run: samples after every step, and the switches.
struct Runs {
    got: Vec<[f64; 6]>,
    want: Vec<[f64; 6]>,
    switches: Vec<f64>,
    ref_events: Vec<RefEvent>,
}

/// A web line started at line speed (ω_L R_w = v_in, no slip in the gap) and at the upstream
/// tension, then driven by `schedule`.
fn run_both(params: &PlantParams, schedule: &[(WebInputs, f64)]) -> Runs {
    let plant = Plant::new(*params).unwrap();
    let web = *plant.web().unwrap();
    let (v_in, t_in) = (schedule[0].0.v_in, schedule[0].0.t_in);
    let omega_l = v_in / web.r_w;
    let omega_m = omega_l * plant.r_l() / plant.r_m();
    let z = [0.0, omega_m, 0.0, omega_l];
    let mut stepper = Stepper::new(plant);
    let mut state = PlantState::new(&plant, z[0], z[1], z[2], z[3]).with_tension(t_in);
    let reference = WebReference::new(params);
    let mut ref_state = reference.state(z, t_in);
    let (mut got, mut want) = (vec![sample(&state)], vec![WebReference::sample(&ref_state)]);
    let (mut switches, mut ref_events) = (Vec::new(), Vec::new());
    let mut t = 0.0;
    for (inputs, h) in schedule {
        let t0 = t;
        stepper
            .step(&mut state, &crate_inputs(&plant, inputs), *h, &mut |e| {
                switches.push(t0 + e.offset)
            })
            .unwrap();
        reference.step(&mut ref_state, t, inputs, *h, &mut ref_events);
        t += h;
        got.push(sample(&state));
        want.push(WebReference::sample(&ref_state));
    }
    Runs {
        got,
        want,
        switches,
        ref_events,
    }
}

fn assert_agrees(params: &PlantParams, schedule: &[(WebInputs, f64)], label: &str) {
    let Runs {
        got,
        want,
        switches,
        ref_events,
    } = run_both(params, schedule);
    let g = Plant::new(*params).unwrap().half_gap();
    let errors = relative_errors(&got, &want, g);
    let worst = errors.iter().fold(0.0, |m: f64, e| m.max(*e));
    println!(
        "{label}: {} switches; relative errors θ {:.1e}, ω {:.1e}, u {:.1e}, T {:.1e}; T within [{:.3}, {:.3}] N",
        switches.len(),
        errors[0],
        errors[1],
        errors[2],
        errors[3],
        want.iter().map(|w| w[5]).fold(f64::INFINITY, f64::min),
        want.iter().map(|w| w[5]).fold(f64::NEG_INFINITY, f64::max),
    );
    assert!(worst <= 1e-9, "{label}: relative errors {errors:?}");
    assert!(
        switches.len() >= 4,
        "{label}: the scenario must switch contact ({})",
        switches.len()
    );
    assert_eq!(switches.len(), ref_events.len(), "{label}: switch counts");
    let mut latest = 0.0f64;
    for (t, e) in switches.iter().zip(&ref_events) {
        latest = latest.max((t - e.t).abs());
        assert!(
            (t - e.t).abs() <= 1e-10,
            "{label}: switch at {t} vs the reference's {}",
            e.t
        );
    }
    println!("{label}: switch instants within {latest:.1e} s of the reference's");
}

/// A reversing motor torque about `bias` (period `period`), held over steps of `h`.
fn reversing(bias: f64, amp: f64, period: f64, h: f64, steps: usize, web: WebInputs) -> Vec<(WebInputs, f64)> {
    (0..steps)
        .map(|k| {
            let sign = if ((k as f64 * h / (0.5 * period)) as i64) % 2 == 0 {
                1.0
            } else {
                -1.0
            };
            (
                WebInputs {
                    tau_m: bias + sign * amp,
                    ..web
                },
                h,
            )
        })
        .collect()
}

#[test]
fn web_line_open_loop_matches_an_independent_solution() {
    let params = web_line(5e-5);
    let upstream = WebInputs {
        v_in: 2.0,
        t_in: 50.0,
        ..WebInputs::default()
    };
    // Held torques reversing every 20 ms: the gear crosses its gap both ways.
    assert_agrees(
        &params,
        &reversing(0.42, 0.3, 0.04, 1e-3, 200, upstream),
        "held, h = 1 ms",
    );
    // Steps of 7 ms (several pieces each) and a load torque.
    let loaded = WebInputs {
        tau_l: -0.2,
        ..upstream
    };
    assert_agrees(&params, &reversing(0.4, 0.5, 0.07, 7e-3, 30, loaded), "held, h = 7 ms");
    // First-order hold: torque, upstream speed and tension all ramp over each step.
    let ramps: Vec<(WebInputs, f64)> = (0..150)
        .map(|k| {
            let t = k as f64 * 2e-3;
            let phase = (2.0 * std::f64::consts::PI * t / 0.05).sin();
            (
                WebInputs {
                    tau_m: 0.42 + 0.4 * phase,
                    dtau_m: 0.4 * 2.0 * std::f64::consts::PI / 0.05 * (2.0 * std::f64::consts::PI * t / 0.05).cos(),
                    tau_l: 0.0,
                    dtau_l: 0.1,
                    v_in: 2.0 + 0.01 * phase,
                    dv_in: -0.05,
                    t_in: 50.0 + 5.0 * phase,
                    dt_in: 30.0,
                },
                2e-3,
            )
        })
        .collect();
    assert_agrees(&params, &ramps, "ramped inputs, h = 2 ms");
}

#[test]
fn a_decoupled_web_leaves_the_belt_drive_as_it_was() {
    // EA and T_in tiny and T starting at 0: the web pulls with R_w T ~ 1e-12 N·m, so the drive
    // train's motion is the belt drive's to far below 1e-9.
    let delta = 5e-5;
    let belt = PlantParams {
        damping: Damping::NONE,
        web: None,
        ..web_line(delta)
    };
    let decoupled = PlantParams {
        damping: Damping::NONE,
        web: Some(WebSpan {
            ea: 1e-9,
            ..web_line(delta).web.unwrap()
        }),
        ..belt
    };
    let (belt_plant, web_plant) = (Plant::new(belt).unwrap(), Plant::new(decoupled).unwrap());
    let (mut belt_stepper, mut web_stepper) = (Stepper::new(belt_plant), Stepper::new(web_plant));
    let start = |p: &Plant| PlantState::new(p, 0.0, 0.0, 0.0, 0.0);
    let (mut a, mut b) = (start(&belt_plant), start(&web_plant));
    let web = *web_plant.web().unwrap();
    let (mut switches_a, mut switches_b) = (0, 0);
    let (mut got, mut want) = (Vec::new(), Vec::new());
    // A sinusoidal motor torque, first-order hold. The lightly damped belt rattles in the gap
    // after each reversal, and a rattling gap amplifies any difference, however small, from
    // one impact to the next (a factor of ~10 per 40 ms here): the run is kept to 150 ms.
    let period = 0.2;
    let w = 2.0 * std::f64::consts::PI / period;
    for k in 0..150 {
        let t = k as f64 * 1e-3;
        let inputs = Inputs {
            dtau_m: 0.05 * w * (w * t).cos(),
            ..Inputs::held(0.05 * (w * t).sin(), 0.0)
        };
        let web_inputs = Inputs {
            span: web.forcing(2.0, 1e-9),
            ..inputs
        };
        switches_a += belt_stepper.step(&mut a, &inputs, 1e-3, &mut |_| {}).unwrap();
        switches_b += web_stepper.step(&mut b, &web_inputs, 1e-3, &mut |_| {}).unwrap();
        got.push(sample(&b));
        want.push(sample(&a));
    }
    let errors = relative_errors(&got, &want, belt_plant.half_gap());
    println!(
        "{switches_a} switches; web vs belt: θ {:.1e}, ω {:.1e}, u {:.1e}; |T| ≤ {:.1e} N",
        errors[0],
        errors[1],
        errors[2],
        got.iter().map(|s| s[5].abs()).fold(0.0, f64::max)
    );
    assert!(
        switches_a >= 4 && switches_a == switches_b,
        "switches {switches_a} vs {switches_b}"
    );
    assert!(errors[..3].iter().all(|e| *e <= 1e-9), "{errors:?}");
}

#[test]
fn web_parameters_are_refused_by_name() {
    let names = ["R_w", "L_w", "EA", "v_ref"];
    for (i, name) in names.iter().enumerate() {
        for bad in [0.0, -1.0, f64::NAN, f64::INFINITY, 1e-300] {
            let mut web = web_line(5e-5).web.unwrap();
            *[&mut web.r_w, &mut web.l_w, &mut web.ea, &mut web.v_ref][i] = bad;
            let params = PlantParams {
                damping: Damping::NONE,
                web: Some(web),
                ..web_line(5e-5)
            };
            let named = match Plant::new(params) {
                Err(ParamError::NotFinite { name, .. })
                | Err(ParamError::NotPositive { name, .. })
                | Err(ParamError::OutOfScale { name, .. }) => name,
                other => panic!("{name} = {bad}: {other:?}"),
            };
            assert_eq!(named, *name, "{name} = {bad}");
        }
    }
    // A shaft pulls a web as well as a belt does: the span is independent of the geometry.
    let shaft = PlantParams {
        damping: Damping::NONE,
        web: web_line(0.0).web,
        ..PlantParams::paper_rig(1e-3)
    };
    assert!(matches!(shaft.geometry, Geometry::Shaft { .. }));
    assert!(Plant::new(shaft).is_ok());
    assert!(Plant::new(belt_damped(1e-4, 0.0, 0.0)).unwrap().web().is_none());
}

/// Twin web lines (with Δ and with Δ = 0) under the same continuous-time PI loops, reversing
/// speed reference and a tension reference, solved by the independent integrator: their
/// tension and load-speed differences stay within the library's bound_T(t) and bound(t) at
/// every sample, with and without the tension loop, and the bounds are not vacuous.
#[test]
fn twin_web_lines_stay_within_bound_t_and_bound() {
    use crate::support::web_reference::{WebLoopSetup, WebPiLoop, PI_OMEGA_L, PI_TENSION};
    use backlash_fmu::physics::stepper::MAX_PIECES;
    use backlash_fmu::physics::{PiGains, WebSpeedBound, WebTensionBound};
    let params = web_line(5e-5);
    let plant = Plant::new(params).unwrap();
    let speed = PiGains {
        kp: 0.178805,
        ki: 57.61789,
    };
    for tension in [PiGains::default(), PiGains { kp: 0.01, ki: 0.05 }] {
        let setup = WebLoopSetup {
            kp: speed.kp,
            ki: speed.ki,
            kp_t: tension.kp,
            ki_t: tension.ki,
            t_ref: 2.0,
            v_in: 0.0,
            t_in: 0.0,
            amp: 30.0,
            w: 2.0 * std::f64::consts::PI * 5.0,
        };
        let mut with_gap = WebPiLoop::new(&params, setup, true);
        let mut without = WebPiLoop::new(&params, setup, false);
        let mut bound_t = WebTensionBound::new(&plant, speed, tension).unwrap();
        let mut bound = WebSpeedBound::new(&plant, speed, tension).unwrap();
        let dt = 2e-4;
        let (mut switches, mut worst_t, mut worst_w) = (0, 0.0f64, 0.0f64);
        for _ in 0..5000 {
            switches += with_gap.advance(dt);
            without.advance(dt);
            bound_t.advance(dt).unwrap();
            bound.advance(dt).unwrap();
            let dt_diff = (with_gap.y[PI_TENSION] - without.y[PI_TENSION]).abs();
            let dw_diff = (with_gap.y[PI_OMEGA_L] - without.y[PI_OMEGA_L]).abs();
            assert!(
                dt_diff <= bound_t.bound() * (1.0 + 1e-9),
                "{tension:?} t = {}: |ΔT| {dt_diff} > bound_T {}",
                with_gap.t,
                bound_t.bound()
            );
            assert!(
                dw_diff <= bound.bound() * (1.0 + 1e-9),
                "{tension:?} t = {}: |Δω_L| {dw_diff} > bound {}",
                with_gap.t,
                bound.bound()
            );
            worst_t = worst_t.max(dt_diff / bound_t.bound());
            worst_w = worst_w.max(dw_diff / bound.bound());
        }
        let (sup_t, sup) = (bound_t.sup().unwrap(), bound.sup().unwrap());
        println!(
            "tension PI {tension:?}: {switches} switches in 1 s; max |ΔT|/bound_T {worst_t:.3}, max |Δω_L|/bound {worst_w:.3}; \
             bound_T(1 s) {:.4} N of bound_T_sup {sup_t:.4} N",
            bound_t.bound()
        );
        assert!(switches >= 8, "the reference reverses: {switches} switches");
        // bound(1 s) ≤ bound_sup holds by ∫_1^∞ |h| ≥ 0, but the two are different sums of
        // |∫h| (this run's pieces, bound_sup's own integration): each, a recursive sum of n
        // non-negative terms, is off by at most n·u relative (u = ε/2), with at most
        // MAX_CROSSINGS + 1 = 65 terms per piece (bound.rs). Pieces: here 5000 advances of
        // ⌈dt/len⌉ (len = max_advance/MAX_PIECES); bound_sup's at most SUP_MAX_PIECES = 2^21.
        let sum_roundoff = |max_advance: f64| {
            let run = 5000.0 * (dt / (max_advance / MAX_PIECES as f64)).ceil();
            65.0 * (run + 2f64.powi(21)) * 0.5 * f64::EPSILON
        };
        let (slack_t, slack) = (sum_roundoff(bound_t.max_advance()), sum_roundoff(bound.max_advance()));
        println!(
            "bound(1 s)/bound_sup − 1: {:.2e} (T), {:.2e} (ω_L); round-off allowances {slack_t:.1e}, {slack:.1e}",
            bound_t.bound() / sup_t - 1.0,
            bound.bound() / sup - 1.0
        );
        assert!(
            bound_t.bound() <= sup_t * (1.0 + slack_t) && bound.bound() <= sup * (1.0 + slack),
            "bound(1 s) above bound_sup: {} vs {sup_t}, {} vs {sup}",
            bound_t.bound(),
            bound.bound()
        );
        assert!(
            worst_t > 0.05 && worst_w > 0.05,
            "bounds far from the differences: {worst_t}, {worst_w}"
        );
    }
}

/// The web line's vector field (`Plant::rates` with the web's pull, `Plant::tension_rate`)
/// against its equations written out here (docs/model.md §8) and against the exact stepper's
/// motion over a short step, in each contact mode.
#[test]
fn the_web_vector_field_is_the_equations_and_the_steppers_motion() {
    let params = web_line(5e-5);
    let plant = Plant::new(params).unwrap();
    let web = *plant.web().unwrap();
    let (j_l, b_l, r_l, g) = (params.j_l, params.b_l, plant.r_l(), plant.half_gap());
    let (v_in, t_in, tau_m, tau_l) = (1.9, 40.0, 0.3, -0.1);
    for u_over_g in [-2.5, 0.4, 3.0] {
        let theta_m = u_over_g * g / plant.r_m();
        let state = PlantState::new(&plant, theta_m, 250.0, 0.0, 41.0).with_tension(35.0);
        let psi = plant.force(state.u, state.du);
        let rates = plant.rates(&state, tau_m, tau_l);
        let span = web.forcing(v_in, t_in);
        let t_rate = plant.tension_rate(&state, span);
        let want_omega_l = (tau_l - b_l * state.omega_l + r_l * psi - web.r_w * state.tension) / j_l;
        let want_t = (web.ea * (web.r_w * state.omega_l - v_in) + web.v_ref * (t_in - state.tension)) / web.l_w;
        assert!(
            (rates[3] - want_omega_l).abs() <= 1e-12 * want_omega_l.abs(),
            "ω_L' {} vs {want_omega_l}",
            rates[3]
        );
        assert!(
            (t_rate - want_t).abs() <= 1e-12 * want_t.abs(),
            "T' {t_rate} vs {want_t}"
        );
        // The exact motion over 1e-8 s: (x(h) − x(0))/h is the rate to O(h).
        let h = 1e-8;
        let mut stepper = Stepper::new(plant);
        let mut next = state;
        let inputs = Inputs {
            span,
            ..Inputs::held(tau_m, tau_l)
        };
        stepper.step(&mut next, &inputs, h, &mut |_| {}).unwrap();
        let moved = [(next.omega_l - state.omega_l) / h, (next.tension - state.tension) / h];
        for (got, want) in moved.iter().zip([want_omega_l, want_t]) {
            assert!(
                (got - want).abs() <= 1e-5 * want.abs(),
                "u/g {u_over_g}: {got} vs {want}"
            );
        }
    }
}

/// The span's forcing is an input of the web line only: the web stepper refuses a non-finite
/// one by name, the drive train's ignores it and names what it does refuse.
#[test]
fn a_non_finite_span_forcing_is_refused_by_the_web_line_only() {
    use backlash_fmu::physics::StepError;
    let bad = Inputs {
        span: f64::NAN,
        ..Inputs::held(0.1, 0.0)
    };
    let web = Plant::new(web_line(5e-5)).unwrap();
    let mut state = PlantState::new(&web, 0.0, 0.0, 0.0, 0.0);
    let refused = Stepper::new(web).step(&mut state, &bad, 1e-3, &mut |_| {});
    assert!(
        matches!(
            refused,
            Err(StepError::NonFiniteInput {
                name: "the web span's forcing w",
                ..
            })
        ),
        "{refused:?}"
    );
    let belt = Plant::new(PlantParams {
        damping: Damping::NONE,
        web: None,
        ..web_line(5e-5)
    })
    .unwrap();
    let mut stepper = Stepper::new(belt);
    let mut state = PlantState::new(&belt, 0.0, 0.0, 0.0, 0.0);
    assert!(stepper.step(&mut state, &bad, 1e-3, &mut |_| {}).is_ok());
    let mut broken = PlantState {
        omega_m: f64::NAN,
        ..state
    };
    let refused = stepper.step(&mut broken, &bad, 1e-3, &mut |_| {});
    assert!(matches!(refused, Err(StepError::NonFiniteState)), "{refused:?}");
}

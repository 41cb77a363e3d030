//! `Stepper::step` against closed forms, one communication step at a time from the stepper's
//! own state (so each step's exactness is measured, not an accumulated drift):
//! - no contact (docs/model.md §1 with ψ = 0): each inertia alone, J ω' = τ − b ω, ZOH and FOH inputs;
//! - permanent undamped contact (b = 0, Δ = 0 or preloaded): q'' + Ω² q = F(t);
//! - Δ = 0 with damping: the linear plant of docs/model.md §3 through the test's own e^{M t}.
//!
//! Tolerance 1e-12 relative to the amplitude of each kind of quantity over the run (angles,
//! speeds, u; u at least g): docs/model.md §2 promises an exact step, so only round-off may remain.

use crate::support::closed_form::{single_inertia_increment, undamped_contact};
use crate::support::expm::{a_p, linear_gap_step, linear_plant_step};
use crate::support::harness::RelativeErrors;
use crate::support::reference::GenericForm;
use crate::support::rigs::{self, belt_damped, rig};
use backlash_fmu::physics::{Inputs, Plant, PlantParams, PlantState, Stepper};

const TOL: f64 = 1e-12;

fn sample(s: &PlantState) -> [f64; 5] {
    [s.theta_m, s.omega_m, s.theta_l, s.omega_l, s.u]
}

/// Steps the plant through `schedule`; `exact(state_before, inputs, h)` gives the wanted
/// [θ_m, ω_m, θ_L, ω_L, u] after the step. Returns the errors and the number of switches.
fn per_step_errors(
    params: &PlantParams,
    init: [f64; 4],
    schedule: &[(Inputs, f64)],
    exact: &dyn Fn(&PlantState, &Inputs, f64) -> [f64; 5],
) -> (RelativeErrors, usize) {
    let plant = Plant::new(*params).unwrap();
    let mut stepper = Stepper::new(plant);
    let mut st = PlantState::new(&plant, init[0], init[1], init[2], init[3]);
    let (mut got, mut want, mut span) = (vec![], vec![], vec![sample(&st)]);
    let mut switches = 0;
    for (inputs, h) in schedule {
        let w = exact(&st, inputs, *h);
        switches += stepper.step(&mut st, inputs, *h, &mut |_| {}).unwrap();
        got.push(sample(&st));
        want.push(w);
        span.push(w);
    }
    (
        RelativeErrors::measure(&got, &want, &span, GenericForm::from_params(params).g),
        switches,
    )
}

/// Two steps of each size from 1 ns to 10 s, alternating held and ramped inputs.
fn schedule(sizes: &[f64], tau_m: f64, tau_l: f64, ramp_m: f64, ramp_l: f64) -> Vec<(Inputs, f64)> {
    let mut out = Vec::new();
    for (i, &h) in sizes.iter().enumerate() {
        out.push((Inputs::held(tau_m, tau_l), h));
        let sign = if i % 2 == 0 { 1.0 } else { -1.0 };
        out.push((
            Inputs {
                tau_m: tau_m * sign,
                tau_l,
                dtau_m: ramp_m * sign,
                dtau_l: ramp_l,
                span: 0.0,
                dspan: 0.0,
            },
            h,
        ));
    }
    out
}

const SIZES: [f64; 7] = [1e-9, 1e-6, 1e-3, 0.05, 1.0, 3.7, 10.0];

#[test]
fn free_inertias_match_the_closed_form() {
    // Δ so large that the gap never closes: ψ = 0 and each side is J ω' = τ − b ω.
    let mut cases = vec![];
    for b in [0.0, 0.05, 5.0] {
        cases.push(rig(1000.0, b));
        cases.push(belt_damped(300.0, b * 0.1, b * 0.1));
    }
    for params in cases {
        let f = GenericForm::from_params(&params);
        let exact = |st: &PlantState, inp: &Inputs, h: f64| {
            let (dm, wm) = single_inertia_increment(f.j_m, f.b_m, st.omega_m, inp.tau_m, inp.dtau_m, h);
            let (dl, wl) = single_inertia_increment(f.j_l, f.b_l, st.omega_l, inp.tau_l, inp.dtau_l, h);
            [
                st.theta_m + dm,
                wm,
                st.theta_l + dl,
                wl,
                st.u + (f.r_m * dm - f.r_l * dl),
            ]
        };
        let sched = schedule(&SIZES, 0.8, -0.3, 0.25, 0.1);
        let (e, switches) = per_step_errors(&params, [0.3, 1.2, -0.2, -0.7], &sched, &exact);
        eprintln!(
            "free, {:?}: rel. error θ {:.1e} ω {:.1e} u {:.1e} (worst step {})",
            params.geometry, e.theta, e.omega, e.u, e.worst_index
        );
        assert_eq!(switches, 0, "{params:?}: the gap must stay open");
        assert!(e.max() <= TOL, "{params:?}: {e:?}");
    }
}

#[test]
fn undamped_permanent_contact_matches_the_closed_form() {
    // b = 0; a motor torque preloads the contact and the initial oscillation is smaller than
    // the static deflection, so u − g > 0 throughout and the plant is linear.
    for params in rigs::undamped() {
        let f = GenericForm::from_params(&params);
        let tau_m = 4.0;
        let init = f.preloaded_start(tau_m);
        let exact = |st: &PlantState, inp: &Inputs, h: f64| {
            undamped_contact(
                f.j_m,
                f.j_l,
                f.r_m,
                f.r_l,
                f.k,
                f.g,
                [st.theta_m, st.omega_m, st.theta_l, st.omega_l],
                st.u,
                [inp.tau_m, inp.tau_l],
                [inp.dtau_m, inp.dtau_l],
                h,
            )
        };
        // Ramps only upwards so that the preload only grows.
        let sched: Vec<_> = SIZES
            .iter()
            .flat_map(|&h| {
                [
                    (Inputs::held(tau_m, 0.0), h),
                    (
                        Inputs {
                            tau_m,
                            tau_l: 0.0,
                            dtau_m: 0.3,
                            dtau_l: 0.0,
                            span: 0.0,
                            dspan: 0.0,
                        },
                        h,
                    ),
                ]
            })
            .collect();
        let (e, switches) = per_step_errors(&params, init, &sched, &exact);
        eprintln!(
            "contact, {:?}: rel. error θ {:.1e} ω {:.1e} u {:.1e} (worst step {})",
            params.geometry, e.theta, e.omega, e.u, e.worst_index
        );
        assert_eq!(switches, 0, "{params:?}: contact must not be lost");
        assert!(e.max() <= TOL, "{params:?}: {e:?}");
    }
}

#[test]
fn zero_gap_reproduces_the_linear_plant() {
    // Δ = 0 is the backlash-free plant (docs/model.md §1): z' = A_p z + B τ, stepped by e^{M h};
    // u through the same construction in gap coordinates.
    for params in [rig(0.0, 0.05), rig(0.0, 0.0), belt_damped(0.0, 0.01, 0.01)] {
        let f = GenericForm::from_params(&params);
        let a = a_p(f.j_m, f.j_l, f.b_m, f.b_l, f.r_m, f.r_l, f.k);
        let exact = |st: &PlantState, inp: &Inputs, h: f64| {
            let z = linear_plant_step(
                &a,
                f.j_m,
                f.j_l,
                [st.theta_m, st.omega_m, st.theta_l, st.omega_l],
                [inp.tau_m, inp.tau_l],
                [inp.dtau_m, inp.dtau_l],
                h,
            );
            let v = f.r_m * st.omega_m - f.r_l * st.omega_l;
            let y0 = [st.u, v, st.omega_m, st.omega_l];
            let (tau, dtau) = ([inp.tau_m, inp.tau_l], [inp.dtau_m, inp.dtau_l]);
            let u = linear_gap_step(f.j_m, f.j_l, f.b_m, f.b_l, f.r_m, f.r_l, f.k, y0, tau, dtau, h);
            [z[0], z[1], z[2], z[3], u]
        };
        // Reversing inputs and an initial twist: u swings through 0 many times.
        let sched = schedule(&SIZES, 1.5, -0.4, 0.6, 0.2);
        let (e, _) = per_step_errors(&params, [0.01, 1.0, -0.02 / f.r_l, -0.5], &sched, &exact);
        eprintln!(
            "Δ = 0, {:?}, b = {}: rel. error θ {:.1e} ω {:.1e} u {:.1e} (worst step {})",
            params.geometry, f.b_m, e.theta, e.omega, e.u, e.worst_index
        );
        assert!(e.max() <= TOL, "{params:?}: {e:?}");
    }
}

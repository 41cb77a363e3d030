//! `SpeedErrorBound` (docs/model.md §3) against computations made here: the loop matrices written out
//! from the documentation (support/closed_loop.rs), the impulse response h(s) = L_c e^{A_cl s} D_1 and
//! its integrals from the Taylor integrator, the worst admissible disturbance simulated on the
//! linear loop, and the continuous PI loop simulated with and without backlash.

use crate::support;
use crate::support::closed_loop::{worst_case_response, ImpulseResponse, LinearLoop, PiLoop};
use crate::support::expm::{expm, scaled};
use crate::support::reference::GenericForm;
use backlash_fmu::physics::{BoundError, PiGains, Plant, PlantParams, SpeedErrorBound, Unbounded};

const KP: f64 = 5.0;
const KI: f64 = 20.0;

fn bound_for(params: &PlantParams, kp: f64, ki: f64) -> SpeedErrorBound {
    SpeedErrorBound::new(&Plant::new(*params).unwrap(), PiGains { kp, ki }).unwrap()
}

fn rel(a: f64, b: f64) -> f64 {
    (a - b).abs() / b.abs().max(f64::MIN_POSITIVE)
}

/// Slowest decay rate among the eigenvalues that are not the rigid-body angle (eigenvalue 0:
/// no feedback acts on the common angle, and h, a speed response, does not see it).
fn slowest_decay(a: &[[f64; 5]; 5], n: usize) -> f64 {
    let m = nalgebra::DMatrix::from_fn(n, n, |i, j| a[i][j]);
    let ev = m.complex_eigenvalues();
    assert_eq!(
        ev.iter().filter(|z| z.norm() < 1e-9).count(),
        1,
        "one rigid-body angle mode: {ev}"
    );
    ev.iter()
        .filter(|z| z.norm() >= 1e-9)
        .map(|z| z.re)
        .fold(f64::NEG_INFINITY, f64::max)
}

#[test]
fn the_chosen_loop_is_stable_and_h_changes_sign() {
    let f = GenericForm::from_params(&PlantParams::paper_rig(1.78e-3));
    let lp = LinearLoop::new(&f, KP, KI);
    let sigma = slowest_decay(&lp.a, 5);
    eprintln!("Kp = {KP}, Ki = {KI}: slowest decay {sigma:.4} 1/s");
    assert!(sigma < -0.2, "the loop should be well damped: {sigma}");
    let mut ir = ImpulseResponse::new(&lp);
    ir.advance(5.0);
    // With integral action ∫h = 0 (docs/model.md §3), so h must change sign.
    assert!(!ir.sign_changes.is_empty());
}

#[test]
fn worst_case_disturbance_attains_the_bound() {
    // φ(τ) = K g sgn h(t − τ) is admissible (|φ| ≤ K g) and gives ∫h(t−τ)φ(τ)dτ = K g ∫|h|.
    for params in [PlantParams::paper_rig(1.78e-3), PlantParams::paper_rig(5.38e-3)] {
        let f = GenericForm::from_params(&params);
        let lp = LinearLoop::new(&f, KP, KI);
        let h0_positive = lp.d1[3] * lp.lc[3] > 0.0;
        for t in [0.05, 0.5, 2.0, 7.3] {
            let mut ir = ImpulseResponse::new(&lp);
            ir.advance(t);
            let worst = worst_case_response(&lp, t, &ir.sign_changes, h0_positive);
            let mut b = bound_for(&params, KP, KI);
            b.advance(t).unwrap();
            eprintln!(
                "Δ = {}, t = {t}: {} sign changes of h, worst-case response {worst:.12e}, bound {:.12e}, K g ∫|h| {:.12e}",
                f.g,
                ir.sign_changes.len(),
                b.bound(),
                lp.kg * ir.l1
            );
            assert!(
                rel(worst, lp.kg * ir.l1) <= 1e-10,
                "the test's own two routes disagree at t = {t}"
            );
            assert!(
                rel(b.bound(), worst) <= 1e-8,
                "t = {t}: bound {} vs attained {worst}",
                b.bound()
            );
        }
    }
}

#[test]
fn bound_holds_for_the_backlash_loop_and_the_printed_formula_does_not() {
    // Reversing reference ω_ref = A sin(w t) through the continuous PI loop, with the gap and
    // without (Δ = 0), from rest: |ω_L^b − ω_L^0| must stay below bound(t) everywhere and is
    // expected to exceed bound_paper(t) (docs/model.md §3: eq. (37) is not a bound).
    let params = PlantParams::paper_rig(1.78e-3);
    let f = GenericForm::from_params(&params);
    let (amp, w) = (1.0, 2.0 * std::f64::consts::PI * 0.5);
    let mut with_gap = PiLoop::new(&f, KP, KI, true, amp, w);
    let mut without = PiLoop::new(&f, KP, KI, false, amp, w);
    let mut b = bound_for(&params, KP, KI);
    let dt = 0.01;
    let (mut worst_margin, mut worst_ratio_paper, mut switches) = (f64::NEG_INFINITY, 0.0f64, 0);
    let mut last_bound = 0.0;
    for _ in 0..1000 {
        switches += with_gap.advance(dt);
        without.advance(dt);
        b.advance(dt).unwrap();
        let diff = (with_gap.omega_l() - without.omega_l()).abs();
        let (bound, paper) = (b.bound(), b.bound_paper());
        // Exact: one `LoopBound` advanced further; its l1 only gains non-negative terms and
        // rounding is monotonic, so K g l1 cannot decrease in floating point either.
        assert!(
            bound >= last_bound,
            "bound decreased at t = {}: {bound} < {last_bound}",
            b.elapsed()
        );
        last_bound = bound;
        worst_margin = worst_margin.max((diff - bound) / bound);
        if paper > 0.0 {
            worst_ratio_paper = worst_ratio_paper.max(diff / paper);
        }
    }
    eprintln!(
        "{switches} switches; max (|Δω_L| − bound)/bound = {worst_margin:.3e}; max |Δω_L| / bound_paper = {worst_ratio_paper:.3}"
    );
    assert!(
        switches >= 10,
        "the reference should make the gap open and close: {switches}"
    );
    assert!(worst_margin <= 1e-9, "bound(t) violated by {worst_margin:e} (relative)");
    assert!(
        worst_ratio_paper > 1.0,
        "bound_paper was never exceeded (max ratio {worst_ratio_paper})"
    );
}

#[test]
fn bound_paper_and_bound_match_independent_integrals() {
    let belt = support::rigs::belt(1e-4);
    for (params, kp, ki) in [
        (PlantParams::paper_rig(1.78e-3), KP, KI),
        (PlantParams::paper_rig(1.78e-3), 0.0, 0.0),
        (belt, 0.05, 0.5),
        (belt, 0.0, 0.0),
    ] {
        let f = GenericForm::from_params(&params);
        let lp = LinearLoop::new(&f, kp, ki);
        let mut ir = ImpulseResponse::new(&lp);
        let mut b = bound_for(&params, kp, ki);
        let mut t = 0.0;
        for dt in [0.003, 0.2, 1.0, 3.7] {
            ir.advance(dt);
            b.advance(dt).unwrap();
            t += dt;
            // ∫_0^t e^{A s} D_1 ds also from e^{M t}, M = [[A, D_1], [0, 0]] (Van Loan).
            let mut m = [[0.0; 6]; 6];
            for i in 0..5 {
                m[i][..5].copy_from_slice(&lp.a[i]);
                m[i][5] = lp.d1[i];
            }
            let e = expm(&scaled(&m, t));
            let via_expm: [f64; 5] = std::array::from_fn(|i| e[i][5]);
            let (mine, mine_expm) = (lp.paper_norm(&ir.integral), lp.paper_norm(&via_expm));
            eprintln!(
                "{:?} Kp = {kp} Ki = {ki} t = {t}: bound_paper {:.12e} (test: {mine:.12e}, {mine_expm:.12e}), bound {:.12e} (test {:.12e})",
                params.geometry,
                b.bound_paper(),
                b.bound(),
                lp.kg * ir.l1
            );
            assert!(rel(mine, mine_expm) <= 1e-11, "the test's two integrals disagree");
            assert!(rel(b.bound_paper(), mine_expm) <= 1e-9, "bound_paper at t = {t}");
            assert!(rel(b.bound(), lp.kg * ir.l1) <= 1e-9, "bound at t = {t}");
        }
    }
}

#[test]
fn bound_sup_is_the_limit_of_bound() {
    // Open loop with more friction than the rig, so that the horizon stays short.
    let rig = PlantParams::paper_rig(3.56e-3);
    for (params, kp, ki) in [
        (rig, KP, KI),
        (
            PlantParams {
                b_m: 0.5,
                b_l: 0.5,
                ..rig
            },
            0.0,
            0.0,
        ),
        (rig, 20.0, 5.0),
    ] {
        let f = GenericForm::from_params(&params);
        let lp = LinearLoop::new(&f, kp, ki);
        let decay = slowest_decay(&lp.a, if lp.open_loop { 4 } else { 5 });
        let horizon = 40.0 / -decay;
        let mut ir = ImpulseResponse::new(&lp);
        ir.advance(horizon);
        let mut b = bound_for(&params, kp, ki);
        let sup = b.sup().unwrap_or_else(|e| panic!("Kp = {kp}, Ki = {ki}: {e}"));
        let mut last = 0.0;
        for t in [0.1, 1.0, 10.0] {
            b.advance(t - b.elapsed()).unwrap();
            // `>= last` is exact: the same bound advanced further, its l1 only gains
            // non-negative terms (rounding is monotonic).
            assert!(b.bound() <= sup * (1.0 + 1e-12) && b.bound() >= last);
            last = b.bound();
        }
        b.advance(horizon - b.elapsed()).unwrap();
        eprintln!(
            "Kp = {kp}, Ki = {ki}: slowest decay {decay:.4} 1/s, horizon {horizon:.0} s: sup {sup:.12e}, bound(horizon) {:.12e}, test K g ∫|h| {:.12e}",
            b.bound(),
            lp.kg * ir.l1
        );
        assert!(
            rel(sup, lp.kg * ir.l1) <= 1e-9,
            "sup vs the test's ∫_0^T |h| with e^(σT) = e^-40"
        );
        assert!(rel(b.bound(), sup) <= 1e-9, "bound(T) has not reached sup");
    }
}

#[test]
fn unbounded_cases_say_why() {
    // Kp = Ki = 0 and no friction: the relative oscillation that φ excites never decays.
    let undamped = PlantParams {
        b_m: 0.0,
        b_l: 0.0,
        ..PlantParams::paper_rig(1.78e-3)
    };
    let b = bound_for(&undamped, 0.0, 0.0);
    assert!(matches!(b.sup(), Err(Unbounded::Undamped)), "{:?}", b.sup());
    // Negative proportional gain beats the friction: unstable.
    let params = PlantParams::paper_rig(1.78e-3);
    let f = GenericForm::from_params(&params);
    for (kp, ki) in [(-1.0, 1.0), (5.0, -20.0)] {
        let lp = LinearLoop::new(&f, kp, ki);
        let sigma = slowest_decay(&lp.a, 5);
        assert!(sigma > 0.0);
        match bound_for(&params, kp, ki).sup() {
            Err(Unbounded::Unstable { abscissa }) => {
                eprintln!("Kp = {kp}, Ki = {ki}: abscissa reported {abscissa:e}, eigenvalues give {sigma:e}");
                assert!(rel(abscissa, sigma) <= 1e-6, "abscissa {abscissa} vs {sigma}");
            }
            other => panic!("Kp = {kp}, Ki = {ki}: {other:?}"),
        }
    }
}

#[test]
fn one_long_advance_equals_many_short_ones_and_reset_restarts() {
    let params = PlantParams::paper_rig(1.78e-3);
    let mut one = bound_for(&params, KP, KI);
    let mut many = bound_for(&params, KP, KI);
    one.advance(4.0).unwrap();
    for _ in 0..400 {
        many.advance(0.01).unwrap();
    }
    assert!(rel(one.bound(), many.bound()) <= 1e-10 && rel(one.bound_paper(), many.bound_paper()) <= 1e-10);
    one.reset();
    // Exact: reset zeroes elapsed, l1 and the integral, and K g·0 and K g·√0 are 0.
    assert_eq!((one.elapsed(), one.bound(), one.bound_paper()), (0.0, 0.0, 0.0));
}

/// Once h has decayed, `advance` adds response·h to the integral and leaves the rest alone; on
/// its fast path it does not compute bound_paper but bounds the integral instead. The settled
/// state of a run, scaled up (settledness compares the response with l1: scaled alike, the
/// state stays settled): every accepted advance adds exactly response·h (one rounding per
/// entry, as written here) with bound_paper finite, both while far from overflow (the fast
/// path) and near it; the advance that would overflow bound_paper is refused with the state
/// left as it was.
#[test]
fn settled_advance_drifts_exactly_and_refuses_overflow() {
    let mut b = bound_for(&PlantParams::paper_rig(1.78e-3), KP, KI);
    for _ in 0..2000 {
        b.advance(1.0).unwrap();
    }
    let settled = b.state();
    b.advance(1.0).unwrap();
    // Exact once settled: the settled advance leaves the response as stored (only `drift`
    // touches the integral); an unsettled one recomputes it.
    assert_eq!(b.state().response, settled.response, "not settled after 2000 s");
    assert!(settled.response.iter().any(|r| *r != 0.0), "no drift to test");
    let h = 100.0;
    let norm = |x: &[f64; 5]| x.iter().map(|v| v * v).sum::<f64>().sqrt();
    // (scale of the response and l1, of the integral, advances): far from overflow for 1000
    // advances; then fast enough to reach it.
    for (c, ci, advances) in [(1e100, 1e100, 1000), (3e167, 1e150, usize::MAX)] {
        let mut s = settled;
        s.response = settled.response.map(|r| r * c);
        s.l1 = settled.l1 * c;
        s.integral = settled.integral.map(|x| x * ci);
        b.restore(&s).unwrap();
        let mut accepted = 0;
        while accepted < advances {
            let before = b.state();
            let mut expected = before.integral;
            for (e, r) in expected.iter_mut().zip(&before.response) {
                *e += r * h;
            }
            match b.advance(h) {
                Ok(()) => {
                    accepted += 1;
                    let now = b.state();
                    // Bit for bit by construction: `expected` is `LoopBound::drift`'s own
                    // arithmetic (I_i += r_i·h, the same operands in the same order), and
                    // `elapsed += h` is `advance`'s; response and l1 are left as stored.
                    assert_eq!(now.integral, expected, "scale {c:e}, advance {accepted}");
                    assert_eq!((now.response, now.l1), (before.response, before.l1));
                    assert_eq!(now.elapsed, before.elapsed + h);
                    assert!(b.bound_paper().is_finite() && b.bound().is_finite());
                }
                Err(e) => {
                    assert!(advances == usize::MAX, "scale {c:e}: refused advance {accepted}: {e}");
                    assert!(matches!(e, BoundError::Overflow { .. }), "{e}");
                    assert_eq!(b.state(), before, "a refused advance changed the state");
                    let scale = b.bound_paper() / norm(&before.integral);
                    assert!(!(scale * norm(&expected)).is_finite(), "refused a finite bound_paper");
                    assert!(accepted >= 2, "the first advances should be accepted: {accepted}");
                    break;
                }
            }
            assert!(accepted < 100_000, "scale {c:e}: never overflowed");
        }
    }
}

#[test]
fn bound_rate_is_the_slope_of_bound() {
    // Centred differences over ±δ, at instants where h keeps its sign over the difference.
    let params = PlantParams::paper_rig(1.78e-3);
    let delta = 1e-5;
    for t in [0.05, 0.5, 2.0] {
        let mut before = bound_for(&params, KP, KI);
        before.advance(t - delta).unwrap();
        let mut at = before.clone();
        at.advance(delta).unwrap();
        let mut after = at.clone();
        after.advance(delta).unwrap();
        let slope = (after.bound() - before.bound()) / (2.0 * delta);
        let rate = at.bound_rate();
        assert!(rate > 0.0);
        assert!(rel(rate, slope) <= 1e-6, "t = {t}: rate {rate} vs difference {slope}");
        let paper_slope = (after.bound_paper() - before.bound_paper()) / (2.0 * delta);
        let paper_rate = at.bound_paper_rate();
        assert!(
            rel(paper_rate, paper_slope) <= 1e-6,
            "t = {t}: paper rate {paper_rate} vs difference {paper_slope}"
        );
    }
}

#[test]
fn bound_paper_rate_at_the_start_is_the_right_derivative() {
    // At t = 0 the integral is 0: the rate is K g ‖e^{A·0} D_1‖, the slope of bound_paper from the
    // right (bound_paper(δ)/δ = K g ‖r‖ + O(δ)).
    let params = PlantParams::paper_rig(1.78e-3);
    let start = bound_for(&params, KP, KI);
    // Exact: the integral starts at zeros, and K g·√0 is 0.
    assert_eq!(start.bound_paper(), 0.0);
    let delta = 1e-8;
    let mut after = start.clone();
    after.advance(delta).unwrap();
    let slope = after.bound_paper() / delta;
    assert!(
        rel(start.bound_paper_rate(), slope) <= 1e-6,
        "rate {} vs difference {slope}",
        start.bound_paper_rate()
    );
    // And bound's rate is K g |h(0)|, h(0) = −r_L/J_L.
    let plant = Plant::new(params).unwrap();
    let expected = plant.stiffness() * plant.half_gap() * plant.r_l() / params.j_l;
    // The same fl(K g) times r_L/J_L (r_L = 1): the library rounds 1/J_L and the product, this
    // side the quotient, so they are at most 3 u = 1.5 ε ≈ 3.3e-16 apart (relative).
    assert!(rel(start.bound_rate(), expected) <= 1e-15);
}

#[test]
fn force_rate_is_the_slope_of_the_force() {
    use backlash_fmu::physics::{ContactMode, Inputs, PlantState, Stepper};
    // A belt, so that the radii differ from 1; centred differences of ψ = K dz(u, g) along the
    // exact trajectory, in contact on both flanks, and 0 in the gap.
    let params = support::rigs::belt(1e-3);
    let plant = Plant::new(params).unwrap();
    let g = plant.half_gap();
    let mut stepper = Stepper::new(plant);
    let inputs = Inputs::held(0.3, -0.1);
    let delta = 1e-6;
    for (u, mode) in [
        (3.0 * g, ContactMode::Positive),
        (-3.0 * g, ContactMode::Negative),
        (0.2 * g, ContactMode::Free),
    ] {
        let theta_m = u / plant.r_m();
        let s0 = PlantState::new(&plant, theta_m, 0.4, 0.0, 0.1);
        assert_eq!(s0.mode, mode);
        let psi0 = plant.force(s0.u, s0.du);
        let mut mid = s0;
        stepper.step(&mut mid, &inputs, delta, &mut |_| {}).unwrap();
        let mut end = mid;
        stepper.step(&mut end, &inputs, delta, &mut |_| {}).unwrap();
        assert_eq!(end.mode, mode, "no switch within the difference");
        let slope = (plant.force(end.u, end.du) - psi0) / (2.0 * delta);
        let rates = stepper.time_derivative(&mid, &inputs, 1);
        let rate = plant.force_rate(mid.mode, [rates[0], rates[2]], [rates[1], rates[3]]);
        if mode == ContactMode::Free {
            // Exact: ψ' is the literal 0 in the gap, and dz(u, g) is exactly 0 inside it at
            // both ends (u = 0.2 g barely moves over 2δ), so the difference is 0/(2δ) = 0.
            assert_eq!(rate, 0.0);
            assert_eq!(slope, 0.0);
        } else {
            assert!(rel(rate, slope) <= 1e-6, "{mode:?}: rate {rate} vs difference {slope}");
            // K (r_m ω_m − r_L ω_L) from the state itself.
            let direct = plant.stiffness() * (plant.r_m() * mid.omega_m - plant.r_l() * mid.omega_l);
            assert!(rel(rate, direct) <= 1e-12, "{mode:?}: rate {rate} vs {direct}");
        }
    }
}

#[test]
fn max_step_is_the_period_cap_of_the_contact_oscillation() {
    use backlash_fmu::physics::{max_step, MAX_PERIODS_PER_STEP};
    for params in [PlantParams::paper_rig(1.78e-3), support::rigs::belt(1e-3)] {
        let plant = Plant::new(params).unwrap();
        let (k, r_m, r_l) = (plant.stiffness(), plant.r_m(), plant.r_l());
        // Bit for bit by construction: `Plant::contact_frequency` and `max_step` written out
        // with the same operands in the same order (and sqrt is correctly rounded).
        let omega0 = (k * (r_m * r_m / params.j_m + r_l * r_l / params.j_l)).sqrt();
        assert_eq!(plant.contact_frequency(), omega0);
        assert_eq!(
            max_step(&plant),
            MAX_PERIODS_PER_STEP * 2.0 * std::f64::consts::PI / omega0
        );
    }
}

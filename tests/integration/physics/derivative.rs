//! `Stepper::time_derivative` against the right-hand side of docs/model.md §1 written out here, its
//! second derivative, and a Richardson-extrapolated difference quotient of `Stepper::step`.

use backlash_fmu::physics::{ContactMode, Inputs, Plant, PlantParams, PlantState, Stepper};

const J_M: f64 = 2.28;
const J_L: f64 = 2.55;
const K: f64 = 200.0;
const B: f64 = 0.05;
const G: f64 = 1.78e-3;

/// [θ', ω', θ'', ω''] for motor (m) and load (l) under contact factor δ (1 in contact, 0 free)
/// and flank σ: ψ = δ K (u − σ g), J_m ω_m' = τ_m − b ω_m − ψ, J_L ω_L' = τ_L − b ω_L + ψ.
fn analytic(s: &PlantState, i: &Inputs, delta: f64, sigma: f64) -> ([f64; 4], [f64; 4]) {
    let psi = delta * K * (s.u - sigma * G);
    let dpsi = delta * K * (s.omega_m - s.omega_l);
    let am = (i.tau_m - B * s.omega_m - psi) / J_M;
    let al = (i.tau_l - B * s.omega_l + psi) / J_L;
    let jm = (i.dtau_m - B * am - dpsi) / J_M;
    let jl = (i.dtau_l - B * al + dpsi) / J_L;
    ([s.omega_m, am, s.omega_l, al], [am, jm, al, jl])
}

/// The drive train's entries of `a` (T's, the fifth, is 0 without a web span) against `b`.
fn close(a: &[f64; 5], b: &[f64; 4], tol: f64) -> bool {
    assert_eq!(a[4], 0.0, "no tension rate without a web span");
    let a = &a[..4];
    let scale = b.iter().fold(1e-300f64, |m, x| m.max(x.abs()));
    a.iter().zip(b).all(|(x, y)| (x - y).abs() <= tol * scale)
}

#[test]
fn first_and_second_derivatives_match_the_equations_of_motion() {
    let plant = Plant::new(PlantParams::paper_rig(G)).unwrap();
    let stepper = Stepper::new(plant);
    let inputs = Inputs {
        tau_m: 1.3,
        tau_l: -0.4,
        dtau_m: 2.0,
        dtau_l: -0.5,
        span: 0.0,
        dspan: 0.0,
    };
    // (θ_m, ω_m, θ_L, ω_L), expected mode, δ, σ. The last two sit exactly on u = g: the mode
    // is the one being entered (docs/model.md §4), which decides the second derivative.
    let cases = [
        ((0.5e-3, 0.7, 0.0, 0.1), ContactMode::Free, 0.0, 0.0),
        ((0.01, 0.7, 0.002, 0.1), ContactMode::Positive, 1.0, 1.0),
        ((-0.01, -0.3, 0.002, 0.4), ContactMode::Negative, 1.0, -1.0),
        ((G, 0.7, 0.0, 0.1), ContactMode::Positive, 1.0, 1.0),
        ((G, 0.1, 0.0, 0.7), ContactMode::Free, 0.0, 0.0),
    ];
    for ((tm, wm, tl, wl), mode, delta, sigma) in cases {
        let s = PlantState::new(&plant, tm, wm, tl, wl);
        assert_eq!(s.mode, mode, "{s:?}");
        let (d1, d2) = analytic(&s, &inputs, delta, sigma);
        let got1 = stepper.time_derivative(&s, &inputs, 1);
        let got2 = stepper.time_derivative(&s, &inputs, 2);
        assert!(
            close(&got1, &d1, 1e-14),
            "{mode:?}: first derivative {got1:?}, want {d1:?}"
        );
        assert!(
            close(&got2, &d2, 1e-13),
            "{mode:?}: second derivative {got2:?}, want {d2:?}"
        );
    }
}

#[test]
fn first_derivative_matches_a_difference_quotient_of_the_step() {
    let plant = Plant::new(PlantParams::paper_rig(G)).unwrap();
    let mut stepper = Stepper::new(plant);
    let inputs = Inputs {
        tau_m: 1.3,
        tau_l: -0.4,
        dtau_m: 2.0,
        dtau_l: -0.5,
        span: 0.0,
        dspan: 0.0,
    };
    for (tm, wm, tl, wl) in [
        (0.5e-3, 0.7, 0.0, 0.1),
        (0.01, 0.7, 0.002, 0.1),
        (-0.01, -0.3, 0.002, 0.4),
    ] {
        let s = PlantState::new(&plant, tm, wm, tl, wl);
        let quotient = |stepper: &mut Stepper, eps: f64| {
            let mut e = s;
            stepper.step(&mut e, &inputs, eps, &mut |_| {}).unwrap();
            [
                (e.theta_m - s.theta_m) / eps,
                (e.omega_m - s.omega_m) / eps,
                (e.theta_l - s.theta_l) / eps,
                (e.omega_l - s.omega_l) / eps,
            ]
        };
        // Richardson: 2 D(ε/2) − D(ε) cancels the O(ε) term; the remainder ε² z'''/12 is
        // ~2e-9 here (z''' ~ K/J · ω' ~ 200), rounding ~ 1e-16 |z| / ε ~ 1e-11.
        let eps = 1e-5;
        let (a, b) = (quotient(&mut stepper, eps), quotient(&mut stepper, eps / 2.0));
        let rich: [f64; 4] = std::array::from_fn(|i| 2.0 * b[i] - a[i]);
        let got = stepper.time_derivative(&s, &inputs, 1);
        assert!(
            close(&got, &rich, 1e-7),
            "{s:?}: derivative {got:?}, difference quotient {rich:?}"
        );
    }
}

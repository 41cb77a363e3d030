//! The test oracles validate themselves: the Taylor reference integrator (support/reference.rs)
//! against the closed forms of the linear regimes, the test's own matrix exponential against
//! nalgebra's, and the reference's energy balance across many contact switches. Nothing here
//! runs the crate's stepper; the other `crate::physics` tests rely on these oracles.

use crate::support::closed_form::{oscillator_kernels, phi, single_inertia, undamped_contact};
use crate::support::expm::{a_p, expm, linear_plant_step, scaled};
use crate::support::reference::{PowerIntegrals, Reference, TH_L, TH_M, U, W_L, W_M};
use crate::support::rigs::{self, belt_damped, rig};
use backlash_fmu::physics::Inputs;

/// |a − b| / scale, componentwise maximum.
fn rel(a: &[f64], b: &[f64], scale: f64) -> f64 {
    a.iter().zip(b).map(|(x, y)| (x - y).abs() / scale).fold(0.0, f64::max)
}

#[test]
fn phi_and_oscillator_kernels_agree_across_their_branches() {
    // The series and the recursive branch must meet where they switch over.
    for x in [-0.999, -1.001, 0.999, 1.001] {
        for k in 0..4 {
            let series_side = phi(k, x * 0.999_999_999);
            let other = phi(k, x);
            assert!((series_side - other).abs() <= 1e-8 * other.abs(), "phi({k}, {x})");
        }
    }
    // F_2 = (1 − cos Ωt)/Ω², F_3 = (t − sin Ωt / Ω)/Ω² straight from their definitions.
    let w = 2.0;
    for t in [1.4, 1.6, 2.5] {
        let f = oscillator_kernels(w, t);
        let (c, s) = ((w * t).cos(), (w * t).sin());
        let want = [c, s / w, (1.0 - c) / (w * w), (t - s / w) / (w * w)];
        for n in 0..4 {
            assert!((f[n] - want[n]).abs() <= 1e-14, "F_{n}({t}) = {} vs {}", f[n], want[n]);
        }
    }
}

#[test]
fn reference_matches_free_inertias_in_closed_form() {
    // Δ = 1000 rad: the gap is never closed, each inertia obeys J ω' = τ − b ω (docs/model.md §1, ψ = 0).
    let mut worst: f64 = 0.0;
    for b in [0.0, 0.05, 5.0] {
        let params = rig(1000.0, b);
        let r = Reference::new(&params);
        for &(h, inputs) in &[
            (1e-3, Inputs::held(3.0, -1.0)),
            (0.05, Inputs::held(-2.0, 0.5)),
            (
                1.0,
                Inputs {
                    tau_m: 1.0,
                    tau_l: 0.3,
                    dtau_m: -0.7,
                    dtau_l: 0.2,
                    span: 0.0,
                    dspan: 0.0,
                },
            ),
            (
                10.0,
                Inputs {
                    tau_m: -1.5,
                    tau_l: 0.0,
                    dtau_m: 0.4,
                    dtau_l: -0.1,
                    span: 0.0,
                    dspan: 0.0,
                },
            ),
        ] {
            let (th_m0, w_m0, th_l0, w_l0) = (0.3, 1.2, -0.2, -0.7);
            let mut s = r.state(th_m0, w_m0, th_l0, w_l0);
            let mut steps = 3;
            let mut t = 0.0;
            while steps > 0 {
                r.step(&mut s, t, &inputs, h, &mut Vec::new(), None);
                t += h;
                steps -= 1;
            }
            // Three steps with the same (τ, dτ) restart the ramp each step, so compare with
            // the closed form composed the same way.
            let (mut a, mut b_) = ((th_m0, w_m0), (th_l0, w_l0));
            for _ in 0..3 {
                a = single_inertia(params.j_m, b, a.0, a.1, inputs.tau_m, inputs.dtau_m, h);
                b_ = single_inertia(params.j_l, b, b_.0, b_.1, inputs.tau_l, inputs.dtau_l, h);
            }
            let theta_scale = a.0.abs().max(b_.0.abs()).max(1.0);
            let omega_scale = a.1.abs().max(b_.1.abs()).max(1e-3);
            let e = rel(&[s.y[TH_M], s.y[TH_L]], &[a.0, b_.0], theta_scale)
                .max(rel(&[s.y[W_M], s.y[W_L]], &[a.1, b_.1], omega_scale))
                .max((s.y[U] - (a.0 - b_.0)).abs() / theta_scale);
            assert!(s.mode == 1, "left the free mode");
            assert!(e <= 1e-13, "b = {b}, h = {h}: relative error {e:e}");
            worst = worst.max(e);
        }
    }
    eprintln!("reference vs free-inertia closed form: worst relative error {worst:.2e}");
}

#[test]
fn reference_matches_undamped_permanent_contact_in_closed_form() {
    // b = 0 and either Δ = 0 or a preload that keeps u ≥ g: q'' + Ω² q = F(t) exactly.
    let mut worst: f64 = 0.0;
    for params in rigs::undamped() {
        let r = Reference::new(&params);
        let f = r.form;
        for &(h, steps, dtau_m) in &[
            (1e-3, 50, 0.0),
            (0.05, 40, 0.0),
            (0.05, 40, 2.0),
            (2.5, 4, 0.0),
            (10.0, 1, 0.5),
        ] {
            // Motor torque T preloads the contact so that the oscillation never opens the gap.
            let tau_m = 4.0;
            let [th_m0, w_m0, th_l0, w_l0] = f.preloaded_start(tau_m);
            let inputs = Inputs {
                tau_m,
                tau_l: 0.0,
                dtau_m,
                dtau_l: 0.0,
                span: 0.0,
                dspan: 0.0,
            };
            let mut s = r.state(th_m0, w_m0, th_l0, w_l0);
            let mut z = [th_m0, w_m0, th_l0, w_l0];
            let mut u = s.y[U];
            let mut t = 0.0;
            let mut events = Vec::new();
            let mut scale = [0.0f64; 3];
            let mut e: f64 = 0.0;
            for _ in 0..steps {
                r.step(&mut s, t, &inputs, h, &mut events, None);
                t += h;
                let c = undamped_contact(
                    f.j_m,
                    f.j_l,
                    f.r_m,
                    f.r_l,
                    f.k,
                    f.g,
                    z,
                    u,
                    [tau_m, 0.0],
                    [dtau_m, 0.0],
                    h,
                );
                z = [c[0], c[1], c[2], c[3]];
                u = c[4];
                scale[0] = scale[0].max(z[0].abs()).max(z[2].abs());
                scale[1] = scale[1].max(z[1].abs()).max(z[3].abs());
                scale[2] = scale[2].max(u.abs());
                e = e
                    .max(rel(&[s.y[TH_M], s.y[TH_L]], &[z[0], z[2]], scale[0]))
                    .max(rel(&[s.y[W_M], s.y[W_L]], &[z[1], z[3]], scale[1]))
                    .max((s.y[U] - u).abs() / scale[2]);
            }
            assert!(
                events.is_empty(),
                "{params:?}: contact was lost, the closed form does not apply"
            );
            assert!(e <= 1e-12, "{params:?}, h = {h}, dτ = {dtau_m}: relative error {e:e}");
            worst = worst.max(e);
        }
    }
    eprintln!("reference vs undamped-contact closed form: worst relative error {worst:.2e}");
}

#[test]
fn own_expm_matches_nalgebra_and_reference_matches_damped_linear_plant() {
    // Damped, Δ = 0: the linear plant of docs/model.md §3 (A_p), no closed form short of e^{A t}.
    let params = rig(0.0, 0.05);
    let r = Reference::new(&params);
    let f = r.form;
    let a = a_p(f.j_m, f.j_l, f.b_m, f.b_l, f.r_m, f.r_l, f.k);
    for t in [1e-3, 0.05, 1.0, 10.0] {
        let mine = expm(&scaled(&a, t));
        let theirs = nalgebra::Matrix4::from_fn(|i, j| a[i][j] * t).exp();
        let scale = mine.iter().flatten().fold(0.0f64, |m, x| m.max(x.abs()));
        let e = (0..4)
            .flat_map(|i| (0..4).map(move |j| (i, j)))
            .map(|(i, j)| (mine[i][j] - theirs[(i, j)]).abs())
            .fold(0.0, f64::max);
        assert!(
            e <= 1e-13 * scale,
            "t = {t}: expm differs from nalgebra by {e:e} (scale {scale:e})"
        );
    }
    let mut worst: f64 = 0.0;
    for &(h, steps, inputs) in &[
        (1e-3, 100, Inputs::held(2.0, -1.0)),
        (
            0.05,
            60,
            Inputs {
                tau_m: 1.0,
                tau_l: -0.5,
                dtau_m: 3.0,
                dtau_l: 0.0,
                span: 0.0,
                dspan: 0.0,
            },
        ),
        (
            10.0,
            2,
            Inputs {
                tau_m: -1.0,
                tau_l: 0.5,
                dtau_m: 0.1,
                dtau_l: -0.2,
                span: 0.0,
                dspan: 0.0,
            },
        ),
    ] {
        let z0 = [0.01, 1.0, -0.02, -0.5];
        let mut s = r.state(z0[0], z0[1], z0[2], z0[3]);
        let mut z = z0;
        let (mut ts, mut ws) = (0.0f64, 0.0f64);
        let mut e: f64 = 0.0;
        for i in 0..steps {
            r.step(&mut s, i as f64 * h, &inputs, h, &mut Vec::new(), None);
            z = linear_plant_step(
                &a,
                f.j_m,
                f.j_l,
                z,
                [inputs.tau_m, inputs.tau_l],
                [inputs.dtau_m, inputs.dtau_l],
                h,
            );
            ts = ts.max(z[0].abs()).max(z[2].abs());
            ws = ws.max(z[1].abs()).max(z[3].abs());
            e = e.max(rel(&[s.y[TH_M], s.y[TH_L]], &[z[0], z[2]], ts)).max(rel(
                &[s.y[W_M], s.y[W_L]],
                &[z[1], z[3]],
                ws,
            ));
        }
        assert!(e <= 1e-12, "h = {h}: reference vs expm relative error {e:e}");
        worst = worst.max(e);
    }
    eprintln!("reference vs expm (damped, Δ = 0): worst relative error {worst:.2e}");
}

#[test]
fn reference_locates_a_grazing_touch_exactly() {
    // b = 0, τ_m = −a J_m: in the gap u'' = −a, so u = u0 + v0 t − a t²/2 peaks at g + ε.
    // The touch: q'' + Ω² q = −a from q = 0, q' = √(2aε): it lasts 2 atan(√(2aε) Ω / a) / Ω.
    let g = 1.78e-3;
    let params = rig(g, 0.0);
    let r = Reference::new(&params);
    let f = r.form;
    let omega = (f.k * (1.0 / f.j_m + 1.0 / f.j_l)).sqrt();
    // v0²/(2a) is a power of two, so ε as realised in u0 is computed exactly below.
    let (acc, v0) = (1.0, 0.0625);
    for eps_wanted in [1e-6 * g, 1e-9 * g, 1e-12 * g] {
        let u0 = (g + eps_wanted) - v0 * v0 / (2.0 * acc);
        let eps = (u0 + v0 * v0 / (2.0 * acc)) - g;
        let mut s = r.state(u0, v0, 0.0, 0.0);
        let mut events = Vec::new();
        r.step(&mut s, 0.0, &Inputs::held(-acc * f.j_m, 0.0), 0.1, &mut events, None);
        let t_in = (v0 - (2.0 * acc * eps).sqrt()) / acc;
        let v_in = (2.0 * acc * eps).sqrt();
        let t_out = t_in + 2.0 * (v_in * omega / acc).atan() / omega;
        assert_eq!(events.len(), 2, "ε = {eps:e}: {events:?}");
        let (e_in, e_out) = ((events[0].t - t_in).abs(), (events[1].t - t_out).abs());
        eprintln!(
            "graze ε = {eps:.1e}: entry error {e_in:.1e} s, exit error {e_out:.1e} s, touch lasts {:.2e} s",
            t_out - t_in
        );
        assert!(
            e_in <= 1e-11 && e_out <= 1e-11,
            "ε = {eps:e}: event times {events:?} vs {t_in}, {t_out}"
        );
        assert_eq!(
            (events[0].from, events[0].to, events[1].from, events[1].to),
            (0, 1, 1, 0)
        );
    }
}

#[test]
fn reference_conserves_energy_across_many_switches() {
    // ½K dz² + ½J_m ω_m² + ½J_L ω_L² − ∫(τ_m ω_m + τ_L ω_L) + ∫(b_m ω_m² + b_L ω_L²) is constant
    // (docs/model.md §1; §5: the contact is elastic). The integrals come from the reference's own dense
    // output, integrated exactly as polynomials.
    for params in [rig(3.56e-3, 0.05), rig(5.38e-3, 0.0), belt_damped(1e-4, 0.01, 0.01)] {
        let r = Reference::new(&params);
        let mut s = r.state(0.0, 2.0, 0.0, -1.0);
        let mut p = PowerIntegrals::default();
        let e0 = r.stored_energy(s.y[U], s.y[W_M], s.y[W_L]);
        let mut events = Vec::new();
        let mut worst: f64 = 0.0;
        let mut scale = e0;
        let h = 0.05;
        for i in 0..200 {
            let t = i as f64 * h;
            let tau = if (t / 0.7).fract() < 0.5 { 3.0 } else { -3.0 };
            r.step(
                &mut s,
                t,
                &Inputs {
                    tau_m: tau,
                    tau_l: -0.2 * tau,
                    dtau_m: 0.3,
                    dtau_l: 0.0,
                    span: 0.0,
                    dspan: 0.0,
                },
                h,
                &mut events,
                Some(&mut p),
            );
            let stored = r.stored_energy(s.y[U], s.y[W_M], s.y[W_L]);
            let balance = stored - p.work_m - p.work_l + p.dissipated - e0;
            scale = scale
                .max(stored)
                .max(p.work_m.abs())
                .max(p.work_l.abs())
                .max(p.dissipated);
            worst = worst.max(balance.abs() / scale);
        }
        eprintln!(
            "{:?}: {} switches, energy balance error {worst:.2e} of {scale:.3e} J",
            params.geometry,
            events.len()
        );
        assert!(events.len() > 20, "too few switches to test anything: {}", events.len());
        assert!(worst <= 1e-13, "energy balance off by {worst:e} (relative)");
    }
}

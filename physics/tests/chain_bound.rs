//! The chain's speed-error bound (physics/src/chain/bound.rs) against computations written here
//! from docs/model.md §10's equations: the loop matrix written out by hand, ∫|h_i| by quadrature
//! of the matrix exponential, twin runs of the chain with and without backlash under a
//! continuous PI (RK4), the worst-sign disturbance that attains the bound, and the one-stage
//! bound of docs/model.md §3.

use backlash_physics::chain::{chain_loop, Body, Chain, ChainParams, OneStageBound, Stage, TwoStageBound};
use backlash_physics::{ContactLaw, Damping, PiGains, Plant, PlantParams, SpeedErrorBound, Trajectory};
use nalgebra::{SMatrix, SVector};

type Mat7 = SMatrix<f64, 7, 7>;
type Vec7 = SVector<f64, 7>;

/// A two-stage gearbox unlike the default drive: ratios 2 and 1.5, unequal stiffnesses and
/// gaps, a light intermediate shaft.
fn gearbox() -> ChainParams<2> {
    ChainParams {
        motor: Body::new(0.8, 0.02),
        driven: [Body::new(0.05, 0.004), Body::new(6.0, 0.3)],
        stages: [
            Stage {
                a: 1.0,
                c: 2.0,
                k: 900.0,
                g: 0.6e-3,
                damper: Damping::NONE,
            },
            Stage {
                a: 1.0,
                c: 1.5,
                k: 2500.0,
                g: 1.1e-3,
                damper: Damping::NONE,
            },
        ],
        web: None,
    }
}

const GAINS: PiGains = PiGains { kp: 9.0, ki: 40.0 };

/// Parameters by the names of docs/model.md §10 (J_m, J_i, J_L, b_m, b_i, b_L, n_1, n_2, k_1,
/// k_2, Δ_1, Δ_2).
struct Named {
    jm: f64,
    ji: f64,
    jl: f64,
    bm: f64,
    bi: f64,
    bl: f64,
    n1: f64,
    n2: f64,
    k1: f64,
    k2: f64,
    d1: f64,
    d2: f64,
    /// Each stage's damper D (docs/model.md §1) and whether its law is 1 (ElastoBacklash).
    damp: [f64; 2],
    law1: bool,
}

fn named(p: &ChainParams<2>) -> Named {
    assert!(p.stages.iter().all(|s| s.a == 1.0), "docs/model.md §10 has r_m = 1");
    Named {
        jm: p.motor.j,
        ji: p.driven[0].j,
        jl: p.driven[1].j,
        bm: p.motor.b,
        bi: p.driven[0].b,
        bl: p.driven[1].b,
        n1: p.stages[0].c,
        n2: p.stages[1].c,
        k1: p.stages[0].k,
        k2: p.stages[1].k,
        d1: p.stages[0].g,
        d2: p.stages[1].g,
        damp: [p.stages[0].damper.d, p.stages[1].damper.d],
        law1: p.stages[0].damper.law == ContactLaw::ElastoBacklash,
    }
}

/// ψ of a member of stiffness k, damper d and half gap g at u moving at v (docs/model.md §1):
/// k dz(u, g) without a damper; with one, past the flank τ_c = k (u ∓ g), τ_d = d v, law 2
/// τ_c + τ_d and law 1 τ_c + min(τ_c, τ_d) (max on the negative flank) while they push, else 0.
fn member_force(k: f64, d: f64, g: f64, law1: bool, u: f64, v: f64) -> f64 {
    if d == 0.0 {
        return k * dead_zone(u, g);
    }
    let side = if u > g {
        1.0
    } else if u < -g {
        -1.0
    } else {
        return 0.0;
    };
    let (tc, td) = (k * (u - side * g), d * v);
    if side * (tc + td) <= 0.0 {
        0.0
    } else if law1 {
        tc + if side > 0.0 { tc.min(td) } else { tc.max(td) }
    } else {
        tc + td
    }
}

/// Whether a damped member's V grows at u moving at v: free, slack or capped (docs/model.md
/// §2, "With a damper"), not in ordinary contact.
fn varies(k: f64, d: f64, g: f64, law1: bool, u: f64, v: f64) -> bool {
    if d == 0.0 || u.abs() < g {
        return d != 0.0;
    }
    let side = u.signum();
    let (tc, td) = (k * (u - side * g), d * v);
    side * (tc + td) <= 0.0 || (law1 && side * td > side * tc)
}

fn dead_zone(u: f64, g: f64) -> f64 {
    if u > g {
        u - g
    } else if u < -g {
        u + g
    } else {
        0.0
    }
}

/// The loop of docs/model.md §10 with the PI on ω_m, z = [θ_m, ω_m, θ_i, ω_i, θ_L, ω_L, x_c],
/// with backlash (`gaps`) or without:
/// J_m ω_m' = τ_m − b_m ω_m − ψ_1, J_i ω_i' = −b_i ω_i + n_1 ψ_1 − ψ_2, J_L ω_L' = −b_L ω_L + n_2 ψ_2,
/// τ_m = Kp (ω_ref − ω_m) + Ki x_c, x_c' = ω_ref − ω_m.
fn loop_rate(p: &Named, gains: PiGains, z: &Vec7, gaps: bool, w_ref: f64) -> Vec7 {
    let [th_m, w_m, th_i, w_i, th_l, w_l, x_c] = [z[0], z[1], z[2], z[3], z[4], z[5], z[6]];
    let u1 = th_m - p.n1 * th_i;
    let u2 = th_i - p.n2 * th_l;
    let (v1, v2) = (w_m - p.n1 * w_i, w_i - p.n2 * w_l);
    let (psi1, psi2) = if gaps {
        (
            member_force(p.k1, p.damp[0], p.d1, p.law1, u1, v1),
            member_force(p.k2, p.damp[1], p.d2, p.law1, u2, v2),
        )
    } else {
        // The twin: the spring-damper K u + D u′ (docs/model.md §3).
        (p.k1 * u1 + p.damp[0] * v1, p.k2 * u2 + p.damp[1] * v2)
    };
    let e = w_ref - w_m;
    let tau_m = gains.kp * e + gains.ki * x_c;
    // Without gains the loop is open and x_c is not kept (it stays 0), as in docs/model.md §3.
    let open = gains.kp == 0.0 && gains.ki == 0.0;
    Vec7::from([
        w_m,
        (tau_m - p.bm * w_m - psi1) / p.jm,
        w_i,
        (-p.bi * w_i + p.n1 * psi1 - psi2) / p.ji,
        w_l,
        (-p.bl * w_l + p.n2 * psi2) / p.jl,
        if open { 0.0 } else { e },
    ])
}

/// The same loop as a matrix, column by column (its rate at unit vectors, no reference).
fn loop_matrix(p: &Named, gains: PiGains) -> Mat7 {
    Mat7::from_fn(|i, j| {
        let mut e = Vec7::zeros();
        e[j] = 1.0;
        loop_rate(p, gains, &e, false, 0.0)[i]
    })
}

/// D_1, D_2 of docs/model.md §10.
fn columns(p: &Named) -> [Vec7; 2] {
    [
        Vec7::from([0.0, 1.0 / p.jm, 0.0, -p.n1 / p.ji, 0.0, 0.0, 0.0]),
        Vec7::from([0.0, 0.0, 0.0, 1.0 / p.ji, 0.0, -p.n2 / p.jl, 0.0]),
    ]
}

fn rk4(f: &dyn Fn(&Vec7) -> Vec7, z: &Vec7, h: f64) -> Vec7 {
    let k1 = f(z);
    let k2 = f(&(z + k1 * (h / 2.0)));
    let k3 = f(&(z + k2 * (h / 2.0)));
    let k4 = f(&(z + k3 * h));
    z + (k1 + k2 * 2.0 + k3 * 2.0 + k4) * (h / 6.0)
}

#[test]
fn the_loop_is_the_equations_of_two_stages() {
    let mut damped = gearbox();
    damped.stages[0].damper.d = 3.0;
    damped.stages[1].damper.d = 6.0;
    for (params, gains) in [(gearbox(), GAINS), (gearbox(), PiGains::default()), (damped, GAINS)] {
        let chain = Chain::new(params).unwrap();
        let p = named(&params);
        let ours = chain_loop::<2, 7>(&chain, gains);
        let theirs = loop_matrix(&p, gains);
        // Each entry is one quotient of a product of at most three parameters in both, summed
        // with at most three others: a few ulps of the largest entry.
        let scale = theirs.abs().max();
        assert!(
            (ours - theirs).abs().max() <= 8.0 * f64::EPSILON * scale,
            "{ours} vs {theirs}"
        );
    }
}

/// Σ_j K_j Δ_j ∫_0^t |h_j| at t = `times` by composite Simpson's rule on the matrix exponential,
/// with steps of `dt`; returned per stage.
fn quadrature(p: &Named, gains: PiGains, times: &[f64], dt: f64) -> Vec<[f64; 2]> {
    let a = loop_matrix(p, gains);
    let (half, step) = ((a * (dt / 2.0)).exp(), (a * dt).exp());
    let scale = [p.k1 * p.d1, p.k2 * p.d2];
    let mut out = Vec::new();
    for (j, d) in columns(p).iter().enumerate() {
        let (mut v, mut total, mut t) = (*d, 0.0, 0.0);
        let mut values = Vec::new();
        for &end in times {
            while t < end - dt / 2.0 {
                let mid = half * v;
                let next = step * v;
                total += dt / 6.0 * (v[5].abs() + 4.0 * mid[5].abs() + next[5].abs());
                v = next;
                t += dt;
            }
            values.push(scale[j] * total);
        }
        out.push(values);
    }
    (0..times.len()).map(|k| [out[0][k], out[1][k]]).collect()
}

#[test]
fn bound_is_the_integral_of_each_stages_response() {
    let params = gearbox();
    let p = named(&params);
    let mut bound = TwoStageBound::new(&Chain::new(params).unwrap(), GAINS).unwrap();
    let times = [0.05, 0.4, 2.0, 6.0];
    let fine = quadrature(&p, GAINS, &times, 2e-5);
    let coarse = quadrature(&p, GAINS, &times, 4e-5);
    let mut t = 0.0;
    for (k, &end) in times.iter().enumerate() {
        while t < end - 1e-12 {
            bound.advance(1e-3).unwrap();
            t += 1e-3;
        }
        for j in 0..2 {
            // Simpson's error is of fourth order where h is smooth; at the sign changes of h
            // |h| has kinks, of second order: the difference of two step sizes bounds it.
            let error = (fine[k][j] - coarse[k][j]).abs() + 1e-12 * fine[k][j];
            let ours = bound.stage_bound(j);
            assert!(
                (ours - fine[k][j]).abs() <= 4.0 * error,
                "t = {end}, stage {j}: {ours} vs {:?}",
                fine[k]
            );
        }
        assert_eq!(bound.bound(), bound.stage_bound(0) + bound.stage_bound(1));
    }
    // bound_sup: ∫|h| to T and to T/2 by quadrature. The slowest mode of this gearbox (the
    // intermediate shaft ringing at 350 rad/s) decays at 0.07/s, so by T = 200 s what is left
    // beyond T is below what was added between T/2 and T (the tail is geometric).
    let sup = bound.sup().unwrap();
    let stages = |dt: f64| {
        let at = quadrature(&p, GAINS, &[100.0, 200.0], dt);
        [at[0][0] + at[0][1], at[1][0] + at[1][1]]
    };
    let (fine, coarse) = (stages(1e-4), stages(2e-4));
    let error = (fine[1] - coarse[1]).abs() + 1e-12 * fine[1];
    let tail = fine[1] - fine[0];
    assert!(sup >= fine[1] - 4.0 * error, "{sup} below ∫|h| to 200 s, {fine:?}");
    assert!(
        sup <= fine[1] + tail + 4.0 * error,
        "{sup} above ∫|h| to 200 s and its tail, {fine:?}"
    );
}

/// max_t |ω_L^b − ω_L^0| over twin runs to `end`, and bound(t) at the time of that maximum
/// and at the end, with RK4 of step `dt` on docs/model.md §10's equations.
fn twin_run(p: &Named, gains: PiGains, dt: f64, end: f64, start: Vec7, reference: &dyn Fn(f64) -> f64) -> Vec<f64> {
    twin_run_with_variation(p, gains, dt, end, start, reference).0
}

/// `twin_run`, with each stage's V after every step: ∫|u′| over its free, slack and capped
/// time on the run with backlash, by the trapezoid rule over the steps it spends so.
fn twin_run_with_variation(
    p: &Named,
    gains: PiGains,
    dt: f64,
    end: f64,
    start: Vec7,
    reference: &dyn Fn(f64) -> f64,
) -> (Vec<f64>, Vec<[f64; 2]>) {
    let (mut b, mut z) = (start, start);
    let (mut deviations, mut variations) = (Vec::new(), Vec::new());
    let mut v_total = [0.0; 2];
    let stages = |z: &Vec7| {
        let u = [z[0] - p.n1 * z[2], z[2] - p.n2 * z[4]];
        let v = [z[1] - p.n1 * z[3], z[3] - p.n2 * z[5]];
        (u, v)
    };
    let params = [(p.k1, p.d1), (p.k2, p.d2)];
    let mut t = 0.0;
    while t < end - dt / 2.0 {
        let w_ref = reference(t);
        let before = stages(&b);
        b = rk4(&|z| loop_rate(p, gains, z, true, w_ref), &b, dt);
        z = rk4(&|z| loop_rate(p, gains, z, false, w_ref), &z, dt);
        let after = stages(&b);
        for j in 0..2 {
            let (k, g) = params[j];
            if varies(k, p.damp[j], g, p.law1, before.0[j], before.1[j]) {
                v_total[j] += 0.5 * dt * (before.1[j].abs() + after.1[j].abs());
            }
        }
        t += dt;
        deviations.push((b[5] - z[5]).abs());
        variations.push(v_total);
    }
    (deviations, variations)
}

#[test]
fn twins_with_and_without_backlash_stay_within_the_bound() {
    let params = gearbox();
    let p = named(&params);
    let chain = Chain::new(params).unwrap();
    // A reversing speed reference (the gaps are crossed at every reversal), from rest with the
    // teeth of stage 1 at one flank and stage 2 in mid-gap.
    let reference = |t: f64| 2.0 * (3.0 * t).sin() + if t > 1.0 { -1.5 } else { 0.0 };
    let mut start = Vec7::zeros();
    start[0] = 0.6e-3;
    let dt = 1e-4;
    let fine = twin_run(&p, GAINS, dt / 2.0, 4.0, start, &reference);
    let coarse = twin_run(&p, GAINS, dt, 4.0, start, &reference);
    let mut bound = TwoStageBound::new(&chain, GAINS).unwrap();
    let mut closest: f64 = 0.0;
    for k in 0..coarse.len() {
        bound.advance(dt).unwrap();
        let deviation = fine[2 * k + 1];
        // RK4 loses order at the gap edges: the two step sizes' difference bounds its error.
        let error = (fine[2 * k + 1] - coarse[k]).abs();
        assert!(
            deviation <= bound.bound() + 4.0 * error + 1e-12,
            "t = {}: deviation {deviation} above bound {}",
            (k + 1) as f64 * dt,
            bound.bound()
        );
        closest = closest.max(deviation / bound.sup().unwrap());
    }
    // A run of the physical drive stays well inside: the bound is for the worst signs.
    assert!(closest > 0.0 && closest < 1.0, "{closest}");
    eprintln!("largest deviation / bound_sup = {closest:.3}");
}

/// With a damper in each stage, under either law: the deviation stays within the bound with
/// its damper terms, D_i max|h_i| V_i, V_i taken from the run itself.
#[test]
fn damped_twins_stay_within_the_bound_with_its_damper_terms() {
    for law in [ContactLaw::ElastoBacklash, ContactLaw::ElastoBacklash2] {
        let mut params = gearbox();
        params.stages[0].damper = Damping { d: 3.0, law };
        params.stages[1].damper = Damping { d: 6.0, law };
        let p = named(&params);
        let chain = Chain::new(params).unwrap();
        let reference = |t: f64| 2.0 * (3.0 * t).sin() + if t > 1.0 { -1.5 } else { 0.0 };
        let mut start = Vec7::zeros();
        start[0] = 0.6e-3;
        let dt = 5e-5;
        let (fine, fine_v) = twin_run_with_variation(&p, GAINS, dt / 2.0, 3.0, start, &reference);
        let (coarse, coarse_v) = twin_run_with_variation(&p, GAINS, dt, 3.0, start, &reference);
        let mut bound = TwoStageBound::new(&chain, GAINS).unwrap();
        let mut closest: f64 = 0.0;
        for k in 0..coarse.len() {
            bound.advance(dt).unwrap();
            let (deviation, v) = (fine[2 * k + 1], fine_v[2 * k + 1]);
            let limit = bound.damped_bound(&v);
            // RK4 through the kinks of the force (and law 2's jump at the flanks) and the
            // trapezoid V: the two step sizes' differences bound their errors.
            let error = (deviation - coarse[k]).abs() + (limit - bound.damped_bound(&coarse_v[k])).abs();
            assert!(
                deviation <= limit + 4.0 * error + 1e-12,
                "{law:?}, t = {}: deviation {deviation} above {limit}",
                (k + 1) as f64 * dt
            );
            closest = closest.max(deviation / limit.max(f64::MIN_POSITIVE));
        }
        let v_end = fine_v.last().unwrap();
        assert!(v_end[0] > 0.0 && v_end[1] > 0.0, "{v_end:?}");
        assert!(bound.damped_bound(v_end) > bound.bound(), "the damper terms count");
        eprintln!("{law:?}: largest deviation / bound = {closest:.3}, V = {v_end:?}");
    }
}

#[test]
fn the_worst_signs_attain_the_bound() {
    // φ_j(s) = K_j Δ_j sign(h_j(T − s)) drives the twin's deviation at T to Σ K_j Δ_j ∫_0^T |h_j|.
    let params = gearbox();
    let p = named(&params);
    let big_t = 0.8;
    let a = loop_matrix(&p, GAINS);
    let d = columns(&p);
    let scale = [p.k1 * p.d1, p.k2 * p.d2];
    let attained = |dt: f64| {
        let steps = (big_t / dt).round() as usize;
        // The signs of h_j on the grid of the run, backwards from T (h_j(s) = [e^{As} D_j]_ω_L).
        let step = (a * dt).exp();
        let mut h = [d[0], d[1]];
        let mut signs = vec![[0.0; 2]; steps + 1];
        for k in 0..=steps {
            signs[steps - k] = [h[0][5].signum(), h[1][5].signum()];
            h = [step * h[0], step * h[1]];
        }
        let mut e = Vec7::zeros();
        for sign in &signs[..steps] {
            // The sign at the step's start (the forcing is piecewise constant on the grid).
            let phi = [scale[0] * sign[0], scale[1] * sign[1]];
            e = rk4(&|e| a * e + d[0] * phi[0] + d[1] * phi[1], &e, dt);
        }
        e[5].abs()
    };
    let (fine, coarse) = (attained(2e-5), attained(4e-5));
    let mut bound = TwoStageBound::new(&Chain::new(params).unwrap(), GAINS).unwrap();
    for _ in 0..800 {
        bound.advance(1e-3).unwrap();
    }
    let error = (fine - coarse).abs() + 1e-12;
    assert!(fine <= bound.bound() + 4.0 * error, "{fine} above {}", bound.bound());
    assert!(
        bound.bound() - fine <= 4.0 * error,
        "{fine} falls short of {}",
        bound.bound()
    );
}

#[test]
fn one_stage_is_the_plants_bound() {
    let plant = Plant::new(PlantParams::paper_rig(0.775e-3)).unwrap();
    let chain = Chain::new(ChainParams::from_plant(&plant).unwrap()).unwrap();
    let gains = PiGains { kp: 42.0, ki: 180.0 };
    let mut ours = OneStageBound::new(&chain, gains).unwrap();
    let mut plants = SpeedErrorBound::new(&plant, gains).unwrap();
    for _ in 0..3000 {
        ours.advance(1e-3).unwrap();
        plants.advance(1e-3).unwrap();
        // The same loop to the bit; the pieces may be cut at other lengths (the chain's fastest
        // rate is its own bound on the contact frequency), and each locates h's sign changes to
        // round-off: ∫|h| agrees to a few hundred ulps of the growing sum.
        assert!((ours.bound() - plants.bound()).abs() <= 1e-13 * plants.bound().max(f64::MIN_POSITIVE));
    }
    let (a, b) = (ours.sup().unwrap(), plants.sup().unwrap());
    assert!((a - b).abs() <= 1e-12 * b, "{a} vs {b}");
}

#[test]
fn one_damped_stage_is_the_plants_damped_bound() {
    let p = PlantParams::paper_rig(0.775e-3);
    let plant = Plant::new(PlantParams {
        damping: Damping {
            d: 10.0,
            law: ContactLaw::ElastoBacklash,
        },
        ..p
    })
    .unwrap();
    let chain = Chain::new(ChainParams::from_plant(&plant).unwrap()).unwrap();
    let gains = PiGains { kp: 42.0, ki: 180.0 };
    let mut ours = OneStageBound::new(&chain, gains).unwrap();
    let mut plants = SpeedErrorBound::new(&plant, gains).unwrap();
    for k in 0..2000 {
        ours.advance(1e-3).unwrap();
        plants.advance(1e-3).unwrap();
        let v = 1e-3 * k as f64;
        let theirs = plants.damped_bound(Trajectory::Stepped {
            variation: v,
            rate: 0.0,
        });
        assert!((ours.damped_bound(&[v]) - theirs).abs() <= 1e-13 * theirs.max(f64::MIN_POSITIVE));
    }
    let (a, b) = (ours.sup().unwrap(), plants.sup().unwrap());
    assert!((a - b).abs() <= 1e-12 * b, "{a} vs {b}");
}

#[test]
fn an_unstable_loop_has_no_bound_sup() {
    let chain = Chain::new(gearbox()).unwrap();
    let bound = TwoStageBound::new(&chain, PiGains { kp: -50.0, ki: 40.0 }).unwrap();
    assert!(bound.sup().is_err());
    assert!(TwoStageBound::new(&chain, PiGains { kp: f64::NAN, ki: 1.0 }).is_err());
}

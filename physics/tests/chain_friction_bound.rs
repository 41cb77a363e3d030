//! The chain's speed-error bound with bearing friction (physics/src/chain/bound.rs; the proof in
//! docs/model.md §10, "The bound with bearing friction") against computations written here: twin
//! runs of the chain with and without backlash, both with the same friction on every body, under
//! a continuous PI, by a hybrid integrator written from the law of stiction (RK4 within each
//! combination of body modes, the switches located by bisection); and a body's ∫|h_b| by
//! quadrature of the matrix exponential.

use backlash_physics::chain::{Body, Chain, ChainBound, ChainParams, Coulomb, OneStageBound, Stage, TwoStageBound};
use backlash_physics::{Damping, PiGains};
use nalgebra::{SMatrix, SVector};

/// A body's friction mode in the reference integrator.
#[derive(Clone, Copy, Debug, PartialEq)]
enum Mode {
    /// No friction on the body: it never switches.
    Free,
    Forward,
    Backward,
    Stuck,
}

/// The chain of S stages under the PI τ_m = Kp (ω_ref − ω_0) + Ki x_c, x_c′ = ω_ref − ω_0, over
/// z = [θ_0, ω_0, …, θ_S, ω_S, x_c], with backlash (`gaps`: ψ_i = K_i dz(u_i, g_i)) or without
/// (ψ_i = K_i u_i); body j: J_j ω_j′ = τ_j − b_j ω_j + f_j with f_j = ∓τ_c sliding, and held
/// still while |τ_j| ≤ peak τ_c at rest (τ_j: τ_m on the motor, c ψ_{j−1} − a ψ_j, docs/model.md
/// §1 and §10).
struct Twin<'a, const S: usize> {
    p: &'a ChainParams<S>,
    gains: PiGains,
    gaps: bool,
    reference: &'a dyn Fn(f64) -> f64,
}

impl<const S: usize> Twin<'_, S> {
    fn body(&self, j: usize) -> &Body {
        if j == 0 {
            &self.p.motor
        } else {
            &self.p.driven[j - 1]
        }
    }

    /// τ_j of every body at z and t: every torque but its own friction and viscous friction.
    fn held(&self, z: &[f64], t: f64) -> Vec<f64> {
        let psi: Vec<f64> = (0..S)
            .map(|i| {
                let s = &self.p.stages[i];
                let u = s.a * z[2 * i] - s.c * z[2 * i + 2];
                if !self.gaps {
                    s.k * u
                } else if u > s.g {
                    s.k * (u - s.g)
                } else if u < -s.g {
                    s.k * (u + s.g)
                } else {
                    0.0
                }
            })
            .collect();
        let tau_m = self.gains.kp * ((self.reference)(t) - z[1]) + self.gains.ki * z[2 * S + 2];
        (0..=S)
            .map(|j| {
                let mut tau = if j == 0 { tau_m } else { 0.0 };
                if j < S {
                    tau -= self.p.stages[j].a * psi[j];
                }
                if j > 0 {
                    tau += self.p.stages[j - 1].c * psi[j - 1];
                }
                tau
            })
            .collect()
    }

    fn rates(&self, z: &[f64], modes: &[Mode], t: f64) -> Vec<f64> {
        let held = self.held(z, t);
        let mut r = vec![0.0; 2 * S + 3];
        for j in 0..=S {
            let b = self.body(j);
            let friction = match modes[j] {
                Mode::Stuck => continue,
                Mode::Free => 0.0,
                Mode::Forward => -b.friction.tau_c,
                Mode::Backward => b.friction.tau_c,
            };
            let w = z[2 * j + 1];
            r[2 * j] = w;
            r[2 * j + 1] = (held[j] - b.b * w + friction) / b.j;
        }
        if self.gains.kp != 0.0 || self.gains.ki != 0.0 {
            r[2 * S + 2] = (self.reference)(t) - z[1];
        }
        r
    }

    fn rk4(&self, z: &[f64], modes: &[Mode], t: f64, dt: f64) -> Vec<f64> {
        let add = |k: &[f64], s: f64| z.iter().zip(k).map(|(a, b)| a + s * b).collect::<Vec<_>>();
        let k1 = self.rates(z, modes, t);
        let k2 = self.rates(&add(&k1, dt / 2.0), modes, t + dt / 2.0);
        let k3 = self.rates(&add(&k2, dt / 2.0), modes, t + dt / 2.0);
        let k4 = self.rates(&add(&k3, dt), modes, t + dt);
        (0..z.len())
            .map(|i| z[i] + dt / 6.0 * (k1[i] + 2.0 * k2[i] + 2.0 * k3[i] + k4[i]))
            .collect()
    }

    /// Whether every body is still inside its mode at z (a sliding body's speed has not gone
    /// through 0, a stuck body's |τ_j| has not passed peak τ_c).
    fn inside(&self, z: &[f64], modes: &[Mode], t: f64) -> bool {
        let held = self.held(z, t);
        (0..=S).all(|j| match modes[j] {
            Mode::Free => true,
            Mode::Forward => z[2 * j + 1] >= 0.0,
            Mode::Backward => z[2 * j + 1] <= 0.0,
            Mode::Stuck => held[j].abs() <= self.body(j).friction.breakaway(),
        })
    }

    /// The law at rest: stuck while |τ_j| ≤ peak τ_c, else sliding the way τ_j pushes.
    fn at_rest(&self, j: usize, held: f64) -> Mode {
        let breakaway = self.body(j).friction.breakaway();
        if held > breakaway {
            Mode::Forward
        } else if held < -breakaway {
            Mode::Backward
        } else {
            Mode::Stuck
        }
    }

    /// From rest: ω_S after each of `steps` intervals of `h`, with RK4 steps of h/`substeps`
    /// cut at the body switches, each located by bisection to the last bit of the step length.
    fn run(&self, h: f64, steps: usize, substeps: usize) -> (Vec<f64>, usize) {
        let mut z = vec![0.0; 2 * S + 3];
        let mut modes: Vec<Mode> = (0..=S)
            .map(|j| {
                if self.body(j).friction.tau_c > 0.0 {
                    self.at_rest(j, 0.0)
                } else {
                    Mode::Free
                }
            })
            .collect();
        let dt = h / substeps as f64;
        let (mut out, mut switches) = (Vec::new(), 0);
        for k in 0..steps {
            for sub in 0..substeps {
                let t0 = (k * substeps + sub) as f64 * dt;
                let mut done = 0.0;
                while done < dt {
                    let step = dt - done;
                    let trial = self.rk4(&z, &modes, t0 + done, step);
                    if self.inside(&trial, &modes, t0 + done + step) {
                        z = trial;
                        break;
                    }
                    let (mut lo, mut hi) = (0.0, step);
                    loop {
                        let mid = lo + 0.5 * (hi - lo);
                        if mid <= lo || mid >= hi {
                            break;
                        }
                        if self.inside(&self.rk4(&z, &modes, t0 + done, mid), &modes, t0 + done + mid) {
                            lo = mid;
                        } else {
                            hi = mid;
                        }
                    }
                    z = self.rk4(&z, &modes, t0 + done, hi);
                    done += hi;
                    let at = t0 + done;
                    let held = self.held(&z, at);
                    let leaving: Vec<bool> = (0..=S)
                        .map(|j| match modes[j] {
                            Mode::Free => false,
                            Mode::Forward => z[2 * j + 1] < 0.0,
                            Mode::Backward => z[2 * j + 1] > 0.0,
                            Mode::Stuck => held[j].abs() > self.body(j).friction.breakaway(),
                        })
                        .collect();
                    for j in 0..=S {
                        if leaving[j] {
                            if modes[j] != Mode::Stuck {
                                z[2 * j + 1] = 0.0;
                            }
                            modes[j] = self.at_rest(j, held[j]);
                            switches += 1;
                        }
                    }
                }
            }
            out.push(z[2 * S + 1]);
        }
        (out, switches)
    }
}

/// One run of the twins at substeps n and 2n: the deviation |ω_S^b − ω_S^0| of the finer run
/// at every sample, and its error estimate, the two runs' difference.
fn twins<const S: usize>(
    p: &ChainParams<S>,
    gains: PiGains,
    reference: &dyn Fn(f64) -> f64,
    h: f64,
    steps: usize,
    substeps: usize,
) -> (Vec<f64>, Vec<f64>, usize) {
    let run = |gaps: bool, n: usize| {
        Twin {
            p,
            gains,
            gaps,
            reference,
        }
        .run(h, steps, n)
    };
    let (coarse_b, _) = run(true, substeps);
    let (coarse_0, _) = run(false, substeps);
    let (fine_b, switches_b) = run(true, 2 * substeps);
    let (fine_0, switches_0) = run(false, 2 * substeps);
    let deviation: Vec<f64> = (0..steps).map(|k| (fine_b[k] - fine_0[k]).abs()).collect();
    let error = (0..steps)
        .map(|k| ((fine_b[k] - fine_0[k]) - (coarse_b[k] - coarse_0[k])).abs())
        .collect();
    (deviation, error, switches_b + switches_0)
}

/// Checks deviation ≤ bound(t) at every sample, within 4x the error estimate (RK4 loses order
/// at the gaps' edges, the switches are located to the last bit) plus 1e-12 of the bound; returns
/// the largest deviation over the gaps' part of the bound alone, bound() − friction_bound().
fn within<const S: usize, const N: usize, const BA: usize, const KO: usize, const R: usize, const OUT: usize>(
    bound: &mut ChainBound<S, N, BA, KO, R, OUT>,
    h: f64,
    deviation: &[f64],
    error: &[f64],
) -> f64 {
    let mut beyond_gaps: f64 = 0.0;
    for k in 0..deviation.len() {
        bound.advance(h).unwrap();
        let (total, gaps) = (bound.bound(), bound.bound() - bound.friction_bound());
        assert!(
            deviation[k] <= total + 4.0 * error[k] + 1e-12 * total,
            "t = {}: deviation {} above bound {total} (error {})",
            (k + 1) as f64 * h,
            deviation[k],
            error[k]
        );
        // Counted only where the excess is beyond the integrators' error.
        if deviation[k] > 4.0 * error[k] {
            beyond_gaps = beyond_gaps.max((deviation[k] - 4.0 * error[k]) / gaps);
        }
    }
    beyond_gaps
}

fn body(j: f64, b: f64, tau_c: f64, peak: f64) -> Body {
    Body {
        j,
        b,
        friction: Coulomb { tau_c, peak },
    }
}

fn stage(c: f64, k: f64, g: f64) -> Stage {
    Stage {
        a: 1.0,
        c,
        k,
        g,
        damper: Damping::NONE,
    }
}

/// The two-stage gearbox of tests/chain_friction.rs: friction on every body, a light
/// intermediate shaft.
fn gearbox() -> ChainParams<2> {
    ChainParams {
        motor: body(2.28, 0.05, 0.3, 1.2),
        driven: [body(0.05, 0.05, 0.2, 1.5), body(2.55, 0.05, 1.0, 1.3)],
        stages: [stage(2.0, 200.0, 1e-3), stage(3.0, 400.0, 2e-3)],
        web: None,
    }
}

fn one_stage() -> ChainParams<1> {
    ChainParams {
        motor: body(2.28, 0.05, 0.4, 1.25),
        driven: [body(2.55, 0.05, 1.2, 1.4)],
        stages: [stage(1.0, 400.0, 0.3875e-3)],
        web: None,
    }
}

const GAINS: PiGains = PiGains { kp: 20.0, ki: 60.0 };

/// A slow reversing speed reference: the bodies break away, stop, stick and break away again.
fn reversing(t: f64) -> f64 {
    0.3 * (2.0 * std::f64::consts::PI * 0.5 * t).sin()
}

#[test]
fn two_stage_twins_with_friction_on_every_body_stay_within_the_bound() {
    let params = gearbox();
    let (h, steps) = (1e-3, 4000);
    let (deviation, error, switches) = twins(&params, GAINS, &reversing, h, steps, 10);
    assert!(switches > 0, "the run never exercised the friction modes");
    let mut bound = TwoStageBound::new(&Chain::new(params).unwrap(), GAINS).unwrap();
    let beyond = within(&mut bound, h, &deviation, &error);
    eprintln!("two stages: {switches} body switches, largest deviation / gaps' part = {beyond:.3}");
}

#[test]
fn one_stage_twins_with_friction_on_both_bodies_stay_within_the_bound() {
    let params = one_stage();
    let (h, steps) = (1e-3, 4000);
    let (deviation, error, switches) = twins(&params, GAINS, &reversing, h, steps, 10);
    assert!(switches > 0, "the run never exercised the friction modes");
    let mut bound = OneStageBound::new(&Chain::new(params).unwrap(), GAINS).unwrap();
    let beyond = within(&mut bound, h, &deviation, &error);
    eprintln!("one stage: {switches} body switches, largest deviation / gaps' part = {beyond:.3}");
}

/// Without friction nothing is added: the bound, its sup and the damped bound are the gaps'
/// terms alone, to the bit.
#[test]
fn without_friction_no_term_is_built() {
    let mut frictionless = gearbox();
    frictionless.motor.friction = Coulomb::NONE;
    for b in &mut frictionless.driven {
        b.friction = Coulomb::NONE;
    }
    let mut bound = TwoStageBound::new(&Chain::new(frictionless).unwrap(), GAINS).unwrap();
    for _ in 0..500 {
        bound.advance(1e-3).unwrap();
    }
    assert_eq!(bound.friction_bound(), 0.0);
    assert!((0..3).all(|b| bound.body_bound(b).is_none()));
    assert_eq!(bound.bound(), bound.stage_bound(0) + bound.stage_bound(1));
    assert_eq!(bound.damped_bound(&[1.0, 2.0]), bound.bound());
    let stages = bound.stage_sup(0).unwrap() + bound.stage_sup(1).unwrap();
    assert_eq!(bound.sup().unwrap(), stages);
}

/// With friction the sup holds the friction terms' sups too: above the bound at every time and
/// above the gaps' sup by at least the friction's part so far.
#[test]
fn the_sup_holds_the_friction_terms() {
    let mut bound = TwoStageBound::new(&Chain::new(gearbox()).unwrap(), GAINS).unwrap();
    let stages = bound.stage_sup(0).unwrap() + bound.stage_sup(1).unwrap();
    let sup = bound.sup().unwrap();
    for _ in 0..3000 {
        bound.advance(1e-3).unwrap();
        // sup() is within 1e-13 relative of the exact ∫_0^∞ (LoopBound::sup_slack).
        assert!(bound.bound() <= sup * (1.0 + 1e-12), "{} above {sup}", bound.bound());
    }
    assert!(sup - stages >= bound.friction_bound() * (1.0 - 1e-12));
}

/// 2 peak_b τ_c,b ∫_0^t |h_b| of each body against composite Simpson's rule on e^{A s} E_b, A
/// the frictionless twin's loop taken column by column from the integrator's rates above.
#[test]
fn each_bodys_term_is_its_response_integral() {
    type Mat7 = SMatrix<f64, 7, 7>;
    type Vec7 = SVector<f64, 7>;
    let params = gearbox();
    let mut frictionless = params;
    frictionless.motor.friction = Coulomb::NONE;
    for b in &mut frictionless.driven {
        b.friction = Coulomb::NONE;
    }
    let zero = |_: f64| 0.0;
    let twin = Twin {
        p: &frictionless,
        gains: GAINS,
        gaps: false,
        reference: &zero,
    };
    let a = Mat7::from_fn(|i, j| {
        let mut e = vec![0.0; 7];
        e[j] = 1.0;
        twin.rates(&e, &[Mode::Free; 3], 0.0)[i]
    });
    let quadrature = |column: Vec7, end: f64, dt: f64| {
        let (half, step) = ((a * (dt / 2.0)).exp(), (a * dt).exp());
        let (mut v, mut total, mut t) = (column, 0.0, 0.0);
        while t < end - dt / 2.0 {
            let (mid, next) = (half * v, step * v);
            total += dt / 6.0 * (v[5].abs() + 4.0 * mid[5].abs() + next[5].abs());
            v = next;
            t += dt;
        }
        total
    };
    let mut bound = TwoStageBound::new(&Chain::new(params).unwrap(), GAINS).unwrap();
    let end = 1.5;
    for _ in 0..1500 {
        bound.advance(1e-3).unwrap();
    }
    for j in 0..3 {
        let coulomb = twin_body(&params, j).friction;
        let mut column = Vec7::zeros();
        column[2 * j + 1] = 1.0 / twin_body(&params, j).j;
        let scale = 2.0 * coulomb.peak * coulomb.tau_c;
        let (fine, coarse) = (
            scale * quadrature(column, end, 1e-5),
            scale * quadrature(column, end, 2e-5),
        );
        // Simpson's error is of fourth order where h is smooth, of second at the kinks of |h|:
        // the two step sizes' difference bounds it.
        let error = (fine - coarse).abs() + 1e-12 * fine;
        let ours = bound.body_bound(j).unwrap();
        assert!(
            (ours - fine).abs() <= 4.0 * error,
            "body {j}: {ours} vs {fine} ± {error}"
        );
    }
    let sum: f64 = (0..3).map(|j| bound.body_bound(j).unwrap()).sum();
    assert!((bound.friction_bound() - sum).abs() <= 4.0 * f64::EPSILON * sum);
}

fn twin_body<const S: usize>(p: &ChainParams<S>, j: usize) -> Body {
    if j == 0 {
        p.motor
    } else {
        p.driven[j - 1]
    }
}

/// The friction term is needed: a slow speed reference winds the member up against a load held
/// by stiction. The twin's load breaks away when K u reaches peak τ_c; the chain with backlash
/// needs u larger by g, and the motor creeps at ω ≈ Ki ω_ref/(K + Ki) (the PI's integral against
/// the member's stiffness), so it breaks away some g/ω later, and the twin's load meanwhile slides
/// ahead. The deviation passes the gaps' part of the bound, and stays within the whole.
#[test]
fn a_breakaway_delayed_by_the_gap_needs_the_friction_term() {
    let (tau_c, peak, speed) = (2.0, 3.0, 0.005);
    let (k, g) = (400.0, 0.3875e-3);
    let params = ChainParams {
        motor: body(2.28, 0.05, 0.05, 1.1),
        driven: [body(2.55, 0.05, tau_c, peak)],
        stages: [stage(1.0, k, g)],
        web: None,
    };
    let creep = GAINS.ki * speed / (k + GAINS.ki);
    // Past the twin's breakaway at u = peak τ_c/K, and the chain's g/creep later.
    let end = 1.5 * peak * tau_c / k / creep;
    let (h, steps) = (1e-3, (end / 1e-3) as usize);
    let reference = |_: f64| speed;
    let (deviation, error, switches) = twins(&params, GAINS, &reference, h, steps, 10);
    let mut bound = OneStageBound::new(&Chain::new(params).unwrap(), GAINS).unwrap();
    let beyond = within(&mut bound, h, &deviation, &error);
    eprintln!("delayed breakaway: {switches} body switches, largest deviation / gaps' part = {beyond:.3}");
    assert!(beyond > 1.0, "the gaps' part alone held: {beyond}");
}

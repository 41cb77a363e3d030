//! The chain of stages (physics/src/chain) against the single-gap stepper, an independent
//! integrator of docs/model.md §10, a closed form, a graze and its refusals.

mod common;

use backlash_physics::chain::{
    Body, Chain, ChainError, ChainEvent, ChainMode, ChainParams, ChainState, ChainStepper, Motion, Part, Stage,
    StageSwitch, TwoStageStepper,
};
use backlash_physics::{
    ContactLaw, ContactMode, Damping, Inputs, Plant, PlantParams, PlantState, StepError, Stepper, WebSpan,
};

const EPS: f64 = f64::EPSILON;

/// The stage switch of an event; a chain without friction has no other.
fn stage_switch(e: ChainEvent) -> StageSwitch {
    match e {
        ChainEvent::Stage(e) => e,
        other => panic!("a body switch in a chain without friction: {other:?}"),
    }
}

/// A reversing motor torque A sin(2π f t), sampled at the step starts and held to first order
/// over the step (the slope to the next sample): a piecewise-linear input both steppers take
/// exactly; and a constant load torque.
fn reversing(amplitude: f64, frequency: f64, load: f64, t: f64, h: f64) -> Inputs {
    let tau = |t: f64| amplitude * (2.0 * std::f64::consts::PI * frequency * t).sin();
    let (a, b) = (tau(t), tau(t + h));
    Inputs {
        dtau_m: (b - a) / h,
        ..Inputs::held(a, load)
    }
}

/// The paper's rig (docs/model.md §4) and a small servo belt drive with a gap.
fn plants() -> [PlantParams; 2] {
    [PlantParams::paper_rig(1e-3), common::servo_belt()]
}

/// S = 1 and the single-gap stepper (physics::Stepper) are two computations of one trajectory
/// (the same augmented layout, but matrices composed differently, so their entries differ in
/// the last bits): over many steps with a reversing torque that drives the motor across the
/// gap again and again against a load torque, the states agree to a few hundred ulps of each
/// quantity's magnitude over the run (u's and u′'s: those of r_m|θ_m| + r_L|θ_L| and
/// r_m|ω_m| + r_L|ω_L|, of which they are the differences), the switch instants to a few
/// hundred ulps of the run's length, and the switches are the same. A few hundred: an ulp of
/// a matrix entry per piece, accumulated over thousands of pieces. (The run is well
/// conditioned: with a load torque ramping up from zero instead, it turns chaotic after a
/// minute and any two computations part exponentially, by some 10⁵ ulps at the end.)
#[test]
fn one_stage_agrees_with_the_single_gap_stepper() {
    for params in plants() {
        agrees_with_the_single_gap_stepper::<10, 8>(params);
    }
}

/// The same for the belt drive pulling a web span (docs/model.md §8, BacklashWeb's film line),
/// with and without a damper, its span forced by the upstream web (a ramp of w): the tension
/// too agrees.
#[test]
fn one_stage_with_a_web_span_agrees_with_the_single_gap_stepper() {
    let span = WebSpan {
        r_w: 0.05,
        l_w: 1.0,
        ea: 1e5,
        v_ref: 2.0,
    };
    let belt = PlantParams {
        web: Some(span),
        ..plants()[1]
    };
    let omega0 = Plant::new(belt).unwrap().contact_frequency();
    let k = Plant::new(belt).unwrap().stiffness();
    let damped = PlantParams {
        damping: Damping {
            d: 2.0 * 0.3 * k / omega0,
            law: ContactLaw::ElastoBacklash,
        },
        ..belt
    };
    for params in [belt, damped] {
        agrees_with_the_single_gap_stepper::<13, 10>(params);
    }
}

/// The same with a damper in the member (docs/model.md §1), under either law, at contact
/// damping ratios 0.05 and 0.5 (D = 2 ζ K / ω_0 in u): the slack and capped modes and the
/// surfaces of the force are the single-gap stepper's (stepper/damped.rs), here per stage.
#[test]
fn one_damped_stage_agrees_with_the_single_gap_stepper() {
    for params in plants() {
        for (law, zeta) in [
            (ContactLaw::ElastoBacklash, 0.5),
            (ContactLaw::ElastoBacklash2, 0.5),
            (ContactLaw::ElastoBacklash, 0.05),
        ] {
            agrees_with_the_single_gap_stepper::<10, 8>(common::with_damper(params, law, zeta));
        }
    }
}

fn agrees_with_the_single_gap_stepper<const N: usize, const KO: usize>(params: PlantParams) {
    {
        let plant = Plant::new(params).unwrap();
        let chain = Chain::new(ChainParams::from_plant(&plant).unwrap()).unwrap();
        let mut reference = Stepper::new(plant);
        let mut stepper = ChainStepper::<1, N, KO>::new(chain);
        let mut a = PlantState::new(&plant, 0.0, 0.0, 0.0, 0.0);
        let mut b = ChainState::new(&chain, Motion::default(), [Motion::default()]);
        // Torque: 20 times the member's force at one gap's stretch, on the motor's arm, enough to
        // cross the gap and load the member; its period: ten contact periods.
        let omega0 = plant.contact_frequency();
        let amplitude = 20.0 * plant.stiffness() * plant.half_gap() * plant.r_m();
        let frequency = omega0 / (2.0 * std::f64::consts::PI) / 10.0;
        let h = 0.3 / omega0;
        // A load torque that opposes the motor's with a fifth of its amplitude.
        let load = -0.2 * amplitude * plant.r_l() / plant.r_m();
        let t_end = 4000.0 * h;
        let (mut switches_a, mut switches_b) = (Vec::new(), Vec::new());
        // Magnitudes over the run: θ_m, ω_m, θ_L, ω_L, u, u′; and the worst deviation in each.
        let mut scale = [0.0f64; 6];
        let mut worst = [0.0f64; 6];
        let mut worst_t = 0.0f64;
        // V (docs/model.md §2, "With a damper"): its largest value and deviation.
        let (mut v_scale, mut v_worst) = (0.0f64, 0.0f64);
        // The web span's tension, likewise.
        let (mut t_scale, mut t_worst) = (0.0f64, 0.0f64);
        for k in 0..4000 {
            let t = k as f64 * h;
            // The load torque ramps by a tenth over the run, to first order too.
            // A web span's forcing (ignored without one): w ramping from 0 to 50 N/s.
            let inputs = Inputs {
                tau_l: load * (0.9 + 0.1 * t / t_end),
                dtau_l: 0.1 * load / t_end,
                span: 50.0 * t / t_end,
                dspan: 50.0 / t_end,
                ..reversing(amplitude, frequency, 0.0, t, h)
            };
            reference
                .step(&mut a, &inputs, h, &mut |e| {
                    switches_a.push((t + e.offset, e.from, e.to))
                })
                .unwrap();
            stepper
                .step(&mut b, &inputs, h, &mut |e| {
                    let e = stage_switch(e);
                    switches_b.push((t + e.offset, e.from, e.to))
                })
                .unwrap();
            let pa = [a.theta_m, a.omega_m, a.theta_l, a.omega_l, a.u, a.du];
            let pb = [
                b.motor.theta,
                b.motor.omega,
                b.driven[0].theta,
                b.driven[0].omega,
                b.u[0],
                b.du[0],
            ];
            // u = r_m θ_m − r_L θ_L and u′ = r_m ω_m − r_L ω_L are differences: a last-bit
            // change of the model (κK, b/J) moves them as much as it moves their terms, so
            // their scales are those of the terms (large once the load torque spins the drive).
            let angles = plant.r_m() * a.theta_m.abs() + plant.r_l() * a.theta_l.abs();
            let speeds = plant.r_m() * a.omega_m.abs() + plant.r_l() * a.omega_l.abs();
            let magnitude = [pa[0].abs(), pa[1].abs(), pa[2].abs(), pa[3].abs(), angles, speeds];
            for i in 0..6 {
                scale[i] = scale[i].max(magnitude[i]);
                worst[i] = worst[i].max((pa[i] - pb[i]).abs());
            }
            assert_eq!(a.mode, b.mode.stages()[0], "step {k}");
            v_scale = v_scale.max(a.variation);
            v_worst = v_worst.max((a.variation - b.variation[0]).abs());
            t_scale = t_scale.max(a.tension.abs());
            t_worst = t_worst.max((a.tension - b.tension).abs());
        }
        assert_eq!(v_scale > 0.0, plant.damping() > 0.0, "V grows with a damper only");
        assert_eq!(switches_a.len(), switches_b.len());
        assert!(
            switches_a.len() > 40,
            "{} switches: the test must cross the gap",
            switches_a.len()
        );
        for (sa, sb) in switches_a.iter().zip(&switches_b) {
            assert_eq!((sa.1, sa.2), (sb.1, sb.2));
            worst_t = worst_t.max((sa.0 - sb.0).abs());
        }
        let ulps: Vec<f64> = (0..6).map(|i| worst[i] / (EPS * scale[i])).collect();
        eprintln!(
            "{} switches; worst deviation in ulps of the scale: {ulps:?}; switch times {:.1} ulps of the run",
            switches_a.len(),
            worst_t / (EPS * t_end)
        );
        for (i, u) in ulps.iter().enumerate() {
            assert!(*u <= 512.0, "component {i}: {u} ulps");
        }
        // V sums |Δu| and bounds piece by piece: a few ulps of its size per piece.
        eprintln!(
            "V: {v_scale:e}, deviation {:.1} ulps of it",
            v_worst / (EPS * v_scale.max(f64::MIN_POSITIVE))
        );
        assert!(v_worst <= 512.0 * EPS * v_scale);
        assert_eq!(t_scale > 0.0, plant.web().is_some(), "T moves with a web span only");
        eprintln!(
            "T: {t_scale:e}, deviation {:.1} ulps of it",
            t_worst / (EPS * t_scale.max(f64::MIN_POSITIVE))
        );
        assert!(t_worst <= 512.0 * EPS * t_scale);
        assert!(worst_t <= 512.0 * EPS * t_end);
    }
}

/// A gear train as docs/model.md §10 writes it, for any number of stages: bodies
/// (J, b), stage j (from 0) with ratio n_j, u_j = θ_j − n_j θ_{j+1}, stiffness k_j, half gap Δ_j.
struct Drive {
    j: Vec<f64>,
    b: Vec<f64>,
    n: Vec<f64>,
    k: Vec<f64>,
    delta: Vec<f64>,
    /// Each stage's damper D (empty: none) and whether the law is 1 (ElastoBacklash).
    d: Vec<f64>,
    law1: bool,
}

/// docs/model.md §10's numbers (`BacklashTwoStage`): a light intermediate shaft between two meshes, each
/// with its compliance and its gap.
fn two_stage() -> Drive {
    Drive {
        j: vec![2.28, 0.05, 2.55],
        b: vec![0.05; 3],
        n: vec![2.0, 3.0],
        k: vec![200.0, 400.0],
        delta: vec![1e-3, 2e-3],
        d: Vec::new(),
        law1: true,
    }
}

/// docs/model.md §10's train with a third mesh: a second light shaft before the load.
fn three_stage() -> Drive {
    Drive {
        j: vec![2.28, 0.05, 0.04, 2.55],
        b: vec![0.05; 4],
        n: vec![2.0, 3.0, 1.5],
        k: vec![200.0, 400.0, 300.0],
        delta: vec![1e-3, 2e-3, 1.5e-3],
        d: Vec::new(),
        law1: true,
    }
}

impl Drive {
    fn chain<const S: usize>(&self) -> Chain<S> {
        assert_eq!(self.n.len(), S);
        let body = |i: usize| Body::new(self.j[i], self.b[i]);
        let stage = |i: usize| Stage {
            a: 1.0,
            c: self.n[i],
            k: self.k[i],
            g: self.delta[i],
            damper: match self.d.get(i) {
                Some(&d) => Damping {
                    d,
                    law: if self.law1 {
                        ContactLaw::ElastoBacklash
                    } else {
                        ContactLaw::ElastoBacklash2
                    },
                },
                None => Damping::NONE,
            },
        };
        Chain::new(ChainParams {
            motor: body(0),
            driven: std::array::from_fn(|i| body(i + 1)),
            stages: std::array::from_fn(stage),
            web: None,
        })
        .unwrap()
    }

    /// u_j = θ_j − n_j θ_{j+1} from z = [θ_0, ω_0, θ_1, ω_1, …].
    fn coordinates(&self, z: &[f64]) -> Vec<f64> {
        (0..self.n.len()).map(|j| z[2 * j] - self.n[j] * z[2 * j + 2]).collect()
    }

    /// docs/model.md §10's right-hand side with each stage's flank given (the event location decides it):
    /// ψ_j = k_j (u_j ∓ Δ_j) on a flank, 0 free; J_i ω_i' = −b_i ω_i + n_{i−1} ψ_{i−1} − ψ_i,
    /// with τ_m added on the motor (body 0) and τ_L on the load (the last body).
    fn rates(&self, z: &[f64], modes: &[ContactMode], tau_m: f64, tau_l: f64) -> Vec<f64> {
        let u = self.coordinates(z);
        let psi: Vec<f64> = (0..self.n.len())
            .map(|j| match modes[j] {
                // With a damper (docs/model.md §1): past the flank, τ_c = K (u ∓ Δ), τ_d = D u′;
                // law 2 τ_c + τ_d, law 1 τ_c + min(τ_c, τ_d) (mirrored on the negative flank),
                // while the sum pushes; else 0. u′ = ω_j − n_j ω_{j+1}.
                ContactMode::Positive | ContactMode::Negative if !self.d.is_empty() => {
                    let side = if modes[j] == ContactMode::Positive { 1.0 } else { -1.0 };
                    let v = z[2 * j + 1] - self.n[j] * z[2 * j + 3];
                    let (tc, td) = (self.k[j] * (u[j] - side * self.delta[j]), self.d[j] * v);
                    if side * (tc + td) <= 0.0 {
                        0.0
                    } else if self.law1 {
                        tc + if side > 0.0 { tc.min(td) } else { tc.max(td) }
                    } else {
                        tc + td
                    }
                }
                // Δ = 0: one spring on both sides of u = 0, no mode to locate (§1).
                _ if self.delta[j] == 0.0 => self.k[j] * u[j],
                ContactMode::Positive => self.k[j] * (u[j] - self.delta[j]),
                ContactMode::Negative => self.k[j] * (u[j] + self.delta[j]),
                _ => 0.0,
            })
            .collect();
        let last = self.j.len() - 1;
        let mut rates = Vec::with_capacity(z.len());
        for i in 0..=last {
            let mut torque = -self.b[i] * z[2 * i + 1];
            if i == 0 {
                torque += tau_m;
            }
            if i == last {
                torque += tau_l;
            }
            if i > 0 {
                torque += self.n[i - 1] * psi[i - 1];
            }
            if i < last {
                torque -= psi[i];
            }
            rates.extend([z[2 * i + 1], torque / self.j[i]]);
        }
        rates
    }

    /// How far each stage's u is inside its mode's region (< 0: it has left it; ∞ without a
    /// gap, where there is no region to leave).
    fn margins(&self, z: &[f64], modes: &[ContactMode]) -> Vec<f64> {
        let u = self.coordinates(z);
        (0..self.n.len())
            .map(|j| {
                let g = self.delta[j];
                match modes[j] {
                    _ if g == 0.0 => f64::INFINITY,
                    ContactMode::Positive => u[j] - g,
                    ContactMode::Negative => -u[j] - g,
                    _ => (g - u[j]).min(g + u[j]),
                }
            })
            .collect()
    }

    /// Classical Runge–Kutta over `dt` from time `t` in fixed modes, the motor torque τ(t)
    /// and the load torque τ_L given.
    fn rk4(&self, z: &[f64], modes: &[ContactMode], t: f64, dt: f64, tau: &dyn Fn(f64) -> f64, tau_l: f64) -> Vec<f64> {
        let add = |k: &[f64], s: f64| -> Vec<f64> { z.iter().zip(k).map(|(z, k)| z + s * k).collect() };
        let k1 = self.rates(z, modes, tau(t), tau_l);
        let k2 = self.rates(&add(&k1, dt / 2.0), modes, tau(t + dt / 2.0), tau_l);
        let k3 = self.rates(&add(&k2, dt / 2.0), modes, tau(t + dt / 2.0), tau_l);
        let k4 = self.rates(&add(&k3, dt), modes, tau(t + dt), tau_l);
        (0..z.len())
            .map(|i| z[i] + dt / 6.0 * (k1[i] + 2.0 * k2[i] + 2.0 * k3[i] + k4[i]))
            .collect()
    }

    /// The reference: RK4 from rest with `substeps` steps per input interval of length h (so
    /// that the piecewise-linear input is smooth inside each RK step), switches located by
    /// bisection on the RK4 step length to the last bit and the state stepped onto them.
    /// Returns the state at each interval's end and each stage's switch instants.
    fn reference_run(&self, inputs: &[Inputs], h: f64, substeps: usize) -> (Vec<Vec<f64>>, Vec<Vec<f64>>) {
        let stages = self.n.len();
        let mut z = vec![0.0; 2 * self.j.len()];
        let mut modes = vec![ContactMode::Free; stages];
        let mut states = Vec::new();
        let mut switches = vec![Vec::new(); stages];
        let inside = |z: &[f64], modes: &[ContactMode]| self.margins(z, modes).iter().all(|&m| m >= 0.0);
        for (k, input) in inputs.iter().enumerate() {
            let t0 = k as f64 * h;
            let tau = |t: f64| input.tau_m + input.dtau_m * (t - t0);
            let mut done = 0.0;
            for target in common::substep_ends(h, substeps) {
                while done < target {
                    let (next, cut) = common::rk4_to_first_exit(
                        target - done,
                        |len| self.rk4(&z, &modes, t0 + done, len, &tau, input.tau_l),
                        |z, _| inside(z, &modes),
                    );
                    z = next;
                    let Some(hi) = cut else {
                        done = target;
                        continue;
                    };
                    done += hi;
                    let (margins, u) = (self.margins(&z, &modes), self.coordinates(&z));
                    for j in 0..stages {
                        if margins[j] < 0.0 {
                            modes[j] = match modes[j] {
                                ContactMode::Free if u[j] > 0.0 => ContactMode::Positive,
                                ContactMode::Free => ContactMode::Negative,
                                _ => ContactMode::Free,
                            };
                            switches[j].push(t0 + done);
                        }
                    }
                }
            }
            states.push(z.clone());
        }
        (states, switches)
    }
}

/// The chain of S stages against RK4 written from docs/model.md §10's equations alone, from rest under a
/// reversing motor torque against a load torque: the light shafts rattle in their gaps. The
/// reference's error is estimated by halving its step (RK4: the finer run is ~16x closer to
/// the exact solution than the two runs are to each other); the exact chain must agree with
/// the finer run within that difference (some 15 times the finer run's own error) plus four
/// times its own round-off (estimated by taking the same input in half steps: the rattling
/// light shafts amplify round-off to some hundreds of ulps over the run, in any integrator)
/// plus 64 ulps, and locate the same switches of each stage at the same instants.
fn agrees_with_the_reference<const S: usize, const N: usize, const KO: usize>(drive: &Drive, min_switches: usize) {
    let h = 1e-3;
    let steps = 1000;
    let inputs: Vec<Inputs> = (0..steps).map(|k| reversing(5.0, 2.0, -2.0, k as f64 * h, h)).collect();
    let (coarse, coarse_switches) = drive.reference_run(&inputs, h, 50);
    let (fine, fine_switches) = drive.reference_run(&inputs, h, 100);

    let (states, switches) = chain_run::<S, N, KO>(drive, &inputs, h, 1);
    // The chain's own round-off, as it propagates through the rattling: the same input in
    // half steps, a different sequence of roundings.
    let (halved, halved_switches) = chain_run::<S, N, KO>(drive, &inputs, h, 2);
    let dim = 2 * (S + 1);
    let (mut scale, mut estimate, mut deviation, mut roundoff) = (
        vec![0.0f64; dim],
        vec![0.0f64; dim],
        vec![0.0f64; dim],
        vec![0.0f64; dim],
    );
    for k in 0..steps {
        for i in 0..dim {
            scale[i] = scale[i].max(fine[k][i].abs());
            estimate[i] = estimate[i].max((coarse[k][i] - fine[k][i]).abs());
            deviation[i] = deviation[i].max((states[k][i] - fine[k][i]).abs());
            roundoff[i] = roundoff[i].max((states[k][i] - halved[k][i]).abs());
        }
    }
    let counts: Vec<usize> = switches.iter().map(Vec::len).collect();
    eprintln!("S = {S}: switches per stage {counts:?}");
    eprintln!("scale {scale:?}\nestimate {estimate:?}\nround-off {roundoff:?}\ndeviation {deviation:?}");
    for j in 0..S {
        if drive.delta[j] == 0.0 {
            // Without a gap both flanks are one spring: nothing to switch.
            assert!(switches[j].is_empty() && fine_switches[j].is_empty(), "stage {j}");
            continue;
        }
        assert_eq!(switches[j].len(), fine_switches[j].len(), "stage {j}");
        assert_eq!(switches[j].len(), halved_switches[j].len(), "stage {j}");
        assert_eq!(coarse_switches[j].len(), fine_switches[j].len(), "stage {j}");
        assert!(switches[j].len() >= min_switches, "stage {j} must cross its gap often");
    }
    let differences = |a: &[Vec<f64>], b: &[Vec<f64>]| {
        (0..S)
            .filter(|&j| drive.delta[j] > 0.0)
            .flat_map(|j| a[j].iter().zip(&b[j]).map(|(a, b)| (a - b).abs()).collect::<Vec<_>>())
            .fold(0.0, f64::max)
    };
    let t_estimate = differences(&coarse_switches, &fine_switches);
    let t_deviation = differences(&switches, &fine_switches);
    let t_roundoff = differences(&switches, &halved_switches);
    eprintln!("switch times: estimate {t_estimate:e}, round-off {t_roundoff:e}, deviation {t_deviation:e}");
    for i in 0..dim {
        let tol = estimate[i] + 4.0 * roundoff[i] + 64.0 * EPS * scale[i];
        assert!(deviation[i] <= tol, "component {i}: {} > {tol}", deviation[i]);
    }
    assert!(t_deviation <= t_estimate + 4.0 * t_roundoff + 64.0 * EPS * steps as f64 * h);
}

/// The chain's run from rest over `inputs` (one per interval of length h), each interval taken
/// in `split` steps: the state at each interval's end and each stage's switch instants.
fn chain_run<const S: usize, const N: usize, const KO: usize>(
    drive: &Drive,
    inputs: &[Inputs],
    h: f64,
    split: usize,
) -> (Vec<Vec<f64>>, Vec<Vec<f64>>) {
    let chain = drive.chain::<S>();
    let mut stepper = ChainStepper::<S, N, KO>::new(chain);
    let mut state = ChainState::new(&chain, Motion::default(), [Motion::default(); S]);
    let mut switches = vec![Vec::new(); S];
    let mut states = Vec::new();
    let step = h / split as f64;
    for (k, input) in inputs.iter().enumerate() {
        for part in 0..split {
            let offset = part as f64 * step;
            let t = k as f64 * h + offset;
            let part_input = Inputs {
                tau_m: input.tau_m + input.dtau_m * offset,
                ..*input
            };
            stepper
                .step(&mut state, &part_input, step, &mut |e| {
                    let e = stage_switch(e);
                    // Crossings of u = ±Δ, which change the side (a damper's force surfaces
                    // keep it; the reference locates only the gap's).
                    if e.from.side() != e.to.side() {
                        switches[e.stage].push(t + e.offset)
                    }
                })
                .unwrap();
        }
        states.push(
            (0..=S)
                .flat_map(|j| [state.body(j).theta, state.body(j).omega])
                .collect::<Vec<_>>(),
        );
    }
    (states, switches)
}

/// `step_to_first_switch`, called again from each switch with the rest of the step, takes the
/// same trajectory as `step`: the same switches, at the same instants and states to within
/// four times the chain's own round-off (measured by taking the input in half steps) plus
/// 64 ulps. At each stop the switching stages sit exactly on their flanks.
#[test]
fn stepping_from_switch_to_switch_takes_the_same_trajectory() {
    let drive = two_stage();
    let h = 1e-3;
    let steps = 300;
    let inputs: Vec<Inputs> = (0..steps).map(|k| reversing(5.0, 2.0, -2.0, k as f64 * h, h)).collect();
    let (states, switches) = chain_run::<2, 13, 14>(&drive, &inputs, h, 1);
    let (halved, _) = chain_run::<2, 13, 14>(&drive, &inputs, h, 2);

    let chain = drive.chain::<2>();
    let mut stepper = TwoStageStepper::new(chain);
    let mut state = ChainState::new(&chain, Motion::default(), [Motion::default(); 2]);
    let mut stops = vec![Vec::new(); 2];
    for (k, input) in inputs.iter().enumerate() {
        let mut done = 0.0;
        loop {
            let rest = Inputs {
                tau_m: input.tau_m + input.dtau_m * done,
                ..*input
            };
            let t = k as f64 * h + done;
            let mut events = Vec::new();
            let stop = stepper
                .step_to_first_switch(&mut state, &rest, h - done, &mut |e| events.push(stage_switch(e)))
                .unwrap();
            let Some(at) = stop else { break };
            assert!(!events.is_empty() && events.iter().all(|e| e.offset == at));
            for e in events {
                assert_eq!(state.u[e.stage].abs(), drive.delta[e.stage], "on the flank");
                stops[e.stage].push(t + at);
            }
            done += at;
        }
        let now: Vec<f64> = (0..=2)
            .flat_map(|j| [state.body(j).theta, state.body(j).omega])
            .collect();
        for i in 0..6 {
            let roundoff = (states[k][i] - halved[k][i]).abs();
            let scale = states[k][i].abs();
            assert!(
                (now[i] - states[k][i]).abs() <= 4.0 * roundoff + 64.0 * EPS * scale,
                "step {k}, component {i}: {} vs {}",
                now[i],
                states[k][i]
            );
        }
    }
    for j in 0..2 {
        assert_eq!(stops[j].len(), switches[j].len(), "stage {j}");
        assert!(!stops[j].is_empty());
        for (a, b) in stops[j].iter().zip(&switches[j]) {
            assert!((a - b).abs() <= 64.0 * EPS * steps as f64 * h, "stage {j}: {a} vs {b}");
        }
    }
}

/// Every entry of a chain state, as bits.
fn bits(s: &ChainState<2>) -> Vec<u64> {
    let bodies = (0..=2).flat_map(|j| [s.body(j).theta, s.body(j).omega]);
    let stages = s.u.iter().chain(&s.du).chain(&s.variation).copied();
    let modes = s.mode.stages().iter().map(|m| m.code() as u64);
    bodies
        .chain(stages)
        .chain([s.tension])
        .map(f64::to_bits)
        .chain(modes)
        .collect()
}

/// `ChainStepper::quiet_step` is `step`'s path through a piece certified clear: wherever it
/// takes a step it gives `step`'s state bit for bit, with no switch in the step. Over a run in
/// which a reversing torque drives both meshes across their gaps (with and without dampers) it
/// takes most steps and declines others; it declines inputs `step` refuses.
#[test]
fn the_quiet_step_is_the_steps_clear_path_bit_for_bit() {
    for drive in [
        two_stage(),
        Drive {
            d: vec![0.5, 1.0],
            ..two_stage()
        },
    ] {
        let chain = drive.chain::<2>();
        let mut stepper = TwoStageStepper::new(chain);
        let mut state = ChainState::new(&chain, Motion::default(), [Motion::default(); 2]);
        let h = 1e-3;
        let (mut taken, mut declined) = (0, 0);
        for k in 0..2000 {
            let inputs = reversing(5.0, 2.0, -2.0, k as f64 * h, h);
            let quiet = stepper.quiet_step(&state, &inputs, h);
            let mut switches = 0;
            stepper.step(&mut state, &inputs, h, &mut |_| switches += 1).unwrap();
            let Some(quiet) = quiet else {
                declined += 1;
                continue;
            };
            taken += 1;
            assert_eq!(switches, 0, "step {k}");
            assert_eq!(bits(&quiet), bits(&state), "step {k}");
        }
        assert!(taken > 1000 && declined > 10, "{taken} taken, {declined} declined");

        // Held inputs from a state it steps: the same step but for one input not finite.
        let held = Inputs::held(0.5, 0.0);
        let mut pressed = state;
        for _ in 0..10_000 {
            if stepper.quiet_step(&pressed, &held, h).is_some() {
                break;
            }
            stepper.step(&mut pressed, &held, h, &mut |_| {}).unwrap();
        }
        assert!(
            stepper.quiet_step(&pressed, &held, h).is_some(),
            "no quiet step within 10 s"
        );
        for bad in [f64::NAN, f64::INFINITY, f64::NEG_INFINITY] {
            let refused = [
                Inputs { tau_m: bad, ..held },
                Inputs { tau_l: bad, ..held },
                Inputs { dtau_m: bad, ..held },
                Inputs { dtau_l: bad, ..held },
                Inputs { span: bad, ..held },
                Inputs { dspan: bad, ..held },
            ];
            for inputs in refused {
                assert!(stepper.quiet_step(&pressed, &inputs, h).is_none(), "{inputs:?}");
                assert!(
                    stepper.step(&mut pressed.clone(), &inputs, h, &mut |_| {}).is_err(),
                    "{inputs:?}"
                );
            }
        }
    }
}

/// S = 2: docs/model.md §10's `BacklashTwoStage`.
#[test]
fn two_stages_agree_with_an_independent_integrator() {
    agrees_with_the_reference::<2, 13, 14>(&two_stage(), 10);
}

/// S = 2 with a damper in each stage, under either law (contact damping ratios near 0.16 and
/// 0.12, D = 0.5 and 1 against the critical 3.2 and 8.2): the reference takes ψ from docs/model.md §1's formula (a function of u and u′ past a
/// flank) and locates only the crossings of u = ±Δ, where law 2's force jumps; the surfaces
/// where the force reaches 0 or law 1's cap begins are kinks it steps through (RK4 loses order
/// there, which the halving estimate measures).
#[test]
fn two_damped_stages_agree_with_an_independent_integrator() {
    for law1 in [true, false] {
        let drive = Drive {
            d: vec![0.5, 1.0],
            law1,
            ..two_stage()
        };
        agrees_with_the_reference::<2, 13, 14>(&drive, 8);
        // The run goes through the damper's modes: slack, and under law 1 capped.
        let chain = drive.chain::<2>();
        let mut stepper = TwoStageStepper::new(chain);
        let mut state = ChainState::new(&chain, Motion::default(), [Motion::default(); 2]);
        let mut entered = Vec::new();
        for k in 0..1000 {
            let inputs = reversing(5.0, 2.0, -2.0, k as f64 * 1e-3, 1e-3);
            stepper
                .step(&mut state, &inputs, 1e-3, &mut |e| entered.push(stage_switch(e).to))
                .unwrap();
        }
        let slack = entered
            .iter()
            .any(|m| matches!(m, ContactMode::SlackPositive | ContactMode::SlackNegative));
        let capped = entered
            .iter()
            .any(|m| matches!(m, ContactMode::CappedPositive | ContactMode::CappedNegative));
        assert!(slack && capped == law1, "modes entered: {entered:?}");
    }
}

/// S = 3: the same code over one more stage (ChainStepper<3, 16, 20>).
#[test]
fn three_stages_agree_with_an_independent_integrator() {
    agrees_with_the_reference::<3, 16, 20>(&three_stage(), 5);
}

/// S = 3 with no gap in the middle stage: its spring acts on both sides of u = 0 (docs/model.md
/// §1, Δ = 0), the other stages switch as before.
#[test]
fn a_stage_without_gap_never_switches() {
    let mut drive = three_stage();
    drive.delta[1] = 0.0;
    agrees_with_the_reference::<3, 16, 20>(&drive, 5);
}

/// x + e^{−x} − 1 = Σ_{k≥2} (−x)^k/k! by its series: without the cancellation of the formula
/// for the small x of a short free flight.
fn free_flight(x: f64) -> f64 {
    let (mut term, mut sum) = (x * x / 2.0, 0.0);
    for k in 3..40 {
        sum += term;
        term *= -x / k as f64;
    }
    sum
}

/// Both stages free (the chain starts at rest in the middle of both gaps), constant τ_m: the
/// motor alone accelerates, ω_m = τ/b (1 − e^{−b t/J_m}), θ_m = τ J_m/b² (x + e^{−x} − 1) with
/// x = b t/J_m, and the rest stays still until u_1 = θ_m reaches Δ_1 at the instant found here
/// by Newton's method on the closed form. Agreement to 64 ulps: the chain's round-off over a few
/// tens of pieces, a few ulps each.
#[test]
fn free_motor_follows_the_closed_form_until_the_first_contact() {
    let p = two_stage();
    let (tau, j, b) = (1.0, p.j[0], p.b[0]);
    let omega = |t: f64| -tau / b * (-b * t / j).exp_m1();
    let theta = |t: f64| tau * j / (b * b) * free_flight(b * t / j);
    // Newton from the frictionless estimate: θ is convex and increasing, so it converges.
    let mut contact = (2.0 * j * p.delta[0] / tau).sqrt();
    for _ in 0..50 {
        contact -= (theta(contact) - p.delta[0]) / omega(contact);
    }
    assert!((theta(contact) - p.delta[0]).abs() <= 4.0 * EPS * p.delta[0]);

    let chain = p.chain::<2>();
    let inputs = Inputs::held(tau, 0.0);
    // Steps before the contact: the free motor on the closed form at each step end.
    let mut stepper = TwoStageStepper::new(chain);
    let mut state = ChainState::new(&chain, Motion::default(), [Motion::default(); 2]);
    let h = 0.01;
    let mut t = 0.0;
    while t + h < contact {
        let switches = stepper.step(&mut state, &inputs, h, &mut |_| {}).unwrap();
        t += h;
        assert_eq!(switches, 0);
        assert!((state.motor.omega - omega(t)).abs() <= 64.0 * EPS * omega(t), "t = {t}");
        assert!((state.motor.theta - theta(t)).abs() <= 64.0 * EPS * theta(t), "t = {t}");
        // u_1 = θ_m − n_1·0, carried alongside θ_m rather than recomputed: equal to round-off.
        assert!((state.u[0] - state.motor.theta).abs() <= 4.0 * EPS * theta(t));
    }
    // One long step to the first switch.
    let mut stepper = TwoStageStepper::new(chain);
    let mut state = ChainState::new(&chain, Motion::default(), [Motion::default(); 2]);
    let mut events = Vec::new();
    let at = stepper
        .step_to_first_switch(&mut state, &inputs, 0.1, &mut |e| events.push(stage_switch(e)))
        .unwrap()
        .expect("the motor reaches the gap's flank");
    assert!((at - contact).abs() <= 64.0 * EPS * contact, "{at} vs {contact}");
    assert_eq!(
        events,
        vec![StageSwitch {
            offset: at,
            stage: 0,
            from: ContactMode::Free,
            to: ContactMode::Positive
        }]
    );
    assert_eq!(state.u[0], p.delta[0], "u is set exactly on the flank");
    assert_eq!(*state.mode.stages(), [ContactMode::Positive, ContactMode::Free]);
    assert!((state.motor.omega - omega(contact)).abs() <= 64.0 * EPS * omega(contact));
    assert!((state.motor.theta - p.delta[0]).abs() <= 64.0 * EPS * p.delta[0]);
    for body in state.driven {
        assert_eq!(body, Motion::default(), "nothing has pushed the other bodies yet");
    }
}

/// A chain whose motor coasts against a constant torque: u_1 = v_0 t − F t²/(2 J) (no
/// friction on the motor, nothing else moving) peaks at v_0² J/(2F), just past the first gap's
/// flank by `overshoot` of it.
fn grazing_chain(overshoot: f64) -> (Chain<2>, f64, f64, f64, f64) {
    let (j, v0, force) = (2.28, 0.01, 1.0);
    let peak = v0 * v0 * j / (2.0 * force);
    let g = peak / (1.0 + overshoot);
    let p = two_stage();
    let mut params = *p.chain::<2>().params();
    params.motor = Body::new(j, 0.0);
    params.stages[0].g = g;
    (Chain::new(params).unwrap(), j, v0, force, g)
}

/// A touch that begins and ends inside one piece of one step: the teeth meet as the motor
/// comes to rest against the flank and part again. Both switches are reported, the first at
/// the closed-form instant 2g/(v_0 + √(v_0² − 2F g/J)), to 64 ulps of g over the speed there
/// (how far round-off in u moves the root), v_0 √ρ with g = peak/(1 + ρ) … 1/(1+ρ) ≈ 1 − ρ.
#[test]
fn a_graze_inside_one_step_reports_both_switches() {
    for overshoot in [1e-4, 1e-8, 1e-11] {
        let (chain, j, v0, force, g) = grazing_chain(overshoot);
        let peak_time = v0 * j / force;
        let h = 2.0 * peak_time;
        let mut stepper = TwoStageStepper::new(chain);
        // The stepper's pieces (PIECE_RATE = 0.5 over the fastest rate, docs/model.md §2).
        let pieces = (h * chain.fastest_rate() / 0.5).ceil();
        let piece = |t: f64| (t / (h / pieces)).floor();
        assert!(pieces > 1.0, "the step is cut into pieces");
        let mut state = ChainState::new(&chain, Motion { theta: 0.0, omega: v0 }, [Motion::default(); 2]);
        let mut events = Vec::new();
        let switches = stepper
            .step(&mut state, &Inputs::held(-force, 0.0), h, &mut |e| {
                events.push(stage_switch(e))
            })
            .unwrap();
        assert_eq!(switches, 2, "overshoot {overshoot}: {events:?}");
        assert_eq!(
            events.iter().map(|e| (e.stage, e.from, e.to)).collect::<Vec<_>>(),
            vec![
                (0, ContactMode::Free, ContactMode::Positive),
                (0, ContactMode::Positive, ContactMode::Free)
            ]
        );
        let speed_sq = v0 * v0 - 2.0 * force * g / j;
        let touch = 2.0 * g / (v0 + speed_sq.sqrt());
        let tol = 64.0 * EPS * (g / speed_sq.sqrt() + touch);
        assert!(
            (events[0].offset - touch).abs() <= tol,
            "{overshoot}: {} vs {touch}",
            events[0].offset
        );
        // The flank pushes back: contact ends no later than the free parabola would leave it.
        assert!(events[1].offset > events[0].offset && events[1].offset <= 2.0 * peak_time - touch + tol);
        assert_eq!(state.mode.stages()[0], ContactMode::Free);
        assert_eq!(
            piece(events[0].offset),
            piece(events[1].offset),
            "the touch is inside one piece"
        );
    }
    // Just short of the flank: no touch, no switch.
    let (chain, j, v0, force, _) = grazing_chain(-1e-8);
    let mut stepper = TwoStageStepper::new(chain);
    let mut state = ChainState::new(&chain, Motion { theta: 0.0, omega: v0 }, [Motion::default(); 2]);
    let h = 2.0 * v0 * j / force;
    assert_eq!(
        stepper.step(&mut state, &Inputs::held(-force, 0.0), h, &mut |_| {}),
        Ok(0)
    );
}

/// Two stages that reach their flanks at one instant switch together: `step_to_first_switch`
/// stops there with both modes entered, and reports both switches at that instant. Exactly
/// (a symmetric chain: the same polynomial for both u) and to round-off (the second u one ulp
/// faster).
#[test]
fn simultaneous_switches_are_entered_together() {
    let body = Body::new(1.0, 0.0);
    let stage = Stage {
        a: 1.0,
        c: 1.0,
        k: 100.0,
        g: 1e-3,
        damper: Damping::NONE,
    };
    let chain = Chain::new(ChainParams {
        motor: body,
        driven: [body; 2],
        stages: [stage; 2],
        web: None,
    })
    .unwrap();
    let w = 0.3;
    for load_speed in [-w, -w * (1.0 + EPS)] {
        let mut stepper = TwoStageStepper::new(chain);
        let start = [
            Motion::default(),
            Motion {
                theta: 0.0,
                omega: load_speed,
            },
        ];
        let mut state = ChainState::new(&chain, Motion { theta: 0.0, omega: w }, start);
        let mut events = Vec::new();
        let at = stepper
            .step_to_first_switch(&mut state, &Inputs::default(), 0.01, &mut |e| {
                events.push(stage_switch(e))
            })
            .unwrap()
            .expect("both stages close their gaps");
        assert!((at - stage.g / w).abs() <= 8.0 * EPS * at);
        assert_eq!(*state.mode.stages(), [ContactMode::Positive; 2]);
        assert_eq!(state.u, [stage.g; 2]);
        assert_eq!(
            events.iter().map(|e| (e.offset, e.stage)).collect::<Vec<_>>(),
            vec![(at, 0), (at, 1)]
        );
    }
}

/// A change that spoils one parameter.
type Spoil = fn(&mut ChainParams<2>);

fn two_stage_params() -> ChainParams<2> {
    *two_stage().chain::<2>().params()
}

/// Invalid parameters are named, with where they sit and their value.
#[test]
fn bad_parameters_are_refused() {
    let cases: [(Spoil, ChainError); 9] = [
        (
            |p| p.motor.j = 0.0,
            ChainError::NotPositive {
                at: Part::Body(0),
                name: "J",
                value: 0.0,
            },
        ),
        (
            |p| p.driven[1].b = -1.0,
            ChainError::Negative {
                at: Part::Body(2),
                name: "b",
                value: -1.0,
            },
        ),
        (
            |p| p.stages[0].k = f64::NAN,
            ChainError::NotFinite {
                at: Part::Stage(0),
                name: "K",
                value: f64::NAN,
            },
        ),
        (
            |p| p.stages[1].g = -1e-3,
            ChainError::Negative {
                at: Part::Stage(1),
                name: "g",
                value: -1e-3,
            },
        ),
        (
            |p| p.stages[1].a = 0.0,
            ChainError::NotPositive {
                at: Part::Stage(1),
                name: "a",
                value: 0.0,
            },
        ),
        (
            |p| p.stages[0].c = f64::INFINITY,
            ChainError::NotFinite {
                at: Part::Stage(0),
                name: "c",
                value: f64::INFINITY,
            },
        ),
        (
            |p| p.driven[0].j = 1e200,
            ChainError::OutOfScale {
                at: Part::Body(1),
                name: "J",
                value: 1e200,
            },
        ),
        (
            |p| p.stages[0].c = -2.0,
            ChainError::NotPositive {
                at: Part::Stage(0),
                name: "c",
                value: -2.0,
            },
        ),
        (
            |p| {
                p.stages[1].k = 1e100;
                p.driven[1].j = 1e-100;
            },
            ChainError::DerivedOutOfScale {
                at: Part::Stage(1),
                name: "K*c^2/J",
                value: 1e100 * 9.0 / 1e-100,
            },
        ),
    ];
    for (spoil, expected) in cases {
        let mut params = two_stage_params();
        spoil(&mut params);
        let err = Chain::new(params).unwrap_err();
        // NaN ≠ NaN: compare the messages, which carry the same facts.
        assert_eq!(err.to_string(), expected.to_string());
    }
    // A mode is the stages' modes without a damper: the damper's modes cannot be put in.
    for index in [0, 1, 8, 48] {
        assert_eq!(ChainMode::<2>::from_index(index).index(), index);
    }
    // Zero friction and zero gap are admissible.
    let mut params = two_stage_params();
    params.motor.b = 0.0;
    params.stages[1].g = 0.0;
    assert!(Chain::new(params).is_ok());
}

/// Bad steps are refused with the reason, the state left as it was; no panic, no NaN.
#[test]
fn bad_steps_are_refused() {
    let chain = two_stage().chain::<2>();
    let mut stepper = TwoStageStepper::new(chain);
    let start = ChainState::new(&chain, Motion { theta: 0.0, omega: 1.0 }, [Motion::default(); 2]);
    let max_h = stepper.max_step();
    let good = Inputs::held(1.0, 0.0);
    let nan_torque = Inputs::held(f64::NAN, 0.0);
    let infinite_slope = Inputs {
        dtau_l: f64::INFINITY,
        ..good
    };
    let mut bad_state = start;
    bad_state.du[1] = f64::NAN;
    let cases = [
        (start, good, f64::NAN, "BadStepSize"),
        (start, good, -1e-3, "BadStepSize"),
        (start, good, 0.0, "BadStepSize"),
        (start, good, f64::INFINITY, "BadStepSize"),
        (start, good, 2.0 * max_h, "StepTooLong"),
        (start, nan_torque, 1e-3, "NonFiniteInput"),
        (start, infinite_slope, 1e-3, "NonFiniteInput"),
        (bad_state, good, 1e-3, "NonFiniteState"),
    ];
    for (state, inputs, h, reason) in cases {
        let mut s = state;
        let err = stepper
            .step(&mut s, &inputs, h, &mut |_| panic!("no switch"))
            .unwrap_err();
        assert!(format!("{err:?}").starts_with(reason), "{h}: {err:?}");
        let err2 = stepper
            .step_to_first_switch(&mut s, &inputs, h, &mut |_| panic!("no switch"))
            .unwrap_err();
        assert_eq!(format!("{err:?}"), format!("{err2:?}"));
        assert_eq!(format!("{s:?}"), format!("{state:?}"), "the state is unchanged");
    }
    assert!(matches!(
        stepper.step(&mut start.clone(), &nan_torque, 1e-3, &mut |_| {}),
        Err(StepError::NonFiniteInput { name: "tau_m", .. })
    ));
    // A huge torque that overflows the state is refused, not returned as infinity.
    let mut s = start;
    let huge = Inputs::held(1e308, 0.0);
    assert_eq!(
        stepper.step(&mut s, &huge, 0.1 * max_h, &mut |_| {}),
        Err(StepError::Overflow)
    );
    assert_eq!(s, start);
    // And the stepper still works after the refusals.
    let mut s = start;
    assert!(stepper.step(&mut s, &good, 1e-3, &mut |_| {}).is_ok());
    assert!(s.is_finite());
}

/// The augmented dimension is a parameter only because stable Rust cannot compute 3S + 7 in a
/// type: one that does not fit S is refused at construction.
#[test]
#[should_panic(expected = "augmented dimension 10 and 14 kernel outputs for this chain: 13 and 14")]
fn an_augmented_dimension_that_does_not_fit_is_refused() {
    let _ = ChainStepper::<2, 10, 14>::new(two_stage().chain::<2>());
}

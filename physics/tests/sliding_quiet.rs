//! The quiet sliding step (`Exact::quiet_sliding_step`, docs/model.md §12): the frictionless
//! plant under torques shifted by the bearings' ∓τ_c, taken when no sliding body's speed can
//! reach 0 within the step. Checked against the chain with friction (`ChainStepper`), which
//! steps the same plant with its own matrices (friction through its constant column) and locates
//! every stop, breakaway and contact switch: on thousands of random states, speeds from 1e-5 to
//! 10 rad/s of either sign, contact and free, the quiet step is taken only where the chain
//! finds no switch in the step, and then ends where the chain ends to round-off.

use backlash_physics::chain::{Chain, ChainEvent, ChainParams, ChainState, ChainStepper, Coulomb, Motion};
mod common;

use backlash_physics::stepper::Exact;
use backlash_physics::{ContactLaw, Inputs, Plant, PlantParams, PlantState, WebSpan};

const EPS: f64 = f64::EPSILON;

/// A small generator of uniform numbers in [0, 1) (64-bit LCG, top 53 bits): the samples are
/// the same on every machine.
struct Lcg(u64);

impl Lcg {
    fn next(&mut self) -> f64 {
        self.0 = self
            .0
            .wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407);
        (self.0 >> 11) as f64 / (1u64 << 53) as f64
    }
    fn sign(&mut self) -> f64 {
        if self.next() < 0.5 {
            -1.0
        } else {
            1.0
        }
    }
    /// 10^U(lo, hi).
    fn log_uniform(&mut self, lo: f64, hi: f64) -> f64 {
        10f64.powf(lo + (hi - lo) * self.next())
    }
}

/// What the comparison found over one plant's samples.
#[derive(Debug, Default)]
struct Tally {
    samples: usize,
    /// The chain found no switch in the step.
    switch_free: usize,
    /// ... and the speeds stayed far from 0 (above 1 mrad/s, not halved), and the frictionless
    /// quiet step takes it.
    easy: usize,
    easy_taken: usize,
    taken: usize,
    /// The chain found a body's stop, breakaway or reversal in the step.
    body_switches: usize,
    /// Largest deviation of the quiet step from the chain, in ulps of the step's scale, of
    /// θ_m, θ_L, ω_m, ω_L, u, u′, T.
    worst_ulps: [f64; 7],
}

/// `samples` random states of `params` with friction `tau_c` on [motor, load], each stepped once
/// over `h` by the chain and by the quiet sliding step.
/// `KO` and `KS`: the chain's kernel outputs and the sliding stepper's.
fn compare<const N: usize, const KO: usize, const KS: usize>(
    params: PlantParams,
    tau_c: [f64; 2],
    h: f64,
    seed: u64,
) -> Tally {
    let plant = Plant::new(params).unwrap();
    let mut chain_params = ChainParams::from_plant(&plant).unwrap();
    chain_params.motor.friction = Coulomb {
        tau_c: tau_c[0],
        peak: 1.3,
    };
    chain_params.driven[0].friction = Coulomb {
        tau_c: tau_c[1],
        peak: 1.3,
    };
    let chain = Chain::new(chain_params).unwrap();
    let mut chained = ChainStepper::<1, N, KO>::new(chain);
    let mut single = Exact::<N, KS>::new(plant);
    single.prepare(h);
    let (r_m, r_l, g) = (plant.r_m(), plant.r_l(), plant.half_gap());
    // Torques that change the speeds by about 1 rad/s in 0.1 s.
    let torque = 10.0 * params.j_m;
    let mut rng = Lcg(seed);
    let mut tally = Tally::default();
    for _ in 0..2000 {
        tally.samples += 1;
        let omega_m = rng.sign() * rng.log_uniform(-5.0, 1.0);
        let omega_l = rng.sign() * rng.log_uniform(-5.0, 1.0);
        // u free, or in contact on either flank by up to ten gaps.
        let u = match (3.0 * rng.next()) as usize {
            0 => g * (2.0 * rng.next() - 1.0),
            1 => g + g * rng.log_uniform(-3.0, 1.0),
            _ => -g - g * rng.log_uniform(-3.0, 1.0),
        };
        let (theta_l, theta_m) = (0.3, (u + r_l * 0.3) / r_m);
        let tension = if params.web.is_some() { 100.0 * rng.next() } else { 0.0 };
        let held = rng.next() < 0.5;
        let slope = |rng: &mut Lcg| {
            if held {
                0.0
            } else {
                torque * 10.0 * (2.0 * rng.next() - 1.0)
            }
        };
        let inputs = Inputs {
            tau_m: torque * (2.0 * rng.next() - 1.0),
            tau_l: 0.3 * torque * (2.0 * rng.next() - 1.0),
            dtau_m: slope(&mut rng),
            dtau_l: slope(&mut rng),
            span: if params.web.is_some() {
                1e3 * (2.0 * rng.next() - 1.0)
            } else {
                0.0
            },
            dspan: 0.0,
        };
        let plant_state = PlantState::new(&plant, theta_m, omega_m, theta_l, omega_l).with_tension(tension);
        let mut state = ChainState::new(
            &chain,
            Motion {
                theta: theta_m,
                omega: omega_m,
            },
            [Motion {
                theta: theta_l,
                omega: omega_l,
            }],
        )
        .with_tension(tension);
        // Both start from the same u and u′ (the chain's are computed the same way, but take
        // no chances: the comparison is of the steps).
        state.u = [plant_state.u];
        state.du = [plant_state.du];
        let directions = [omega_m.signum(), omega_l.signum()];
        // Sliding forward, a bearing adds −τ_c (docs/model.md §12).
        let bearings = [-directions[0] * tau_c[0], -directions[1] * tau_c[1]];
        let mut switches = Vec::new();
        chained.step(&mut state, &inputs, h, &mut |e| switches.push(e)).unwrap();
        if switches.iter().any(|e| matches!(e, ChainEvent::Body(_))) {
            tally.body_switches += 1;
        }
        let quiet = single.quiet_sliding_step(&plant_state, &inputs, bearings, h);
        if switches.is_empty() {
            tally.switch_free += 1;
            // Far from 0: above 1 mrad/s, and not halved over the step.
            let far = |w0: f64, w1: f64| w0 * w1 > 0.0 && w1.abs() > 0.5 * w0.abs() && w0.abs() > 1e-3;
            // The frictionless quiet step under the shifted torques.
            let shifted = Inputs {
                tau_m: inputs.tau_m + bearings[0],
                tau_l: inputs.tau_l + bearings[1],
                ..inputs
            };
            let frictionless_clear = single.quiet_step(&plant_state, &shifted, h).is_some();
            if far(omega_m, state.motor.omega) && far(omega_l, state.driven[0].omega) && frictionless_clear {
                tally.easy += 1;
                tally.easy_taken += quiet.is_some() as usize;
            }
        }
        let Some(next) = quiet else { continue };
        tally.taken += 1;
        assert!(
            switches.is_empty(),
            "the quiet step was taken over switches {switches:?} from {plant_state:?} under {inputs:?}"
        );
        // Scales: the angles', the speeds' (at the start and the end; ω_m's also those of
        // (u′ + r_L ω_L)/r_m, which it is computed from), the tension's.
        let speed_scale = omega_m.abs() + omega_l.abs() + next.omega_m.abs() + next.omega_l.abs();
        let motor_scale =
            speed_scale + (plant_state.du.abs() + next.du.abs() + r_l * (omega_l.abs() + next.omega_l.abs())) / r_m;
        let angle_scale = theta_m.abs() + theta_l.abs() + h * speed_scale;
        let pairs = [
            (next.theta_m, state.motor.theta, angle_scale),
            (next.theta_l, state.driven[0].theta, angle_scale),
            (next.omega_m, state.motor.omega, motor_scale),
            (next.omega_l, state.driven[0].omega, speed_scale),
            (next.u, state.u[0], r_m * angle_scale + r_l * angle_scale),
            (next.du, state.du[0], r_m * speed_scale + r_l * speed_scale),
            (next.tension, state.tension, tension.abs() + next.tension.abs() + 1e-300),
        ];
        for (i, (a, b, scale)) in pairs.into_iter().enumerate() {
            let ulps = (a - b).abs() / (EPS * scale);
            assert!(
                ulps <= TOLERANCE,
                "quantity {i}: {a} against the chain's {b}, {ulps} ulps of {scale} from {plant_state:?}"
            );
            tally.worst_ulps[i] = tally.worst_ulps[i].max(ulps);
        }
    }
    tally
}

/// Deviation allowed from the chain over one step, in ulps of each quantity's scale: both are
/// exact to round-off, through different matrices (the chain's composed per stage, friction in
/// its constant column; the single gap's, friction shifting the torques). Measured on linux64:
/// 0.9 ulps at most on the shaft, 26 on the web line (ω_m: its light motor, J_m = 1e-4, makes the
/// stiffest matrices here); over twice that leaves room for another platform's rounding in the
/// matrix exponentials.
const TOLERANCE: f64 = 64.0;

fn check(name: &str, tally: Tally) {
    eprintln!("{name}: {tally:?}");
    // The samples reach both verdicts: steps with a stop, breakaway or reversal (which the quiet
    // step must refuse, asserted in `compare`) and steps it takes.
    assert!(tally.body_switches > 100, "{name}: too few friction switches sampled");
    assert!(tally.taken > 500, "{name}: too few quiet steps taken");
    // And the speeds' certificate is not needlessly cautious: where the speeds stay far from 0
    // and the frictionless quiet step would take the step, it takes 99% of them (measured: every
    // one on the shaft; on the web line with law 1, 413 of 416, speeds of a few mrad/s changing by
    // tenfold within the step, which the quadratic's error term does not clear).
    assert!(
        tally.easy_taken as f64 >= 0.99 * tally.easy as f64,
        "{name}: {} of {} easy steps taken",
        tally.easy_taken,
        tally.easy
    );
}

#[test]
fn the_quiet_sliding_step_agrees_with_the_chain_on_the_shaft() {
    let rig = PlantParams::paper_rig(1e-3);
    for (i, tau_c) in [[0.3, 0.2], [0.3, 0.0], [0.0, 0.2]].into_iter().enumerate() {
        for h in [1e-3, 1e-4] {
            let seed = 17 + i as u64;
            check(
                &format!("shaft {tau_c:?} h {h}"),
                compare::<10, 8, 12>(rig, tau_c, h, seed),
            );
        }
    }
    for law in [ContactLaw::ElastoBacklash, ContactLaw::ElastoBacklash2] {
        let params = common::with_damper(rig, law, 0.05);
        check(
            &format!("shaft {law:?}"),
            compare::<10, 8, 12>(params, [0.3, 0.2], 1e-3, 5),
        );
    }
}

#[test]
fn the_quiet_sliding_step_agrees_with_the_chain_on_the_web_line() {
    let belt = PlantParams {
        web: Some(WebSpan {
            r_w: 0.05,
            l_w: 1.0,
            ea: 1e5,
            v_ref: 2.0,
        }),
        ..common::servo_belt()
    };
    check("web", compare::<13, 10, 14>(belt, [1e-3, 2e-3], 1e-4, 3));
    let params = common::with_damper(belt, ContactLaw::ElastoBacklash, 0.3);
    check("web, law 1", compare::<13, 10, 14>(params, [1e-3, 2e-3], 1e-4, 4));
}

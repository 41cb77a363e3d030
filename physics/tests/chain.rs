//! The chain of stages (physics/src/chain) against the single-gap stepper, an independent
//! integrator of ../shared/spec/model.md §11, a closed form, a graze and its refusals.

use backlash_physics::chain::{
    Body, Chain, ChainError, ChainParams, ChainState, Motion, OneStageStepper, Part, Stage, StageSwitch,
    TwoStageStepper,
};
use backlash_physics::{ContactMode, Damping, Geometry, Inputs, Plant, PlantParams, PlantState, StepError, Stepper};

const EPS: f64 = f64::EPSILON;

/// A reversing motor torque A sin(2π f t), sampled at the step starts and held to first order
/// over the step (the slope to the next sample): a piecewise-linear input both steppers take
/// exactly.
fn reversing(amplitude: f64, frequency: f64, t: f64, h: f64) -> Inputs {
    let tau = |t: f64| amplitude * (2.0 * std::f64::consts::PI * frequency * t).sin();
    let (a, b) = (tau(t), tau(t + h));
    Inputs {
        dtau_m: (b - a) / h,
        ..Inputs::held(a, 0.0)
    }
}

/// The paper's rig (docs/model.md §4) and a small servo belt drive with a gap.
fn plants() -> [PlantParams; 2] {
    let belt = PlantParams {
        j_m: 1e-4,
        j_l: 5e-3,
        b_m: 1e-4,
        b_l: 1e-3,
        geometry: Geometry::Belt {
            k_b: 2e5,
            r_1: 0.02,
            r_2: 0.04,
            r_g1: 0.015,
            r_g2: 0.045,
            delta: 5e-5,
        },
        damping: Damping::NONE,
        web: None,
    };
    [PlantParams::paper_rig(1e-3), belt]
}

/// S = 1 and the single-gap stepper (physics::Stepper) are two computations of one trajectory
/// (the same augmented layout, but matrices composed differently, so their entries differ in
/// the last bits): over many steps with a reversing torque that drives the motor across the
/// gap again and again, the states and the switch instants agree to a few hundred ulps of each
/// quantity's magnitude over the run (u′'s: that of r_m|ω_m| + r_L|ω_L|, of which it is the
/// difference), and the switches are the same. A few hundred: an ulp of a matrix entry per
/// piece, accumulated over thousands of pieces, and amplified where b_m/J_m − b_L/J_L cancels.
#[test]
fn one_stage_agrees_with_the_single_gap_stepper() {
    for params in plants() {
        let plant = Plant::new(params).unwrap();
        let chain = Chain::new(ChainParams::from_plant(&plant).unwrap()).unwrap();
        let mut reference = Stepper::new(plant);
        let mut stepper = OneStageStepper::new(chain);
        let mut a = PlantState::new(&plant, 0.0, 0.0, 0.0, 0.0);
        let mut b = ChainState::new(&chain, Motion::default(), [Motion::default()]);
        // Torque: enough to cross the gap and load the member; period: many contact periods.
        let omega0 = plant.contact_frequency();
        let amplitude = 20.0 * plant.stiffness() * plant.half_gap() / plant.r_m();
        let frequency = omega0 / (2.0 * std::f64::consts::PI) / 10.0;
        let h = 0.3 / omega0;
        let (mut switches_a, mut switches_b) = (Vec::new(), Vec::new());
        // Magnitudes over the run: θ_m, ω_m, θ_L, ω_L, u, u′; and the worst deviation in each.
        let mut scale = [0.0f64; 6];
        let mut worst = [0.0f64; 6];
        let mut worst_t = 0.0f64;
        for k in 0..4000 {
            let t = k as f64 * h;
            let inputs = reversing(amplitude, frequency, t, h);
            reference
                .step(&mut a, &inputs, h, &mut |e| {
                    switches_a.push((t + e.offset, e.from, e.to))
                })
                .unwrap();
            stepper
                .step(&mut b, &inputs, h, &mut |e: StageSwitch| {
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
            // u′ = r_m ω_m − r_L ω_L is a difference: its scale is that of the terms (so is the
            // scale of its rate, whose friction terms b/J nearly cancel on the paper's rig).
            let relative = plant.r_m() * a.omega_m.abs() + plant.r_l() * a.omega_l.abs();
            let magnitude = [
                pa[0].abs(),
                pa[1].abs(),
                pa[2].abs(),
                pa[3].abs(),
                pa[4].abs(),
                relative,
            ];
            for i in 0..6 {
                scale[i] = scale[i].max(magnitude[i]);
                worst[i] = worst[i].max((pa[i] - pb[i]).abs());
            }
            assert_eq!(a.mode, b.mode.stages[0], "step {k}");
        }
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
        let t_end = 4000.0 * h;
        eprintln!(
            "{} switches; worst deviation in ulps of the scale: {ulps:?}; switch times {:.1} ulps of the run",
            switches_a.len(),
            worst_t / (EPS * t_end)
        );
        for (i, u) in ulps.iter().enumerate() {
            assert!(*u <= 512.0, "component {i}: {u} ulps");
        }
        assert!(worst_t <= 512.0 * EPS * t_end);
    }
}

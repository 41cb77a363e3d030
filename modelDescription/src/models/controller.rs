//! BacklashController: the sampled speed PI of the paper's experiments and the web line's tension
//! PI (docs/model.md §3, §8), with the speed references of the experiments, as a Co-Simulation
//! model that closes the loop around a drive in a co-simulation master (docs/model.md §9).
//!
//! Its sampling: at each communication point t_k (fmi2DoStep(t_k, h)) it reads `omega_m` and
//! `T` as set for t_k, computes u_k (physics crate, `controller`), and outputs u_k from the end
//! of that step on; over [t_k, t_k + h) it holds u_(k-1), and `tau_m`'s start value before the
//! first sample. So `tau_m` depends on no input at the same instant (no direct feedthrough, no
//! algebraic loop), and every master that passes values after each step, in any order, gives the
//! same run: the drive sees the torque one sample late, as behind a controller that computes
//! during the step. Its time is its own count of samples times `h`, not the master's clock.

use backlash_physics::Reference;

use super::{parameter, pi_gains, quantity_input, var};
use crate::{Causality, DefaultExperiment, Initial, Kind, Model, Range, SquareWave, Type, Variability};

/// The defaults are the paper's sine experiment on BacklashShaft's defaults (systems/sine): the
/// gains of the design answer for the paper's rig (`backlash design --accuracy 0.02`, the
/// best-damped PI) and the reversing sine of 0.05 at the mean natural frequency of its closed-loop
/// poles; tests/python/test_masters.py checks them against the design answer.
const PAPER_RIG_KP: f64 = 42.70304505387717;
const PAPER_RIG_KI: f64 = 179.2424837177854;
const PAPER_RIG_FREQUENCY: f64 = 1.4103246998179486;

pub(super) fn model() -> Model {
    use Range::*;
    let [kp, ki] = pi_gains();
    let mut v = vec![
        quantity_input(
            "omega_m",
            "MeasuredSpeed",
            1,
            "rad/s",
            "AngularVelocity",
            "Measured motor speed, sampled at each communication point",
        ),
        quantity_input(
            "T",
            "MeasuredTension",
            2,
            "N",
            "Force",
            "Measured web tension, sampled at each communication point (read by the tension loop only: Kp_T = Ki_T = 0 turns it off)",
        ),
        var(
            "tau_m",
            "TorqueCommand",
            3,
            Type::Real,
            Causality::Output,
            Variability::Discrete,
            Initial::Exact,
            Some(0.0),
            Finite,
            "N.m",
            "Torque",
            "Motor torque u_k = Kp*e_k + Ki*x_c of the sample at the start of the last step, held until the end of the next one; its start value is held until the first step ends",
        ),
        crate::Var {
            vr: 4,
            start: Some(PAPER_RIG_KP),
            description: "Proportional gain of the speed PI",
            ..kp
        },
        crate::Var {
            vr: 5,
            start: Some(PAPER_RIG_KI),
            description: "Integral gain of the speed PI",
            ..ki
        },
        parameter(
            "Kp_T",
            "KpT",
            6,
            0.0,
            Finite,
            "rad/(s.N)",
            "",
            "Proportional gain of the tension PI that trims the speed reference (0 with Ki_T = 0: no tension loop)",
        ),
        parameter(
            "Ki_T",
            "KiT",
            7,
            0.0,
            Finite,
            "rad/(s2.N)",
            "",
            "Integral gain of the tension PI",
        ),
        parameter("T_ref", "TRef", 8, 0.0, Finite, "N", "Force", "Tension set point"),
        parameter(
            "h",
            "SamplePeriod",
            9,
            1e-3,
            Positive,
            "s",
            "Time",
            "Sample period (> 0): every communication step must be this long (to 1e-9 relative); the references and the integrators count samples of it",
        ),
        var(
            "reference",
            "ReferenceKind",
            10,
            Type::Integer,
            Causality::Parameter,
            Variability::Fixed,
            Initial::Exact,
            Some(Reference::SINE as f64),
            Integers {
                min: Reference::STEP,
                max: Reference::SINE,
            },
            "",
            "",
            "Speed reference r(t), t the time since the start: 1 step (amplitude from t = 0), 2 trapezoid (up in t_ramp, held t_hold, down in t_ramp), 3 sine (amplitude*sin(2*pi*frequency*t))",
        ),
        parameter(
            "amplitude",
            "Amplitude",
            11,
            0.05,
            Finite,
            "rad/s",
            "AngularVelocity",
            "Amplitude of the speed reference",
        ),
        parameter(
            "frequency",
            "Frequency",
            12,
            PAPER_RIG_FREQUENCY,
            NonNegative,
            "Hz",
            "Frequency",
            "Frequency of the sine reference (>= 0)",
        ),
        parameter(
            "t_ramp",
            "RampTime",
            13,
            1.0,
            Positive,
            "s",
            "Time",
            "Rise and fall time of the trapezoid reference (> 0)",
        ),
        parameter(
            "t_hold",
            "HoldTime",
            14,
            2.0,
            NonNegative,
            "s",
            "Time",
            "Time the trapezoid reference holds its amplitude (>= 0)",
        ),
    ];
    v.sort_by_key(|v| v.vr);
    Model {
        identifier: "BacklashController",
        kind: Kind::Controller,
        description: "Sampled speed PI (and web tension PI) with the paper's speed references, to close the loop around BacklashShaft, BacklashBelt or BacklashWeb in a co-simulation master; Co-Simulation only; defaults are the paper's sine experiment",
        default_experiment: DefaultExperiment {
            start_time: 0.0,
            stop_time: 8.0,
            step_size: 1e-3,
        },
        // The measured speed steps between +-0.02 every half second, against the sine reference.
        reference_inputs: &[SquareWave {
            input: "omega_m",
            level: 0.0,
            amplitude: 0.02,
            half_period: 500,
        }],
        variables: v,
    }
}

//! BacklashShaft: a compliant shaft and gear backlash in series (the paper's Fig. 5/6, eqs.
//! 11–12); its defaults are the paper's rig (docs/model.md §4).

use backlash_physics::{Geometry, PlantParams};

use super::Transmission;
use super::{
    common_head, damper_variables, drive_train, event_indicators, friction_variables, parameter, pi_gains,
    state_derivatives, with_state_nominals, ModelDef,
};
use crate::{DefaultExperiment, Kind, Model, Range, SquareWave};

pub(super) const MODEL: ModelDef = ModelDef {
    describe: model,
    kind: Kind::Plant(plant_params),
};

/// The shaft's plant (paper eqs. 11–12): r_m = r_L = 1, K = k, g = Delta, D = d
/// (docs/model.md §1).
fn plant_params(at: &dyn Fn(&str) -> f64) -> PlantParams {
    let geometry = Geometry::Shaft {
        k: at("k"),
        delta: at("Delta"),
    };
    drive_train(at, geometry, &SHAFT)
}

/// u = theta_m - theta_L is an angle; psi is the shaft's torque; d damps the shaft's twist.
const SHAFT: Transmission = Transmission {
    coordinate_unit: "rad",
    psi_unit: "N.m",
    psi_quantity: "Torque",
    psi_description: "Torque psi carried by the compliant shaft: k*dz(theta_m - theta_L, Delta), and with a damper (d > 0) the damped torque clipped by contact_law so that it never pulls",
    damping_name: "d",
    damping_symbol: "D",
    damping_unit: "N.m.s/rad",
    damping_quantity: "RotationalDampingConstant",
    damping_description: "Shaft damping, in parallel with its stiffness k (>= 0; 0: no damper)",
};

/// The shaft's default experiment.
pub(super) const EXPERIMENT: DefaultExperiment = DefaultExperiment {
    start_time: 0.0,
    stop_time: 10.0,
    step_size: 1e-2,
};

/// The inputs of its reference experiment: the motor torque reverses every second, so the motor
/// crosses the gap and takes up the other flank again and again; a load torque from t = 5 s.
pub(super) const REFERENCE_INPUTS: &[SquareWave] = &[
    SquareWave {
        input: "tau_m",
        level: 0.0,
        amplitude: 3.0,
        half_period: 100,
    },
    SquareWave {
        input: "tau_L",
        level: -0.25,
        amplitude: 0.25,
        half_period: 500,
    },
];

fn model() -> Model {
    use Range::*;
    let mut v = common_head(&SHAFT);
    v.extend([
        parameter(
            "J_m",
            "JM",
            12,
            2.28,
            Positive,
            "kg.m2",
            "MomentOfInertia",
            "Motor inertia (> 0)",
        ),
        parameter(
            "J_L",
            "JL",
            13,
            2.55,
            Positive,
            "kg.m2",
            "MomentOfInertia",
            "Load inertia (> 0)",
        ),
        parameter(
            "b_m",
            "BM",
            14,
            0.05,
            NonNegative,
            "N.m.s/rad",
            "RotationalDampingConstant",
            "Motor viscous friction (>= 0)",
        ),
        parameter(
            "b_L",
            "BL",
            15,
            0.05,
            NonNegative,
            "N.m.s/rad",
            "RotationalDampingConstant",
            "Load viscous friction (>= 0)",
        ),
        parameter(
            "Delta",
            "Delta",
            16,
            0.775e-3,
            NonNegative,
            "rad",
            "Angle",
            "Half backlash gap (>= 0): total free play is 2*Delta; default is half the paper's 1.55 mm gap",
        ),
    ]);
    v.extend(pi_gains());
    v.extend([parameter(
        "k",
        "K",
        19,
        200.0,
        Positive,
        "N.m/rad",
        "RotationalSpringConstant",
        "Shaft stiffness (> 0)",
    )]);
    let derivatives = state_derivatives(&v);
    v.extend(derivatives);
    v.extend(event_indicators(&SHAFT));
    v.extend(damper_variables(&SHAFT));
    v.extend(friction_variables());
    with_state_nominals(Model {
        identifier: "BacklashShaft",
        kind: Kind::Plant(plant_params),
        description: "Compliant shaft and gear backlash in series (paper Fig. 5, eqs. 11-12), exact stepping with located contact switches; defaults are the paper's rig",
        default_experiment: EXPERIMENT,
        reference_inputs: REFERENCE_INPUTS,
        variables: v,
    })
}

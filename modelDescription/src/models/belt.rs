//! BacklashBelt: a belt–pulley drive and gear backlash in series (the paper's Fig. 7, eqs.
//! 20–21), a small servo drive; its drive train is also BacklashWeb's.

use backlash_physics::{Geometry, PlantParams};

use super::Transmission;
use super::{
    common_head, drive_train, event_indicators, parameter, pi_gains, state_derivatives, with_state_nominals, ModelDef,
};
use crate::{DefaultExperiment, Kind, Model, Range, SquareWave, Var};

pub(super) const MODEL: ModelDef = ModelDef {
    describe: model,
    kind: Kind::Plant(plant_params),
};

/// The belt drive's plant (paper eqs. 20–21): r_m = R_1, r_L = alpha_1, K = K_b,
/// g = alpha_2 Delta, D = D_b (docs/model.md §1); also the drive of BacklashWeb.
pub(super) fn plant_params(at: &dyn Fn(&str) -> f64) -> PlantParams {
    let geometry = Geometry::Belt {
        k_b: at("K_b"),
        r_1: at("R_1"),
        r_2: at("R_2"),
        r_g1: at("R_g1"),
        r_g2: at("R_g2"),
        delta: at("Delta"),
    };
    drive_train(at, geometry, &BELT)
}

/// u = R_1 theta_m - alpha_1 theta_L is a length on the belt; psi is the belt's force.
const BELT: Transmission = Transmission {
    coordinate_unit: "m",
    psi_unit: "N",
    psi_quantity: "Force",
    psi_description: "Belt force psi = K_b*dz(R_1*theta_m - alpha_1*theta_L, alpha_2*Delta), alpha_1 = R_2*R_g2/R_g1, alpha_2 = R_2/R_g1; with a damper (D_b > 0) the damped force clipped by contact_law so that it never pulls",
    damping_name: "D_b",
    damping_symbol: "DB",
    damping_unit: "N.s/m",
    damping_quantity: "TranslationalDampingConstant",
    damping_description: "Belt damping, in parallel with its stiffness K_b (>= 0; 0: no damper)",
};

fn model() -> Model {
    with_state_nominals(Model {
        identifier: "BacklashBelt",
        kind: Kind::Plant(plant_params),
        description: "Belt-pulley drive and gear backlash in series (paper Fig. 7, eqs. 20-21), exact stepping with located contact switches",
        default_experiment: DefaultExperiment {
            start_time: 0.0,
            stop_time: 0.2,
            step_size: 1e-4,
        },
        // The motor torque reverses every 25 ms; a load torque from t = 0.1 s.
        reference_inputs: &[
            SquareWave { input: "tau_m", level: 0.0, amplitude: 0.02, half_period: 250 },
            SquareWave { input: "tau_L", level: -0.005, amplitude: 0.005, half_period: 1000 },
        ],
        variables: belt_variables()
            .into_iter()
            .chain(damper_variables())
            .chain(super::friction_variables())
            .collect(),
    })
}

/// The belt's damper and its event indicators (value references 42–47), after every other
/// variable of BacklashBelt and of the web line.
pub(super) fn damper_variables() -> [Var; 6] {
    super::damper_variables(&BELT)
}

/// The belt drive's variables (value references 1–29), of BacklashBelt and of the web line's
/// drive.
pub(super) fn belt_variables() -> Vec<Var> {
    use Range::*;
    let mut v = common_head(&BELT);
    // A small servo belt drive: 2:1 belt (R_2/R_1), 3:1 gear (R_g2/R_g1), 6:1 overall;
    // belt-gear natural frequency about 190 Hz, half gap 50 um on the pitch circle.
    v.extend([
        parameter(
            "J_m",
            "JM",
            12,
            1e-4,
            Positive,
            "kg.m2",
            "MomentOfInertia",
            "Motor inertia including the motor pulley (> 0)",
        ),
        parameter(
            "J_L",
            "JL",
            13,
            5e-3,
            Positive,
            "kg.m2",
            "MomentOfInertia",
            "Load inertia including gear 2 (> 0)",
        ),
        parameter(
            "b_m",
            "BM",
            14,
            1e-4,
            NonNegative,
            "N.m.s/rad",
            "RotationalDampingConstant",
            "Motor viscous friction (>= 0)",
        ),
        parameter(
            "b_L",
            "BL",
            15,
            1e-3,
            NonNegative,
            "N.m.s/rad",
            "RotationalDampingConstant",
            "Load viscous friction (>= 0)",
        ),
        parameter(
            "Delta",
            "Delta",
            16,
            5e-5,
            NonNegative,
            "m",
            "Length",
            "Half backlash gap on the pitch circle of the gears (>= 0): total free play is 2*Delta",
        ),
    ]);
    v.extend(pi_gains());
    v.extend([
        parameter(
            "K_b",
            "KB",
            19,
            2e5,
            Positive,
            "N/m",
            "TranslationalSpringConstant",
            "Belt stiffness (> 0)",
        ),
        parameter(
            "R_1",
            "R1",
            20,
            0.02,
            Positive,
            "m",
            "Length",
            "Radius of the motor pulley (> 0)",
        ),
        parameter(
            "R_2",
            "R2",
            21,
            0.04,
            Positive,
            "m",
            "Length",
            "Radius of the driven pulley (> 0)",
        ),
        parameter(
            "R_g1",
            "Rg1",
            22,
            0.015,
            Positive,
            "m",
            "Length",
            "Pitch radius of gear 1, on the driven pulley's shaft (> 0)",
        ),
        parameter(
            "R_g2",
            "Rg2",
            23,
            0.045,
            Positive,
            "m",
            "Length",
            "Pitch radius of gear 2, on the load (> 0)",
        ),
    ]);
    let derivatives = state_derivatives(&v);
    v.extend(derivatives);
    v.extend(event_indicators(&BELT));
    v
}

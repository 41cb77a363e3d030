//! BacklashShaft: a compliant shaft and gear backlash in series (the paper's Fig. 5/6, eqs.
//! 11–12); its defaults are the paper's rig (docs/model.md §4).

use super::{common_head, event_indicators, parameter, pi_gains, state_derivatives};
use crate::{DefaultExperiment, DriveTrain, Model, Range};

pub(super) fn model() -> Model {
    use Range::*;
    // θ nominal g/r = Delta, ω nominal ω₀·Delta with ω₀ = sqrt(k (1/J_m + 1/J_L)).
    let mut v = common_head(
        DriveTrain::Shaft,
        [0.000775, 0.009989707035044964, 0.000775, 0.009989707035044964],
    );
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
    v.extend(event_indicators(DriveTrain::Shaft));
    Model {
        identifier: "BacklashShaft",
        drive_train: DriveTrain::Shaft,
        description: "Compliant shaft and gear backlash in series (paper Fig. 5, eqs. 11-12), exact stepping with located contact switches; defaults are the paper's rig",
        default_experiment: DefaultExperiment {
            start_time: 0.0,
            stop_time: 10.0,
            step_size: 1e-2,
        },
        variables: v,
    }
}

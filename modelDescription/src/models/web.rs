//! BacklashWeb: BacklashBelt's drive whose load roller pulls one web span (the paper's future
//! work; docs/model.md §8).

use backlash_physics::{PlantParams, WebSpan};

use super::belt::{self, belt_variables, damper_variables};
use super::{
    calculated_output, parameter, quantity_input, state_derivative, state_output, supremum, with_state_nominals,
    ModelDef,
};
use crate::{DefaultExperiment, Kind, Model, Range, SquareWave, Var};

pub(super) const MODEL: ModelDef = ModelDef {
    describe: model,
    kind: Kind::Plant(plant_params),
};

/// BacklashBelt's plant, its damper included, whose load pulls the web span (docs/model.md §8).
fn plant_params(at: &dyn Fn(&str) -> f64) -> PlantParams {
    PlantParams {
        web: Some(WebSpan {
            r_w: at("R_w"),
            l_w: at("L_w"),
            ea: at("EA"),
            v_ref: at("v_ref"),
        }),
        ..belt::plant_params(at)
    }
}

fn model() -> Model {
    with_state_nominals(Model {
        identifier: "BacklashWeb",
        kind: Kind::Plant(plant_params),
        description: "BacklashBelt's drive whose load roller pulls one web span (the paper's future work): span tension T as a fifth state, bounds on load speed and tension, exact stepping with located contact switches",
        default_experiment: DefaultExperiment {
            start_time: 0.0,
            stop_time: 1.0,
            step_size: 1e-4,
        },
        // A constant motor torque against the web entering under a constant tension: the span
        // oscillates, and the drive crosses the gap with it, without reversals of the torque,
        // which would rattle the drive through the gap and make the run's end hang on the
        // last bits of its start (a difference of 1e-12 in the inputs grows to 1e-9 or less
        // here, to 1e-1 with a reversing torque).
        reference_inputs: &[
            SquareWave { input: "tau_m", level: 0.02, amplitude: 0.0, half_period: 10_000 },
            SquareWave { input: "T_in", level: 50.0, amplitude: 0.0, half_period: 10_000 },
        ],
        variables: web_variables(),
    })
}

/// BacklashWeb: the belt drive's variables, then the web span's (value references 30–41,
/// docs/model.md §8), then the belt's damper (42–47). Its defaults are BacklashBelt's drive pulling a film line: 50 mm roller,
/// 1 m span, EA = 1e5 N (e.g. 50 µm PET, 0.5 m wide), 2 m/s.
fn web_variables() -> Vec<Var> {
    use Range::*;
    let mut v = belt_variables();
    let tension = state_output(
        "T",
        "Tension",
        32,
        "N",
        "Force",
        "Web span tension; its start value is the initial state",
    );
    let der_tension = state_derivative("der(T)", "DerTension", 33, &tension, "N/s", "");
    v.extend([
        quantity_input(
            "v_in",
            "VIn",
            30,
            "m/s",
            "Velocity",
            "Web speed entering the span upstream, held over each communication step, or along a line where input derivatives are set",
        ),
        quantity_input(
            "T_in",
            "TIn",
            31,
            "N",
            "Force",
            "Web tension upstream of the span, held over each communication step, or along a line where input derivatives are set",
        ),
        tension,
        der_tension,
        calculated_output(
            "bound_T",
            "BoundT",
            34,
            "N",
            "Force",
            "Rigorous bound on |T with backlash - T without backlash| since the start time: K*g*integral of |h_T|",
        ),
        supremum(
            "bound_T_sup",
            "BoundTSup",
            35,
            "N",
            "Force",
            "Supremum of bound_T over all times: K*g*integral of |h_T| to infinity; +inf (with a warning) if the loop is not asymptotically stable",
        ),
        parameter(
            "R_w",
            "Rw",
            36,
            0.05,
            Positive,
            "m",
            "Length",
            "Radius of the load roller that pulls the web (> 0)",
        ),
        parameter("L_w", "Lw", 37, 1.0, Positive, "m", "Length", "Length of the web span (> 0)"),
        parameter(
            "EA",
            "EA",
            38,
            1e5,
            Positive,
            "N",
            "Force",
            "Web stiffness: Young's modulus times cross-section (> 0)",
        ),
        parameter(
            "v_ref",
            "VRef",
            39,
            2.0,
            Positive,
            "m/s",
            "Velocity",
            "Web speed at which the span's transport term is linearized (> 0)",
        ),
        parameter(
            "Kp_T",
            "KpT",
            40,
            0.0,
            Finite,
            "rad/(s.N)",
            "",
            "Proportional gain of the outer tension PI, which trims the speed reference by Kp_T*(T_ref - T) + Ki_T*integral(T_ref - T); used by the bounds only (Kp_T = Ki_T = 0: no tension loop)",
        ),
        parameter(
            "Ki_T",
            "KiT",
            41,
            0.0,
            Finite,
            "rad/(s2.N)",
            "",
            "Integral gain of the outer tension PI; used by the bounds only",
        ),
    ]);
    v.extend(damper_variables());
    v.extend(super::friction_variables());
    v
}

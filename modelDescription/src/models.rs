//! The models' variable tables: value references, kinds, start values, units and texts
//! (docs/model.md §4; the defaults of BacklashShaft are the paper's rig).

use crate::{
    model_identifiers, Causality, DefaultExperiment, DriveTrain, Initial, Model, Range, Type, Var, Variability,
};

#[allow(clippy::too_many_arguments)]
const fn var(
    name: &'static str,
    symbol: &'static str,
    vr: u32,
    ty: Type,
    causality: Causality,
    variability: Variability,
    initial: Initial,
    start: Option<f64>,
    range: Range,
    unit: &'static str,
    quantity: &'static str,
    description: &'static str,
) -> Var {
    Var {
        name,
        symbol,
        vr,
        ty,
        causality,
        variability,
        initial,
        start,
        range,
        unit,
        quantity,
        description,
        nominal: None,
        derivative_of: None,
    }
}

fn input(name: &'static str, symbol: &'static str, vr: u32, description: &'static str) -> Var {
    quantity_input(name, symbol, vr, "N.m", "Torque", description)
}

fn quantity_input(
    name: &'static str,
    symbol: &'static str,
    vr: u32,
    unit: &'static str,
    quantity: &'static str,
    description: &'static str,
) -> Var {
    use Causality::*;
    var(
        name,
        symbol,
        vr,
        Type::Real,
        Input,
        Variability::Continuous,
        Initial::Unset,
        Some(0.0),
        Range::Finite,
        unit,
        quantity,
        description,
    )
}

fn state_output(
    name: &'static str,
    symbol: &'static str,
    vr: u32,
    unit: &'static str,
    quantity: &'static str,
    nominal: f64,
    description: &'static str,
) -> Var {
    use Causality::*;
    let state = var(
        name,
        symbol,
        vr,
        Type::Real,
        Output,
        Variability::Continuous,
        Initial::Exact,
        Some(0.0),
        Range::Finite,
        unit,
        quantity,
        description,
    );
    Var {
        nominal: Some(nominal),
        ..state
    }
}

#[allow(clippy::too_many_arguments)]
fn parameter(
    name: &'static str,
    symbol: &'static str,
    vr: u32,
    start: f64,
    range: Range,
    unit: &'static str,
    quantity: &'static str,
    description: &'static str,
) -> Var {
    use Causality::*;
    var(
        name,
        symbol,
        vr,
        Type::Real,
        Parameter,
        Variability::Fixed,
        Initial::Exact,
        Some(start),
        range,
        unit,
        quantity,
        description,
    )
}

/// Value references are unique across types, so a reference alone names a variable.
/// The PI gains (value references 17 and 18), the same in every model: they parameterize
/// the bounds only.
fn pi_gains() -> [Var; 2] {
    [
        parameter(
            "Kp",
            "Kp",
            17,
            0.0,
            Range::Finite,
            "N.m.s/rad",
            "",
            "Proportional gain of the PI loop on omega_m used by the bounds only (0 with Ki = 0: open loop)",
        ),
        parameter(
            "Ki",
            "Ki",
            18,
            0.0,
            Range::Finite,
            "N.m/rad",
            "",
            "Integral gain of the PI loop on omega_m used by the bounds only",
        ),
    ]
}

/// The time derivative `der(x)` of the continuous state `x` (Model Exchange, docs/model.md §6).
fn state_derivative(
    name: &'static str,
    symbol: &'static str,
    vr: u32,
    of: &Var,
    unit: &'static str,
    quantity: &'static str,
) -> Var {
    Var {
        derivative_of: Some(of.vr),
        ..continuous_local(
            name,
            symbol,
            vr,
            unit,
            quantity,
            "Time derivative of the continuous state (Model Exchange); a pure function of the state and the inputs",
        )
    }
}

/// A local Real computed from the state and the inputs (Model Exchange's derivatives and event
/// indicators).
fn continuous_local(
    name: &'static str,
    symbol: &'static str,
    vr: u32,
    unit: &'static str,
    quantity: &'static str,
    description: &'static str,
) -> Var {
    var(
        name,
        symbol,
        vr,
        Type::Real,
        Causality::Local,
        Variability::Continuous,
        Initial::Calculated,
        None,
        Range::Finite,
        unit,
        quantity,
        description,
    )
}

/// The event indicators u − g and u + g as variables, value references 28 and 29 in every model
/// (FMI 3.0 lists event indicators by value reference; FMI 2.0 importers see two locals).
fn event_indicators(drive_train: DriveTrain) -> [Var; 2] {
    let unit = match drive_train {
        DriveTrain::Shaft => "rad",
        DriveTrain::Belt | DriveTrain::Web => "m",
    };
    let indicator = |name, symbol, vr, description| continuous_local(name, symbol, vr, unit, "", description);
    [
        indicator(
            "u_minus_g",
            "UMinusG",
            28,
            "Event indicator u - g (u = r_m*theta_m - r_L*theta_L): positive in contact on the positive flank",
        ),
        indicator(
            "u_plus_g",
            "UPlusG",
            29,
            "Event indicator u + g: negative in contact on the negative flank",
        ),
    ]
}

/// `der(theta_m)` … `der(omega_L)`, value references 24–27 in every model, after the state
/// outputs of `v`.
fn state_derivatives(v: &[Var]) -> [Var; 4] {
    let state = |name: &str| v.iter().find(|w| w.name == name).expect("the state outputs come first");
    [
        state_derivative(
            "der(theta_m)",
            "DerThetaM",
            24,
            state("theta_m"),
            "rad/s",
            "AngularVelocity",
        ),
        state_derivative(
            "der(omega_m)",
            "DerOmegaM",
            25,
            state("omega_m"),
            "rad/s2",
            "AngularAcceleration",
        ),
        state_derivative(
            "der(theta_L)",
            "DerThetaL",
            26,
            state("theta_L"),
            "rad/s",
            "AngularVelocity",
        ),
        state_derivative(
            "der(omega_L)",
            "DerOmegaL",
            27,
            state("omega_L"),
            "rad/s2",
            "AngularAcceleration",
        ),
    ]
}

/// Inputs, the state outputs (with `nominals` of θ_m, ω_m, θ_L, ω_L at the default parameters:
/// the library's `Plant::state_nominals` computes them for any parameters) and the calculated
/// outputs.
fn common_head(drive_train: DriveTrain, nominals: [f64; 4]) -> Vec<Var> {
    use Causality::*;
    let (psi_unit, psi_quantity, psi_text) = match drive_train {
        DriveTrain::Shaft => ("N.m", "Torque", "Torque psi = k*dz(theta_m - theta_L, Delta) carried by the compliant shaft"),
        DriveTrain::Belt | DriveTrain::Web => (
            "N",
            "Force",
            "Belt force psi = K_b*dz(R_1*theta_m - alpha_1*theta_L, alpha_2*Delta), alpha_1 = R_2*R_g2/R_g1, alpha_2 = R_2/R_g1",
        ),
    };
    vec![
        input("tau_m", "TauM", 1, "Motor torque, held over each communication step, or along a line where input derivatives are set"),
        input("tau_L", "TauL", 2, "Load torque, held over each communication step, or along a line where input derivatives are set"),
        state_output("theta_m", "ThetaM", 3, "rad", "Angle", nominals[0], "Motor angle; its start value is the initial state"),
        state_output("omega_m", "OmegaM", 4, "rad/s", "AngularVelocity", nominals[1], "Motor speed; its start value is the initial state"),
        state_output("theta_L", "ThetaL", 5, "rad", "Angle", nominals[2], "Load angle; its start value is the initial state"),
        state_output("omega_L", "OmegaL", 6, "rad/s", "AngularVelocity", nominals[3], "Load speed; its start value is the initial state"),
        var("psi", "Psi", 7, Type::Real, Output, Variability::Continuous, Initial::Calculated, None, Range::Finite, psi_unit, psi_quantity, psi_text),
        var(
            "contact",
            "Contact",
            8,
            Type::Integer,
            Output,
            Variability::Discrete,
            Initial::Calculated,
            None,
            Range::Finite,
            "",
            "",
            "Contact mode at the communication point: +1 positive flank, 0 free (inside the gap), -1 negative flank",
        ),
        var(
            "bound",
            "Bound",
            9,
            Type::Real,
            Output,
            Variability::Continuous,
            Initial::Calculated,
            None,
            Range::Finite,
            "rad/s",
            "AngularVelocity",
            "Rigorous bound on |omega_L with backlash - omega_L without backlash| since the start time: K*g*integral of |h|",
        ),
        var(
            "bound_paper",
            "BoundPaper",
            10,
            Type::Real,
            Output,
            Variability::Continuous,
            Initial::Calculated,
            None,
            Range::Finite,
            "rad/s",
            "AngularVelocity",
            "Paper eq. (37)/(41) as printed: K*g*norm of the integral of exp(A s)*D_1; reproduction only, not a guarantee",
        ),
        var(
            "bound_sup",
            "BoundSup",
            11,
            Type::Real,
            CalculatedParameter,
            Variability::Fixed,
            Initial::Calculated,
            None,
            Range::Finite,
            "rad/s",
            "AngularVelocity",
            "Supremum of bound over all times: K*g*integral of |h| to infinity; +inf (with a warning) if the loop is not asymptotically stable",
        ),
    ]
}

/// The description of `identifier`. Panics on an identifier not in [`model_identifiers`].
pub fn model(identifier: &str) -> Model {
    use Range::*;
    match identifier {
        "BacklashShaft" => {
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
        "BacklashBelt" => Model {
            identifier: "BacklashBelt",
            drive_train: DriveTrain::Belt,
            description: "Belt-pulley drive and gear backlash in series (paper Fig. 7, eqs. 20-21), exact stepping with located contact switches",
            default_experiment: DefaultExperiment {
                start_time: 0.0,
                stop_time: 0.2,
                step_size: 1e-4,
            },
            variables: belt_variables(DriveTrain::Belt),
        },
        "BacklashWeb" => Model {
            identifier: "BacklashWeb",
            drive_train: DriveTrain::Web,
            description: "BacklashBelt's drive whose load roller pulls one web span (the paper's future work): span tension T as a fifth state, bounds on load speed and tension, exact stepping with located contact switches",
            default_experiment: DefaultExperiment {
                start_time: 0.0,
                stop_time: 1.0,
                step_size: 1e-4,
            },
            variables: web_variables(),
        },
        other => panic!("unknown model identifier {other:?}; known: {:?}", model_identifiers()),
    }
}

/// The belt drive's variables (value references 1–29), of BacklashBelt and of the web line's
/// drive.
fn belt_variables(drive_train: DriveTrain) -> Vec<Var> {
    use Range::*;
    // θ_m nominal g/r_m, θ_L nominal g/r_L, ω nominal ω₀ times those, with g = R_2 Delta/R_g1,
    // r_m = R_1, r_L = R_2 R_g2/R_g1, ω₀ = sqrt(K_b (r_m²/J_m + r_L²/J_L)).
    let mut v = common_head(
        drive_train,
        [
            0.006666666666666668,
            7.8202017592614315,
            0.0011111111111111113,
            1.303366959876905,
        ],
    );
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
    v.extend(event_indicators(drive_train));
    v
}

/// BacklashWeb: the belt drive's variables, then the web span's (value references 30–41,
/// docs/model.md §8). Its defaults are BacklashBelt's drive pulling a film line: 50 mm roller,
/// 1 m span, EA = 1e5 N (e.g. 50 µm PET, 0.5 m wide), 2 m/s.
fn web_variables() -> Vec<Var> {
    use Causality::*;
    use Range::*;
    let mut v = belt_variables(DriveTrain::Web);
    // T nominal: the tension that balances on the roller the belt force of a gap's stretch,
    // K_b g r_L/R_w (g = R_2 Delta/R_g1, r_L = R_2 R_g2/R_g1).
    let tension = state_output(
        "T",
        "Tension",
        32,
        "N",
        "Force",
        64.0,
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
        var(
            "bound_T",
            "BoundT",
            34,
            Type::Real,
            Output,
            Variability::Continuous,
            Initial::Calculated,
            None,
            Finite,
            "N",
            "Force",
            "Rigorous bound on |T with backlash - T without backlash| since the start time: K*g*integral of |h_T|",
        ),
        var(
            "bound_T_sup",
            "BoundTSup",
            35,
            Type::Real,
            CalculatedParameter,
            Variability::Fixed,
            Initial::Calculated,
            None,
            Finite,
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
    v
}

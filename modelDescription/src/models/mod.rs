//! The models, one module each (its variables: value references, kinds, start values, units
//! and texts; its description and default experiment; docs/model.md §4; and its physics
//! mapping, from which its state nominals here and its model structure in `crate::structure`
//! are computed), and what they share: the constructors of the kinds of variables and the
//! variables every model has. [`MODELS`] is the one list of the models.

mod belt;
mod controller;
mod shaft;
mod two_stage;
mod web;

use backlash_physics::{Chain, ChainParams, ContactLaw, Damping, Geometry, Plant, PlantParams, WebSpan};

use crate::{Causality, Initial, Kind, Model, Range, Type, Var, Variability};

/// What a model's drive says of its transmission coordinate u, of the force ψ in its compliant
/// member and of the damper in that member: their units, ψ's quantity and text, and the
/// damping parameter's name, symbol, unit, quantity and text.
pub(super) struct Transmission {
    /// The unit of u and g (and of the event indicators u ∓ g).
    coordinate_unit: &'static str,
    /// The unit of ψ (and of the event indicators of the damped force).
    psi_unit: &'static str,
    psi_quantity: &'static str,
    psi_description: &'static str,
    damping_name: &'static str,
    damping_symbol: &'static str,
    damping_unit: &'static str,
    damping_quantity: &'static str,
    damping_description: &'static str,
}

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

/// A Real output computed from the state (ψ, the bounds).
fn calculated_output(
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
        Causality::Output,
        Variability::Continuous,
        Initial::Calculated,
        None,
        Range::Finite,
        unit,
        quantity,
        description,
    )
}

/// A bound's supremum over all times: a calculated parameter (`bound_sup`, `bound_T_sup`).
fn supremum(
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
        Causality::CalculatedParameter,
        Variability::Fixed,
        Initial::Calculated,
        None,
        Range::Finite,
        unit,
        quantity,
        description,
    )
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

/// A continuous state as an output; its nominal is computed by [`with_state_nominals`].
fn state_output(
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
        Output,
        Variability::Continuous,
        Initial::Exact,
        Some(0.0),
        Range::Finite,
        unit,
        quantity,
        description,
    )
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
fn event_indicators(transmission: &Transmission) -> [Var; 2] {
    let unit = transmission.coordinate_unit;
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

/// The damper in the compliant member (docs/model.md §1, §4) and its event indicators (§6),
/// after every other variable of a model: its damping D (value reference 42, `d` of the shaft,
/// `D_b` of a belt), the Integer `contact_law` (43), and the event indicators of the damped
/// force (44–47), which read 1 where the plant has no such surface.
fn damper_variables(transmission: &Transmission) -> [Var; 6] {
    let Transmission {
        psi_unit,
        psi_quantity,
        damping_name,
        damping_symbol,
        damping_unit,
        damping_quantity,
        damping_description,
        ..
    } = *transmission;
    let indicator =
        |name, symbol, vr, description| continuous_local(name, symbol, vr, psi_unit, psi_quantity, description);
    [
        parameter(
            damping_name,
            damping_symbol,
            42,
            0.0,
            Range::NonNegative,
            damping_unit,
            damping_quantity,
            damping_description,
        ),
        var(
            "contact_law",
            "ContactLaw",
            43,
            Type::Integer,
            Causality::Parameter,
            Variability::Fixed,
            Initial::Exact,
            Some(ContactLaw::ElastoBacklash.code() as f64),
            Range::Integers {
                min: ContactLaw::ElastoBacklash.code(),
                max: ContactLaw::ElastoBacklash2.code(),
            },
            "",
            "",
            "1: Modelica ElastoBacklash (damper force capped by the spring force), 2: ElastoBacklash2",
        ),
        indicator(
            "force_upper",
            "ForceUpper",
            44,
            "Event indicator K*(u - g) + D*u' (spring and damper force on the positive flank): with a damper, contact on the positive flank holds while it is positive; 1 without a damper",
        ),
        indicator(
            "force_lower",
            "ForceLower",
            45,
            "Event indicator K*(u + g) + D*u' (spring and damper force on the negative flank): with a damper, contact on the negative flank holds while it is negative; 1 without a damper",
        ),
        indicator(
            "cap_upper",
            "CapUpper",
            46,
            "Event indicator D*u' - K*(u - g): with contact_law = 1, the damper force is capped by the spring force on the positive flank while it is positive; 1 without a damper or with contact_law = 2",
        ),
        indicator(
            "cap_lower",
            "CapLower",
            47,
            "Event indicator D*u' - K*(u + g): with contact_law = 1, the damper force is capped by the spring force on the negative flank while it is negative; 1 without a damper or with contact_law = 2",
        ),
    ]
}

/// A discrete Integer output of −1, 0 or +1 (`contact`, `sliding_m`, `sliding_L`).
fn sign_output(name: &'static str, symbol: &'static str, vr: u32, description: &'static str) -> Var {
    var(
        name,
        symbol,
        vr,
        Type::Integer,
        Causality::Output,
        Variability::Discrete,
        Initial::Calculated,
        None,
        Range::Integers { min: -1, max: 1 },
        "",
        "",
        description,
    )
}

/// Bearing friction with stiction on the motor and on the load (docs/model.md §12), after the
/// damper in every plant: the sliding torques `tau_c_m`, `tau_c_L` (value references 48, 49),
/// breakaway over sliding `peak_m`, `peak_L` (50, 51), the Integer outputs `sliding_m`,
/// `sliding_L` (52, 53), and the event indicators of the friction modes (54–57; docs/model.md
/// §6, §12), which read 1 where the body has no such surface. With both `tau_c` 0 (the default)
/// the plant has no friction modes.
fn friction_variables() -> [Var; 10] {
    [
        parameter(
            "tau_c_m",
            "TauCM",
            48,
            0.0,
            Range::NonNegative,
            "N.m",
            "Torque",
            "Coulomb friction torque in the motor bearing while it slides (>= 0; 0: no friction)",
        ),
        parameter(
            "tau_c_L",
            "TauCL",
            49,
            0.0,
            Range::NonNegative,
            "N.m",
            "Torque",
            "Coulomb friction torque in the load bearing while it slides (>= 0; 0: no friction)",
        ),
        parameter(
            "peak_m",
            "PeakM",
            50,
            1.0,
            Range::AtLeastOne,
            "",
            "",
            "Breakaway torque of the motor bearing over tau_c_m (>= 1): at rest the motor sticks while the torque on it stays within peak_m*tau_c_m",
        ),
        parameter(
            "peak_L",
            "PeakL",
            51,
            1.0,
            Range::AtLeastOne,
            "",
            "",
            "Breakaway torque of the load bearing over tau_c_L (>= 1): at rest the load sticks while the torque on it stays within peak_L*tau_c_L",
        ),
        sign_output(
            "sliding_m",
            "SlidingM",
            52,
            "Friction mode of the motor at the communication point: +1 sliding forward, 0 stuck, -1 sliding backward (without friction the sign of omega_m)",
        ),
        sign_output(
            "sliding_L",
            "SlidingL",
            53,
            "Friction mode of the load at the communication point: +1 sliding forward, 0 stuck, -1 sliding backward (without friction the sign of omega_L)",
        ),
        continuous_local(
            "stop_m",
            "StopM",
            54,
            "rad/s",
            "AngularVelocity",
            "Event indicator omega_m while the motor slides with friction: it stops where this crosses 0; 1 stuck or without friction",
        ),
        continuous_local(
            "breakaway_m",
            "BreakawayM",
            55,
            "N.m",
            "Torque",
            "Event indicator peak_m*tau_c_m - |tau_h| while the motor is stuck (tau_h: every other torque on it, tau_m - r_m*psi): it breaks away where this crosses 0; 1 sliding or without friction",
        ),
        continuous_local(
            "stop_L",
            "StopL",
            56,
            "rad/s",
            "AngularVelocity",
            "Event indicator omega_L while the load slides with friction: it stops where this crosses 0; 1 stuck or without friction",
        ),
        continuous_local(
            "breakaway_L",
            "BreakawayL",
            57,
            "N.m",
            "Torque",
            "Event indicator peak_L*tau_c_L - |tau_h| while the load is stuck (tau_h: every other torque on it, tau_L + r_L*psi, minus R_w*T on a web line): it breaks away where this crosses 0; 1 sliding or without friction",
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

/// The torque inputs `tau_m`, `tau_L` (value references 1, 2) and the motor's states
/// `theta_m`, `omega_m` (3, 4): the first variables of every plant.
fn inputs_and_motor() -> [Var; 4] {
    [
        input(
            "tau_m",
            "TauM",
            1,
            "Motor torque, held over each communication step, or along a line where input derivatives are set",
        ),
        input(
            "tau_L",
            "TauL",
            2,
            "Load torque, held over each communication step, or along a line where input derivatives are set",
        ),
        state_output(
            "theta_m",
            "ThetaM",
            3,
            "rad",
            "Angle",
            "Motor angle; its start value is the initial state",
        ),
        state_output(
            "omega_m",
            "OmegaM",
            4,
            "rad/s",
            "AngularVelocity",
            "Motor speed; its start value is the initial state",
        ),
    ]
}

/// The load's states `theta_L`, `omega_L`, value references `vr` and `vr + 1`.
fn load_states(vr: u32) -> [Var; 2] {
    [
        state_output(
            "theta_L",
            "ThetaL",
            vr,
            "rad",
            "Angle",
            "Load angle; its start value is the initial state",
        ),
        state_output(
            "omega_L",
            "OmegaL",
            vr + 1,
            "rad/s",
            "AngularVelocity",
            "Load speed; its start value is the initial state",
        ),
    ]
}

/// Inputs, the state outputs and the calculated outputs.
fn common_head(transmission: &Transmission) -> Vec<Var> {
    let Transmission {
        psi_unit,
        psi_quantity,
        psi_description: psi_text,
        ..
    } = *transmission;
    let [tau_m, tau_l, theta_m, omega_m] = inputs_and_motor();
    let [theta_l, omega_l] = load_states(5);
    vec![
        tau_m,
        tau_l,
        theta_m,
        omega_m,
        theta_l,
        omega_l,
        calculated_output("psi", "Psi", 7, psi_unit, psi_quantity, psi_text),
        sign_output(
            "contact",
            "Contact",
            8,
            "Contact at the communication point, the sign of psi: +1 positive flank, 0 free (inside the gap, or the damped force would pull), -1 negative flank",
        ),
        calculated_output(
            "bound",
            "Bound",
            9,
            "rad/s",
            "AngularVelocity",
            "Rigorous bound on |omega_L with backlash - omega_L without backlash| since the start time: K*g*integral of |h|",
        ),
        calculated_output(
            "bound_paper",
            "BoundPaper",
            10,
            "rad/s",
            "AngularVelocity",
            "Paper eq. (37)/(41) as printed: K*g*norm of the integral of exp(A s)*D_1; reproduction only, not a guarantee",
        ),
        supremum(
            "bound_sup",
            "BoundSup",
            11,
            "rad/s",
            "AngularVelocity",
            "Supremum of bound over all times: K*g*integral of |h| to infinity; +inf (with a warning) if the loop is not asymptotically stable",
        ),
    ]
}

/// `model` with the nominal of each continuous state: the scale it moves on at the default
/// parameters, computed by the physics (`Plant::state_nominals`, `Chain::state_nominals`,
/// docs/model.md §6). The continuous states are, in value-reference order, the entries of the
/// plant's state z = [θ_m, ω_m, θ_L, ω_L, T] (a chain's z = [θ_0, ω_0, …, θ_S, ω_S, T]).
fn with_state_nominals(mut model: Model) -> Model {
    let nominals = physics_of(&model, &parameters(&model)).state_nominals();
    let mut states: Vec<&mut Var> = model.variables.iter_mut().filter(|v| v.is_continuous_state()).collect();
    states.sort_by_key(|v| v.vr);
    assert!(
        states.len() <= nominals.len(),
        "{}: more states than the plant has",
        model.identifier
    );
    for (v, nominal) in states.into_iter().zip(nominals) {
        v.nominal = Some(nominal);
    }
    model
}

/// The plant of `model`'s start values (its default parameters).
pub(crate) fn default_plant(model: &Model) -> Plant {
    plant_of(model, &parameters(model))
}

/// The plant parameters of the model `identifier` at its parameters' start values (its default
/// parameters, docs/model.md §4), or `None` if no single-gap plant has that identifier.
pub fn default_plant_params(identifier: &str) -> Option<PlantParams> {
    described(identifier)
        .filter(|m| matches!(m.kind, Kind::Plant(_)))
        .map(|m| *default_plant(&m).params())
}

/// The parameters of the model `identifier` by name, at their start values (its default
/// parameters, docs/model.md §4), or `None` if no model has that identifier.
pub fn default_parameters(identifier: &str) -> Option<Vec<(&'static str, f64)>> {
    described(identifier).map(|m| parameters(&m))
}

/// The two-stage chain (docs/model.md §10) of the model `identifier` at the parameter `values`
/// (by name, as [`default_parameters`] lists them), by the model's own mapping; `None` if no
/// two-stage model has that identifier. Panics on values the model's parameters do not admit
/// (a `contact_law` other than 1 or 2): the caller checks them.
pub fn two_stage_params(identifier: &str, values: &[(&'static str, f64)]) -> Option<ChainParams<2>> {
    let model = described(identifier)?;
    let Kind::TwoStage(mapping) = model.kind else {
        return None;
    };
    Some(mapping(&|name| lookup(&model, values, name)))
}

/// The description of the plant `identifier`, or `None`.
fn described(identifier: &str) -> Option<Model> {
    MODELS
        .iter()
        .map(|m| m.describe)
        .map(|describe| describe())
        .find(|m| m.identifier == identifier)
}

/// The parameters of `model` by name, at their start values.
pub(crate) fn parameters(model: &Model) -> Vec<(&'static str, f64)> {
    model
        .variables
        .iter()
        .filter(|v| v.causality == Causality::Parameter)
        .map(|v| {
            let start = v
                .start
                .unwrap_or_else(|| panic!("{}: parameter {} has no start", model.identifier, v.name));
            (v.name, start)
        })
        .collect()
}

/// The physics of a plant model: the single gap's plant, or a chain of two stages.
pub(crate) enum Physics {
    Gap(Plant),
    TwoStage(Chain<2>),
}

impl Physics {
    /// The scale of each entry of z (docs/model.md §6).
    pub(crate) fn state_nominals(&self) -> Vec<f64> {
        match self {
            Physics::Gap(plant) => plant.state_nominals().to_vec(),
            Physics::TwoStage(chain) => chain.state_nominals(),
        }
    }

    /// The web span on the load, if any.
    pub(crate) fn web(&self) -> Option<&WebSpan> {
        match self {
            Physics::Gap(plant) => plant.web(),
            Physics::TwoStage(chain) => chain.web(),
        }
    }
}

/// The lookup of `model`'s parameter `name` in `values`. Panics on a name that is no parameter:
/// the description is wrong, caught when it is built.
fn lookup(model: &Model, values: &[(&'static str, f64)], name: &str) -> f64 {
    values
        .iter()
        .find(|(n, _)| *n == name)
        .map(|(_, x)| *x)
        .unwrap_or_else(|| panic!("{}: its physics reads {name}, which is no parameter", model.identifier))
}

/// The physics of `model` whose parameters have `values`. Panics if they are not a valid plant,
/// or `model` is a controller: the description is wrong, caught when it is built.
pub(crate) fn physics_of(model: &Model, values: &[(&'static str, f64)]) -> Physics {
    let at = |name: &str| lookup(model, values, name);
    match model.kind {
        Kind::Plant(_) => Physics::Gap(plant_of(model, values)),
        Kind::TwoStage(mapping) => {
            Physics::TwoStage(Chain::new(mapping(&at)).unwrap_or_else(|e| panic!("{}: {e}", model.identifier)))
        }
        Kind::Controller => panic!("{} is a controller: it has no plant", model.identifier),
    }
}

/// The plant of `model` whose parameters have `values`. Panics if they are not a valid plant or
/// the physics mapping reads a name that is no parameter: the description is wrong, caught when
/// it is built.
pub(crate) fn plant_of(model: &Model, values: &[(&'static str, f64)]) -> Plant {
    let at = |name: &str| lookup(model, values, name);
    let Kind::Plant(mapping) = model.kind else {
        panic!("{} is no single-gap plant", model.identifier)
    };
    Plant::new(mapping(&at)).unwrap_or_else(|e| panic!("{}: {e}", model.identifier))
}

/// The plant of a drive train of `geometry` whose inertias and viscous frictions are the
/// parameters J_m, J_L, b_m, b_L (docs/model.md §4) and whose compliant member has the damper
/// of `transmission` (its damping parameter and `contact_law`), read by `at`; its load an
/// inertia.
fn drive_train(at: &dyn Fn(&str) -> f64, geometry: Geometry, transmission: &Transmission) -> PlantParams {
    PlantParams {
        j_m: at("J_m"),
        j_l: at("J_L"),
        b_m: at("b_m"),
        b_l: at("b_L"),
        geometry,
        damping: Damping {
            d: at(transmission.damping_name),
            law: contact_law(at("contact_law")),
        },
        web: None,
    }
}

/// The law of a `contact_law` value. Only 1 and 2 reach here: the library refuses any other
/// value when it is set or restored (its range), and the model structure moves it between the
/// two; anything else is a fault of the caller.
fn contact_law(value: f64) -> ContactLaw {
    let code = value as i32;
    match ContactLaw::from_code(code) {
        Some(law) if code as f64 == value => law,
        _ => panic!("contact_law = {value} is neither 1 nor 2"),
    }
}

/// One plant: the function that describes it and its kind with its physics mapping (also in its
/// description, [`Model::kind`]; here for the library's static tables).
#[derive(Clone, Copy)]
pub struct ModelDef {
    pub describe: fn() -> Model,
    pub kind: Kind,
}

/// Every model, in a fixed order. A new model is a module here and a line in this list; its
/// identifier is in its description, nowhere else.
pub const MODELS: [ModelDef; 4] = [shaft::MODEL, belt::MODEL, web::MODEL, two_stage::MODEL];

/// Every controller, in a fixed order: a module here and a line in this list, as a plant.
pub const CONTROLLERS: [fn() -> Model; 1] = [controller::model];

/// The description of `identifier`. Panics on an identifier of no model in [`MODELS`] or
/// [`CONTROLLERS`].
pub fn model(identifier: &str) -> Model {
    MODELS
        .iter()
        .map(|m| m.describe)
        .chain(CONTROLLERS)
        .map(|describe| describe())
        .find(|m| m.identifier == identifier)
        .unwrap_or_else(|| {
            panic!(
                "unknown model identifier {identifier:?}; known: {:?} and {:?}",
                crate::model_identifiers(),
                crate::controller_identifiers()
            )
        })
}

//! The interface description of the FMUs: one table per model (variables, units, log
//! categories, default experiment; docs/model.md §4), and the generators of everything derived
//! from it.
//!
//! Std and the physics crate (each model's state nominals and model structure are computed from
//! its plant). Used by `build.rs` (the Rust tables of the library: [`rust::variable_tables`],
//! [`rust::log_categories`]), by the library itself (the kinds of variables), by `cargo xtask
//! fmu` (the FMI 2.0 `modelDescription.xml` of [`xml::model_description`] and the FMI 3.0 one of
//! [`xml3::model_description`]) and by the tests. The XML and the Rust code come from the same
//! tables, so they cannot disagree; what both descriptions write alike is written once (the
//! private `common` module). The guid (FMI 2.0) and the instantiation token (FMI 3.0) are each a
//! hash of their description: a changed description gets a new one, and a binary built from the
//! old one refuses to instantiate it.

mod common;
mod models;
pub mod rust;
mod structure;
pub mod xml;
pub mod xml3;

use backlash_physics::{ChainParams, PlantParams};

pub use models::{default_parameters, default_plant_params, model, two_stage_params, ModelDef, CONTROLLERS, MODELS};

/// The plants this crate describes, in a fixed order (that of the one list, [`MODELS`]).
pub fn model_identifiers() -> &'static [&'static str] {
    static IDENTIFIERS: std::sync::OnceLock<Vec<&'static str>> = std::sync::OnceLock::new();
    IDENTIFIERS.get_or_init(|| MODELS.iter().map(|m| (m.describe)().identifier).collect())
}

/// The controllers this crate describes (models of [`Kind::Controller`]), in the order of
/// [`CONTROLLERS`]: served by the same library, packed as archives of their own, and kept out of
/// [`model_identifiers`], whose every tool expects a plant.
pub fn controller_identifiers() -> &'static [&'static str] {
    static IDENTIFIERS: std::sync::OnceLock<Vec<&'static str>> = std::sync::OnceLock::new();
    IDENTIFIERS.get_or_init(|| CONTROLLERS.iter().map(|describe| describe().identifier).collect())
}

/// What a model is: a plant, made by its physics mapping, or a sampled controller (Co-Simulation
/// only: no continuous state, no event indicator, its output held between samples).
#[derive(Clone, Copy, Debug)]
pub enum Kind {
    Plant(PlantMapping),
    /// A plant of two stages in series (docs/model.md §10), made by its physics mapping.
    TwoStage(TwoStageMapping),
    Controller,
}

impl Kind {
    /// A plant of either form: Model Exchange and Co-Simulation, continuous states, event
    /// indicators.
    pub fn is_plant(&self) -> bool {
        !matches!(self, Kind::Controller)
    }
}

/// Scalar type of a variable.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Type {
    Real,
    Integer,
}

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Causality {
    Input,
    Output,
    Parameter,
    CalculatedParameter,
    /// Computed by the FMU, neither input nor output: the state derivatives of Model Exchange.
    Local,
}

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Variability {
    Fixed,
    Discrete,
    Continuous,
}

/// The `initial` attribute; `Unset` where FMI 2.0 forbids it (inputs).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Initial {
    Unset,
    Exact,
    Calculated,
}

/// Admissible values, checked when a value is set (FMI's min is inclusive, so `Positive` is
/// stated in the description only). An Integer's value is held as an f64 (the library's value
/// store); `Integers` admits the whole numbers from `min` to `max`, both written into the
/// description as its `min` and `max`.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Range {
    /// Any finite value.
    Finite,
    /// Finite and >= 0.
    NonNegative,
    /// Finite and > 0.
    Positive,
    /// Finite and >= 1 (a ratio such as a breakaway torque over a sliding one).
    AtLeastOne,
    /// A whole number from `min` to `max`.
    Integers { min: i32, max: i32 },
}

impl Range {
    pub fn admits(self, value: f64) -> bool {
        value.is_finite()
            && match self {
                Range::Finite => true,
                Range::NonNegative => value >= 0.0,
                Range::Positive => value > 0.0,
                Range::AtLeastOne => value >= 1.0,
                Range::Integers { min, max } => value.trunc() == value && min as f64 <= value && value <= max as f64,
            }
    }

    /// The admissible values in words, for the reason of a refusal.
    pub fn describe(self) -> std::borrow::Cow<'static, str> {
        match self {
            Range::Finite => "finite".into(),
            Range::NonNegative => "finite and >= 0".into(),
            Range::Positive => "finite and > 0".into(),
            Range::AtLeastOne => "finite and >= 1".into(),
            Range::Integers { min, max } if max == min + 1 => format!("{min} or {max}").into(),
            Range::Integers { min, max } => format!("an integer from {min} to {max}").into(),
        }
    }
}

/// A model's physics mapping: its plant parameters (docs/model.md §1, §8) from the values of its
/// parameters, looked up by name.
pub type PlantMapping = fn(&dyn Fn(&str) -> f64) -> PlantParams;

/// A two-stage model's physics mapping: its chain (docs/model.md §10) from the values of its
/// parameters, looked up by name.
pub type TwoStageMapping = fn(&dyn Fn(&str) -> f64) -> ChainParams<2>;

/// One scalar variable. `symbol` says what the variable is: here the name of a variant of the
/// generated `Symbol` enum, in the library's generated tables that variant itself (which the
/// library's model adapter maps to the physics).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Variable<S = &'static str> {
    pub name: &'static str,
    pub symbol: S,
    pub vr: u32,
    pub ty: Type,
    pub causality: Causality,
    pub variability: Variability,
    pub initial: Initial,
    pub start: Option<f64>,
    pub range: Range,
    /// Unit name from [`UNITS`], "" for none.
    pub unit: &'static str,
    /// The FMI `declaredType`-free `quantity` attribute.
    pub quantity: &'static str,
    pub description: &'static str,
    /// The `nominal` attribute: the scale of a continuous state at the default parameters
    /// (docs/model.md §6); importers derive absolute tolerances from it.
    pub nominal: Option<f64>,
    /// For a state derivative `der(x)`: the value reference of x (the `derivative` attribute).
    pub derivative_of: Option<u32>,
}

/// The description's variables, with the symbol as its name.
pub type Var = Variable<&'static str>;

impl<S> Variable<S> {
    /// Outputs with initial = exact carry the settable initial state (docs/model.md §4).
    pub fn is_initial_state(&self) -> bool {
        self.causality == Causality::Output && self.initial == Initial::Exact
    }

    /// A continuous state of Model Exchange: an initial state that is continuous in time.
    pub fn is_continuous_state(&self) -> bool {
        self.is_initial_state() && self.variability == Variability::Continuous
    }
}

/// The `<DefaultExperiment>` [s].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct DefaultExperiment {
    pub start_time: f64,
    pub stop_time: f64,
    pub step_size: f64,
}

/// One input of a model's reference experiment: the default experiment driven by square waves,
/// whose results every archive carries (`cargo xtask fmu`, FMI-LS-REF). Over the steps
/// k = 0, 1, ... of the default experiment the value held over step k is `level + amplitude`
/// while ⌊k / half_period⌋ is even and `level - amplitude` while it is odd (with amplitude 0, a
/// constant).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SquareWave {
    pub input: &'static str,
    pub level: f64,
    pub amplitude: f64,
    /// Steps between the flips (> 0).
    pub half_period: u32,
}

impl SquareWave {
    /// The value held over step `k`.
    pub fn at(&self, k: u64) -> f64 {
        if (k / u64::from(self.half_period)).is_multiple_of(2) {
            self.level + self.amplitude
        } else {
            self.level - self.amplitude
        }
    }
}

#[derive(Clone)]
pub struct Model {
    pub identifier: &'static str,
    /// A plant: how its parameters make it (its state nominals and model structure are computed
    /// from that plant); or a controller.
    pub kind: Kind,
    pub description: &'static str,
    pub default_experiment: DefaultExperiment,
    /// The inputs of its reference experiment ([`SquareWave`]); the others keep their start
    /// values.
    pub reference_inputs: &'static [SquareWave],
    pub variables: Vec<Var>,
}

/// Unit name, SI base-unit exponents (kg, m, s, rad) and display units (name, factor):
/// display value = factor · value.
type UnitRow = (&'static str, [i32; 4], &'static [(&'static str, f64)]);

pub(crate) const UNITS: &[UnitRow] = &[
    ("N.m", [1, 2, -2, 0], &[]),
    ("N", [1, 1, -2, 0], &[]),
    ("rad/s", [0, 0, -1, 1], &[("rpm", 30.0 / std::f64::consts::PI)]),
    ("rad/s2", [0, 0, -2, 1], &[]),
    ("rad", [0, 0, 0, 1], &[("deg", 180.0 / std::f64::consts::PI)]),
    ("m", [0, 1, 0, 0], &[("mm", 1000.0)]),
    ("kg.m2", [1, 2, 0, 0], &[]),
    ("N.m.s/rad", [1, 2, -1, -1], &[]),
    ("N.s/m", [1, 0, -1, 0], &[]),
    ("N.m/rad", [1, 2, -2, -1], &[]),
    ("N/m", [1, 0, -2, 0], &[]),
    ("m/s", [0, 1, -1, 0], &[]),
    ("N/s", [1, 1, -3, 0], &[]),
    ("rad/(s.N)", [-1, -1, 1, 1], &[]),
    ("rad/(s2.N)", [-1, -1, 0, 1], &[]),
    ("s", [0, 0, 1, 0], &[("ms", 1000.0)]),
    ("Hz", [0, 0, -1, 0], &[]),
];

/// One log category (FMI 2.0 §2.2.4): the Rust variant that names it in the library, its
/// name in the description and its description.
pub struct LogCategory {
    pub variant: &'static str,
    pub name: &'static str,
    pub description: &'static str,
}

/// The log categories of every model (docs/model.md §4), in the order of the description.
pub const LOG_CATEGORIES: &[LogCategory] = &[
    LogCategory {
        variant: "ContactEvents",
        name: "logContactEvents",
        description: "Every contact switch located inside a communication step (time, old and new mode)",
    },
    LogCategory {
        variant: "Warnings",
        name: "logWarnings",
        description: "Warnings, e.g. bound_sup is infinite because the loop is not asymptotically stable",
    },
    LogCategory {
        variant: "Errors",
        name: "logErrors",
        description:
            "Reasons for every refused call (status Error or Discard): illegal calls, invalid arguments or values",
    },
    LogCategory {
        variant: "Calls",
        name: "logCalls",
        description: "Every call of an FMI function and the status it returned",
    },
];

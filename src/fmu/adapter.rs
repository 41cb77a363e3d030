//! The model adapter: the one place that maps the description's variables to the physics
//! (parameters, inputs, the initial state, outputs and their derivatives, start values).
//!
//! Every match over [`Symbol`] or [`DriveTrain`] here is exhaustive, without a catch-all arm:
//! a variable added to the description (`modelDescription/`) without a mapping here is a
//! compile error. The rest of `fmu` handles variables only through [`source`].

use super::simulation::Simulation;
use super::variables::{model_by_identifier, DriveTrain, ModelInfo, Symbol};
use crate::physics::{Geometry, Inputs, PiGains, Plant, PlantParams, PlantState};

/// Values of the settable variables (inputs, parameters, the initial state), by [`Symbol`].
pub type Values = [f64; Symbol::COUNT];

/// Where a variable's value comes from.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Source {
    /// An input, stored; its slot among [`Inputs`] (0: τ_m, 1: τ_L) for input derivatives.
    Input(usize),
    /// A parameter, stored.
    Parameter,
    /// An entry of the plant state; stored as its start value before initialization.
    State(StateEntry),
    /// Computed from the physics in force (docs/model.md §1, §3).
    Calculated(Calculated),
    /// The time derivative of a state entry: the vector field of docs/model.md §1 (Model
    /// Exchange's `der(...)`).
    Derivative(StateEntry),
    /// The contact mode (Integer; docs/model.md §4).
    Contact,
}

/// The four entries of the state z = [θ_m, ω_m, θ_L, ω_L] (docs/model.md §1).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum StateEntry {
    ThetaM,
    OmegaM,
    ThetaL,
    OmegaL,
}

/// The Real variables computed from the physics.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Calculated {
    Psi,
    /// The event indicators u − g and u + g (docs/model.md §6).
    UMinusG,
    UPlusG,
    Bound,
    BoundPaper,
    BoundSup,
}

/// Where `symbol`'s value comes from.
#[inline]
pub fn source(symbol: Symbol) -> Source {
    match symbol {
        Symbol::TauM => Source::Input(0),
        Symbol::TauL => Source::Input(1),
        Symbol::ThetaM => Source::State(StateEntry::ThetaM),
        Symbol::OmegaM => Source::State(StateEntry::OmegaM),
        Symbol::ThetaL => Source::State(StateEntry::ThetaL),
        Symbol::OmegaL => Source::State(StateEntry::OmegaL),
        Symbol::Psi => Source::Calculated(Calculated::Psi),
        Symbol::Contact => Source::Contact,
        Symbol::Bound => Source::Calculated(Calculated::Bound),
        Symbol::BoundPaper => Source::Calculated(Calculated::BoundPaper),
        Symbol::BoundSup => Source::Calculated(Calculated::BoundSup),
        Symbol::UMinusG => Source::Calculated(Calculated::UMinusG),
        Symbol::UPlusG => Source::Calculated(Calculated::UPlusG),
        Symbol::DerThetaM => Source::Derivative(StateEntry::ThetaM),
        Symbol::DerOmegaM => Source::Derivative(StateEntry::OmegaM),
        Symbol::DerThetaL => Source::Derivative(StateEntry::ThetaL),
        Symbol::DerOmegaL => Source::Derivative(StateEntry::OmegaL),
        Symbol::JM
        | Symbol::JL
        | Symbol::BM
        | Symbol::BL
        | Symbol::Delta
        | Symbol::Kp
        | Symbol::Ki
        | Symbol::K
        | Symbol::KB
        | Symbol::R1
        | Symbol::R2
        | Symbol::Rg1
        | Symbol::Rg2 => Source::Parameter,
    }
}

impl StateEntry {
    /// The symbol that carries this entry.
    pub fn symbol(self) -> Symbol {
        match self {
            StateEntry::ThetaM => Symbol::ThetaM,
            StateEntry::OmegaM => Symbol::OmegaM,
            StateEntry::ThetaL => Symbol::ThetaL,
            StateEntry::OmegaL => Symbol::OmegaL,
        }
    }

    /// Its index in z = [θ_m, ω_m, θ_L, ω_L].
    pub fn index(self) -> usize {
        self as usize
    }

    /// The entries in the order of z, which is also the order of Model Exchange's continuous
    /// states.
    pub const ALL: [StateEntry; 4] = [
        StateEntry::ThetaM,
        StateEntry::OmegaM,
        StateEntry::ThetaL,
        StateEntry::OmegaL,
    ];

    /// Its value in `state`.
    #[inline]
    pub fn of(self, state: &PlantState) -> f64 {
        match self {
            StateEntry::ThetaM => state.theta_m,
            StateEntry::OmegaM => state.omega_m,
            StateEntry::ThetaL => state.theta_l,
            StateEntry::OmegaL => state.omega_l,
        }
    }
}

impl Calculated {
    /// Its value in the physics in force; `bound_sup` is +∞ when the loop is unstable.
    #[inline]
    pub fn of(self, sim: &Simulation) -> f64 {
        match self {
            Calculated::Psi => sim.plant().force(sim.state.u),
            Calculated::UMinusG => sim.plant().event_indicators(&sim.state)[0],
            Calculated::UPlusG => sim.plant().event_indicators(&sim.state)[1],
            Calculated::Bound => sim.bound.bound(),
            Calculated::BoundPaper => sim.bound.bound_paper(),
            Calculated::BoundSup => sim.bound_sup_value(),
        }
    }

    /// Its time derivative, given z' = d/dt [θ_m, ω_m, θ_L, ω_L] in the mode in force; None for
    /// `bound_sup`, a parameter.
    pub fn rate(self, sim: &Simulation, z_dot: &[f64; 4]) -> Option<f64> {
        match self {
            Calculated::Psi => Some(sim.plant().force_rate(sim.state.mode, z_dot[0], z_dot[2])),
            Calculated::UMinusG | Calculated::UPlusG => Some(sim.plant().transmission(z_dot[0], z_dot[2])),
            Calculated::Bound => Some(sim.bound.bound_rate()),
            Calculated::BoundPaper => Some(sim.bound.bound_paper_rate()),
            Calculated::BoundSup => None,
        }
    }
}

/// The value store right after instantiation: every start value of the description.
pub fn start_values(model: &ModelInfo) -> Values {
    let mut values = [0.0; Symbol::COUNT];
    for v in model.variables {
        if let Some(start) = v.start {
            values[v.symbol.index()] = start;
        }
    }
    values
}

/// The plant parameters of `model` from the stored values (validated by [`Plant::new`]).
pub fn plant_params(model: &ModelInfo, v: &Values) -> PlantParams {
    let at = |s: Symbol| v[s.index()];
    let geometry = match model.drive_train {
        DriveTrain::Shaft => Geometry::Shaft {
            k: at(Symbol::K),
            delta: at(Symbol::Delta),
        },
        DriveTrain::Belt => Geometry::Belt {
            k_b: at(Symbol::KB),
            r_1: at(Symbol::R1),
            r_2: at(Symbol::R2),
            r_g1: at(Symbol::Rg1),
            r_g2: at(Symbol::Rg2),
            delta: at(Symbol::Delta),
        },
    };
    PlantParams {
        j_m: at(Symbol::JM),
        j_l: at(Symbol::JL),
        b_m: at(Symbol::BM),
        b_l: at(Symbol::BL),
        geometry,
        web: None,
    }
}

/// The plant of the start values of the model `identifier`: its default parameters
/// (docs/model.md §4). Panics if the library serves no such model (for the tests, benches and
/// tools that name one).
pub fn default_plant_params(identifier: &str) -> PlantParams {
    let model = model_by_identifier(identifier).unwrap_or_else(|| panic!("the library serves no model {identifier}"));
    plant_params(model, &start_values(model))
}

/// The PI gains the bounds assume (docs/model.md §3).
pub fn gains(v: &Values) -> PiGains {
    PiGains {
        kp: v[Symbol::Kp.index()],
        ki: v[Symbol::Ki.index()],
    }
}

/// The inputs with their slopes (set by fmi2SetRealInputDerivatives).
#[inline]
pub fn inputs(v: &Values, slopes: [f64; 2]) -> Inputs {
    Inputs {
        tau_m: v[Symbol::TauM.index()],
        tau_l: v[Symbol::TauL.index()],
        dtau_m: slopes[0],
        dtau_l: slopes[1],
        span: 0.0,
        dspan: 0.0,
    }
}

/// The state from z = [θ_m, ω_m, θ_L, ω_L] (Model Exchange's continuous states); the mode is the
/// one u lies in.
pub fn state_of(plant: &Plant, z: &[f64; 4]) -> PlantState {
    PlantState::new(plant, z[0], z[1], z[2], z[3])
}

/// z = [θ_m, ω_m, θ_L, ω_L] of `state`.
pub fn entries_of(state: &PlantState) -> [f64; 4] {
    StateEntry::ALL.map(|e| e.of(state))
}

/// Stores the input values at the end of a step (the input lines continue from there).
#[inline]
pub fn store_inputs(v: &mut Values, tau: [f64; 2]) {
    v[Symbol::TauM.index()] = tau[0];
    v[Symbol::TauL.index()] = tau[1];
}

/// The initial state from the start values of θ and ω.
pub fn initial_state(plant: &Plant, v: &Values) -> PlantState {
    let at = |e: StateEntry| v[e.symbol().index()];
    PlantState::new(
        plant,
        at(StateEntry::ThetaM),
        at(StateEntry::OmegaM),
        at(StateEntry::ThetaL),
        at(StateEntry::OmegaL),
    )
}

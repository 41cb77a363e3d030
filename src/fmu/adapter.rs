//! The model adapter: the one place that maps the description's variables to the physics
//! (parameters, inputs, the initial state, outputs and their derivatives, start values).
//!
//! Each variable's [`Source`] is generated from the description (`Symbol::source`: a parameter
//! is stored, a state is its plant-state entry, a calculated variable the [`Calculated`] of its
//! symbol, so that a new calculated variable without a variant here is a compile error); the rest
//! of `fmu` handles variables only through it. The plant parameters come from each model's own
//! mapping ([`ModelInfo::plant_params`]).

use super::simulation::Simulation;
use super::variables::{Kind, ModelInfo, Symbol, MODELS};

/// The event indicators of a plant: the contact surfaces (docs/model.md §6), then the friction
/// surfaces (§12).
pub const EVENT_INDICATORS: usize = crate::physics::vector_field::EVENT_INDICATORS + 4;
use crate::physics::{Inputs, PiGains, Plant, PlantParams, PlantState};

/// Values of the settable variables (inputs, parameters, the initial state), by [`Symbol`]. An
/// Integer parameter (`contact_law`) is held as its f64, admitted by its range when it is set or
/// restored (so the physics mapping reads only 1.0 or 2.0).
pub type Values = [f64; Symbol::COUNT];

/// Where a variable's value comes from.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Source {
    /// An input, stored; its slot among the input lines (0: τ_m, 1: τ_L, 2: v_in, 3: T_in)
    /// for input derivatives.
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
    /// The `contact` output: the sign of ψ in the mode in force (Integer; docs/model.md §4).
    Contact,
    /// A stage's `contact_j` output on a chain of stages (0 the first; docs/model.md §10).
    StageContact(usize),
    /// A body's `sliding` output (Integer; docs/model.md §12): 0 the motor, 1 the load, 2 a
    /// chain's intermediate shaft.
    Sliding(usize),
    /// A controller's input, stored; read at each sample (docs/model.md §9).
    Sampled,
    /// A controller's output: the command of its last sample, held (before the first sample,
    /// stored as its start value).
    Command,
}

/// The entries of the state z = [θ_m, ω_m, θ_L, ω_L] (docs/model.md §1), and T on a web line
/// (§8); a two-stage chain's intermediate shaft θ_i, ω_i (§10), whose z is [θ_m, ω_m, θ_i, ω_i,
/// θ_L, ω_L] ([`StateEntry::chain_index`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum StateEntry {
    ThetaM,
    OmegaM,
    ThetaL,
    OmegaL,
    Tension,
    ThetaI,
    OmegaI,
}

/// The most state entries of a single gap's model: z with a web span's tension. A gearbox's six
/// are the chain's own ([`crate::fmu::geared::Geared::z`]).
pub const MAX_STATES: usize = 5;

/// z of a single gap's model, [θ_m, ω_m, θ_L, ω_L, T]; T is 0 for the drive trains.
pub type StateVector = [f64; MAX_STATES];

/// The most input lines of any model: τ_m, τ_L and a web span's v_in, T_in.
pub const MAX_INPUTS: usize = 4;

/// The Real variables computed from the physics.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Calculated {
    Psi,
    /// The event indicators (docs/model.md §6), in the order of `Plant::event_indicators`:
    /// u − g and u + g,
    UMinusG,
    UPlusG,
    /// K (u − g) + D u′ and K (u + g) + D u′, the damped force on either flank,
    ForceUpper,
    ForceLower,
    /// D u′ − K (u − g) and D u′ − K (u + g), law 1's cap on either flank.
    CapUpper,
    CapLower,
    /// The friction surfaces of the motor and the load (docs/model.md §12): a sliding body's
    /// speed, peak·τ_c − |τ_h| of a stuck one.
    StopM,
    BreakawayM,
    StopL,
    BreakawayL,
    Bound,
    BoundPaper,
    BoundSup,
    /// `bound_T`, `bound_T_sup` of a web line (docs/model.md §8).
    BoundT,
    BoundTSup,
    /// A gearbox's own (`crate::fmu::geared`): never a single gap's.
    Gear(GearQuantity),
}

/// The quantities only a two-stage chain has (docs/model.md §10): each stage's ψ, its contact
/// surfaces (as the single gap's, stage by stage) and the intermediate shaft's friction
/// surfaces. The generated sources name a symbol's variant here when no single-gap model has
/// the symbol.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum GearQuantity {
    Psi1,
    Psi2,
    UMinusG1,
    UPlusG1,
    ForceUpper1,
    ForceLower1,
    CapUpper1,
    CapLower1,
    UMinusG2,
    UPlusG2,
    ForceUpper2,
    ForceLower2,
    CapUpper2,
    CapLower2,
    StopI,
    BreakawayI,
}

impl StateEntry {
    /// The symbol that carries this entry.
    pub fn symbol(self) -> Symbol {
        match self {
            StateEntry::ThetaM => Symbol::ThetaM,
            StateEntry::OmegaM => Symbol::OmegaM,
            StateEntry::ThetaL => Symbol::ThetaL,
            StateEntry::OmegaL => Symbol::OmegaL,
            StateEntry::Tension => Symbol::Tension,
            StateEntry::ThetaI => Symbol::ThetaI,
            StateEntry::OmegaI => Symbol::OmegaI,
        }
    }

    /// Its index in a two-stage chain's z = [θ_m, ω_m, θ_i, ω_i, θ_L, ω_L] (body by body, angle
    /// then speed: `Chain::STATES`' order).
    pub fn chain_index(self) -> usize {
        match self {
            StateEntry::ThetaM => 0,
            StateEntry::OmegaM => 1,
            StateEntry::ThetaI => 2,
            StateEntry::OmegaI => 3,
            StateEntry::ThetaL => 4,
            StateEntry::OmegaL => 5,
            StateEntry::Tension => 6,
        }
    }

    /// The entries of a two-stage chain's z, in order.
    pub const CHAIN: [StateEntry; 6] = [
        StateEntry::ThetaM,
        StateEntry::OmegaM,
        StateEntry::ThetaI,
        StateEntry::OmegaI,
        StateEntry::ThetaL,
        StateEntry::OmegaL,
    ];

    /// Its index in z = [θ_m, ω_m, θ_L, ω_L, T].
    pub fn index(self) -> usize {
        self as usize
    }

    /// The entries in the order of z, which is also the order of Model Exchange's continuous
    /// states.
    pub const ALL: [StateEntry; MAX_STATES] = [
        StateEntry::ThetaM,
        StateEntry::OmegaM,
        StateEntry::ThetaL,
        StateEntry::OmegaL,
        StateEntry::Tension,
    ];

    /// The entries of `model`'s state: T only on a web line.
    pub fn of_model(model: &ModelInfo) -> &'static [StateEntry] {
        &StateEntry::ALL[..model.states]
    }

    /// Its value in `state` (a single gap's: a chain's intermediate shaft is not there, NaN).
    #[inline]
    pub fn of(self, state: &PlantState) -> f64 {
        match self {
            StateEntry::ThetaM => state.theta_m,
            StateEntry::OmegaM => state.omega_m,
            StateEntry::ThetaL => state.theta_l,
            StateEntry::OmegaL => state.omega_l,
            StateEntry::Tension => state.tension,
            StateEntry::ThetaI | StateEntry::OmegaI => f64::NAN,
        }
    }
}

impl Calculated {
    /// The event indicators, in the order of `Plant::event_indicators` (and of the
    /// descriptions' `<EventIndicator>`s).
    pub const INDICATORS: [Calculated; EVENT_INDICATORS] = [
        Calculated::UMinusG,
        Calculated::UPlusG,
        Calculated::ForceUpper,
        Calculated::ForceLower,
        Calculated::CapUpper,
        Calculated::CapLower,
        Calculated::StopM,
        Calculated::BreakawayM,
        Calculated::StopL,
        Calculated::BreakawayL,
    ];

    /// Its index among the event indicators, None for the other quantities.
    pub fn indicator(self) -> Option<usize> {
        Calculated::INDICATORS.iter().position(|c| *c == self)
    }

    /// Its value in the physics in force with the inputs of `v` and `slopes`; `bound_sup` is +∞
    /// when the loop is unstable.
    #[inline]
    pub fn of(self, sim: &Simulation, v: &Values, slopes: &InputSlopes) -> f64 {
        match self {
            Calculated::Psi => sim.plant().force(sim.state.u, sim.state.du),
            Calculated::UMinusG
            | Calculated::UPlusG
            | Calculated::ForceUpper
            | Calculated::ForceLower
            | Calculated::CapUpper
            | Calculated::CapLower => {
                let i = self.indicator().expect("an event indicator");
                sim.plant().event_indicators(&sim.state)[i]
            }
            Calculated::StopM | Calculated::BreakawayM | Calculated::StopL | Calculated::BreakawayL => {
                let i = self.indicator().expect("an event indicator") - crate::physics::vector_field::EVENT_INDICATORS;
                sim.friction_indicators(&inputs(sim.plant(), v, slopes))[i]
            }
            Calculated::Bound | Calculated::BoundSup | Calculated::BoundT | Calculated::BoundTSup if !sim.bounded() => {
                f64::INFINITY
            }
            Calculated::Bound => sim.clock.bound.bound(sim.trajectory()),
            Calculated::BoundPaper => sim.clock.bound.bound_paper(),
            Calculated::BoundSup => sim.bound_sup_value(),
            Calculated::BoundT => sim.clock.bound.bound_t(sim.trajectory()),
            Calculated::BoundTSup => sim.bound_t_sup_value(),
            // A gearbox's: read from its chain (`crate::fmu::geared`), never from a single gap.
            Calculated::Gear(_) => f64::NAN,
        }
    }

    /// Its time derivative, given z' = d/dt [θ_m, ω_m, θ_L, ω_L, T] in the mode in force; None
    /// for the suprema, parameters.
    pub fn rate(self, sim: &Simulation, z_dot: &StateVector) -> Option<f64> {
        match self {
            Calculated::Psi => Some(
                sim.plant()
                    .force_rate(sim.state.mode, [z_dot[0], z_dot[2]], [z_dot[1], z_dot[3]]),
            ),
            Calculated::UMinusG
            | Calculated::UPlusG
            | Calculated::ForceUpper
            | Calculated::ForceLower
            | Calculated::CapUpper
            | Calculated::CapLower => {
                let i = self.indicator().expect("an event indicator");
                Some(indicator_rates(sim.plant(), z_dot)[i])
            }
            // Locals, not outputs: no output derivative.
            Calculated::StopM | Calculated::BreakawayM | Calculated::StopL | Calculated::BreakawayL => None,
            Calculated::Bound | Calculated::BoundT if !sim.bounded() => None,
            Calculated::Bound => Some(sim.clock.bound.bound_rate(sim.trajectory())),
            Calculated::BoundPaper => Some(sim.clock.bound.bound_paper_rate()),
            Calculated::BoundT => Some(sim.clock.bound.bound_t_rate(sim.trajectory())),
            Calculated::BoundSup | Calculated::BoundTSup | Calculated::Gear(_) => None,
        }
    }
}

/// The rates of the event indicators (or their directional derivatives) for z' (or a change of
/// z) `dz`: from u′ = r_m θ_m′ − r_L θ_L′ and u″ = r_m ω_m′ − r_L ω_L′ (docs/model.md §6).
#[inline]
pub fn indicator_rates(plant: &Plant, dz: &StateVector) -> [f64; crate::physics::vector_field::EVENT_INDICATORS] {
    plant.event_indicator_rates(plant.transmission(dz[0], dz[2]), plant.transmission(dz[1], dz[3]))
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

/// The plant parameters of `model` from the stored values (validated by [`Plant::new`]), by the
/// model's own mapping. A name the model lacks reads NaN, which [`Plant::new`] refuses; the
/// description's build computes every model's plant, so none does.
/// `None` for a controller, which has no plant.
pub fn plant_params(model: &ModelInfo, v: &Values) -> Option<PlantParams> {
    let Kind::Plant(mapping) = model.kind else {
        return None;
    };
    Some(mapping(&|name| {
        model.by_name(name).map_or(f64::NAN, |var| v[var.symbol.index()])
    }))
}

/// The plant of the start values of the model `identifier`: its default parameters
/// (docs/model.md §4). Panics if the library serves no such model (for the tests, benches and
/// tools that name one).
pub fn default_plant_params(identifier: &str) -> PlantParams {
    model_description::default_plant_params(identifier)
        .unwrap_or_else(|| panic!("the library serves no model {identifier}"))
}

/// The PI gains the bounds assume (docs/model.md §3): the speed loop's, and the tension
/// loop's of a web line (§8; 0 for the drive trains, which have none).
pub fn gains(v: &Values) -> (PiGains, PiGains) {
    let at = |s: Symbol| v[s.index()];
    let speed = PiGains {
        kp: at(Symbol::Kp),
        ki: at(Symbol::Ki),
    };
    let tension = PiGains {
        kp: at(Symbol::KpT),
        ki: at(Symbol::KiT),
    };
    (speed, tension)
}

/// The input lines' slopes, by [`Source::Input`] slot (set by fmi2SetRealInputDerivatives).
pub type InputSlopes = [f64; MAX_INPUTS];

/// The inputs with their slopes; a web span's forcing w (and its slope) from v_in, T_in
/// ([`WebSpan::forcing`], linear in both).
#[inline]
pub fn inputs(plant: &Plant, v: &Values, slopes: &InputSlopes) -> Inputs {
    let (span, dspan) = plant.web().map_or((0.0, 0.0), |w| {
        (
            w.forcing(v[Symbol::VIn.index()], v[Symbol::TIn.index()]),
            w.forcing(slopes[2], slopes[3]),
        )
    });
    Inputs {
        tau_m: v[Symbol::TauM.index()],
        tau_l: v[Symbol::TauL.index()],
        dtau_m: slopes[0],
        dtau_l: slopes[1],
        span,
        dspan,
    }
}

/// The input lines, by their [`Source::Input`] slot (from the descriptions: each model's inputs in
/// value-reference order), as many as the physics has.
pub const INPUT_SYMBOLS: [Symbol; MAX_INPUTS] = super::variables::INPUT_SYMBOLS;

/// The values of the input lines, by slot.
#[inline]
pub fn input_values(v: &Values) -> [f64; MAX_INPUTS] {
    INPUT_SYMBOLS.map(|s| v[s.index()])
}

/// The name of the input line in `slot`, as the descriptions give it (for messages).
pub fn input_name(slot: usize) -> &'static str {
    MODELS
        .iter()
        .find_map(|m| m.by_symbol(INPUT_SYMBOLS[slot]))
        .map_or("an input", |v| v.name)
}

/// The state from z (Model Exchange's continuous states); the mode is the one u lies in.
pub fn state_of(plant: &Plant, z: &StateVector) -> PlantState {
    PlantState::new(plant, z[0], z[1], z[2], z[3]).with_tension(z[4])
}

/// z = [θ_m, ω_m, θ_L, ω_L, T] of `state`.
pub fn entries_of(state: &PlantState) -> StateVector {
    StateEntry::ALL.map(|e| e.of(state))
}

/// Stores the input values at the end of a step (the input lines continue from there).
#[inline]
pub fn store_inputs(v: &mut Values, lines: &[f64; MAX_INPUTS]) {
    for (s, x) in INPUT_SYMBOLS.iter().zip(lines) {
        v[s.index()] = *x;
    }
}

/// The initial state from the start values of θ, ω (and T).
pub fn initial_state(plant: &Plant, v: &Values) -> PlantState {
    let at = |e: StateEntry| v[e.symbol().index()];
    let state = PlantState::new(
        plant,
        at(StateEntry::ThetaM),
        at(StateEntry::OmegaM),
        at(StateEntry::ThetaL),
        at(StateEntry::OmegaL),
    );
    match plant.web() {
        Some(_) => state.with_tension(at(StateEntry::Tension)),
        None => state,
    }
}

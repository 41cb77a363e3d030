//! The physics behind one instance after initialization: plant, exact stepper, state and the
//! speed-error bound (spec §1–§3), assembled from the variable values.

use super::error::FmuError;
use super::variables::{Causality, DriveTrain, ModelInfo, Symbol};
use crate::physics::{
    finite, BoundState, Geometry, Inputs, PiGains, Plant, PlantParams, PlantState, SpeedErrorBound, Stepper, Unbounded,
};

/// Values of the settable variables, indexed by [`Symbol`].
pub type Values = [f64; Symbol::COUNT];

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
    }
}

pub fn inputs(v: &Values, slopes: [f64; 2]) -> Inputs {
    Inputs {
        tau_m: v[Symbol::TauM.index()],
        tau_l: v[Symbol::TauL.index()],
        dtau_m: slopes[0],
        dtau_l: slopes[1],
    }
}

#[derive(Clone, Debug)]
pub struct Simulation {
    pub stepper: Stepper,
    pub state: PlantState,
    pub bound: SpeedErrorBound,
    /// bound_sup, or why it is +∞ (spec §3).
    pub bound_sup: Result<f64, Unbounded>,
    /// The longest step accepted, see [`max_step`].
    pub max_step: f64,
}

/// The largest step, in periods of the fastest contact oscillation: bounds the number of
/// contact switches one step can contain, so no step runs for long.
pub const MAX_PERIODS_PER_STEP: f64 = 1e4;

/// The largest admissible step: [`MAX_PERIODS_PER_STEP`] periods of the undamped contact
/// oscillation, ω² = K (r_m²/J_m + r_L²/J_L); finite, so that a step no longer than it is.
fn max_step(p: &Plant) -> f64 {
    let params = p.params();
    let omega_sq = p.stiffness() * (p.r_m() * p.r_m() / params.j_m + p.r_l() * p.r_l() / params.j_l);
    (MAX_PERIODS_PER_STEP * 2.0 * std::f64::consts::PI / omega_sq.sqrt()).min(f64::MAX)
}

impl Simulation {
    /// The plant at the start: parameters validated (the error names the parameter), state
    /// from the start values of θ and ω, bound at elapsed time 0.
    pub fn build(model: &ModelInfo, v: &Values) -> Result<Simulation, FmuError> {
        let mut sim = template(model, v)?;
        let at = |s: Symbol| v[s.index()];
        sim.state = PlantState::new(
            sim.plant(),
            at(Symbol::ThetaM),
            at(Symbol::OmegaM),
            at(Symbol::ThetaL),
            at(Symbol::OmegaL),
        );
        sim.check_state(&sim.state, format_args!("the initial state overflows"))?;
        Ok(sim)
    }

    /// Whether `state` is finite and its force ψ = K·dz(u, g) too: finite but huge angles,
    /// speeds or parameters must not turn into ∞/NaN outputs. Runs on every fmi2DoStep.
    #[inline]
    pub fn state_ok(&self, state: &PlantState) -> bool {
        state.is_finite() & self.plant().force(state.u).is_finite()
    }

    /// The refusal of a state that is not `state_ok`, saying `what` overflows.
    #[cold]
    pub fn overflow(&self, state: &PlantState, what: std::fmt::Arguments<'_>) -> FmuError {
        let psi = self.plant().force(state.u);
        FmuError::Overflow(format!(
            "{what}: theta_m = {:e}, omega_m = {:e}, theta_L = {:e}, omega_L = {:e}, u = {:e}, psi = {psi:e}; \
             reduce the start values, inputs or parameters",
            state.theta_m, state.omega_m, state.theta_l, state.omega_l, state.u
        ))
    }

    /// `state_ok`, or its refusal.
    pub fn check_state(&self, state: &PlantState, what: std::fmt::Arguments<'_>) -> Result<(), FmuError> {
        if self.state_ok(state) {
            Ok(())
        } else {
            Err(self.overflow(state, what))
        }
    }

    /// Advances plant and bound over `h` when the stepper's quiet path applies (see
    /// [`Stepper::quiet_step`]) and both stay finite; returns whether it did. When it did not,
    /// nothing changed and the general path does the step, or says why it cannot.
    #[inline]
    pub fn quiet_step(&mut self, inputs: &Inputs, h: f64) -> bool {
        let Some(next) = self.stepper.quiet_step(&self.state, inputs, h) else {
            return false;
        };
        // `next` is finite: its force is what is left of `state_ok`. The bound changes only
        // when it stays finite, and last, so that a refusal leaves both as they were.
        if !finite(self.plant().force(next.u)) || self.bound.advance(h).is_err() {
            return false;
        }
        self.state = next;
        true
    }

    /// Rebuilds from saved values and continues from a saved plant and bound state.
    pub fn restore(
        model: &ModelInfo,
        v: &Values,
        state: PlantState,
        bound: &BoundState,
    ) -> Result<Simulation, FmuError> {
        let mut sim = Simulation::build(model, v)?;
        if !state.is_finite() {
            return Err(FmuError::StateRefused("the plant state is not finite".into()));
        }
        sim.check_state(&state, format_args!("the saved plant state overflows"))?;
        sim.state = state;
        sim.bound.restore(bound)?;
        Ok(sim)
    }

    pub fn plant(&self) -> &Plant {
        self.stepper.plant()
    }

    pub fn bound_sup_value(&self) -> f64 {
        self.bound_sup.unwrap_or(f64::INFINITY)
    }

    /// K·g, the largest |φ| (spec §3): the scale of both bounds.
    fn disturbance_scale(&self) -> f64 {
        self.plant().stiffness() * self.plant().half_gap()
    }

    /// d bound/dt = K g |h(t)|, h = ω_L entry (index 3) of e^{A t} D_1 (spec §3).
    pub fn bound_rate(&self) -> f64 {
        self.disturbance_scale() * self.bound.state().response[3].abs()
    }

    /// d bound_paper/dt = K g (I·r)/‖I‖ with I = ∫ e^{A s} D_1 ds and r = e^{A t} D_1; at I = 0
    /// (t = start) the right derivative K g ‖r‖, since I ≈ t r there.
    pub fn bound_paper_rate(&self) -> f64 {
        let s = self.bound.state();
        let norm = s.integral.iter().map(|x| x * x).sum::<f64>().sqrt();
        let rate = if norm > 0.0 {
            s.integral.iter().zip(&s.response).map(|(i, r)| i * r).sum::<f64>() / norm
        } else {
            s.response.iter().map(|x| x * x).sum::<f64>().sqrt()
        };
        self.disturbance_scale() * rate
    }
}

/// How many parameter sets keep their built physics.
const TEMPLATE_CACHE: usize = 8;

type TemplateKey = (&'static str, Vec<u64>);

/// Built physics by model and exact parameter bits. Building the bound (its supremum needs an
/// integration to convergence) is by far the most expensive part of an instance, and
/// fmi2Reset, fmi2SetFMUstate and fresh instances of a parameter sweep rebuild the same plant
/// again and again. Building is deterministic, so a copy steps bit-identically to a new build.
static TEMPLATES: std::sync::Mutex<Vec<(TemplateKey, Simulation)>> = std::sync::Mutex::new(Vec::new());

fn template(model: &ModelInfo, v: &Values) -> Result<Simulation, FmuError> {
    let key: TemplateKey = (
        model.identifier,
        model
            .variables
            .iter()
            .filter(|var| var.causality == Causality::Parameter)
            .map(|var| v[var.symbol.index()].to_bits())
            .collect(),
    );
    let lock = || TEMPLATES.lock().unwrap_or_else(|poisoned| poisoned.into_inner());
    if let Some((_, sim)) = lock().iter().find(|(k, _)| *k == key) {
        return Ok(sim.clone());
    }
    // Built outside the lock: other instances need not wait for it.
    let plant = Plant::new(plant_params(model, v))?;
    let gains = PiGains {
        kp: v[Symbol::Kp.index()],
        ki: v[Symbol::Ki.index()],
    };
    let bound = SpeedErrorBound::new(&plant, gains)?;
    let bound_sup = bound.sup();
    let state = PlantState::new(&plant, 0.0, 0.0, 0.0, 0.0);
    let sim = Simulation {
        max_step: max_step(&plant),
        stepper: Stepper::new(plant),
        state,
        bound,
        bound_sup,
    };
    let mut cache = lock();
    if cache.len() == TEMPLATE_CACHE {
        cache.remove(0);
    }
    cache.push((key, sim.clone()));
    Ok(sim)
}

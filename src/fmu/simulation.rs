//! The physics behind one instance after initialization: plant, exact stepper, state and the
//! bounds (docs/model.md §1–§3, §8), assembled from the variable values.

use super::adapter::{self, StateVector, Values};
use super::bounds::Bounds;
use super::error::FmuError;
use super::friction::{self, Friction};
use super::templates::Templates;
use super::variables::ModelInfo;
use crate::physics::chain::OneStageFrictionBound;
use crate::physics::{finite, max_step, BoundError, ContactMode, Inputs, Plant, PlantState, Stepper, Trajectory};

#[derive(Clone, Debug)]
pub struct Simulation {
    pub stepper: Stepper,
    /// The plant's state (with friction too: the chain's state is it in the chain's mode).
    pub state: PlantState,
    /// With Coulomb friction on a body (docs/model.md §12): the chain that steps the plant.
    /// None without: the single-gap stepper steps it.
    pub friction: Option<Box<Friction>>,
    /// The bounds and how far they lag behind the plant.
    pub clock: BoundClock<Bounds>,
    /// The longest step accepted ([`max_step`]).
    pub max_step: f64,
    /// Model Exchange with a damper: the trajectory's terms of the bound, gathered at the
    /// importer's events and completed steps.
    pub events: EventTerms,
}

/// The trajectory's terms of the damped bound in Model Exchange (docs/model.md §3, "With a
/// damper"), where the FMU sees the trajectory only at the points the importer sets: the phase
/// in progress (its mode and u where it began), Σ|Δu| over the finished slack and capped phases
/// (u is monotone in each) and the number of phases in the gap. A phase ends where the mode of the
/// state changes, which the importer locates as an event (the event indicators of §6); a change
/// it does not locate is taken where it is first seen (docs/model.md §3: the guarantee rests on
/// the importer locating them).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct EventTerms {
    /// False in Co-Simulation, where the stepper follows the whole trajectory
    /// ([`PlantState::variation`]).
    pub tracked: bool,
    pub phase: ContactMode,
    pub phase_u: f64,
    pub monotone: f64,
    pub gaps: f64,
}

impl EventTerms {
    pub const UNTRACKED: EventTerms = EventTerms {
        tracked: false,
        phase: ContactMode::Free,
        phase_u: 0.0,
        monotone: 0.0,
        gaps: 0.0,
    };

    /// Tracking from `state`, the first phase's start.
    pub fn start(state: &PlantState) -> EventTerms {
        EventTerms {
            tracked: true,
            phase: state.mode,
            phase_u: state.u,
            monotone: 0.0,
            gaps: if state.mode == ContactMode::Free { 1.0 } else { 0.0 },
        }
    }

    /// Slack and capped phases, in which u is monotone.
    pub fn monotone_in(mode: ContactMode) -> bool {
        !matches!(mode, ContactMode::Free | ContactMode::Positive | ContactMode::Negative)
    }

    /// The importer's trajectory is at `state` (an event, or a completed integrator step).
    pub fn roll(&mut self, state: &PlantState) {
        if !self.tracked || state.mode == self.phase {
            return;
        }
        if Self::monotone_in(self.phase) {
            self.monotone += (state.u - self.phase_u).abs();
        }
        if state.mode == ContactMode::Free {
            self.gaps += 1.0;
        }
        self.phase = state.mode;
        self.phase_u = state.u;
    }

    /// (Σ|Δu| over the slack and capped phases, phases in the gap) up to `state`, the phase in
    /// progress included.
    pub fn now(&self, state: &PlantState) -> (f64, f64) {
        let mut monotone = self.monotone;
        if Self::monotone_in(self.phase) {
            monotone += (state.u - self.phase_u).abs();
        }
        let opened = state.mode == ContactMode::Free && self.phase != ContactMode::Free;
        (monotone, self.gaps + if opened { 1.0 } else { 0.0 })
    }

    /// As numbers, for FMU states: tracked (0 or 1), the phase's mode code, phase_u, monotone,
    /// gaps.
    pub fn words(&self) -> [f64; 5] {
        [
            if self.tracked { 1.0 } else { 0.0 },
            self.phase.code() as f64,
            self.phase_u,
            self.monotone,
            self.gaps,
        ]
    }

    /// From [`EventTerms::words`], refused unless they could be such words.
    pub fn from_words(w: &[f64; 5]) -> Result<EventTerms, String> {
        let phase = ContactMode::from_code(w[1] as i32)
            .filter(|m| m.code() as f64 == w[1])
            .ok_or_else(|| format!("unknown contact mode {}", w[1]))?;
        if !(w[0] == 0.0 || w[0] == 1.0) {
            return Err(format!("tracking flag {} is neither 0 nor 1", w[0]));
        }
        if !(w.iter().all(|x| x.is_finite()) && w[3] >= 0.0 && w[4] >= 0.0 && w[4].fract() == 0.0) {
            return Err(format!("the trajectory's terms {w:?} are not finite, >= 0 counts"));
        }
        Ok(EventTerms {
            tracked: w[0] == 1.0,
            phase,
            phase_u: w[2],
            monotone: w[3],
            gaps: w[4],
        })
    }
}

impl Simulation {
    /// The plant at the start: parameters validated (the error names the parameter), state
    /// from the start values of θ and ω, bound at elapsed time 0.
    pub fn build(model: &ModelInfo, v: &Values) -> Result<Simulation, FmuError> {
        let mut sim = template(model, v)?;
        let state = adapter::initial_state(sim.plant(), v);
        let inputs = adapter::inputs(sim.plant(), v, &[0.0; adapter::MAX_INPUTS]);
        sim.set_state(state, &inputs);
        sim.check_state(&sim.state, format_args!("the initial state overflows"))?;
        Ok(sim)
    }

    /// Makes `state` the plant's, with friction each body's mode by the law of stiction under
    /// `inputs` (docs/model.md §12: the initial mode follows the law at the start time; a state
    /// the importer sets likewise).
    pub fn set_state(&mut self, state: PlantState, inputs: &Inputs) {
        match &mut self.friction {
            None => self.state = state,
            Some(f) => self.state = f.start(&state, inputs),
        }
    }

    /// Sets the continuous states of Model Exchange: each body's friction mode is a discrete
    /// state, kept until Event Mode (docs/model.md §12).
    pub fn set_continuous(&mut self, state: PlantState) {
        if let Some(f) = &mut self.friction {
            f.restore(&state, f.bodies());
        }
        self.state = state;
    }

    /// The friction surfaces' event indicators [stop_m, breakaway_m, stop_L, breakaway_L]
    /// (docs/model.md §12); 1 without friction.
    pub fn friction_indicators(&self, inputs: &Inputs) -> [f64; 4] {
        self.friction
            .as_ref()
            .map_or([1.0; 4], |f| f.indicators(&self.state, inputs))
    }

    /// Model Exchange's Event Mode: each body's friction mode by the law at the state in force
    /// (docs/model.md §12). Returns whether a state changed (a body that sticks is set at rest).
    pub fn settle_friction(&mut self, inputs: &Inputs) -> bool {
        let plant = self.stepper.plant();
        let Some(f) = &mut self.friction else {
            return false;
        };
        match f.settle(plant, &self.state, inputs) {
            Some(state) => {
                self.state = state;
                true
            }
            None => false,
        }
    }

    /// Body `j`'s `sliding` output (0 the motor, 1 the load; docs/model.md §12).
    pub fn sliding(&self, j: usize) -> i32 {
        match &self.friction {
            None => friction::sign_of(friction::speed(&self.state, j)),
            Some(f) => f.sliding(j, &self.state),
        }
    }

    /// Whether the bounds stand for this plant: not on a web line with Coulomb friction, whose
    /// loop's friction terms are not built (docs/model.md §12); they are +∞ then. A drive train
    /// with friction adds them (§10).
    pub fn bounded(&self) -> bool {
        self.friction.is_none() || self.plant().web().is_none()
    }

    /// Whether `state` is finite and its force ψ = K·dz(u, g) too: finite but huge angles,
    /// speeds or parameters must not turn into ∞/NaN outputs. Runs on every fmi2DoStep.
    #[inline]
    pub fn state_ok(&self, state: &PlantState) -> bool {
        state.is_finite() & self.plant().force(state.u, state.du).is_finite()
    }

    /// The refusal of a state that is not `state_ok`, saying `what` overflows.
    #[cold]
    pub fn overflow(&self, state: &PlantState, what: std::fmt::Arguments<'_>) -> FmuError {
        let psi = self.plant().force(state.u, state.du);
        let tension = match self.plant().web() {
            Some(_) => format!(", T = {:e}", state.tension),
            None => String::new(),
        };
        FmuError::Overflow(format!(
            "{what}: theta_m = {:e}, omega_m = {:e}, theta_L = {:e}, omega_L = {:e}{tension}, u = {:e}, psi = \
             {psi:e}; reduce the start values, inputs or parameters",
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

    /// The vector field z' = d/dt [θ_m, ω_m, θ_L, ω_L, T] at `state` under `inputs`, refused unless
    /// finite (say `what` overflows): the accelerations of huge torques over small inertias
    /// leave f64. T' is 0 without a web span.
    #[inline]
    pub fn rates(
        &self,
        state: &PlantState,
        inputs: &Inputs,
        what: std::fmt::Arguments<'_>,
    ) -> Result<StateVector, FmuError> {
        let rates = match &self.friction {
            None => self.frictionless_rates(state, inputs),
            // In the held friction modes (docs/model.md §12).
            Some(f) => f.rates(state, inputs),
        };
        if rates_finite(&rates) {
            return Ok(rates);
        }
        Err(rates_overflow(rates, inputs, self.plant().web().is_some(), what))
    }

    /// [`Simulation::rates`] written into `out` (z′'s first `out.len()` entries, at most
    /// [`adapter::MAX_STATES`]): Model Exchange's derivatives. Without friction the field goes
    /// from registers to `out` value by value: merged with the friction's in one array (as in
    /// `rates`), it was stored in pieces and copied on in wider ones, a store-forwarding stall
    /// on the solver's most frequent call (BENCHMARKS.md, `me_get_derivatives`: 34.2 ns before,
    /// 17.3 ns after).
    #[inline]
    pub fn write_rates(
        &self,
        state: &PlantState,
        inputs: &Inputs,
        out: &mut [f64],
        what: std::fmt::Arguments<'_>,
    ) -> Result<(), FmuError> {
        if self.friction.is_some() {
            let rates = self.rates(state, inputs, what)?;
            out.copy_from_slice(&rates[..out.len()]);
            return Ok(());
        }
        let rates = self.frictionless_rates(state, inputs);
        if !rates_finite(&rates) {
            return Err(rates_overflow(rates, inputs, self.plant().web().is_some(), what));
        }
        for (slot, x) in out.iter_mut().zip(rates) {
            *slot = x;
        }
        Ok(())
    }

    /// The vector field of the plant without friction (T' 0 without a web span).
    #[inline(always)]
    fn frictionless_rates(&self, state: &PlantState, inputs: &Inputs) -> StateVector {
        let plant = self.plant();
        let [a, b, c, d] = plant.rates(state, inputs.tau_m, inputs.tau_l);
        [a, b, c, d, plant.tension_rate(state, inputs.span)]
    }

    /// Advances the plant over `h` when the stepper's quiet path applies (see
    /// [`Stepper::quiet_step`]) and it stays finite; returns whether it did. When it did not,
    /// nothing changed and the general path does the step, or says why it cannot.
    #[inline]
    pub fn quiet_step(&mut self, inputs: &Inputs, h: f64) -> bool {
        if self.friction.is_some() {
            return self.quiet_sliding_step(inputs, h);
        }
        let Some(next) = self.stepper.quiet_step(&self.state, inputs, h) else {
            return false;
        };
        // `next` is finite: its force is what is left of `state_ok`.
        if !finite(self.plant().force(next.u, next.du)) {
            return false;
        }
        self.state = next;
        self.bounds_lag(h);
        true
    }

    /// `quiet_step` with friction: while every body with friction slides and no speed can reach
    /// 0 within the step, the frictionless plant under the bearings' torques takes it
    /// ([`Friction::quiet_step`]), and the chain follows in its modes.
    #[inline(never)]
    fn quiet_sliding_step(&mut self, inputs: &Inputs, h: f64) -> bool {
        let friction = self.friction.as_ref().expect("a plant with friction");
        let Some(next) = friction.quiet_step(&self.state, inputs, h) else {
            return false;
        };
        self.state = next;
        self.bounds_lag(h);
        true
    }

    /// The plant advanced by `h` ([`BoundClock::lag`]).
    #[inline]
    pub fn bounds_lag(&mut self, h: f64) {
        self.clock.lag(h);
    }

    /// Brings the bounds up to the plant ([`BoundClock::current`]).
    pub fn bounds_current(&mut self) -> Result<(), BoundError> {
        self.clock.current()
    }

    /// Rebuilds from saved values and continues from a saved plant and bound state, the bounds
    /// lagging `bounds_behind` behind the plant.
    pub fn restore(
        model: &ModelInfo,
        v: &Values,
        state: PlantState,
        bodies: [crate::physics::chain::BodyMode; 2],
        bound: &[f64],
        bounds_behind: f64,
        events: EventTerms,
    ) -> Result<Simulation, FmuError> {
        let mut sim = Simulation::build(model, v)?;
        if !state.is_finite() {
            return Err(FmuError::StateRefused("the plant state is not finite".into()));
        }
        sim.check_state(&state, format_args!("the saved plant state overflows"))?;
        sim.state = state;
        if let Some(f) = &mut sim.friction {
            f.restore(&state, bodies);
        }
        sim.clock.bound.restore(bound)?;
        sim.clock.set_behind(bounds_behind)?;
        sim.events = events;
        Ok(sim)
    }

    /// Brings the bound to `elapsed` seconds after the start time ([`BoundClock::at`]).
    pub fn bound_at(&mut self, elapsed: f64) -> Result<(), BoundError> {
        self.clock.at(elapsed)
    }

    pub fn plant(&self) -> &Plant {
        self.stepper.plant()
    }

    /// What `bound` and `bound_T` follow on the trajectory (docs/model.md §3, "With a damper"):
    /// the stepper's variation (Co-Simulation) or the phases between the importer's events
    /// (Model Exchange); each grows at |u′| where it counts.
    pub fn trajectory(&self) -> Trajectory {
        let speed = self.state.du.abs();
        if self.events.tracked {
            let (monotone, gaps) = self.events.now(&self.state);
            let rate = if EventTerms::monotone_in(self.events.phase) {
                speed
            } else {
                0.0
            };
            Trajectory::AtEvents { monotone, gaps, rate }
        } else {
            let rate = if self.state.mode.in_contact() { 0.0 } else { speed };
            Trajectory::Stepped {
                variation: self.state.variation,
                rate,
            }
        }
    }

    /// bound_sup, +∞ when unbounded (docs/model.md §3).
    pub fn bound_sup_value(&self) -> f64 {
        self.clock.bound.sup().unwrap_or(f64::INFINITY)
    }

    /// bound_T_sup of a web line, +∞ when unbounded (docs/model.md §8).
    pub fn bound_t_sup_value(&self) -> f64 {
        self.clock.bound.sup_t().unwrap_or(f64::INFINITY)
    }
}

/// Whether a vector field is finite: θ' = ω is with the state; the rest are checked in one branch.
#[inline(always)]
fn rates_finite(rates: &StateVector) -> bool {
    finite(rates[1]) & finite(rates[3]) & finite(rates[4])
}

#[cold]
#[inline(never)]
fn rates_overflow(rates: StateVector, inputs: &Inputs, web: bool, what: std::fmt::Arguments<'_>) -> FmuError {
    let (tension, span) = match web {
        true => (
            format!(", der(T) = {:e}", rates[4]),
            format!(", the span's forcing (v_ref*T_in - EA*v_in)/L_w = {:e}", inputs.span),
        ),
        false => (String::new(), String::new()),
    };
    FmuError::Overflow(format!(
        "{what}: der(omega_m) = {:e}, der(omega_L) = {:e}{tension} with tau_m = {:e}, tau_L = {:e}{span}; reduce \
         the inputs, start values or parameters",
        rates[1], rates[3], inputs.tau_m, inputs.tau_l
    ))
}

/// What a bound does with time: advance by h (refusing an advance longer than it accepts in one
/// call with [`BoundError::AdvanceTooLong`]), say its elapsed time, start over.
pub trait Advancing {
    fn advance(&mut self, h: f64) -> Result<(), BoundError>;
    fn elapsed(&self) -> f64;
    fn reset(&mut self);
    fn max_advance(&self) -> f64;
}

impl Advancing for Bounds {
    fn advance(&mut self, h: f64) -> Result<(), BoundError> {
        Bounds::advance(self, h)
    }
    fn elapsed(&self) -> f64 {
        Bounds::elapsed(self)
    }
    fn reset(&mut self) {
        Bounds::reset(self)
    }
    fn max_advance(&self) -> f64 {
        Bounds::max_advance(self)
    }
}

impl Advancing for crate::physics::chain::TwoStageBound {
    fn advance(&mut self, h: f64) -> Result<(), BoundError> {
        crate::physics::chain::TwoStageBound::advance(self, h)
    }
    fn elapsed(&self) -> f64 {
        crate::physics::chain::TwoStageBound::elapsed(self)
    }
    fn reset(&mut self) {
        crate::physics::chain::TwoStageBound::reset(self)
    }
    fn max_advance(&self) -> f64 {
        crate::physics::chain::TwoStageBound::max_advance(self)
    }
}

/// A bound and how far it lags behind the plant. Co-Simulation steps advance the plant only
/// and add their length to the lag; the bound, a function of elapsed time alone, is brought up
/// to date when read ([`BoundClock::current`]), or by a step once it lags by the longest step,
/// so that reading it after any number of unread steps costs at most that much work. In Model
/// Exchange it is brought to the time the importer sets ([`BoundClock::at`]).
#[derive(Clone, Debug)]
pub struct BoundClock<B> {
    pub bound: B,
    /// How far the bound lags behind the plant [s] (0 in Model Exchange).
    pub behind: f64,
    /// The lag at which a step brings the bound along: the longest step, or the longest advance
    /// the bound accepts if that is shorter.
    limit: f64,
    /// The last attempt to bring the bound up to date failed (it overflows): steps no longer
    /// try, reads do (and report it).
    refused: bool,
}

impl<B: Advancing> BoundClock<B> {
    /// `bound` at elapsed time 0, for a plant whose longest step is `longest`.
    pub fn new(bound: B, longest: f64) -> Self {
        let limit = longest.min(bound.max_advance());
        BoundClock {
            bound,
            behind: 0.0,
            limit,
            refused: false,
        }
    }

    /// The plant advanced by `h`: the bound lags behind by that much more. Once it lags by the
    /// longest step it is brought along (an error there is the one a read reports, and the steps
    /// after it do not try again).
    #[inline]
    pub fn lag(&mut self, h: f64) {
        self.behind += h;
        if self.behind >= self.limit && !self.refused {
            self.current().ok();
        }
    }

    /// Brings the bound up to the plant: advances it by the time it lags behind, in one advance
    /// when it accepts it (so that a bound read after every step is exactly one advanced step by
    /// step), else in the longest advances it accepts. On error it stays at some time between,
    /// and still lags behind by the rest. Out of line: the steps' hot path calls it only once
    /// the bound lags by the longest step.
    #[inline(never)]
    pub fn current(&mut self) -> Result<(), BoundError> {
        let result = self.catch_up();
        self.refused = result.is_err();
        result
    }

    /// At most [`MAX_BOUND_ADVANCES`] advances, as [`BoundClock::at`]: a lag the bound cannot
    /// follow within them (extreme parameters, where its longest advance is far shorter than a
    /// step) is refused rather than followed for ever.
    fn catch_up(&mut self) -> Result<(), BoundError> {
        for _ in 0..MAX_BOUND_ADVANCES {
            let h = self.behind;
            if h <= 0.0 {
                return Ok(());
            }
            match self.bound.advance(h) {
                Ok(()) => self.behind = 0.0,
                Err(BoundError::AdvanceTooLong { max_h, .. }) => {
                    self.bound.advance(max_h)?;
                    self.behind = h - max_h;
                }
                Err(e) => return Err(e),
            }
        }
        if self.behind <= 0.0 {
            return Ok(());
        }
        let reached = self.bound.elapsed();
        Err(BoundError::TooFar {
            elapsed: reached + self.behind,
            reached,
        })
    }

    /// Sets the lag of a restored state, refused unless finite and >= 0.
    pub fn set_behind(&mut self, behind: f64) -> Result<(), FmuError> {
        if !(behind.is_finite() && behind >= 0.0) {
            return Err(FmuError::StateRefused(format!(
                "the bounds' lag {behind} s must be finite and >= 0"
            )));
        }
        self.behind = behind;
        Ok(())
    }

    /// Brings the bound to `elapsed` seconds after the start time (Model Exchange, where time
    /// is whatever the importer's solver sets): forward by advancing, backward by starting over,
    /// the bound being a function of elapsed time alone. Once the loop's response has decayed
    /// (settled) an advance of any length is one step; before, advances are cut to the longest
    /// the bound accepts, a bounded number of them per call, so that a time far out on a loop
    /// that never settles (or settles only after a very long time) is refused rather than
    /// computed for ever. On error the bound is left at some time between its old one and
    /// `elapsed`.
    pub fn at(&mut self, elapsed: f64) -> Result<(), BoundError> {
        if elapsed < self.bound.elapsed() {
            self.bound.reset();
        }
        for _ in 0..MAX_BOUND_ADVANCES {
            let now = self.bound.elapsed();
            let left = elapsed - now;
            if left <= 0.0 || left.is_nan() {
                return Ok(());
            }
            match self.bound.advance(left) {
                Ok(()) => {}
                Err(BoundError::AdvanceTooLong { max_h, .. }) => self.bound.advance(max_h)?,
                Err(e) => return Err(e),
            }
            // A remainder below the resolution of `now` changes nothing: done.
            if self.bound.elapsed() == now {
                return Ok(());
            }
        }
        Err(BoundError::TooFar {
            elapsed,
            reached: self.bound.elapsed(),
        })
    }
}

/// Advances of the longest length (the bound's `MAX_PIECES` pieces) allowed in one
/// [`Simulation::bound_at`]. An advance locates every sign change of h in it: on an undamped
/// loop about 0.4 s of work (shaft rig, release build), on a decaying one far less once h is
/// small, and at most about 2 s where h hovers at zero through every piece (extreme
/// parameters; the searches' budget is capped, `roots::work_budget`). The rigs' loops settle
/// within the first; after that an advance of any length is one step.
pub const MAX_BOUND_ADVANCES: usize = 4;

/// The single gap's built physics ([`Templates`]).
static TEMPLATES: Templates<Simulation> = Templates::new();

fn template(model: &ModelInfo, v: &Values) -> Result<Simulation, FmuError> {
    TEMPLATES.get(model, v, || build(model, v))
}

/// The simulation of `model` at the parameter values of `v`, at the zero state.
fn build(model: &ModelInfo, v: &Values) -> Result<Simulation, FmuError> {
    let params = adapter::plant_params(model, v)
        .ok_or_else(|| FmuError::InvalidArgument(format!("{} is a controller: it has no plant", model.identifier)))?;
    let plant = Plant::new(params)?;
    let (speed, tension) = adapter::gains(v);
    let friction = Friction::of(&plant, friction::coulomb_of(v))?;
    // A drive train with friction adds the friction's terms (docs/model.md §10); a web line
    // with friction has no bound ([`Simulation::bounded`]).
    let bound = match &friction {
        Some(f) if plant.web().is_none() => {
            Bounds::with_friction(&plant, speed, OneStageFrictionBound::new(f.chain(), speed)?)?
        }
        _ => Bounds::new(&plant, speed, tension)?,
    };
    let state = PlantState::new(&plant, 0.0, 0.0, 0.0, 0.0);
    let longest = friction
        .as_ref()
        .map_or(max_step(&plant), |f| max_step(&plant).min(f.max_step()));
    Ok(Simulation {
        max_step: longest,
        stepper: Stepper::new(plant),
        state,
        friction: friction.map(Box::new),
        clock: BoundClock::new(bound, longest),
        events: EventTerms::UNTRACKED,
    })
}

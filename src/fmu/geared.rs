//! The physics behind one instance of a two-stage gearbox (`BacklashTwoStage`, docs/model.md
//! §10): the chain of two stages stepped exactly between the switches of either stage or any
//! body's friction, its state, and its bound (one disturbance per stage, one term per body with
//! friction), assembled from the variable values. The single-gap plants keep their own
//! [`super::simulation::Simulation`]; what both do with the bounds' lag is shared
//! ([`super::simulation::BoundClock`]).

use super::adapter::{self, StateEntry, Values};
use super::error::FmuError;
use super::simulation::BoundClock;
use super::templates::Templates;
use super::variables::{Kind, ModelInfo, Symbol};
use crate::physics::chain::{
    BodyMode, Chain, ChainEvent, ChainMode, ChainState, Motion, TwoStageBound, TwoStageStepper,
};
use crate::physics::{finite, ContactMode, Inputs, StepError};

/// The bodies as the chain numbers them, with the letter their variables carry: 0 the motor,
/// 1 the intermediate shaft, 2 the load.
pub const BODIES: [(&str, &str); 3] = [("m", "motor"), ("i", "intermediate shaft"), ("L", "load")];

/// How many event indicators a two-stage plant has: each stage's six contact surfaces, then
/// each body's two friction surfaces.
pub const INDICATORS: usize = 2 * Chain::<2>::STAGE_INDICATORS + 2 * 3;

#[derive(Clone, Debug)]
pub struct Geared {
    pub stepper: TwoStageStepper,
    /// The chain's state, in its mode (every body's friction mode included).
    pub state: ChainState<2>,
    /// The bound and how far it lags behind the chain.
    pub clock: BoundClock<TwoStageBound>,
    /// The longest step accepted.
    pub max_step: f64,
}

/// The chain body of a `Sliding` slot (0 the motor, 1 the load, 2 the intermediate shaft).
pub fn body_of_slot(slot: usize) -> usize {
    match slot {
        0 => 0,
        1 => 2,
        _ => 1,
    }
}

/// The gearboxes' built physics ([`Templates`]).
static GEARBOXES: Templates<Geared> = Templates::new();

impl Geared {
    /// The gearbox at the start: parameters validated (the error names the parameter), the
    /// state from the start values, each body's friction mode by the law of stiction under the
    /// inputs at the start (docs/model.md §12), the bound at elapsed time 0.
    pub fn build(model: &ModelInfo, v: &Values) -> Result<Geared, FmuError> {
        let mut geared = GEARBOXES.get(model, v, || Geared::at_rest(model, v))?;
        let at = |e: StateEntry| v[e.symbol().index()];
        let motion = |theta, omega| Motion {
            theta: at(theta),
            omega: at(omega),
        };
        geared.state = ChainState::new(
            geared.chain(),
            motion(StateEntry::ThetaM, StateEntry::OmegaM),
            [
                motion(StateEntry::ThetaI, StateEntry::OmegaI),
                motion(StateEntry::ThetaL, StateEntry::OmegaL),
            ],
        );
        geared
            .stepper
            .apply_stiction(&mut geared.state, &inputs(v, &[0.0; adapter::MAX_INPUTS]));
        geared.check(&geared.state, format_args!("the initial state overflows"))?;
        Ok(geared)
    }

    /// What the parameter values of `v` alone determine (the chain, its stepper, the bound at
    /// elapsed time 0), at the zero state.
    fn at_rest(model: &ModelInfo, v: &Values) -> Result<Geared, FmuError> {
        let Kind::TwoStage(mapping) = model.kind else {
            return Err(FmuError::InvalidArgument(format!(
                "{} is not a two-stage gearbox",
                model.identifier
            )));
        };
        let params = mapping(&|name| model.by_name(name).map_or(f64::NAN, |var| v[var.symbol.index()]));
        let chain = Chain::new(params).map_err(|e| FmuError::InvalidArgument(e.to_string()))?;
        let (speed, _) = adapter::gains(v);
        let bound = TwoStageBound::new(&chain, speed)?;
        let rest = Motion { theta: 0.0, omega: 0.0 };
        let state = ChainState::new(&chain, rest, [rest, rest]);
        let stepper = TwoStageStepper::new(chain);
        let max_step = stepper.max_step();
        Ok(Geared {
            clock: BoundClock::new(bound, max_step),
            stepper,
            state,
            max_step,
        })
    }

    pub fn chain(&self) -> &Chain<2> {
        self.stepper.chain()
    }

    /// Refused unless `state` and its forces are finite (say `what` overflows).
    pub fn check(&self, state: &ChainState<2>, what: std::fmt::Arguments<'_>) -> Result<(), FmuError> {
        let forces = state.forces(self.chain());
        if state.is_finite() && forces.iter().all(|f| finite(*f)) {
            return Ok(());
        }
        let z = Chain::<2>::z_of(state);
        Err(FmuError::Overflow(format!(
            "{what}: theta_m = {:e}, omega_m = {:e}, theta_i = {:e}, omega_i = {:e}, theta_L = {:e}, omega_L = \
             {:e}, psi_1 = {:e}, psi_2 = {:e}; reduce the start values, inputs or parameters",
            z[0], z[1], z[2], z[3], z[4], z[5], forces[0], forces[1]
        )))
    }

    /// [`Geared::check`] of a state the stepper returned, which is finite (the stepper refuses
    /// one that is not: `StepError::Overflow`): only its forces can still overflow.
    #[inline]
    pub fn check_stepped(&self, state: &ChainState<2>, what: std::fmt::Arguments<'_>) -> Result<(), FmuError> {
        if state.forces(self.chain()).iter().all(|f| finite(*f)) {
            return Ok(());
        }
        self.check(state, what)
    }

    /// A state entry's value.
    pub fn entry(&self, entry: StateEntry) -> f64 {
        Chain::<2>::z_of(&self.state)[entry.chain_index()]
    }

    /// z = [θ_m, ω_m, θ_i, ω_i, θ_L, ω_L].
    pub fn z(&self) -> [f64; 6] {
        let z = Chain::<2>::z_of(&self.state);
        std::array::from_fn(|i| z[i])
    }

    /// The state at z, refused unless finite with its forces: in Model Exchange with the bodies'
    /// friction modes held (discrete states until Event Mode, docs/model.md §12), in
    /// Co-Simulation each body's mode by the law of stiction under `inputs`, as at a step's start.
    pub fn state_at(&mut self, z: &[f64; 6], stiction: Option<&Inputs>) -> Result<ChainState<2>, FmuError> {
        let mut full = z.to_vec();
        full.push(0.0);
        let mut state = match stiction {
            None => self.chain().state_in(&full, &self.state.mode),
            Some(_) => self.chain().state_at(&full),
        };
        self.check(&state, format_args!("the continuous states overflow"))?;
        if let Some(inputs) = stiction {
            self.stepper.apply_stiction(&mut state, inputs);
        }
        Ok(state)
    }

    /// ψ of stage `j` (0 the first).
    pub fn psi(&self, j: usize) -> f64 {
        self.state.forces(self.chain())[j]
    }

    /// Stage `j`'s `contact`: the sign of its ψ in the mode in force (without gap or damper the
    /// sign of u, as the single gap's, docs/model.md §4).
    pub fn contact(&self, j: usize) -> i32 {
        let s = self.chain().stage(j);
        if s.g == 0.0 && s.d() == 0.0 {
            let u = self.state.u[j];
            return (u > 0.0) as i32 - (u < 0.0) as i32;
        }
        self.state.mode.stages()[j].as_i32()
    }

    /// A body's `sliding` output, by its slot (see [`body_of_slot`]): its friction mode with
    /// friction, the sign of its speed without.
    pub fn sliding(&self, slot: usize) -> i32 {
        let j = body_of_slot(slot);
        if self.chain().body(j).friction.tau_c > 0.0 {
            self.state.mode.body(j).sliding()
        } else {
            let w = self.state.body(j).omega;
            (w > 0.0) as i32 - (w < 0.0) as i32
        }
    }

    /// Whether the bound stands in this flavour: in Model Exchange a damped stage's trajectory
    /// term is not followed (the importer's solver steps through its modes), so the bound is +∞
    /// there with a damper (docs/model.md §10).
    pub fn bounded(&self, model_exchange: bool) -> bool {
        !(model_exchange && (0..2).any(|j| self.chain().stage(j).d() > 0.0))
    }

    /// `bound` at the bound's time: the gaps' and the friction's terms, with a damper the
    /// trajectory's (the stepper follows each stage's variation).
    pub fn bound(&self) -> f64 {
        self.clock.bound.damped_bound(&self.state.variation)
    }

    /// `bound_sup`, +∞ when the loop is unbounded.
    pub fn bound_sup(&self) -> f64 {
        self.clock.bound.sup().unwrap_or(f64::INFINITY)
    }

    /// z′ at the state in its mode under `inputs` (a stuck body does not accelerate), refused
    /// unless finite.
    pub fn rates(&self, inputs: &Inputs) -> Result<[f64; 6], FmuError> {
        let r = self.chain().rates(&self.state, inputs.tau_m, inputs.tau_l, 0.0);
        if let Some(x) = r.iter().find(|x| !x.is_finite()) {
            return Err(FmuError::Overflow(format!(
                "the state derivatives overflow ({x:e}) with tau_m = {:e}, tau_L = {:e}; reduce the inputs, start \
                 values or parameters",
                inputs.tau_m, inputs.tau_l
            )));
        }
        Ok(std::array::from_fn(|i| r[i]))
    }

    /// τ_h of body `j`: every torque on it but its bearing's.
    fn holding(&self, inputs: &Inputs, j: usize) -> f64 {
        self.stepper.holding(&self.state, inputs, j)
    }

    /// The event indicators: each stage's contact surfaces (docs/model.md §6), then each body's
    /// [stop, breakaway] (§12: a sliding body's speed, peak·τ_c − |τ_h| of a stuck one; 1 where
    /// the body has no such surface).
    pub fn indicators(&self, inputs: &Inputs) -> [f64; INDICATORS] {
        let mut out = [1.0; INDICATORS];
        let contact = self.chain().event_indicators(&self.state);
        out[..contact.len()].copy_from_slice(&contact);
        for j in 0..3 {
            let c = self.chain().body(j).friction;
            if c.tau_c == 0.0 {
                continue;
            }
            let at = contact.len() + 2 * j;
            match self.state.mode.body(j) {
                BodyMode::Stuck => out[at + 1] = c.breakaway() - self.holding(inputs, j).abs(),
                BodyMode::Forward | BodyMode::Backward => out[at] = self.state.body(j).omega,
            }
        }
        out
    }

    /// Model Exchange's Event Mode: each body's friction mode by the law of stiction at the
    /// state under `inputs`; returns whether a state changed (a body that sticks is set at
    /// rest).
    pub fn settle(&mut self, inputs: &Inputs) -> bool {
        if !self.chain().has_friction() {
            return false;
        }
        let before = self.state;
        // The law from the state's speeds: a body at rest (or whose speed the solver took
        // through 0) takes its mode afresh.
        let mut state = self.state;
        for j in 0..3 {
            let w = state.body(j).omega;
            let mode = state.mode.body(j);
            let through = match mode {
                BodyMode::Forward => w <= 0.0,
                BodyMode::Backward => w >= 0.0,
                BodyMode::Stuck => false,
            };
            if through && self.chain().body(j).friction.tau_c > 0.0 {
                state = self.with_speed_zero(&state, j);
            }
        }
        self.stepper.apply_stiction(&mut state, inputs);
        self.state = state;
        Chain::<2>::z_of(&state) != Chain::<2>::z_of(&before)
    }

    /// `state` with body `j` at rest (its angle kept), the stages' u and u′ from the motions.
    fn with_speed_zero(&self, state: &ChainState<2>, j: usize) -> ChainState<2> {
        let mut z = Chain::<2>::z_of(state);
        z[2 * j + 1] = 0.0;
        let mut next = self.chain().state_at(&z);
        for b in 0..3 {
            next.mode.set_body(b, state.mode.body(b));
        }
        next.mode.set_body(j, BodyMode::Stuck);
        next.variation = state.variation;
        next
    }

    /// The step of Co-Simulation over `h` under `inputs`, in place: where it stopped (with
    /// `early_return`, at the first switch inside it), each switch passed to `record`. A refused
    /// step leaves the state as it was (the stepper writes it only on success); the bound is
    /// moved on by [`Geared::lag`] once the step is accepted. An event-free step of the size
    /// the stepper last took goes its quiet path ([`TwoStageStepper::quiet_step`], the same state
    /// bit for bit); the general step works in place, which spares a copy of the state the
    /// stepper has just written, whose read-back stalls.
    pub fn step(
        &mut self,
        inputs: &Inputs,
        h: f64,
        early_return: bool,
        record: &mut dyn FnMut(ChainEvent),
    ) -> Result<Option<f64>, StepError> {
        if let Some(next) = self.stepper.quiet_step(&self.state, inputs, h) {
            self.state = next;
            return Ok(None);
        }
        if early_return {
            self.stepper.step_to_first_switch(&mut self.state, inputs, h, record)
        } else {
            self.stepper.step(&mut self.state, inputs, h, record)?;
            Ok(None)
        }
    }

    /// The state after an accepted step of `advanced` seconds: the bound lags that much more.
    pub fn lag(&mut self, advanced: f64) {
        self.clock.lag(advanced);
    }

    /// The stage mode a contact switch names, for its log line.
    pub fn half_gap(&self, stage: usize) -> f64 {
        self.chain().stage(stage).g
    }

    /// The FMU state's words of the chain: z, each stage's u, u′ and variation, the stages'
    /// mode codes and the bodies' friction modes.
    pub fn words(&self) -> Vec<f64> {
        let s = &self.state;
        let mut w: Vec<f64> = Chain::<2>::z_of(s)[..6].to_vec();
        for j in 0..2 {
            w.extend([s.u[j], s.du[j], s.variation[j], f64::from(s.mode.stages()[j].code())]);
        }
        w.extend((0..3).map(|j| f64::from(s.mode.body(j).sliding())));
        w
    }

    /// How many [`Geared::words`] there are.
    pub const WORDS: usize = 6 + 2 * 4 + 3;

    /// The names of [`Geared::words`], for the reasons of a refusal.
    pub const WORD_NAMES: [&'static str; Self::WORDS] = [
        "theta_m",
        "omega_m",
        "theta_i",
        "omega_i",
        "theta_L",
        "omega_L",
        "u_1",
        "du_1/dt",
        "V_1",
        "the contact mode of stage 1",
        "u_2",
        "du_2/dt",
        "V_2",
        "the contact mode of stage 2",
        "the friction mode of the motor",
        "the friction mode of the intermediate shaft",
        "the friction mode of the load",
    ];

    /// Refused unless `w` could be [`Geared::words`]: finite, each V ≥ 0, each stage's a known
    /// contact mode code and each body's a friction mode (−1, 0, +1).
    pub fn check_words(w: &[f64]) -> Result<(), FmuError> {
        let refuse = |why: String| Err(FmuError::StateRefused(why));
        if w.len() != Self::WORDS {
            return refuse(format!("{} words of the gearbox's state", w.len()));
        }
        if let Some((i, x)) = w.iter().enumerate().find(|(_, x)| !x.is_finite()) {
            return refuse(format!("{} = {x} is not finite", Self::WORD_NAMES[i]));
        }
        for j in 0..2 {
            let at = 6 + 4 * j;
            if w[at + 2] < 0.0 {
                return refuse(format!("V_{} = {} must be >= 0", j + 1, w[at + 2]));
            }
            let code = w[at + 3];
            if ContactMode::from_code(code as i32).is_none_or(|m| f64::from(m.code()) != code) {
                return refuse(format!("unknown contact mode {code} of stage {}", j + 1));
            }
        }
        for j in 0..3 {
            let x = w[14 + j];
            if !(x == 1.0 || x == 0.0 || x == -1.0) {
                return refuse(format!("unknown friction mode {x} of the {}", BODIES[j].1));
            }
        }
        Ok(())
    }

    /// The state of [`Geared::words`], refused unless it could be such words.
    pub fn state_of_words(&self, w: &[f64]) -> Result<ChainState<2>, FmuError> {
        Self::check_words(w)?;
        let mut z = w[..6].to_vec();
        z.push(0.0);
        let mut state = self.chain().state_at(&z);
        let mut stages = [ContactMode::Free; 2];
        for (j, stage) in stages.iter_mut().enumerate() {
            let at = 6 + 4 * j;
            let code = w[at + 3];
            *stage = ContactMode::from_code(code as i32)
                .filter(|m| f64::from(m.code()) == code)
                .ok_or_else(|| FmuError::StateRefused(format!("unknown contact mode {code} of stage {}", j + 1)))?;
            state.u[j] = w[at];
            state.du[j] = w[at + 1];
            if w[at + 2] < 0.0 {
                return Err(FmuError::StateRefused(format!(
                    "V_{} = {} must be >= 0",
                    j + 1,
                    w[at + 2]
                )));
            }
            state.variation[j] = w[at + 2];
        }
        let mut mode = ChainMode::new(stages);
        for j in 0..3 {
            let body = match w[14 + j] {
                1.0 => BodyMode::Forward,
                0.0 => BodyMode::Stuck,
                -1.0 => BodyMode::Backward,
                x => {
                    return Err(FmuError::StateRefused(format!(
                        "unknown friction mode {x} of the {}",
                        BODIES[j].1
                    )))
                }
            };
            mode.set_body(j, body);
        }
        state.mode = mode;
        self.check(&state, format_args!("the saved state overflows"))?;
        Ok(state)
    }

    /// Rebuilds from saved values and continues from saved words, bound states and lag.
    pub fn restore(
        model: &ModelInfo,
        v: &Values,
        words: &[f64],
        bound: &[f64],
        bounds_behind: f64,
    ) -> Result<Geared, FmuError> {
        let mut geared = Geared::build(model, v)?;
        geared.state = geared.state_of_words(words)?;
        super::bounds::two_stage::restore(&mut geared.clock.bound, bound)?;
        geared.clock.set_behind(bounds_behind)?;
        Ok(geared)
    }
}

/// The inputs of a gearbox (τ_m, τ_L and their slopes; no web span).
pub fn inputs(v: &Values, slopes: &adapter::InputSlopes) -> Inputs {
    Inputs {
        tau_m: v[Symbol::TauM.index()],
        tau_l: v[Symbol::TauL.index()],
        dtau_m: slopes[0],
        dtau_l: slopes[1],
        span: 0.0,
        dspan: 0.0,
    }
}

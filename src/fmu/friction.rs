//! Bearing friction with stiction in an instance (docs/model.md §12): when a body's `tau_c` is
//! above 0 the plant is stepped as the one-stage chain with Coulomb friction on its bodies
//! (`backlash_physics::chain`), whose modes join each body's (sliding forward, backward, stuck)
//! to the contact mode. The simulation's plant state is the state, with friction as without (the
//! chain's state is the plant state in the bodies' modes, which this module holds), so that every
//! output reads the same quantities with and without friction; without friction the chain is not
//! built at all and the single-gap stepper runs as before, bit for bit. While every
//! body with friction slides, the plant is the frictionless one under the bearings' constant
//! torques: a step that no speed can cross 0 in is the sliding stepper's quiet step
//! (`backlash_physics::SlidingDriveStepper`), which the chain then follows.

use super::adapter::Values;
use super::error::FmuError;
use super::variables::Symbol;
use crate::physics::chain::{
    mode_of, BodyMode, ChainEvent, ChainMode, ChainParams, ChainState, Coulomb, Motion, OneStageStepper,
    OneStageWebStepper,
};
use crate::physics::stepper::Exact;
use crate::physics::{finite, Chain, Inputs, Plant, PlantState, StepError};

/// The motor (body 0) and the load (body 1), as the chain numbers them.
pub const BODIES: [&str; 2] = ["motor", "load"];

/// The one-stage chain that steps a plant with friction, without or with a web span (the
/// augmented systems differ in size).
#[derive(Clone, Debug)]
#[allow(clippy::large_enum_variant, reason = "the simulation boxes it whole")]
pub enum Friction {
    Drive(Chained<10, 8, 12>),
    Web(Chained<13, 10, 14>),
}

/// A chain stepper, the chain's mode in force, and the sliding stepper of the quiet path (`KS`
/// kernel outputs: `crate::physics::SlidingDriveStepper` or `SlidingWebStepper`).
#[derive(Clone, Debug)]
pub struct Chained<const N: usize, const KO: usize, const KS: usize> {
    stepper: crate::physics::chain::ChainStepper<1, N, KO>,
    mode: ChainMode<1>,
    /// The torques the bearings add in `mode` (0 on a body without friction), None when a body
    /// with friction is stuck: the quiet step's shift ([`Exact::quiet_sliding_step`]).
    bearings: Option<[f64; 2]>,
    quiet: Exact<N, KS>,
}

/// The friction of each body from the stored values: `tau_c_m`, `peak_m` on the motor,
/// `tau_c_L`, `peak_L` on the load.
pub fn coulomb_of(v: &Values) -> [Coulomb; 2] {
    let at = |s: Symbol| v[s.index()];
    [
        Coulomb {
            tau_c: at(Symbol::TauCM),
            peak: at(Symbol::PeakM),
        },
        Coulomb {
            tau_c: at(Symbol::TauCL),
            peak: at(Symbol::PeakL),
        },
    ]
}

impl<const N: usize, const KO: usize, const KS: usize> Chained<N, KO, KS> {
    fn new(stepper: crate::physics::chain::ChainStepper<1, N, KO>, mode: ChainMode<1>, plant: &Plant) -> Self {
        let mut chained = Chained {
            stepper,
            mode,
            bearings: None,
            quiet: Exact::new(*plant),
        };
        chained.set_mode(mode);
        chained
    }

    /// Makes `mode` the chain's, with the bearings' torques in it.
    fn set_mode(&mut self, mode: ChainMode<1>) {
        self.mode = mode;
        let mut bearings = Some([0.0; 2]);
        for j in 0..2 {
            let f = self.stepper.chain().body(j).friction;
            if f.tau_c > 0.0 {
                match (mode.body(j), &mut bearings) {
                    (BodyMode::Stuck, _) => bearings = None,
                    (sliding, Some(b)) => b[j] = sliding.friction_sign() * f.tau_c,
                    (_, None) => {}
                }
            }
        }
        self.bearings = bearings;
    }

    /// The chain's mode with the contact mode of `state` (the bodies' held).
    fn mode_at(&self, state: &PlantState) -> ChainMode<1> {
        mode_with(state, [self.mode.body(0), self.mode.body(1)])
    }
}

/// The chain mode of the contact mode of `state` and the bodies' modes `bodies`.
fn mode_with(state: &PlantState, bodies: [BodyMode; 2]) -> ChainMode<1> {
    let mut mode = ChainMode::new([state.mode]);
    mode.set_body(0, bodies[0]);
    mode.set_body(1, bodies[1]);
    mode
}

/// Dispatches to the chain of either size.
macro_rules! each {
    ($self:expr, $c:ident => $body:expr) => {
        match $self {
            Friction::Drive($c) => $body,
            Friction::Web($c) => $body,
        }
    };
}

impl Friction {
    /// The chain of `plant` with `coulomb` on its bodies, None when neither has friction (the
    /// plant then has no friction modes). Refused when the chain refuses its parameters.
    pub fn of(plant: &Plant, coulomb: [Coulomb; 2]) -> Result<Option<Friction>, FmuError> {
        if coulomb.iter().all(|c| c.tau_c == 0.0) {
            return Ok(None);
        }
        let mut params = ChainParams::from_plant(plant).expect("every plant is a one-stage chain");
        params.motor.friction = coulomb[0];
        params.driven[0].friction = coulomb[1];
        let chain = Chain::new(params).map_err(|e| FmuError::InvalidArgument(e.to_string()))?;
        let start = ChainState::new(&chain, Motion::default(), [Motion::default()]).mode;
        Ok(Some(match chain.web() {
            None => Friction::Drive(Chained::new(OneStageStepper::new(chain), start, plant)),
            Some(_) => Friction::Web(Chained::new(OneStageWebStepper::new(chain), start, plant)),
        }))
    }

    /// The chain it steps.
    pub fn chain(&self) -> &Chain<1> {
        each!(self, c => c.stepper.chain())
    }

    /// The longest step the chain accepts [s].
    pub fn max_step(&self) -> f64 {
        each!(self, c => c.stepper.max_step())
    }

    /// The chain's mode in force.
    pub fn mode(&self) -> ChainMode<1> {
        each!(self, c => c.mode)
    }

    /// Starts from `s` with the law of stiction applied with `inputs` (docs/model.md
    /// §12: the initial mode follows the law at the start time; a state set by the importer
    /// likewise); returns the state the law leaves.
    pub fn start(&mut self, s: &PlantState, inputs: &Inputs) -> PlantState {
        each!(self, c => {
            // Each body with friction by the sign of its speed, stuck at rest; then the law.
            let mode = mode_of(c.stepper.chain(), &[s.u], &[s.du], &[s.omega_m, s.omega_l]);
            let mut state = chain_state(s, mode);
            c.stepper.apply_stiction(&mut state, inputs);
            c.set_mode(state.mode);
            plant_state(&state)
        })
    }

    /// Continues from a plant state in the contact mode it has with the bodies' modes `bodies`.
    pub fn restore(&mut self, plant_state: &PlantState, bodies: [BodyMode; 2]) {
        each!(self, c => c.set_mode(mode_with(plant_state, bodies)))
    }

    /// The bodies' friction modes.
    pub fn bodies(&self) -> [BodyMode; 2] {
        let mode = self.mode();
        [mode.body(0), mode.body(1)]
    }

    /// Steps the plant from `plant_state` over `h` (to the first switch with `early_return`) in
    /// the chain, calling `record` for each switch; returns the new chain state and the offset of
    /// the switch it stopped at. Nothing changes until [`Friction::commit`].
    pub fn step(
        &mut self,
        plant_state: &PlantState,
        inputs: &Inputs,
        h: f64,
        early_return: bool,
        record: &mut dyn FnMut(ChainEvent),
    ) -> Result<(ChainState<1>, Option<f64>), StepError> {
        each!(self, c => {
            let mut next = chain_state(plant_state, c.mode);
            let stopped = if early_return {
                c.stepper.step_to_first_switch(&mut next, inputs, h, record)?
            } else {
                c.stepper.step(&mut next, inputs, h, record)?;
                None
            };
            Ok((next, stopped))
        })
    }

    /// The quiet step of a plant whose bodies with friction all slide
    /// ([`Exact::quiet_sliding_step`]): when no speed can reach 0 and no contact switch happen
    /// within `h`, and the state stays finite with its force, the state after it, in the modes
    /// in force. None when one may, or a body is stuck.
    #[inline]
    pub fn quiet_step(&self, state: &PlantState, inputs: &Inputs, h: f64) -> Option<PlantState> {
        each!(self, c => {
            let next = c.quiet.quiet_sliding_step(state, inputs, c.bearings?, h)?;
            // `next` is finite: its force is what is left of the state's check.
            finite(c.quiet.plant().force(next.u, next.du)).then_some(next)
        })
    }

    /// Makes `h` the step size of the quiet path (after a whole step of that size).
    pub fn prepare(&mut self, h: f64) {
        each!(self, c => c.quiet.prepare(h))
    }

    /// Makes the mode of `next` (from [`Friction::step`]) the chain's.
    pub fn commit(&mut self, next: &ChainState<1>) {
        each!(self, c => c.set_mode(next.mode))
    }

    /// d/dt [θ_m, ω_m, θ_L, ω_L, T] at `state` in the mode in force (a stuck body does not
    /// accelerate). θ′ is the speed itself, ω′ and T′ from the chain's mode.
    pub fn rates(&self, state: &PlantState, inputs: &Inputs) -> [f64; 5] {
        let r = each!(self, c => c.stepper.rates(&chain_state(state, c.mode), inputs));
        [state.omega_m, r[1], state.omega_l, r[3], r[4]]
    }

    /// Body `j`'s `sliding` output (docs/model.md §12): its friction mode with friction, the
    /// sign of its speed without.
    pub fn sliding(&self, j: usize, plant_state: &PlantState) -> i32 {
        let with_friction = each!(self, c => c.stepper.chain().body(j).friction.tau_c > 0.0);
        if with_friction {
            self.mode().body(j).sliding()
        } else {
            sign_of(speed(plant_state, j))
        }
    }
}

/// The index of body `j`'s speed in z = [θ_m, ω_m, θ_L, ω_L, T].
pub const fn speed_index(j: usize) -> usize {
    2 * j + 1
}

impl Friction {
    /// τ_h of body `j` at `state` in the contact mode it has (docs/model.md §12): every torque on
    /// the body but its bearing's, τ_m − r_m ψ on the motor, τ_L + r_L ψ − R_w T on the load.
    pub fn holding_torque(&self, state: &PlantState, inputs: &Inputs, j: usize) -> f64 {
        each!(self, c => c.stepper.holding(&chain_state(state, c.mode_at(state)), inputs, j))
    }

    /// Its change for a change `dz` of z = [θ_m, ω_m, θ_L, ω_L, T] and `dtau` of (τ_m, τ_L).
    fn holding_rate(&self, state: &PlantState, dz: &[f64; 5], dtau: [f64; 2], j: usize) -> f64 {
        let d_inputs = Inputs::held(dtau[0], dtau[1]);
        each!(self, c => {
            let motor = Motion { theta: dz[0], omega: dz[1] };
            let load = Motion { theta: dz[2], omega: dz[3] };
            let d = ChainState::new(c.stepper.chain(), motor, [load]).with_tension(dz[4]);
            c.stepper.holding_change(&c.mode_at(state), &d, &d_inputs, j)
        })
    }

    /// Body `j`'s friction, when it has any.
    fn coulomb(&self, j: usize) -> Option<Coulomb> {
        let c = each!(self, c => c.stepper.chain().body(j).friction);
        (c.tau_c > 0.0).then_some(c)
    }

    /// The friction surfaces' event indicators [stop_m, breakaway_m, stop_L, breakaway_L]
    /// (docs/model.md §12): a sliding body's speed, peak·τ_c − |τ_h| of a stuck one; 1 where
    /// the body has no such surface.
    pub fn indicators(&self, state: &PlantState, inputs: &Inputs) -> [f64; 4] {
        let mut out = [1.0; 4];
        for j in 0..2 {
            let Some(c) = self.coulomb(j) else { continue };
            match self.mode().body(j) {
                BodyMode::Stuck => out[2 * j + 1] = c.breakaway() - self.holding_torque(state, inputs, j).abs(),
                BodyMode::Forward | BodyMode::Backward => out[2 * j] = speed(state, j),
            }
        }
        out
    }

    /// Their changes for a change `dz` of the state and `dtau` of the torques (the Jacobian's
    /// rows; 0 where an indicator is the constant 1).
    pub fn indicator_rates(&self, state: &PlantState, inputs: &Inputs, dz: &[f64; 5], dtau: [f64; 2]) -> [f64; 4] {
        let mut out = [0.0; 4];
        for j in 0..2 {
            if self.coulomb(j).is_none() {
                continue;
            }
            match self.mode().body(j) {
                BodyMode::Stuck => {
                    let tau_h = self.holding_torque(state, inputs, j);
                    out[2 * j + 1] = -tau_h.signum() * self.holding_rate(state, dz, dtau, j)
                }
                BodyMode::Forward | BodyMode::Backward => out[2 * j] = dz[speed_index(j)],
            }
        }
        out
    }

    /// Whether body `j` is stuck (its speed held at 0: Model Exchange's Jacobian row of its
    /// acceleration is 0).
    pub fn stuck(&self, j: usize) -> bool {
        self.coulomb(j).is_some() && self.mode().body(j) == BodyMode::Stuck
    }

    /// Model Exchange's Event Mode (docs/model.md §12): the law of stiction applied to the held
    /// modes at `state` under `inputs`. A sliding body whose speed reached 0 (or passed it, by the
    /// solver's tolerance) sticks while |τ_h| ≤ peak·τ_c, its speed set to 0 exactly, and slides on
    /// in τ_h's direction beyond; a stuck body breaks away in τ_h's direction once |τ_h| exceeds
    /// peak·τ_c. Returns the state with the speeds set, when one was.
    pub fn settle(&mut self, plant: &Plant, state: &PlantState, inputs: &Inputs) -> Option<PlantState> {
        let mut z = [
            state.theta_m,
            state.omega_m,
            state.theta_l,
            state.omega_l,
            state.tension,
        ];
        let mut modes = self.bodies();
        let mut moved = false;
        for (j, mode) in modes.iter_mut().enumerate() {
            let Some(c) = self.coulomb(j) else { continue };
            let omega = z[speed_index(j)];
            let tau_h = self.holding_torque(state, inputs, j);
            let beyond = tau_h.abs() > c.breakaway();
            let stopped = match *mode {
                BodyMode::Forward => omega <= 0.0,
                BodyMode::Backward => omega >= 0.0,
                BodyMode::Stuck => true,
            };
            if !stopped {
                continue;
            }
            *mode = match (beyond, tau_h > 0.0) {
                (false, _) => BodyMode::Stuck,
                (true, true) => BodyMode::Forward,
                (true, false) => BodyMode::Backward,
            };
            if *mode == BodyMode::Stuck && omega != 0.0 {
                z[speed_index(j)] = 0.0;
                moved = true;
            }
        }
        let settled = match moved {
            true => PlantState::new(plant, z[0], z[1], z[2], z[3]).with_tension(z[4]),
            false => *state,
        };
        self.restore(&settled, modes);
        moved.then_some(settled)
    }
}

/// Body `j`'s speed in `state`.
pub fn speed(state: &PlantState, j: usize) -> f64 {
    if j == 0 {
        state.omega_m
    } else {
        state.omega_l
    }
}

/// +1, 0 or −1 by the sign of `x`: a body without friction's `sliding`.
pub fn sign_of(x: f64) -> i32 {
    if x > 0.0 {
        1
    } else if x < 0.0 {
        -1
    } else {
        0
    }
}

/// The chain state of a plant state, in `mode`: the same angles, speeds, u, u′, V and T.
fn chain_state(s: &PlantState, mode: ChainMode<1>) -> ChainState<1> {
    ChainState {
        motor: Motion {
            theta: s.theta_m,
            omega: s.omega_m,
        },
        driven: [Motion {
            theta: s.theta_l,
            omega: s.omega_l,
        }],
        u: [s.u],
        du: [s.du],
        mode,
        variation: [s.variation],
        tension: s.tension,
    }
}

/// The plant state of a chain state (the inverse of `chain_state`).
pub fn plant_state(c: &ChainState<1>) -> PlantState {
    PlantState {
        theta_m: c.motor.theta,
        omega_m: c.motor.omega,
        theta_l: c.driven[0].theta,
        omega_l: c.driven[0].omega,
        tension: c.tension,
        u: c.u[0],
        du: c.du[0],
        variation: c.variation[0],
        mode: c.mode.stages()[0],
    }
}

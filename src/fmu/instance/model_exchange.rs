//! The Model Exchange calls (FMI 2.0.4 §3.2): the importer's solver sets time and the
//! continuous states z = [θ_m, ω_m, θ_L, ω_L] (and T on a web line) and reads the vector field,
//! the event indicators [u − g, u + g, K (u − g) + D u′, K (u + g) + D u′, D u′ − K (u − g),
//! D u′ − K (u + g)] and those of the bodies' friction [stop_m, breakaway_m, stop_L,
//! breakaway_L], the states' nominal values and the exact Jacobian of the mode in force
//! (docs/model.md §6, §12). The contact modes follow u and u′; with Coulomb friction each body's
//! mode (sliding or stuck) is a discrete state, changed in Event Mode by the law of stiction.
//! There are no time events.

use super::Instance;
use crate::fmu::adapter::EVENT_INDICATORS;
use crate::fmu::adapter::{self, Calculated, Source, StateEntry, StateVector, MAX_INPUTS, MAX_STATES};
use crate::fmu::error::{FmuError, Status};
use crate::fmu::friction;
use crate::fmu::state_machine::{Function, Interface, Phase, Standard};
use crate::fmu::variables::VarType;
use crate::physics::finite;

/// The answer of fmi2NewDiscreteStates.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct EventInfo {
    pub new_discrete_states_needed: bool,
    pub terminate_simulation: bool,
    pub nominals_changed: bool,
    pub values_changed: bool,
    pub next_event_time: Option<f64>,
}

/// How far back fmi2SetTime / fmi3SetTime may go: not before the start time, the second-last
/// completed integrator step or the last event. FMI 3.0.2 §3.2.1: time "must be larger or equal
/// to: startTime, the time at the second last call to fmi3CompletedIntegratorStep, the time at
/// the last call to fmi3EnterEventMode". FMI 2.0.4 §3.2.2 says the same of FMI 2.0: "After
/// fmi2CompletedIntegratorStep is called, it is still allowed to go back in time […]. However,
/// it is not allowed to go back in time over the previous fmi2CompletedIntegratorStep or the
/// previous fmi2EnterEventMode call" (going back over the call just made is what the first
/// sentence allows, so the previous call is the one before it). Kept in FMU states.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct TimeMarks {
    /// The times of the second-last and the last completed integrator step (the start time
    /// before there were two).
    pub completed_steps: [f64; 2],
    /// The time of the last fmi2EnterEventMode; initialization ends in Event Mode, so the start
    /// time before any.
    pub event: f64,
}

impl TimeMarks {
    /// The marks of an instance at `start`, before any step or event.
    pub fn at_start(start: f64) -> TimeMarks {
        TimeMarks {
            completed_steps: [start; 2],
            event: start,
        }
    }

    /// The earliest time that may be set, and what sets it (the start time is at or before
    /// both marks).
    pub fn earliest(&self) -> (f64, &'static str) {
        let [second_last, _] = self.completed_steps;
        if self.event >= second_last {
            (
                self.event,
                "the last event (Event Mode entered, or initialization ended)",
            )
        } else {
            (second_last, "the second-last completed integrator step")
        }
    }
}

impl Instance {
    /// Model Exchange, and FMI 3.0 Co-Simulation with Event Mode (after a step that stopped at
    /// a contact switch, or whenever the importer wants to act).
    pub(crate) fn enter_event_mode_body(&mut self) -> Result<Status, FmuError> {
        if self.flavour.interface == Interface::CoSimulation && !self.options.event_mode_used {
            return Err(FmuError::InvalidArgument(
                "the instance was created with eventModeUsed = false: it has no Event Mode".into(),
            ));
        }
        self.life.enter(Phase::EventMode);
        self.time_marks.event = self.time;
        self.roll_events();
        Ok(Status::Ok)
    }

    /// FMI 3.0 Co-Simulation: from Event Mode back to stepping.
    pub(crate) fn enter_step_mode_body(&mut self) -> Result<Status, FmuError> {
        self.life.enter(Phase::StepComplete);
        Ok(Status::Ok)
    }

    /// The number of continuous states (FMI 3.0 asks; FMI 2.0 descriptions say).
    pub(crate) fn continuous_state_count(&self) -> usize {
        self.model.states
    }

    /// The number of event indicators: u ∓ g, the damped force's and the cap's surfaces
    /// (docs/model.md §6), and the bodies' friction surfaces (§12).
    pub(crate) fn event_indicator_count(&self) -> usize {
        match self.model.is_geared() {
            true => crate::fmu::geared::INDICATORS,
            false => EVENT_INDICATORS,
        }
    }

    /// The contact modes follow the state; in Model Exchange each body with friction takes its
    /// mode by the law of stiction here, and one that sticks is set at rest (its speed, a
    /// continuous state, changed: valuesOfContinuousStatesChanged). One pass settles the law: no
    /// iteration, no time event.
    pub(crate) fn new_discrete_states_body(&mut self) -> Result<EventInfo, FmuError> {
        let mut values_changed = false;
        if self.flavour.interface == Interface::ModelExchange {
            if let Some(sim) = self.life.sim_mut() {
                let inputs = adapter::inputs(sim.plant(), &self.values, &self.input_slopes);
                values_changed = sim.settle_friction(&inputs);
            } else if self.model.is_geared() {
                values_changed = self.gear_settle();
            }
        }
        Ok(EventInfo {
            new_discrete_states_needed: false,
            terminate_simulation: false,
            nominals_changed: false,
            values_changed,
            next_event_time: None,
        })
    }

    pub(crate) fn enter_continuous_time_mode_body(&mut self) -> Result<Status, FmuError> {
        self.life.enter(Phase::ContinuousTimeMode);
        Ok(Status::Ok)
    }

    /// Returns (enterEventMode, terminateSimulation): neither is ever needed, modes being a
    /// function of the state.
    pub(crate) fn completed_integrator_step_body(&mut self) -> Result<(bool, bool), FmuError> {
        let [_, last] = self.time_marks.completed_steps;
        self.time_marks.completed_steps = [last, self.time];
        self.roll_events();
        Ok((false, false))
    }

    /// Model Exchange: the importer's trajectory is at the current state, an event or a
    /// completed step: the damped bound's terms follow it ([`crate::fmu::simulation::EventTerms`]).
    fn roll_events(&mut self) {
        if let Some(sim) = self.life.sim_mut() {
            let state = sim.state;
            sim.events.roll(&state);
        }
    }

    /// Any finite time from the start time on, forwards, or backwards as far as [`TimeMarks`]
    /// allows. A time past the stop time is accepted: variable-step solvers evaluate the
    /// right-hand side beyond the end of the interval they integrate (fmpy's CVode does), and
    /// the model is defined there.
    pub(crate) fn set_time_body(&mut self, time: f64) -> Result<Status, FmuError> {
        let start = self.experiment.start_time;
        if !(finite(time) && time >= start) {
            return Err(FmuError::InvalidArgument(format!(
                "time {time} must be finite and >= the start time {start} of the experiment"
            )));
        }
        let (earliest, mark) = self.time_marks.earliest();
        if time < earliest {
            return Err(FmuError::TimeGoesBack {
                time,
                earliest,
                mark,
                rule: match self.flavour.standard {
                    Standard::Fmi2 => {
                        "FMI 2.0.4 §3.2.2: \"it is not allowed to go back in time over the previous \
                         fmi2CompletedIntegratorStep or the previous fmi2EnterEventMode call\""
                    }
                    Standard::Fmi3 => {
                        "FMI 3.0.2 §3.2.1: time \"must be larger or equal to: startTime, the time at the second \
                         last call to fmi3CompletedIntegratorStep, the time at the last call to fmi3EnterEventMode\""
                    }
                },
            });
        }
        self.time = time;
        Ok(Status::Ok)
    }

    pub(crate) fn set_continuous_states_body(&mut self, x: &[f64]) -> Result<Status, FmuError> {
        if self.model.is_geared() {
            self.checked_states(x, &StateEntry::CHAIN)?;
            self.gear_set_continuous_states(&super::gearbox::six(x))?;
            return Ok(Status::Ok);
        }
        let z = self.state_vector(x)?;
        let sim = self.life.running()?;
        let state = adapter::state_of(sim.plant(), &z);
        sim.check_state(&state, format_args!("the continuous states overflow"))?;
        sim.set_continuous(state);
        Ok(Status::Ok)
    }

    /// x as z = [θ_m, ω_m, θ_L, ω_L, T] (T = 0 for the drive trains), refused unless of the
    /// model's length and finite.
    fn state_vector(&self, x: &[f64]) -> Result<StateVector, FmuError> {
        self.checked_states(x, &StateEntry::ALL)?;
        let mut z = [0.0; MAX_STATES];
        z[..x.len()].copy_from_slice(x);
        Ok(z)
    }

    /// Refused unless x has the model's number of states, each finite (`entries` name them).
    #[inline]
    fn checked_states(&self, x: &[f64], entries: &[StateEntry]) -> Result<(), FmuError> {
        Self::same_length("continuous states", x.len(), self.continuous_state_count())?;
        match x.iter().position(|x| !x.is_finite()) {
            None => Ok(()),
            Some(i) => Err(self.state_refusal(x, entries, i)),
        }
    }

    /// Why x is refused: its `i`-th state is not finite.
    #[cold]
    fn state_refusal(&self, x: &[f64], entries: &[StateEntry], i: usize) -> FmuError {
        FmuError::InvalidArgument(format!(
            "continuous state {} ({}) is {}; states must be finite",
            i + 1,
            self.model.by_symbol(entries[i].symbol()).map_or("?", |v| v.name),
            x[i]
        ))
    }

    fn fill(out: &mut [f64], what: &'static str, values: &[f64]) -> Result<Status, FmuError> {
        Self::same_length(what, out.len(), values.len())?;
        if let Some(x) = values.iter().find(|x| !x.is_finite()) {
            return Err(FmuError::Overflow(format!("{what} evaluate to {x}")));
        }
        out.copy_from_slice(values);
        Ok(Status::Ok)
    }

    pub(crate) fn get_continuous_states_body(&mut self, out: &mut [f64]) -> Result<Status, FmuError> {
        if self.model.is_geared() {
            let z = self.gear_z()?;
            return Self::fill(out, "continuous states", &z);
        }
        let n = self.continuous_state_count();
        let z = adapter::entries_of(&self.physics()?.state);
        Self::fill(out, "continuous states", &z[..n])
    }

    /// The solver's most frequent call: `rates` has checked the values already.
    #[inline]
    pub(crate) fn get_derivatives_body(&mut self, out: &mut [f64]) -> Result<Status, FmuError> {
        let n = self.continuous_state_count();
        Self::same_length("derivatives", out.len(), n)?;
        if let Err(e) = self.physics() {
            return match self.model.is_geared() {
                true => Self::fill(out, "derivatives", &self.gear_rates()?),
                false => Err(e),
            };
        }
        let sim = self.built();
        let inputs = adapter::inputs(sim.plant(), &self.values, &self.input_slopes);
        sim.write_rates(&sim.state, &inputs, out, format_args!("the state derivatives overflow"))?;
        Ok(Status::Ok)
    }

    pub(crate) fn get_event_indicators_body(&mut self, out: &mut [f64]) -> Result<Status, FmuError> {
        if let Err(e) = self.physics() {
            return match self.model.is_geared() {
                true => Self::fill(out, "event indicators", &self.gear_event_indicators()?),
                false => Err(e),
            };
        }
        let sim = self.built();
        let contact = sim.plant().event_indicators(&sim.state);
        let friction = match &sim.friction {
            None => [1.0; 4],
            Some(_) => sim.friction_indicators(&adapter::inputs(sim.plant(), &self.values, &self.input_slopes)),
        };
        let mut indicators = [0.0; EVENT_INDICATORS];
        let (head, tail) = indicators.split_at_mut(contact.len());
        head.copy_from_slice(&contact);
        tail.copy_from_slice(&friction);
        Self::fill(out, "event indicators", &indicators)
    }

    pub(crate) fn get_nominals_body(&mut self, out: &mut [f64]) -> Result<Status, FmuError> {
        let n = self.continuous_state_count();
        if self.model.is_geared() {
            let nominals = self.gear_nominals()?;
            return Self::fill(out, "nominals of the continuous states", &nominals);
        }
        let nominals = self.physics()?.plant().state_nominals();
        Self::fill(out, "nominals of the continuous states", &nominals[..n])
    }

    /// Model Exchange only (providesDirectionalDerivative is false for Co-Simulation).
    pub(crate) fn check_directional_derivative_provided(&self) -> Result<(), FmuError> {
        match self.flavour.interface {
            Interface::ModelExchange => Ok(()),
            Interface::CoSimulation => Err(FmuError::NotProvided(
                "fmi2GetDirectionalDerivative in Co-Simulation (providesDirectionalDerivative=\"false\" there)",
            )),
        }
    }

    /// dv_unknown = J dv_known with J the exact Jacobian, in the mode in force, of the unknowns
    /// (state derivatives, states, ψ, the event indicators, and the bounds, which depend on time
    /// alone) with respect to the knowns (states and inputs). The knowns are Real: an Integer
    /// (`contact_law`, `contact`) is refused by its type.
    pub(crate) fn get_directional_derivative_body(
        &mut self,
        unknowns: &[u32],
        knowns: &[u32],
        dv_known: &[f64],
        dv_unknown: &mut [f64],
    ) -> Result<Status, FmuError> {
        self.check_directional_derivative_provided()?;
        Self::same_length("fmi2GetDirectionalDerivative dvKnown", dv_known.len(), knowns.len())?;
        Self::same_length(
            "fmi2GetDirectionalDerivative dvUnknown",
            dv_unknown.len(),
            unknowns.len(),
        )?;
        if self.model.is_geared() {
            return self.gear_directional_derivative(unknowns, knowns, dv_known, dv_unknown);
        }
        // The seed as a change of z and of the input lines.
        let mut dz = [0.0; MAX_STATES];
        let mut dinput = [0.0; MAX_INPUTS];
        for (vr, dv) in knowns.iter().zip(dv_known) {
            let v = self.typed_variable(*vr, VarType::Real)?;
            if !dv.is_finite() {
                return Err(FmuError::ValueRefused {
                    name: v.name,
                    value: *dv,
                    range: "a finite seed".into(),
                });
            }
            match v.symbol.source() {
                Source::State(entry) => dz[entry.index()] += dv,
                Source::Input(slot) => dinput[slot] += dv,
                Source::Parameter
                | Source::Calculated(_)
                | Source::Derivative(_)
                | Source::Contact
                | Source::StageContact(_)
                | Source::Sliding(_)
                | Source::Sampled
                | Source::Command => {
                    return Err(FmuError::InvalidArgument(format!(
                        "{} is not a known of the Jacobian: the knowns are the continuous states and the inputs",
                        v.name
                    )))
                }
            }
        }
        let mut rows = Vec::with_capacity(unknowns.len());
        for vr in unknowns {
            let v = self.typed_variable(*vr, VarType::Real)?;
            rows.push(Unknown::of(v.symbol.source()).ok_or_else(|| {
                FmuError::InvalidArgument(format!(
                    "{} is not an unknown of the Jacobian: the unknowns are the state derivatives and the outputs",
                    v.name
                ))
            })?);
        }
        let (values, slopes) = (self.values, self.input_slopes);
        let sim = self.physics()?;
        let plant = sim.plant();
        let (mut jz, mut jinputs) = plant.jacobian(&sim.state);
        // A stuck body does not accelerate (docs/model.md §12): its row is 0.
        if let Some(f) = &sim.friction {
            for j in 0..2 {
                if f.stuck(j) {
                    let row = friction::speed_index(j);
                    jz[row] = [0.0; MAX_STATES];
                    jinputs[row] = [0.0; 3];
                }
            }
        }
        let friction_rates = sim.friction.as_ref().map_or([0.0; 4], |f| {
            let inputs = adapter::inputs(plant, &values, &slopes);
            f.indicator_rates(&sim.state, &inputs, &dz, [dinput[0], dinput[1]])
        });
        // The span's forcing w is linear in v_in and T_in.
        let dw = plant.web().map_or(0.0, |w| w.forcing(dinput[2], dinput[3]));
        let dforcing = [dinput[0], dinput[1], dw];
        let psi_rate = |dz: &StateVector| plant.force_rate(sim.state.mode, [dz[0], dz[2]], [dz[1], dz[3]]);
        // The indicators are linear in u and u′, and do not depend on the inputs.
        let indicator_rates = adapter::indicator_rates(plant, &dz);
        // Computed in full before anything is written: a refusal leaves dvUnknown as it was.
        let mut values = Vec::with_capacity(rows.len());
        for row in rows {
            let value = match row {
                Unknown::Derivative(entry) => {
                    let i = entry.index();
                    (0..MAX_STATES).map(|j| jz[i][j] * dz[j]).sum::<f64>()
                        + jinputs[i][0] * dforcing[0]
                        + jinputs[i][1] * dforcing[1]
                        + jinputs[i][2] * dforcing[2]
                }
                Unknown::State(entry) => dz[entry.index()],
                Unknown::Psi => psi_rate(&dz),
                Unknown::Indicator(i) => match indicator_rates.get(i) {
                    Some(rate) => *rate,
                    None => friction_rates[i - indicator_rates.len()],
                },
                Unknown::TimeOnly => 0.0,
            };
            if !value.is_finite() {
                return Err(FmuError::Overflow(format!(
                    "a directional derivative evaluates to {value}"
                )));
            }
            values.push(value);
        }
        dv_unknown.copy_from_slice(&values);
        Ok(Status::Ok)
    }
}

/// A row of the Jacobian an importer may ask for (docs/model.md §6).
#[derive(Clone, Copy)]
enum Unknown {
    Derivative(StateEntry),
    State(StateEntry),
    Psi,
    /// The event indicator of this index (docs/model.md §6): u ∓ g move with u, the others with
    /// u and u′.
    Indicator(usize),
    /// The bounds: functions of time alone, so their rows are 0.
    TimeOnly,
}

impl Unknown {
    /// The row of a variable, or None for one that is no unknown of the Jacobian. Exhaustive: a
    /// new output must be placed here.
    fn of(source: Source) -> Option<Unknown> {
        match source {
            Source::Derivative(entry) => Some(Unknown::Derivative(entry)),
            Source::State(entry) => Some(Unknown::State(entry)),
            Source::Calculated(quantity) => match quantity {
                Calculated::Psi => Some(Unknown::Psi),
                Calculated::UMinusG
                | Calculated::UPlusG
                | Calculated::ForceUpper
                | Calculated::ForceLower
                | Calculated::CapUpper
                | Calculated::CapLower
                | Calculated::StopM
                | Calculated::BreakawayM
                | Calculated::StopL
                | Calculated::BreakawayL => quantity.indicator().map(Unknown::Indicator),
                Calculated::Bound | Calculated::BoundPaper | Calculated::BoundT => Some(Unknown::TimeOnly),
                // A gearbox's (`super::gearbox`), none a single gap's.
                Calculated::BoundSup | Calculated::BoundTSup | Calculated::Gear(_) => None,
            },
            Source::Input(_)
            | Source::Parameter
            | Source::Contact
            | Source::StageContact(_)
            | Source::Sliding(_)
            | Source::Sampled
            | Source::Command => None,
        }
    }
}

/// The checked Model Exchange calls (the Rust API; the C layer calls `run` with the bodies).
impl Instance {
    pub fn enter_event_mode(&mut self) -> Result<Status, FmuError> {
        self.run(Function::EnterEventMode, |s| s.enter_event_mode_body())
    }

    pub fn new_discrete_states(&mut self) -> Result<EventInfo, FmuError> {
        self.run(Function::NewDiscreteStates, |s| s.new_discrete_states_body())
    }

    pub fn enter_continuous_time_mode(&mut self) -> Result<Status, FmuError> {
        self.run(Function::EnterContinuousTimeMode, |s| {
            s.enter_continuous_time_mode_body()
        })
    }

    pub fn completed_integrator_step(&mut self) -> Result<(bool, bool), FmuError> {
        self.run(Function::CompletedIntegratorStep, |s| {
            s.completed_integrator_step_body()
        })
    }

    pub fn set_time(&mut self, time: f64) -> Result<Status, FmuError> {
        self.run(Function::SetTime, |s| s.set_time_body(time))
    }

    pub fn set_continuous_states(&mut self, x: &[f64]) -> Result<Status, FmuError> {
        self.run(Function::SetContinuousStates, |s| s.set_continuous_states_body(x))
    }

    pub fn get_continuous_states(&mut self, out: &mut [f64]) -> Result<Status, FmuError> {
        self.run(Function::GetContinuousStates, |s| s.get_continuous_states_body(out))
    }

    pub fn get_derivatives(&mut self, out: &mut [f64]) -> Result<Status, FmuError> {
        self.run(Function::GetDerivatives, |s| s.get_derivatives_body(out))
    }

    pub fn get_event_indicators(&mut self, out: &mut [f64]) -> Result<Status, FmuError> {
        self.run(Function::GetEventIndicators, |s| s.get_event_indicators_body(out))
    }

    pub fn get_nominals_of_continuous_states(&mut self, out: &mut [f64]) -> Result<Status, FmuError> {
        self.run(Function::GetNominalsOfContinuousStates, |s| s.get_nominals_body(out))
    }

    pub fn get_directional_derivative(
        &mut self,
        unknowns: &[u32],
        knowns: &[u32],
        dv_known: &[f64],
        dv_unknown: &mut [f64],
    ) -> Result<Status, FmuError> {
        self.run(Function::GetDirectionalDerivative, |s| {
            s.get_directional_derivative_body(unknowns, knowns, dv_known, dv_unknown)
        })
    }
}

//! fmi2DoStep and fmi3DoStep: argument checks, the quiet path for an event-free step, and the
//! general step with located contact switches, which in FMI 3.0 may stop at the first one.

use super::Instance;
use crate::fmu::adapter::{self, MAX_INPUTS};
use crate::fmu::error::{FmuError, Status};
use crate::fmu::friction;
use crate::fmu::logging::LogCategory;
use crate::physics::chain::ChainEvent;
use crate::physics::ContactMode;
use crate::physics::{finite, Inputs, StepError, MAX_PERIODS_PER_STEP};

/// Relative tolerance for "the communication point equals the current time": steps are
/// accumulated by the importer in floating point, so they drift by a few ulps per step.
const TIME_TOLERANCE: f64 = 1e-9;

/// What fmi3DoStep reports besides its status.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct StepOutcome {
    /// The step stopped at a contact switch: `time` is the switch instant.
    pub early_return: bool,
    /// The importer should enter Event Mode (it uses Event Mode and the step stopped at a switch).
    pub event_handling_needed: bool,
    /// Where the step ended: the end of the step, or the switch instant.
    pub time: f64,
}

impl Instance {
    pub(crate) fn do_step_body(&mut self, communication_point: f64, h: f64) -> Result<Status, FmuError> {
        self.step_body(communication_point, h, false).map(|_| Status::Ok)
    }

    /// fmi3DoStep: with early return allowed, the step stops at the first contact switch
    /// inside it, located to round-off.
    pub(crate) fn do_step3_body(&mut self, communication_point: f64, h: f64) -> Result<StepOutcome, FmuError> {
        let early = self.options.early_return_allowed;
        let stopped = self.step_body(communication_point, h, early)?;
        Ok(StepOutcome {
            early_return: stopped,
            event_handling_needed: stopped && self.options.event_mode_used,
            time: self.time,
        })
    }

    /// The step; returns whether it stopped early at a contact switch (only when `early_return`).
    #[inline]
    fn step_body(&mut self, communication_point: f64, h: f64, early_return: bool) -> Result<bool, FmuError> {
        let (limit, at_time) = (self.step_limit(), self.at_time(communication_point));
        // A controller has no simulation: its step is a sample, off the plants' path; a gearbox's
        // is its chain's. Told apart without `running`, whose refusal allocates its reason.
        let sim = match self.life.sim_mut() {
            Some(sim) => sim,
            None => return self.step_without_simulation(communication_point, h, early_return),
        };
        let inputs = adapter::inputs(sim.plant(), &self.values, &self.input_slopes);
        let lines = adapter::input_values(&self.values);
        let lines_end = match accepted_lines(
            &lines,
            &self.input_slopes,
            communication_point,
            h,
            sim.max_step,
            limit,
            at_time,
        ) {
            Ok(lines_end) => lines_end,
            Err(lines_end) => return Err(self.step_refusal(communication_point, h, &lines_end)),
        };
        if !sim.quiet_step(&inputs, h) {
            let stopped = self.general_step(communication_point, &inputs, h, early_return)?;
            return Ok(self.step_taken(communication_point, h, &lines, &lines_end, stopped));
        }
        Ok(self.step_taken(communication_point, h, &lines, &lines_end, None))
    }

    /// After a step from `communication_point` that stopped at the switch `stopped` (an offset
    /// in it) or went its whole length `h`: the input lines and the time moved there. Returns
    /// whether it stopped early.
    #[inline(always)]
    fn step_taken(
        &mut self,
        communication_point: f64,
        h: f64,
        lines: &[f64; MAX_INPUTS],
        lines_end: &[f64; MAX_INPUTS],
        stopped: Option<f64>,
    ) -> bool {
        if let Some(offset) = stopped {
            // Stopped at a switch: the input lines and the time move to it.
            let at_switch = std::array::from_fn(|i| lines[i] + offset * self.input_slopes[i]);
            adapter::store_inputs(&mut self.values, &at_switch);
            self.time = communication_point + offset;
            return true;
        }
        // The input lines continue over the next step unless set again (see
        // `set_real_input_derivatives_body`).
        adapter::store_inputs(&mut self.values, lines_end);
        // FMI 2.0.4 §4.2.2: synchronize to tc + h rather than accumulate.
        self.time = communication_point + h;
        false
    }

    /// `step_body` of an instance without a single gap's simulation: a controller's sample, a
    /// gearbox's step, or the refusal of a plant's step before initialization has ended.
    #[cold]
    #[inline(never)]
    fn step_without_simulation(
        &mut self,
        communication_point: f64,
        h: f64,
        early_return: bool,
    ) -> Result<bool, FmuError> {
        if self.model.is_controller() {
            return self.sample_step(communication_point, h);
        }
        if self.model.is_geared() {
            return self.geared_step_body(communication_point, h, early_return);
        }
        // `running` refuses: there is no simulation to step.
        self.life.running().map(|_| false)
    }

    /// `step_body` of a gearbox (`super::gearbox`): the same argument checks, the chain's step,
    /// the input lines and the time moved as there.
    #[cold]
    #[inline(never)]
    fn geared_step_body(&mut self, communication_point: f64, h: f64, early_return: bool) -> Result<bool, FmuError> {
        let (limit, at_time) = (self.step_limit(), self.at_time(communication_point));
        let lines = adapter::input_values(&self.values);
        let max_step = self.max_step();
        let lines_end = match accepted_lines(
            &lines,
            &self.input_slopes,
            communication_point,
            h,
            max_step,
            limit,
            at_time,
        ) {
            Ok(lines_end) => lines_end,
            Err(lines_end) => return Err(self.step_refusal(communication_point, h, &lines_end)),
        };
        let stopped = self.gear_step(communication_point, h, early_return)?;
        Ok(self.step_taken(communication_point, h, &lines, &lines_end, stopped))
    }

    /// The longest step the physics accepts (NaN before there is any).
    fn max_step(&self) -> f64 {
        match (self.life.sim(), self.life.geared()) {
            (Some(sim), _) => sim.max_step,
            (None, Some(g)) => g.max_step,
            (None, None) => f64::NAN,
        }
    }

    /// Where steps must end: the stop time (to [`TIME_TOLERANCE`]), or anywhere finite, so that
    /// time stays finite.
    #[inline]
    pub(super) fn step_limit(&self) -> f64 {
        match self.experiment.stop_time {
            Some(stop) => stop + TIME_TOLERANCE * stop.abs().max(1.0),
            None => f64::MAX,
        }
    }

    /// Whether a communication point is the instance's time, to [`TIME_TOLERANCE`].
    #[inline]
    pub(super) fn at_time(&self, communication_point: f64) -> bool {
        (communication_point - self.time).abs() <= TIME_TOLERANCE * self.time.abs().max(1.0)
    }

    /// Why `do_step_body` refuses its arguments (called only when it does).
    #[cold]
    #[inline(never)]
    pub(super) fn step_refusal(&self, communication_point: f64, h: f64, lines_end: &[f64; MAX_INPUTS]) -> FmuError {
        let bad = FmuError::InvalidArgument;
        if !communication_point.is_finite() {
            return bad(format!("currentCommunicationPoint {communication_point} is not finite"));
        }
        if !(h.is_finite() && h > 0.0) {
            return bad(format!("communicationStepSize {h} must be finite and > 0"));
        }
        let now = self.time;
        if !self.at_time(communication_point) {
            return bad(format!(
                "currentCommunicationPoint {communication_point} differs from the FMU's time {now}; restore an FMU \
                 state to step from another time"
            ));
        }
        let end = communication_point + h;
        if end <= communication_point {
            return bad(format!(
                "communicationStepSize {h} is below the resolution of time {communication_point}"
            ));
        }
        if let Some(stop) = self.experiment.stop_time {
            if end > stop + TIME_TOLERANCE * stop.abs().max(1.0) {
                return bad(format!(
                    "the step to {end} passes the stopTime {stop} set in fmi2SetupExperiment"
                ));
            }
        }
        if !end.is_finite() {
            return bad(format!(
                "the step from {communication_point} by {h} leaves the range of f64"
            ));
        }
        if let Some(i) = lines_end.iter().position(|x| !x.is_finite()) {
            return FmuError::Overflow(format!(
                "the input ramp of {} reaches {:e} at the end of the step",
                adapter::input_name(i),
                lines_end[i]
            ));
        }
        let max_step = self.max_step();
        bad(format!(
            "communicationStepSize {h} exceeds {max_step:e} s ({MAX_PERIODS_PER_STEP:e} periods of the contact \
             oscillation); split it into smaller steps"
        ))
    }

    /// The step of `step_body` past its argument checks, when the quiet path did not take
    /// it: contact switches located and logged, overflow of plant or bounds refused. With
    /// `early_return`, stops at the first switch that lies inside the step and after its
    /// start, and returns its offset.
    #[cold]
    #[inline(never)]
    fn general_step(
        &mut self,
        communication_point: f64,
        inputs: &Inputs,
        h: f64,
        early_return: bool,
    ) -> Result<Option<f64>, FmuError> {
        // Named in the refusal of a step whose state overflows.
        let lines = adapter::input_values(&self.values);
        let inputs_named = || {
            let named: Vec<String> = (0..self.model.inputs)
                .map(|i| format!("{} = {:e}", adapter::input_name(i), lines[i]))
                .collect();
            named.join(", ")
        };
        let overflow = |e: StepError| match e {
            StepError::Overflow => FmuError::Overflow(format!(
                "the step from t = {communication_point} overflows with the inputs at its start {}; reduce the \
                 inputs, start values or parameters",
                inputs_named()
            )),
            e => e.into(),
        };
        if self.life.sim().is_some_and(|sim| sim.friction.is_some()) {
            return self.friction_step(communication_point, inputs, h, early_return, &overflow);
        }
        let sim = self.life.running()?;
        // The plant steps a copy of its state, and the bound fails (on a bad h, excluded above)
        // before changing anything: a failed step leaves the instance as it was.
        let mut state = sim.state;
        let mut switches = Vec::new();
        let want_switches = self.log.is_enabled(LogCategory::ContactEvents);
        let mut stopped = None;
        {
            let mut record = |event| {
                if want_switches {
                    switches.push(event)
                }
            };
            if early_return {
                stopped = sim
                    .stepper
                    .step_to_first_switch(&mut state, inputs, h, &mut record)
                    .map_err(overflow)?;
            } else {
                sim.stepper.step(&mut state, inputs, h, &mut record).map_err(overflow)?;
            }
        }
        // A switch that does not move time (on the step's start, or at its end to round-off) is
        // no reason to return early: the whole step is taken instead.
        if without_progress(communication_point, h, stopped) {
            stopped = None;
            state = sim.state;
            switches.clear();
            sim.stepper
                .step(&mut state, inputs, h, &mut |event| {
                    if want_switches {
                        switches.push(event)
                    }
                })
                .map_err(overflow)?;
        }
        let advanced = stopped.unwrap_or(h);
        let end = communication_point + advanced;
        if !sim.state_ok(&state) {
            return Err(sim.overflow(&state, format_args!("the step to t = {end} overflows")));
        }
        sim.state = state;
        sim.bounds_lag(advanced);
        let half_gap = sim.plant().half_gap();
        for e in switches {
            let t = communication_point + e.offset;
            self.log.emit(Status::Ok, LogCategory::ContactEvents, || {
                contact_switch(t, e.from, e.to, half_gap)
            });
        }
        Ok(stopped)
    }

    /// `general_step` of a plant with Coulomb friction (docs/model.md §12): the chain steps it,
    /// with its contact and friction switches located, from the plant state in the bodies' modes.
    #[cold]
    #[inline(never)]
    fn friction_step(
        &mut self,
        communication_point: f64,
        inputs: &Inputs,
        h: f64,
        early_return: bool,
        overflow: &dyn Fn(StepError) -> FmuError,
    ) -> Result<Option<f64>, FmuError> {
        let want_switches = self.log.is_enabled(LogCategory::ContactEvents);
        let sim = self.life.running()?;
        let friction = sim.friction.as_mut().expect("a plant with friction");
        let mut switches = Vec::new();
        let mut record = |event| {
            if want_switches {
                switches.push(event)
            }
        };
        let (mut next, mut stopped) = friction
            .step(&sim.state, inputs, h, early_return, &mut record)
            .map_err(overflow)?;
        // As `general_step`: a switch that does not move time is no reason to return early.
        if without_progress(communication_point, h, stopped) {
            switches.clear();
            let mut record = |event| {
                if want_switches {
                    switches.push(event)
                }
            };
            (next, stopped) = friction
                .step(&sim.state, inputs, h, false, &mut record)
                .map_err(overflow)?;
        }
        let advanced = stopped.unwrap_or(h);
        let end = communication_point + advanced;
        let state = friction::plant_state(&next);
        if !sim.state_ok(&state) {
            return Err(sim.overflow(&state, format_args!("the step to t = {end} overflows")));
        }
        sim.friction.as_mut().expect("a plant with friction").commit(&next);
        sim.state = state;
        // The quiet path of the steps that follow takes this step size (after a whole step: one
        // that stopped early is usually followed by its remainder, then by the steps before it).
        if stopped.is_none() {
            sim.friction.as_mut().expect("a plant with friction").prepare(h);
        }
        sim.bounds_lag(advanced);
        let half_gap = sim.plant().half_gap();
        for e in switches {
            let t = communication_point + e.offset();
            self.log.emit(Status::Ok, LogCategory::ContactEvents, || match e {
                ChainEvent::Stage(s) => contact_switch(t, s.from, s.to, half_gap),
                ChainEvent::Body(b) => format!(
                    "friction switch of the {} at t = {t} s: {:?} -> {:?}",
                    friction::BODIES[b.body],
                    b.from,
                    b.to
                ),
            });
        }
        Ok(stopped)
    }
}

/// Whether the switch a step stopped at (its offset in `stopped`) does not move time: on the
/// step's start, or at its end to round-off. That is no reason to return early; the whole step
/// is taken instead.
pub(super) fn without_progress(communication_point: f64, h: f64, stopped: Option<f64>) -> bool {
    stopped.is_some_and(|offset| {
        let t = communication_point + offset;
        t <= communication_point || t >= communication_point + h
    })
}

/// The logged line of a contact switch at `t`.
fn contact_switch(t: f64, from: ContactMode, to: ContactMode, half_gap: f64) -> String {
    format!("contact switch at t = {t} s: {from:?} -> {to:?} (g = {half_gap})")
}

/// The input lines at the end of a step from `communication_point` over `h`: Ok if every
/// argument is acceptable, Err (the same lines, which the refusal names) if not. Acceptable: a
/// finite point at the instance's time (`at_time`), 0 < h <= `max_step`, an end that moves time
/// and stays within `limit`, lines that stay in f64 (refused before stepping, so that a refused
/// step changes nothing). All in one branch (non-short-circuit `&`, each false on
/// NaN); `step_refusal` sorts out the reason only when one fails.
#[inline(always)]
fn accepted_lines(
    lines: &[f64; MAX_INPUTS],
    slopes: &[f64; MAX_INPUTS],
    communication_point: f64,
    h: f64,
    max_step: f64,
    limit: f64,
    at_time: bool,
) -> Result<[f64; MAX_INPUTS], [f64; MAX_INPUTS]> {
    let end = communication_point + h;
    let lines_end: [f64; MAX_INPUTS] = std::array::from_fn(|i| lines[i] + h * slopes[i]);
    let accepted = finite(communication_point)
        & (h > 0.0)
        & (h <= max_step)
        & at_time
        & (end > communication_point)
        & (end <= limit)
        & lines_end.iter().fold(true, |ok, x| ok & finite(*x));
    if accepted {
        Ok(lines_end)
    } else {
        Err(lines_end)
    }
}

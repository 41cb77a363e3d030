//! Get and set by value reference (all or nothing), input and output derivatives: every
//! variable is reached through the model adapter.

use super::lifecycle::Lifecycle;
use super::Instance;
use crate::fmu::adapter::{self, Calculated, Source};
use crate::fmu::error::{FmuError, Status};
use crate::fmu::simulation::Simulation;
use crate::fmu::state_machine::{Function, Interface, Phase, Standard};
use crate::fmu::variables::{Causality, VarType, Variable};
use crate::physics::{contact_indicator, BoundError};

/// The independent variable of the FMI 3.0 descriptions: the instance's time.
use model_description::xml3::TIME;

impl Instance {
    /// Whether `vr` is FMI 3.0's independent variable `time` (FMI 2.0 has no such variable).
    #[inline]
    fn is_time(&self, vr: u32) -> bool {
        vr == TIME.1 && self.flavour.standard == Standard::Fmi3
    }

    fn variable(&self, vr: u32) -> Result<&'static Variable, FmuError> {
        // Built only on refusal: an eagerly built error costs a call of its drop glue on every
        // lookup (callgrind: 40 instructions per set(2) + get(1)), which clippy does not see.
        #[allow(clippy::unnecessary_lazy_evaluations)]
        self.model.by_vr(vr).ok_or_else(|| FmuError::UnknownValueReference {
            vr,
            model: self.model.identifier,
        })
    }

    pub(super) fn typed_variable(&self, vr: u32, ty: VarType) -> Result<&'static Variable, FmuError> {
        let v = self.variable(vr)?;
        if v.ty != ty {
            let requested = match ty {
                VarType::Real => "Real",
                VarType::Integer => "Integer",
            };
            return Err(Self::wrong_type(v, requested));
        }
        Ok(v)
    }

    pub(super) fn same_length(what: &'static str, length: usize, expected: usize) -> Result<(), FmuError> {
        if length == expected {
            Ok(())
        } else {
            Err(FmuError::LengthMismatch { what, length, expected })
        }
    }

    /// The physics in force: the simulation after initialization, before it the plant the
    /// current parameters and start values describe (built once per change).
    #[inline]
    pub(super) fn physics(&mut self) -> Result<&Simulation, FmuError> {
        if !matches!(self.life, Lifecycle::Running { .. }) {
            self.preview()?;
        }
        Ok(self.built())
    }

    /// Before initialization: builds the plant the current values describe unless built since
    /// they last changed, or refuses (a controller). Out of line: a simulation under
    /// construction takes kilobytes of stack, which the calls after initialization need not set
    /// up.
    #[cold]
    #[inline(never)]
    fn preview(&mut self) -> Result<(), FmuError> {
        match &mut self.life {
            Lifecycle::Running { .. } => Ok(()),
            Lifecycle::Sampling { .. } => Err(FmuError::InvalidArgument(format!(
                "{} is a controller: it has no plant",
                self.model.identifier
            ))),
            Lifecycle::Geared { .. } => Err(self.no_single_gap()),
            Lifecycle::Setup { .. } if self.model.is_geared() => Err(self.no_single_gap()),
            Lifecycle::Setup { preview, .. } => {
                if preview.is_none() {
                    *preview = Some(Simulation::build(self.model, &self.values)?);
                }
                Ok(())
            }
        }
    }

    /// The refusal of a single gap's physics to a gearbox, whose own is `gearbox`.
    #[cold]
    fn no_single_gap(&self) -> FmuError {
        FmuError::InvalidArgument(format!("{} is a gearbox: it has no single gap", self.model.identifier))
    }

    /// The physics [`Instance::physics`] has built (after a successful call of it).
    pub(super) fn built(&self) -> &Simulation {
        match &self.life {
            Lifecycle::Running { sim, .. } => sim,
            Lifecycle::Setup { preview: Some(sim), .. } => sim,
            Lifecycle::Setup { preview: None, .. } | Lifecycle::Sampling { .. } | Lifecycle::Geared { .. } => {
                unreachable!("Instance::physics builds the simulation or refuses")
            }
        }
    }

    /// The bounds at the instance's time (docs/model.md §4: measured from the start time), for
    /// reading: in Model Exchange at the time the solver set, in Co-Simulation caught up with
    /// the steps taken since they were last read.
    pub(super) fn bound_to_time(&mut self) -> Result<(), FmuError> {
        let elapsed = self.time - self.experiment.start_time;
        let model_exchange = self.flavour.interface == Interface::ModelExchange;
        match self.life.sim_mut() {
            Some(sim) => match model_exchange {
                true => sim.bound_at(elapsed),
                false => sim.bounds_current(),
            }
            .map_err(|e| match e {
                BoundError::Overflow { bound, bound_paper } => FmuError::Overflow(format!(
                    "the bounds at t = {} overflow: bound = {bound:e}, bound_paper = {bound_paper:e}",
                    self.time
                )),
                e => e.into(),
            }),
            None => Ok(()),
        }
    }

    fn real_value(&mut self, v: &Variable) -> Result<f64, FmuError> {
        Ok(match v.symbol.source() {
            Source::Input(_) | Source::Parameter | Source::Sampled => self.values[v.symbol.index()],
            Source::Command => match &self.life {
                Lifecycle::Sampling { pi, .. } => pi.torque,
                _ => self.values[v.symbol.index()],
            },
            Source::State(entry) => match self.life.sim() {
                Some(sim) => entry.of(&sim.state),
                None if self.model.is_geared() => self.gear_real(v)?,
                None => self.values[v.symbol.index()],
            },
            Source::Calculated(_) | Source::Derivative(_) if self.model.is_geared() => self.gear_real(v)?,
            Source::Calculated(quantity) => {
                if matches!(
                    quantity,
                    Calculated::Bound | Calculated::BoundPaper | Calculated::BoundT
                ) {
                    self.bound_to_time()?;
                }
                self.physics()?;
                quantity.of(self.built(), &self.values, &self.input_slopes)
            }
            Source::Derivative(entry) => self.rates()?[entry.index()],
            Source::Contact | Source::StageContact(_) | Source::Sliding(_) => return Err(Self::wrong_type(v, "Real")),
        })
    }

    /// d/dt [θ_m, ω_m, θ_L, ω_L, T] of the vector field at the state in force and the current
    /// inputs (docs/model.md §1, §8).
    pub(super) fn rates(&mut self) -> Result<adapter::StateVector, FmuError> {
        let (values, slopes) = (self.values, self.input_slopes);
        let sim = self.physics()?;
        let inputs = adapter::inputs(sim.plant(), &values, &slopes);
        sim.rates(&sim.state, &inputs, format_args!("the state derivatives overflow"))
    }

    /// The refusal of a `requested` access to `v` of another type.
    fn wrong_type(v: &Variable, requested: &'static str) -> FmuError {
        FmuError::WrongType {
            name: v.name,
            vr: v.vr,
            actual: v.ty,
            requested,
        }
    }

    pub(crate) fn get_real_body(&mut self, vrs: &[u32], out: &mut [f64]) -> Result<Status, FmuError> {
        Self::same_length("fmi2GetReal values", out.len(), vrs.len())?;
        for (vr, slot) in vrs.iter().zip(out.iter_mut()) {
            if self.is_time(*vr) {
                *slot = self.time;
                continue;
            }
            let v = self.typed_variable(*vr, VarType::Real)?;
            let x = self.real_value(v)?;
            // The suprema are +∞ by definition when the loop is unstable (docs/model.md §4), and
            // every bound with Coulomb friction (§12); nothing else may leave the FMU as ∞ or NaN.
            let unbounded = |s: &mut Self| match s.model.is_geared() {
                true => s.gear_unbounded(),
                false => s.physics().is_ok_and(|sim| !sim.bounded()),
            };
            let supremum = match v.symbol.source() {
                Source::Calculated(Calculated::BoundSup | Calculated::BoundTSup) => true,
                Source::Calculated(Calculated::Bound | Calculated::BoundT) => x == f64::INFINITY && unbounded(self),
                _ => false,
            };
            if x.is_nan() || (x.is_infinite() && !supremum) {
                return Err(FmuError::Overflow(format!("{} evaluates to {x}", v.name)));
            }
            *slot = x;
        }
        Ok(Status::Ok)
    }

    /// The Integers: `contact`, the sign of ψ in the physics in force, and the stored Integer
    /// parameters (`contact_law`), whose values are whole numbers in their range.
    pub(crate) fn get_integer_body(&mut self, vrs: &[u32], out: &mut [i32]) -> Result<Status, FmuError> {
        Self::same_length("fmi2GetInteger values", out.len(), vrs.len())?;
        for (vr, slot) in vrs.iter().zip(out.iter_mut()) {
            let v = self.typed_variable(*vr, VarType::Integer)?;
            *slot = match v.symbol.source() {
                Source::Contact => {
                    let sim = self.physics()?;
                    contact_indicator(&sim.state, sim.plant())
                }
                Source::StageContact(_) => self.gear_integer(v.symbol.source())?,
                Source::Sliding(_) if self.model.is_geared() => self.gear_integer(v.symbol.source())?,
                Source::Sliding(j) => self.physics()?.sliding(j),
                Source::Parameter => self.values[v.symbol.index()] as i32,
                _ => return Err(Self::wrong_type(v, "Integer")),
            };
        }
        Ok(Status::Ok)
    }

    /// Boolean and String: the models have no such variables, so any reference is refused
    /// (by name and type when it is a variable of another type).
    pub(crate) fn get_untyped_body(
        &mut self,
        vrs: &[u32],
        count: usize,
        requested: &'static str,
    ) -> Result<Status, FmuError> {
        Self::same_length("values", count, vrs.len())?;
        match vrs.first() {
            None => Ok(Status::Ok),
            Some(vr) => Err(Self::wrong_type(self.variable(*vr)?, requested)),
        }
    }

    /// As `get_untyped_body`: the models have no variable of the types set this way.
    pub(crate) fn set_untyped_body(
        &mut self,
        vrs: &[u32],
        count: usize,
        requested: &'static str,
    ) -> Result<Status, FmuError> {
        self.get_untyped_body(vrs, count, requested)
    }

    /// The tables of allowed calls, per variable: before and during initialization inputs,
    /// parameters and initial = exact outputs (the initial state); afterwards inputs (all
    /// parameters are fixed) and, where the standard allows it, the continuous-time states
    /// ([`Instance::states_settable`]).
    fn check_settable(&self, v: &Variable) -> Result<(), FmuError> {
        let refuse = |reason| {
            Err(FmuError::NotSettable {
                name: v.name,
                phase: self.phase(),
                reason,
            })
        };
        match v.causality {
            Causality::CalculatedParameter => refuse("it is a calculatedParameter, computed by the FMU"),
            Causality::Local if v.derivative_of.is_some() => refuse("it is a state derivative, computed by the FMU"),
            Causality::Local => refuse("it is computed by the FMU from the state"),
            Causality::Output if !v.is_initial_state() => refuse("it is an output computed by the FMU"),
            _ => match self.phase() {
                Phase::Instantiated | Phase::InitializationMode => Ok(()),
                Phase::StepComplete | Phase::EventMode | Phase::ContinuousTimeMode => match v.causality {
                    Causality::Input => Ok(()),
                    Causality::Parameter => {
                        refuse("it is a fixed parameter; it can change only before fmi2ExitInitializationMode")
                    }
                    _ if v.is_continuous_state() && self.states_settable() => Ok(()),
                    _ => refuse(match (self.flavour.standard, self.phase()) {
                        (Standard::Fmi2, Phase::EventMode) => {
                            "FMI 2.0.4 §3.2.3 allows in Event Mode inputs and tunable parameters only \
                             (condition 4); a continuous-time state can be set in Continuous-Time Mode"
                        }
                        _ => {
                            "its start value is the initial state; it can change only before \
                             fmi2ExitInitializationMode (in Model Exchange, also in Continuous-Time Mode)"
                        }
                    }),
                },
                _ => refuse("no variable can be set in this state"),
            },
        }
    }

    /// The common case of a set, checked in one pass: at most `MAX_INPUTS` elements, each an
    /// input of type `ty` whose value its range admits, in a state in which inputs can be set.
    /// Where each value is stored, in the order of `vrs`; None for anything else, which goes
    /// through `check_settable` and the range's refusal, which give the reason.
    #[inline]
    fn admitted_inputs(&self, vrs: &[u32], values: &[f64], ty: VarType) -> Option<[usize; adapter::MAX_INPUTS]> {
        let takes_inputs = matches!(
            self.phase(),
            Phase::Instantiated
                | Phase::InitializationMode
                | Phase::StepComplete
                | Phase::EventMode
                | Phase::ContinuousTimeMode
        );
        if !takes_inputs || vrs.len() > adapter::MAX_INPUTS {
            return None;
        }
        let mut at = [0; adapter::MAX_INPUTS];
        for ((vr, value), at) in vrs.iter().zip(values).zip(&mut at) {
            let v = self.model.by_vr(*vr)?;
            if !((v.causality == Causality::Input) & (v.ty == ty) && v.range.admits(*value)) {
                return None;
            }
            *at = v.symbol.index();
        }
        Some(at)
    }

    /// Whether a continuous-time state can be set by value reference now. FMI 2.0.4 §3.2.3,
    /// condition 5 of fmi2SetReal in Continuous-Time Mode: "for a variable with causality =
    /// "input" and variability = "continuous", and for a continuous-time state variable". FMI
    /// 3.0.2 §3.2.1, Continuous-Time Mode: "Only for variables with causality = input and
    /// variability = continuous, and continuous-time states"; §2.3.5, Event Mode (of either
    /// interface): "… and continuous-time states with reinit = false" (no state declares
    /// reinit, whose default is false).
    fn states_settable(&self) -> bool {
        match self.phase() {
            Phase::ContinuousTimeMode => true,
            Phase::EventMode => self.flavour.standard == Standard::Fmi3,
            _ => false,
        }
    }

    /// All values are checked before any is stored, so a refused call changes nothing. A
    /// continuous-time state set after initialization sets the plant's state exactly as
    /// fmi2SetContinuousStates with the other entries unchanged would.
    pub(crate) fn set_real_body(&mut self, vrs: &[u32], values: &[f64]) -> Result<Status, FmuError> {
        Self::same_length("fmi2SetReal values", values.len(), vrs.len())?;
        self.set_values(vrs, values, VarType::Real)
    }

    /// fmi2SetInteger, fmi3SetInt32: the Integer parameters (`contact_law`), by the rules of
    /// the Real parameters, each value admitted by its range (1 or 2) before any is stored;
    /// `contact`, an output, is not settable.
    pub(crate) fn set_integer_body(&mut self, vrs: &[u32], values: &[i32]) -> Result<Status, FmuError> {
        Self::same_length("fmi2SetInteger values", values.len(), vrs.len())?;
        let values: Vec<f64> = values.iter().map(|x| *x as f64).collect();
        self.set_values(vrs, &values, VarType::Integer)
    }

    /// Sets variables of type `ty` (an Integer's value as its f64).
    fn set_values(&mut self, vrs: &[u32], values: &[f64], ty: VarType) -> Result<Status, FmuError> {
        if let Some(at) = self.admitted_inputs(vrs, values, ty) {
            // Inputs are stored values in every state that takes one (`check_settable`), and a
            // plant's preview does not read them.
            for (value, at) in values.iter().zip(at) {
                self.values[at] = *value;
            }
            return Ok(Status::Ok);
        }
        // The plant's state with the states set here, once one is (after initialization); a
        // gearbox's states set, by entry.
        let mut z: Option<adapter::StateVector> = None;
        let mut gear_states = Vec::new();
        // All or nothing: every element is checked before any is stored.
        for (vr, value) in vrs.iter().zip(values) {
            if self.is_time(*vr) && ty == VarType::Real {
                return Err(FmuError::NotSettable {
                    name: TIME.0,
                    phase: self.phase(),
                    reason: "it is the independent variable: fmi3DoStep and fmi3SetTime move it",
                });
            }
            let v = self.typed_variable(*vr, ty)?;
            self.check_settable(v)?;
            if !v.range.admits(*value) {
                return Err(FmuError::ValueRefused {
                    name: v.name,
                    value: *value,
                    range: v.range.describe(),
                });
            }
            if let (Source::State(entry), Some(sim)) = (v.symbol.source(), self.life.sim()) {
                z.get_or_insert_with(|| adapter::entries_of(&sim.state))[entry.index()] = *value;
            }
            if let (Source::State(entry), Some(_)) = (v.symbol.source(), self.life.geared()) {
                gear_states.push((entry, *value));
            }
        }
        if !gear_states.is_empty() {
            // Checked and made the gearbox's before any value is stored: a refusal changes nothing.
            self.gear_set_states(&gear_states)?;
        }
        let state = match (self.life.sim(), z) {
            (Some(sim), Some(z)) => {
                let state = adapter::state_of(sim.plant(), &z);
                sim.check_state(&state, format_args!("the continuous states overflow"))?;
                Some(state)
            }
            _ => None,
        };
        for (vr, value) in vrs.iter().zip(values) {
            let v = self.typed_variable(*vr, ty)?;
            // After initialization a state's slot keeps its start value; the plant holds the state.
            let physics = self.life.sim().is_some() || self.life.geared().is_some();
            if !(physics && matches!(v.symbol.source(), Source::State(_))) {
                self.values[v.symbol.index()] = *value;
            }
        }
        match (&mut self.life, state) {
            // Model Exchange keeps each body's friction mode, a discrete state, until Event Mode;
            // Co-Simulation applies the law to the state set, as at a step's start.
            (Lifecycle::Running { sim, .. }, Some(state)) => match self.flavour.interface {
                Interface::ModelExchange => sim.set_continuous(state),
                Interface::CoSimulation => {
                    let inputs = adapter::inputs(sim.plant(), &self.values, &self.input_slopes);
                    sim.set_state(state, &inputs)
                }
            },
            (Lifecycle::Running { .. }, None) | (Lifecycle::Sampling { .. }, _) | (Lifecycle::Geared { .. }, _) => {}
            (Lifecycle::Setup { preview, geared, .. }, _) => {
                *preview = None;
                *geared = None;
            }
        }
        Ok(Status::Ok)
    }

    /// Order-1 derivatives of the inputs, with respect to the start of the next step (FMI
    /// 2.0.4 §4.2.1). They stay in force until set again, and the input value moves along
    /// the line: after a step of size h, τ ← τ + h·dτ/dt (a continuous piecewise-linear input).
    pub(crate) fn set_real_input_derivatives_body(
        &mut self,
        vrs: &[u32],
        orders: &[i32],
        values: &[f64],
    ) -> Result<Status, FmuError> {
        self.check_offered(Function::SetRealInputDerivatives)?;
        Self::same_length("fmi2SetRealInputDerivatives orders", orders.len(), vrs.len())?;
        Self::same_length("fmi2SetRealInputDerivatives values", values.len(), vrs.len())?;
        let mut targets = Vec::with_capacity(vrs.len());
        for ((vr, order), value) in vrs.iter().zip(orders).zip(values) {
            let v = self.typed_variable(*vr, VarType::Real)?;
            let Source::Input(slot) = v.symbol.source() else {
                return Err(FmuError::InvalidArgument(format!(
                    "{} is not an input; only inputs have input derivatives",
                    v.name
                )));
            };
            if *order != 1 {
                return Err(FmuError::InvalidArgument(format!(
                    "derivative order {order} of {}: inputs are interpolated linearly, only order 1 is accepted",
                    v.name
                )));
            }
            if !value.is_finite() {
                return Err(FmuError::ValueRefused {
                    name: v.name,
                    value: *value,
                    range: "a finite derivative".into(),
                });
            }
            targets.push(slot);
        }
        for (slot, value) in targets.into_iter().zip(values) {
            self.input_slopes[slot] = *value;
        }
        Ok(Status::Ok)
    }

    pub(crate) fn get_real_output_derivatives_body(
        &mut self,
        vrs: &[u32],
        orders: &[i32],
        out: &mut [f64],
    ) -> Result<Status, FmuError> {
        self.check_offered(Function::GetRealOutputDerivatives)?;
        Self::same_length("fmi2GetRealOutputDerivatives orders", orders.len(), vrs.len())?;
        Self::same_length("fmi2GetRealOutputDerivatives values", out.len(), vrs.len())?;
        // The bounds' rates at the instance's time, when one is asked for.
        let bounds = vrs.iter().any(|vr| {
            self.model.by_vr(*vr).is_some_and(|v| {
                matches!(
                    v.symbol.source(),
                    Source::Calculated(Calculated::Bound | Calculated::BoundPaper | Calculated::BoundT)
                )
            })
        });
        if bounds {
            self.bound_to_time()?;
        }
        if self.model.is_geared() {
            return self.gear_output_derivatives(vrs, orders, out);
        }
        // Before initialization has ended (state Error entered then) there is nothing to derive;
        // the bounds above are brought to time only when there is a simulation.
        let sim = self
            .life
            .sim()
            .ok_or_else(|| FmuError::InvalidArgument("no output derivatives before initialization has ended".into()))?;
        let inputs = adapter::inputs(sim.plant(), &self.values, &self.input_slopes);
        let mut rates: Option<adapter::StateVector> = None;
        for ((vr, order), slot) in vrs.iter().zip(orders).zip(out.iter_mut()) {
            let v = self.typed_variable(*vr, VarType::Real)?;
            if v.causality != Causality::Output {
                return Err(FmuError::InvalidArgument(format!("{} is not an output", v.name)));
            }
            if *order != 1 {
                return Err(FmuError::InvalidArgument(format!(
                    "derivative order {order} of {}: maxOutputDerivativeOrder is 1",
                    v.name
                )));
            }
            // d/dt [θ_m, ω_m, θ_L, ω_L, T] in the mode in force (at a switch: the mode entered).
            let z_dot = *rates.get_or_insert_with(|| match &sim.friction {
                None => sim.stepper.time_derivative(&sim.state, &inputs, 1),
                Some(f) => f.rates(&sim.state, &inputs),
            });
            let rate = match v.symbol.source() {
                Source::State(entry) => Some(z_dot[entry.index()]),
                Source::Calculated(quantity) => quantity.rate(sim, &z_dot),
                Source::Input(_)
                | Source::Parameter
                | Source::Contact
                | Source::StageContact(_)
                | Source::Sliding(_)
                | Source::Derivative(_)
                | Source::Sampled
                | Source::Command => None,
            };
            *slot = rate.ok_or_else(|| FmuError::InvalidArgument(format!("{} has no output derivative", v.name)))?;
            if !slot.is_finite() {
                return Err(FmuError::Overflow(format!("d{}/dt evaluates to {slot}", v.name)));
            }
        }
        Ok(Status::Ok)
    }
}

//! One FMU instance: the state machine of FMI 2.0 Co-Simulation, get/set by value reference
//! from the generated table, stepping, output derivatives, and FMU states.
//!
//! Every public call goes through [`Instance::run`]: legal-state check, the work, and on
//! failure one place that logs the reason and (for fmi2Error) enters state Error.

use super::error::{FmuError, Status};
use super::logging::{LogCategory, LogSink, Logging};
use super::simulation::{inputs, Simulation, Values, MAX_PERIODS_PER_STEP};
use super::snapshot::{PhysicsSnapshot, Snapshot};
use super::state_machine::{Function, Phase};
use super::variables::{model_by_guid, Causality, ModelInfo, Symbol, VarType, Variable};
use crate::physics::ContactMode;
use crate::physics::{contact_indicator, finite, BoundError, Inputs};

/// Relative slack of bound_sup (see `SpeedErrorBound::sup_slack`) above which
/// exitInitializationMode warns.
const SUP_SLACK_WARNING: f64 = 1e-9;

/// Experiment set by fmi2SetupExperiment (defaults: start 0, no stop time).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Experiment {
    pub start_time: f64,
    pub stop_time: Option<f64>,
    /// Accepted and kept, but unused: stepping is exact (spec §2).
    pub tolerance: Option<f64>,
}

impl Default for Experiment {
    fn default() -> Self {
        Experiment {
            start_time: 0.0,
            stop_time: None,
            tolerance: None,
        }
    }
}

/// What fmi2GetXXXStatus is asked for (fmi2StatusKind).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum StatusKind {
    DoStepStatus,
    PendingStatus,
    LastSuccessfulTime,
    Terminated,
}

/// Relative tolerance for "the communication point equals the current time": steps are
/// accumulated by the importer in floating point, so they drift by a few ulps per step.
const TIME_TOLERANCE: f64 = 1e-9;

pub struct Instance {
    model: &'static ModelInfo,
    phase: Phase,
    /// Inputs, parameters and start values (θ, ω before initialization), by [`Symbol`].
    values: Values,
    /// dτ_m/dt, dτ_L/dt set by fmi2SetRealInputDerivatives (order 1).
    input_slopes: [f64; 2],
    experiment: Experiment,
    time: f64,
    /// Present from fmi2ExitInitializationMode on.
    sim: Option<Simulation>,
    /// Built on demand for fmi2GetXXX in Initialization Mode, dropped on every set.
    preview: Option<Simulation>,
    log: Logging,
}

impl Instance {
    /// A fresh instance of `model` (state Instantiated, all start values).
    pub fn new(model: &'static ModelInfo, sink: Option<Box<dyn LogSink>>, logging_on: bool) -> Instance {
        Instance {
            model,
            phase: Phase::Instantiated,
            values: start_values(model),
            input_slopes: [0.0; 2],
            experiment: Experiment::default(),
            time: 0.0,
            sim: None,
            preview: None,
            log: Logging::new(sink, logging_on),
        }
    }

    /// fmi2Instantiate for Co-Simulation: the model is chosen by its guid.
    pub fn instantiate(guid: &str, sink: Option<Box<dyn LogSink>>, logging_on: bool) -> Result<Instance, FmuError> {
        let model = model_by_guid(guid).ok_or_else(|| {
            FmuError::InvalidArgument(format!(
                "guid {guid:?} is not the guid of any model in this binary (BacklashShaft, BacklashBelt): the \
                 modelDescription.xml and the binary come from different builds"
            ))
        })?;
        Ok(Instance::new(model, sink, logging_on))
    }

    pub fn model(&self) -> &'static ModelInfo {
        self.model
    }

    pub fn phase(&self) -> Phase {
        self.phase
    }

    /// Current communication point [s].
    pub fn time(&self) -> f64 {
        self.time
    }

    pub fn experiment(&self) -> Experiment {
        self.experiment
    }

    /// The one entry point: checks that `function` is legal now, runs `body`, and on failure
    /// logs the reason and enters state Error (fmi2Error) or stays (fmi2Discard).
    pub fn run<T>(
        &mut self,
        function: Function,
        body: impl FnOnce(&mut Instance) -> Result<T, FmuError>,
    ) -> Result<T, FmuError> {
        let result = self.check_legal(function).and_then(|()| body(self));
        match &result {
            Ok(_) => self.log.emit(Status::Ok, LogCategory::Calls, || {
                format!("{} -> OK", function.c_name())
            }),
            Err(e) => self.fail(function, e),
        }
        result
    }

    /// Inlined, so that the mask of a known `function` is a constant.
    #[inline]
    pub fn check_legal(&self, function: Function) -> Result<(), FmuError> {
        // No phase bit is set in the mask of a Model Exchange function.
        if function.is_legal_in(self.phase) {
            return Ok(());
        }
        self.illegal(function)
    }

    #[cold]
    #[inline(never)]
    fn illegal(&self, function: Function) -> Result<(), FmuError> {
        if function.is_model_exchange_only() {
            Err(FmuError::ModelExchangeOnly {
                function: function.c_name(),
            })
        } else if function.is_legal_in(self.phase) {
            Ok(())
        } else {
            Err(FmuError::IllegalCall {
                function: function.c_name(),
                phase: self.phase,
            })
        }
    }

    fn fail(&mut self, function: Function, e: &FmuError) {
        let status = e.status();
        self.log
            .emit(status, LogCategory::Errors, || format!("{}: {e}", function.c_name()));
        self.log.emit(status, LogCategory::Calls, || {
            format!("{} -> {status:?}", function.c_name())
        });
        if status == Status::Error {
            self.phase = Phase::Error;
        }
    }

    /// After a panic inside a call: whatever was half done is discarded by entering Error.
    pub fn fail_after_panic(&mut self, function: Function, message: String) {
        let e = FmuError::Panic {
            function: function.c_name(),
            message,
        };
        self.fail(function, &e);
        self.phase = Phase::Error;
    }

    /// Logs through the instance's filter (used by the C layer for its own messages).
    pub fn log(&mut self, status: Status, category: LogCategory, message: impl FnOnce() -> String) {
        self.log.emit(status, category, message)
    }

    // ---- checked calls (the Rust API; the C layer calls `run` with the bodies below) ----

    pub fn set_debug_logging(&mut self, logging_on: bool, categories: &[&str]) -> Result<Status, FmuError> {
        self.run(Function::SetDebugLogging, |s| {
            s.set_debug_logging_body(logging_on, categories)
        })
    }

    pub fn setup_experiment(
        &mut self,
        tolerance: Option<f64>,
        start: f64,
        stop: Option<f64>,
    ) -> Result<Status, FmuError> {
        self.run(Function::SetupExperiment, |s| {
            s.setup_experiment_body(tolerance, start, stop)
        })
    }

    pub fn enter_initialization_mode(&mut self) -> Result<Status, FmuError> {
        self.run(Function::EnterInitializationMode, |s| {
            s.enter_initialization_mode_body()
        })
    }

    pub fn exit_initialization_mode(&mut self) -> Result<Status, FmuError> {
        self.run(Function::ExitInitializationMode, |s| s.exit_initialization_mode_body())
    }

    pub fn terminate(&mut self) -> Result<Status, FmuError> {
        self.run(Function::Terminate, |s| s.terminate_body())
    }

    pub fn reset(&mut self) -> Result<Status, FmuError> {
        self.run(Function::Reset, |s| s.reset_body())
    }

    pub fn get_real(&mut self, vrs: &[u32], values: &mut [f64]) -> Result<Status, FmuError> {
        self.run(Function::GetReal, |s| s.get_real_body(vrs, values))
    }

    pub fn get_integer(&mut self, vrs: &[u32], values: &mut [i32]) -> Result<Status, FmuError> {
        self.run(Function::GetInteger, |s| s.get_integer_body(vrs, values))
    }

    pub fn get_boolean(&mut self, vrs: &[u32], values: &mut [i32]) -> Result<Status, FmuError> {
        self.run(Function::GetBoolean, |s| {
            s.get_untyped_body(vrs, values.len(), "Boolean")
        })
    }

    pub fn get_string(&mut self, vrs: &[u32], count: usize) -> Result<Status, FmuError> {
        self.run(Function::GetString, |s| s.get_untyped_body(vrs, count, "String"))
    }

    pub fn set_real(&mut self, vrs: &[u32], values: &[f64]) -> Result<Status, FmuError> {
        self.run(Function::SetReal, |s| s.set_real_body(vrs, values))
    }

    pub fn set_integer(&mut self, vrs: &[u32], values: &[i32]) -> Result<Status, FmuError> {
        self.run(Function::SetInteger, |s| {
            s.set_untyped_body(vrs, values.len(), "Integer")
        })
    }

    pub fn set_boolean(&mut self, vrs: &[u32], values: &[i32]) -> Result<Status, FmuError> {
        self.run(Function::SetBoolean, |s| {
            s.set_untyped_body(vrs, values.len(), "Boolean")
        })
    }

    pub fn set_string(&mut self, vrs: &[u32], count: usize) -> Result<Status, FmuError> {
        self.run(Function::SetString, |s| s.set_untyped_body(vrs, count, "String"))
    }

    pub fn set_real_input_derivatives(
        &mut self,
        vrs: &[u32],
        orders: &[i32],
        values: &[f64],
    ) -> Result<Status, FmuError> {
        self.run(Function::SetRealInputDerivatives, |s| {
            s.set_real_input_derivatives_body(vrs, orders, values)
        })
    }

    pub fn get_real_output_derivatives(
        &mut self,
        vrs: &[u32],
        orders: &[i32],
        values: &mut [f64],
    ) -> Result<Status, FmuError> {
        self.run(Function::GetRealOutputDerivatives, |s| {
            s.get_real_output_derivatives_body(vrs, orders, values)
        })
    }

    pub fn do_step(&mut self, communication_point: f64, step_size: f64) -> Result<Status, FmuError> {
        self.run(Function::DoStep, |s| s.do_step_body(communication_point, step_size))
    }

    pub fn cancel_step(&mut self) -> Result<Status, FmuError> {
        self.run(Function::CancelStep, |_| Ok(Status::Ok))
    }

    pub fn get_status(&mut self, kind: StatusKind) -> Result<Status, FmuError> {
        self.run(Function::GetStatus, |s| s.get_status_body(kind))
    }

    pub fn get_real_status(&mut self, kind: StatusKind) -> Result<f64, FmuError> {
        self.run(Function::GetRealStatus, |s| s.get_real_status_body(kind))
    }

    pub fn get_boolean_status(&mut self, kind: StatusKind) -> Result<bool, FmuError> {
        self.run(Function::GetBooleanStatus, |s| s.get_boolean_status_body(kind))
    }

    pub fn get_fmu_state(&mut self) -> Result<Snapshot, FmuError> {
        self.run(Function::GetFmuState, |s| Ok(s.snapshot()))
    }

    pub fn set_fmu_state(&mut self, snapshot: &Snapshot) -> Result<Status, FmuError> {
        self.run(Function::SetFmuState, |s| s.restore_body(snapshot))
    }

    pub fn serialize_fmu_state(&mut self, snapshot: &Snapshot) -> Result<Vec<u8>, FmuError> {
        self.run(Function::SerializeFmuState, |_| Ok(snapshot.to_bytes()))
    }

    pub fn deserialize_fmu_state(&mut self, bytes: &[u8]) -> Result<Snapshot, FmuError> {
        self.run(Function::DeSerializeFmuState, |s| Snapshot::from_bytes(s.model, bytes))
    }

    // ---- bodies: called only through `run`, which has checked the state ----

    pub(crate) fn set_debug_logging_body(&mut self, logging_on: bool, categories: &[&str]) -> Result<Status, FmuError> {
        self.log.configure(logging_on, categories)?;
        Ok(Status::Ok)
    }

    pub(crate) fn setup_experiment_body(
        &mut self,
        tolerance: Option<f64>,
        start: f64,
        stop: Option<f64>,
    ) -> Result<Status, FmuError> {
        if !start.is_finite() {
            return Err(FmuError::InvalidArgument(format!("startTime {start} must be finite")));
        }
        if let Some(stop) = stop {
            if !stop.is_finite() || stop < start {
                return Err(FmuError::InvalidArgument(format!(
                    "stopTime {stop} must be finite and >= startTime {start}"
                )));
            }
        }
        self.experiment = Experiment {
            start_time: start,
            stop_time: stop,
            tolerance,
        };
        self.time = start;
        Ok(Status::Ok)
    }

    pub(crate) fn enter_initialization_mode_body(&mut self) -> Result<Status, FmuError> {
        self.phase = Phase::InitializationMode;
        self.time = self.experiment.start_time;
        Ok(Status::Ok)
    }

    pub(crate) fn exit_initialization_mode_body(&mut self) -> Result<Status, FmuError> {
        let sim = match self.preview.take() {
            Some(sim) => sim,
            None => Simulation::build(self.model, &self.values)?,
        };
        let unbounded = sim.bound_sup.err();
        let slack = sim.bound.sup_slack().unwrap_or(0.0);
        self.sim = Some(sim);
        self.time = self.experiment.start_time;
        self.phase = Phase::StepComplete;
        match unbounded {
            None if slack > SUP_SLACK_WARNING => {
                self.log.emit(Status::Warning, LogCategory::Warnings, || {
                    format!(
                        "bound_sup is an upper bound that may exceed K*g*integral(|h|) by {:.2e} (relative): \
                         the loop decays too slowly for the integration horizon",
                        slack
                    )
                });
                Ok(Status::Warning)
            }
            None => Ok(Status::Ok),
            Some(why) => {
                self.log.emit(Status::Warning, LogCategory::Warnings, || {
                    format!("bound_sup = +inf: {why}")
                });
                Ok(Status::Warning)
            }
        }
    }

    pub(crate) fn terminate_body(&mut self) -> Result<Status, FmuError> {
        self.phase = Phase::Terminated;
        Ok(Status::Ok)
    }

    /// Back to the state right after fmi2Instantiate; the logging configuration is the
    /// importer's and stays.
    pub(crate) fn reset_body(&mut self) -> Result<Status, FmuError> {
        self.phase = Phase::Instantiated;
        self.values = start_values(self.model);
        self.input_slopes = [0.0; 2];
        self.experiment = Experiment::default();
        self.time = 0.0;
        self.sim = None;
        self.preview = None;
        Ok(Status::Ok)
    }

    fn variable(&self, vr: u32) -> Result<&'static Variable, FmuError> {
        self.model.by_vr(vr).ok_or(FmuError::UnknownValueReference {
            vr,
            model: self.model.identifier,
        })
    }

    fn typed_variable(&self, vr: u32, ty: VarType) -> Result<&'static Variable, FmuError> {
        let v = self.variable(vr)?;
        if v.ty != ty {
            let requested = match ty {
                VarType::Real => "Real",
                VarType::Integer => "Integer",
            };
            return Err(FmuError::WrongType {
                name: v.name,
                vr,
                actual: v.ty,
                requested,
            });
        }
        Ok(v)
    }

    fn same_length(what: &'static str, length: usize, expected: usize) -> Result<(), FmuError> {
        if length == expected {
            Ok(())
        } else {
            Err(FmuError::LengthMismatch { what, length, expected })
        }
    }

    /// The physics in force: the simulation after initialization, before it the plant the
    /// current parameters and start values describe (built once per change).
    fn physics(&mut self) -> Result<&Simulation, FmuError> {
        if let Some(sim) = &self.sim {
            return Ok(sim);
        }
        if self.preview.is_none() {
            self.preview = Some(Simulation::build(self.model, &self.values)?);
        }
        Ok(self.preview.as_ref().expect("built above"))
    }

    fn real_value(&mut self, v: &Variable) -> Result<f64, FmuError> {
        let state_value = |sim: &Simulation| match v.symbol {
            Symbol::ThetaM => sim.state.theta_m,
            Symbol::OmegaM => sim.state.omega_m,
            Symbol::ThetaL => sim.state.theta_l,
            _ => sim.state.omega_l,
        };
        Ok(match v.symbol {
            Symbol::ThetaM | Symbol::OmegaM | Symbol::ThetaL | Symbol::OmegaL => match &self.sim {
                Some(sim) => state_value(sim),
                None => self.values[v.symbol.index()],
            },
            Symbol::Psi => {
                let sim = self.physics()?;
                sim.plant().force(sim.state.u)
            }
            Symbol::Bound => self.physics()?.bound.bound(),
            Symbol::BoundPaper => self.physics()?.bound.bound_paper(),
            Symbol::BoundSup => self.physics()?.bound_sup_value(),
            _ => self.values[v.symbol.index()],
        })
    }

    pub(crate) fn get_real_body(&mut self, vrs: &[u32], out: &mut [f64]) -> Result<Status, FmuError> {
        Self::same_length("fmi2GetReal values", out.len(), vrs.len())?;
        for (vr, slot) in vrs.iter().zip(out.iter_mut()) {
            let v = self.typed_variable(*vr, VarType::Real)?;
            let x = self.real_value(v)?;
            // bound_sup is +∞ by definition when the loop is unstable (spec §4); nothing else
            // may leave the FMU as ∞ or NaN.
            if x.is_nan() || (x.is_infinite() && v.symbol != Symbol::BoundSup) {
                return Err(FmuError::Overflow(format!("{} evaluates to {x}", v.name)));
            }
            *slot = x;
        }
        Ok(Status::Ok)
    }

    pub(crate) fn get_integer_body(&mut self, vrs: &[u32], out: &mut [i32]) -> Result<Status, FmuError> {
        Self::same_length("fmi2GetInteger values", out.len(), vrs.len())?;
        for (vr, slot) in vrs.iter().zip(out.iter_mut()) {
            let v = self.typed_variable(*vr, VarType::Integer)?;
            debug_assert_eq!(v.symbol, Symbol::Contact, "contact is the only Integer variable");
            let sim = self.physics()?;
            *slot = contact_indicator(&sim.state, sim.plant().half_gap());
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
            Some(vr) => {
                let v = self.variable(*vr)?;
                Err(FmuError::WrongType {
                    name: v.name,
                    vr: *vr,
                    actual: v.ty,
                    requested,
                })
            }
        }
    }

    /// As `get_untyped_body`; setting `contact` (the only Integer, a calculated output) is
    /// refused as not settable first.
    pub(crate) fn set_untyped_body(
        &mut self,
        vrs: &[u32],
        count: usize,
        requested: &'static str,
    ) -> Result<Status, FmuError> {
        Self::same_length("values", count, vrs.len())?;
        let integer = vrs
            .first()
            .and_then(|vr| self.model.by_vr(*vr))
            .filter(|v| v.ty == VarType::Integer);
        if let (Some(v), "Integer") = (integer, requested) {
            self.check_settable(v)?;
        }
        self.get_untyped_body(vrs, count, requested)
    }

    /// FMI 2.0.4 Co-Simulation table of allowed calls, per variable: before and during
    /// initialization inputs, parameters and initial = exact outputs (the initial state); in
    /// StepComplete inputs only (all parameters are fixed).
    fn check_settable(&self, v: &Variable) -> Result<(), FmuError> {
        let refuse = |reason| {
            Err(FmuError::NotSettable {
                name: v.name,
                phase: self.phase,
                reason,
            })
        };
        match v.causality {
            Causality::CalculatedParameter => refuse("it is a calculatedParameter, computed by the FMU"),
            Causality::Output if !v.is_initial_state() => refuse("it is an output computed by the FMU"),
            _ => match self.phase {
                Phase::Instantiated | Phase::InitializationMode => Ok(()),
                Phase::StepComplete => match v.causality {
                    Causality::Input => Ok(()),
                    Causality::Parameter => {
                        refuse("it is a fixed parameter; it can change only before fmi2ExitInitializationMode")
                    }
                    _ => refuse(
                        "its start value is the initial state; it can change only before fmi2ExitInitializationMode",
                    ),
                },
                _ => refuse("no variable can be set in this state"),
            },
        }
    }

    /// All values are checked before any is stored, so a refused call changes nothing.
    pub(crate) fn set_real_body(&mut self, vrs: &[u32], values: &[f64]) -> Result<Status, FmuError> {
        Self::same_length("fmi2SetReal values", values.len(), vrs.len())?;
        // All or nothing: every element is checked before any is stored.
        for (vr, value) in vrs.iter().zip(values) {
            let v = self.typed_variable(*vr, VarType::Real)?;
            self.check_settable(v)?;
            if !v.range.admits(*value) {
                return Err(FmuError::ValueRefused {
                    name: v.name,
                    value: *value,
                    range: v.range.describe(),
                });
            }
        }
        for (vr, value) in vrs.iter().zip(values) {
            let v = self.typed_variable(*vr, VarType::Real)?;
            self.values[v.symbol.index()] = *value;
        }
        if self.sim.is_none() {
            self.preview = None;
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
        Self::same_length("fmi2SetRealInputDerivatives orders", orders.len(), vrs.len())?;
        Self::same_length("fmi2SetRealInputDerivatives values", values.len(), vrs.len())?;
        let mut targets = Vec::with_capacity(vrs.len());
        for ((vr, order), value) in vrs.iter().zip(orders).zip(values) {
            let v = self.typed_variable(*vr, VarType::Real)?;
            let slot = match v.symbol {
                Symbol::TauM => 0,
                Symbol::TauL => 1,
                _ => {
                    return Err(FmuError::InvalidArgument(format!(
                        "{} is not an input; only inputs have input derivatives",
                        v.name
                    )))
                }
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
                    range: "a finite derivative",
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
        Self::same_length("fmi2GetRealOutputDerivatives orders", orders.len(), vrs.len())?;
        Self::same_length("fmi2GetRealOutputDerivatives values", out.len(), vrs.len())?;
        let inputs = inputs(&self.values, self.input_slopes);
        let Some(sim) = &self.sim else {
            return Err(FmuError::InvalidArgument(
                "no output derivatives before initialization has ended".into(),
            ));
        };
        let mut rates: Option<[f64; 4]> = None;
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
            // d/dt [θ_m, ω_m, θ_L, ω_L] in the mode in force (at a switch: the mode entered).
            let z_dot = *rates.get_or_insert_with(|| sim.stepper.time_derivative(&sim.state, &inputs, 1));
            *slot = match v.symbol {
                Symbol::ThetaM => z_dot[0],
                Symbol::OmegaM => z_dot[1],
                Symbol::ThetaL => z_dot[2],
                Symbol::OmegaL => z_dot[3],
                // ψ = K dz(u, g): dψ/dt = K u' in contact, 0 in the gap (spec §1).
                Symbol::Psi => match sim.state.mode {
                    ContactMode::Free => 0.0,
                    _ => sim.plant().stiffness() * (sim.plant().r_m() * z_dot[0] - sim.plant().r_l() * z_dot[2]),
                },
                Symbol::Bound => sim.bound_rate(),
                Symbol::BoundPaper => sim.bound_paper_rate(),
                _ => unreachable!("every Real output is listed"),
            };
            if !slot.is_finite() {
                return Err(FmuError::Overflow(format!("d{}/dt evaluates to {slot}", v.name)));
            }
        }
        Ok(Status::Ok)
    }

    pub(crate) fn do_step_body(&mut self, communication_point: f64, h: f64) -> Result<Status, FmuError> {
        let inputs = inputs(&self.values, self.input_slopes);
        // The input lines at the end of the step (see below); refused before stepping if they
        // leave f64, so that a refused step changes nothing.
        let tau_end = [inputs.tau_m + h * inputs.dtau_m, inputs.tau_l + h * inputs.dtau_l];
        let end = communication_point + h;
        let now = self.time;
        // Where steps must end: finite, so that time stays finite.
        let limit = match self.experiment.stop_time {
            Some(stop) => stop + TIME_TOLERANCE * stop.abs().max(1.0),
            None => f64::MAX,
        };
        let Some(sim) = self.sim.as_mut() else {
            unreachable!("StepComplete implies a simulation")
        };
        // All argument checks in one branch (non-short-circuit `&`, each false on NaN); the
        // reason is sorted out by `step_refusal` only when one fails. `max_step` is finite.
        let accepted = finite(communication_point)
            & (h > 0.0)
            & (h <= sim.max_step)
            & ((communication_point - now).abs() <= TIME_TOLERANCE * now.abs().max(1.0))
            & (end > communication_point)
            & (end <= limit)
            & finite(tau_end[0])
            & finite(tau_end[1]);
        if !accepted {
            return Err(self.step_refusal(communication_point, h, tau_end));
        }
        if !sim.quiet_step(&inputs, h) {
            self.general_step(communication_point, &inputs, h)?;
        }
        // The input lines continue over the next step unless set again (see
        // `set_real_input_derivatives_body`).
        self.values[Symbol::TauM.index()] = tau_end[0];
        self.values[Symbol::TauL.index()] = tau_end[1];
        // FMI 2.0.4 §4.2.2: synchronize to tc + h rather than accumulate.
        self.time = end;
        Ok(Status::Ok)
    }

    /// Why `do_step_body` refuses its arguments (called only when it does).
    #[cold]
    #[inline(never)]
    fn step_refusal(&self, communication_point: f64, h: f64, tau_end: [f64; 2]) -> FmuError {
        let bad = FmuError::InvalidArgument;
        if !communication_point.is_finite() {
            return bad(format!("currentCommunicationPoint {communication_point} is not finite"));
        }
        if !(h.is_finite() && h > 0.0) {
            return bad(format!("communicationStepSize {h} must be finite and > 0"));
        }
        let now = self.time;
        if (communication_point - now).abs() > TIME_TOLERANCE * now.abs().max(1.0) {
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
        if !tau_end.iter().all(|x| x.is_finite()) {
            return FmuError::Overflow(format!(
                "the input ramps reach tau_m = {:e}, tau_L = {:e} at the end of the step",
                tau_end[0], tau_end[1]
            ));
        }
        let max_step = self.sim.as_ref().map_or(f64::NAN, |sim| sim.max_step);
        bad(format!(
            "communicationStepSize {h} exceeds {max_step:e} s ({MAX_PERIODS_PER_STEP:e} periods of the contact \
             oscillation); split it into smaller steps"
        ))
    }

    /// The step of `do_step_body` past its argument checks, when the quiet path did not take
    /// it: contact switches located and logged, overflow of plant or bounds refused.
    #[cold]
    #[inline(never)]
    fn general_step(&mut self, communication_point: f64, inputs: &Inputs, h: f64) -> Result<(), FmuError> {
        let end = communication_point + h;
        let sim = self.sim.as_mut().expect("StepComplete implies a simulation");
        // The plant steps a copy of its state, and the bound fails (on a bad h, excluded above)
        // before changing anything: a failed step leaves the instance as it was.
        let mut state = sim.state;
        let mut switches = Vec::new();
        let want_switches = self.log.is_enabled(LogCategory::ContactEvents);
        sim.stepper.step(&mut state, inputs, h, &mut |event| {
            if want_switches {
                switches.push(event)
            }
        })?;
        if !sim.state_ok(&state) {
            return Err(sim.overflow(&state, format_args!("the step to t = {end} overflows")));
        }
        // Fails before changing anything (a bad h is excluded above).
        sim.bound.advance(h).map_err(|e| match e {
            BoundError::Overflow { bound, bound_paper } => FmuError::Overflow(format!(
                "the step to t = {end} overflows the bounds: bound = {bound:e}, bound_paper = {bound_paper:e}"
            )),
            e => e.into(),
        })?;
        sim.state = state;
        let half_gap = sim.plant().half_gap();
        for e in switches {
            let t = communication_point + e.offset;
            self.log.emit(Status::Ok, LogCategory::ContactEvents, || {
                format!(
                    "contact switch at t = {t} s: {:?} -> {:?} (g = {half_gap})",
                    e.from, e.to
                )
            });
        }
        Ok(())
    }

    pub(crate) fn get_status_body(&mut self, kind: StatusKind) -> Result<Status, FmuError> {
        match kind {
            // Steps are synchronous: the last fmi2DoStep finished with the status it returned.
            StatusKind::DoStepStatus => Ok(Status::Ok),
            _ => Err(FmuError::StatusUnavailable(format!(
                "{kind:?} is not an fmi2Status status kind"
            ))),
        }
    }

    pub(crate) fn get_real_status_body(&mut self, kind: StatusKind) -> Result<f64, FmuError> {
        match kind {
            StatusKind::LastSuccessfulTime => Ok(self.time),
            _ => Err(FmuError::StatusUnavailable(format!(
                "{kind:?} is not a Real status kind"
            ))),
        }
    }

    pub(crate) fn get_boolean_status_body(&mut self, kind: StatusKind) -> Result<bool, FmuError> {
        match kind {
            // The FMU never asks the master to end the simulation.
            StatusKind::Terminated => Ok(false),
            _ => Err(FmuError::StatusUnavailable(format!(
                "{kind:?} is not a Boolean status kind"
            ))),
        }
    }

    pub(crate) fn get_integer_status_body(&mut self, kind: StatusKind) -> Result<i32, FmuError> {
        Err(FmuError::StatusUnavailable(format!(
            "{kind:?}: FMI 2.0 defines no Integer status"
        )))
    }

    pub(crate) fn get_string_status_body(&mut self, kind: StatusKind) -> Result<(), FmuError> {
        Err(FmuError::StatusUnavailable(match kind {
            StatusKind::PendingStatus => "no step is pending: every fmi2DoStep completes before it returns".into(),
            _ => format!("{kind:?} is not a String status kind"),
        }))
    }

    pub(crate) fn snapshot(&self) -> Snapshot {
        Snapshot {
            guid: self.model.guid,
            phase: self.phase,
            time: self.time,
            experiment: self.experiment,
            values: self.values,
            input_slopes: self.input_slopes,
            physics: self.sim.as_ref().map(|sim| PhysicsSnapshot {
                plant: sim.state,
                bound: sim.bound.state(),
            }),
        }
    }

    pub(crate) fn restore_body(&mut self, snapshot: &Snapshot) -> Result<Status, FmuError> {
        if snapshot.guid != self.model.guid {
            return Err(FmuError::StateRefused(format!(
                "it belongs to the model with guid {}, this instance is {} ({})",
                snapshot.guid, self.model.identifier, self.model.guid
            )));
        }
        let sim = match &snapshot.physics {
            Some(p) => Some(Simulation::restore(self.model, &snapshot.values, p.plant, &p.bound)?),
            None => None,
        };
        self.phase = snapshot.phase;
        self.time = snapshot.time;
        self.experiment = snapshot.experiment;
        self.values = snapshot.values;
        self.input_slopes = snapshot.input_slopes;
        self.sim = sim;
        self.preview = None;
        Ok(Status::Ok)
    }
}

/// The value store right after instantiation: every start value of the description.
fn start_values(model: &ModelInfo) -> Values {
    let mut values = [0.0; Symbol::COUNT];
    for v in model.variables {
        if let Some(start) = v.start {
            values[v.symbol.index()] = start;
        }
    }
    values
}

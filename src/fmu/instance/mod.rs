//! One FMU instance, of Model Exchange or Co-Simulation: its state machine and lifecycle calls.
//! The other calls are in the files beside this one: get/set by value reference and derivatives
//! (`values`), Co-Simulation stepping (`stepping`) and status queries (`status`), the Model
//! Exchange calls (`model_exchange`), FMU states (`fmu_state`).
//!
//! Every public call goes through [`Instance::run`]: legal-state check, the work, and on
//! failure one place that logs the reason and (for fmi2Error) enters state Error.

mod fmu_state;
mod gearbox;
mod lifecycle;
mod model_exchange;
mod sampling;
mod status;
mod stepping;
mod values;

use super::adapter::{self, Values};
use super::error::{FmuError, Status};
use super::logging::{LogCategory, LogSink, Logging};
use super::simulation::{EventTerms, Simulation};
use super::snapshot::Snapshot;
use super::state_machine::{Flavour, Function, Interface, Phase, Standard};
use super::variables::ModelInfo;
use lifecycle::Lifecycle;

/// Relative slack of bound_sup or bound_T_sup (see `LoopBound::sup_slack`) above which
/// exitInitializationMode warns.
const SUP_SLACK_WARNING: f64 = 1e-9;

/// Why the bounds of a web line are +∞ with Coulomb friction (docs/model.md §12).
const FRICTION_UNBOUNDED: &str = "with Coulomb friction (tau_c_m or tau_c_L > 0) on a web line: the friction's \
                                  terms of the web loop's bounds are not built";

/// Experiment set by fmi2SetupExperiment (defaults: start 0, no stop time).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Experiment {
    pub start_time: f64,
    pub stop_time: Option<f64>,
    /// Accepted and kept, but unused: stepping is exact (docs/model.md §2).
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

#[cfg(test)]
pub(crate) use gearbox::indicator as gear_indicator;
pub use model_exchange::{EventInfo, TimeMarks};
pub(crate) use sampling::NO_FMU_STATE;
pub use stepping::StepOutcome;

/// The choices of fmi3InstantiateCoSimulation (FMI 3.0 §4.2.1).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct CoSimulationOptions {
    /// The importer handles events in Event Mode: initialization ends there, and a step that
    /// stops at a contact switch asks for it.
    pub event_mode_used: bool,
    /// fmi3DoStep may stop at the first contact switch inside the step.
    pub early_return_allowed: bool,
}

pub struct Instance {
    model: &'static ModelInfo,
    flavour: Flavour,
    options: CoSimulationOptions,
    /// The state, with the simulation in the states that have one.
    life: Lifecycle,
    /// Inputs, parameters and start values (θ, ω before initialization), by [`Symbol`].
    values: Values,
    /// The input lines' slopes (dτ_m/dt, dτ_L/dt, and dv_in/dt, dT_in/dt on a web line) set by
    /// fmi2SetRealInputDerivatives (order 1).
    input_slopes: adapter::InputSlopes,
    experiment: Experiment,
    /// Co-Simulation: the communication point; Model Exchange: the time set by fmi2SetTime.
    time: f64,
    /// Model Exchange: how far back the time may be set.
    time_marks: TimeMarks,
    log: Logging,
}

impl Instance {
    /// A fresh Co-Simulation instance of `model` (state Instantiated, all start values).
    pub fn new(model: &'static ModelInfo, sink: Option<Box<dyn LogSink>>, logging_on: bool) -> Instance {
        Instance::new_for(model, Interface::CoSimulation, sink, logging_on)
    }

    /// A fresh FMI 2.0 instance of `model` serving `interface`.
    pub fn new_for(
        model: &'static ModelInfo,
        interface: Interface,
        sink: Option<Box<dyn LogSink>>,
        logging_on: bool,
    ) -> Instance {
        let flavour = Flavour {
            standard: Standard::Fmi2,
            interface,
        };
        Instance::with(model, flavour, CoSimulationOptions::default(), sink, logging_on)
    }

    /// A fresh instance of `model` of any flavour; `options` apply to FMI 3.0 Co-Simulation.
    pub fn with(
        model: &'static ModelInfo,
        flavour: Flavour,
        options: CoSimulationOptions,
        sink: Option<Box<dyn LogSink>>,
        logging_on: bool,
    ) -> Instance {
        Instance {
            model,
            flavour,
            options,
            life: Lifecycle::instantiated(),
            values: adapter::start_values(model),
            input_slopes: [0.0; adapter::MAX_INPUTS],
            experiment: Experiment::default(),
            time: 0.0,
            time_marks: TimeMarks::at_start(0.0),
            log: Logging::new(sink, logging_on, flavour.standard),
        }
    }

    pub fn model(&self) -> &'static ModelInfo {
        self.model
    }

    pub fn phase(&self) -> Phase {
        self.life.phase()
    }

    pub fn interface(&self) -> Interface {
        self.flavour.interface
    }

    pub fn flavour(&self) -> Flavour {
        self.flavour
    }

    /// The C name of `function` in this instance's standard, for messages.
    pub fn name_of(&self, function: Function) -> &'static str {
        function.name(self.flavour.standard)
    }

    /// Current communication point [s].
    pub fn time(&self) -> f64 {
        self.time
    }

    pub fn experiment(&self) -> Experiment {
        self.experiment
    }

    /// The one entry point: checks that `function` is legal now, runs `body`, and on failure
    /// logs the reason and enters state Error (fmi2Error) or stays (fmi2Discard). The C layer
    /// goes through [`Instance::run_status`], the same with the status alone.
    pub fn run<T>(
        &mut self,
        function: Function,
        body: impl FnOnce(&mut Instance) -> Result<T, FmuError>,
    ) -> Result<T, FmuError> {
        let checked = if self.is_legal(function) {
            Ok(())
        } else {
            self.illegal(function)
        };
        let result = checked.and_then(|()| body(self));
        match &result {
            Ok(_) => self.log.emit(Status::Ok, LogCategory::Calls, || {
                format!("{} -> OK", function.name(self.flavour.standard))
            }),
            Err(e) => self.fail(function, e),
        }
        result
    }

    /// [`Instance::run`] of a body that returns a status, answering the status alone: the C
    /// layer's path, with `legal` = [`Instance::is_legal`] tested by the caller. The FFI guard
    /// tests it before its unwinding boundary, where the mask of its known `function` folds to
    /// a constant (behind the boundary `function` is read back from memory and its mask looked
    /// up in a jump table on every call).
    ///
    /// The error is logged and dropped here. Handing the whole `Result` back instead (wider
    /// than two registers, so returned in memory) made every call read it back whole right
    /// after storing its first bytes, a store-forwarding stall (BENCHMARKS.md, the runs before
    /// and after: event-free `fmi2DoStep` 38.9 -> 33.7 ns, set(2) + get(1) 36.7 -> 31.3 ns).
    ///
    /// It repeats `run`'s legality check and success log inline: shared through two helpers
    /// (even `#[inline(always)]`), every call measured 1 to 3 ns slower in each of four code
    /// layouts (benches/native_host.c's suite, median of 7 runs each).
    #[inline]
    pub fn run_status(
        &mut self,
        function: Function,
        legal: bool,
        body: impl FnOnce(&mut Instance) -> Result<Status, FmuError>,
    ) -> Status {
        let checked = if legal { Ok(()) } else { self.illegal(function) };
        match checked.and_then(|()| body(self)) {
            Ok(status) => {
                self.log.emit(Status::Ok, LogCategory::Calls, || {
                    format!("{} -> OK", function.name(self.flavour.standard))
                });
                status
            }
            Err(e) => {
                self.fail(function, &e);
                e.status()
            }
        }
    }

    /// Whether `function` is legal in the current state. Inlined, so that the mask of a known
    /// `function` is a constant.
    #[inline]
    pub fn is_legal(&self, function: Function) -> bool {
        function.is_legal_in(self.flavour, self.phase())
    }

    #[cold]
    #[inline(never)]
    fn illegal(&self, function: Function) -> Result<(), FmuError> {
        match function.only_for(self.flavour.standard) {
            Some(other) if other != self.flavour.interface => Err(FmuError::OtherInterface {
                function: self.name_of(function),
                belongs_to: other.name(),
                serves: self.flavour.interface.name(),
            }),
            _ if function.is_legal_in(self.flavour, self.phase()) => Ok(()),
            _ => Err(FmuError::IllegalCall {
                function: self.name_of(function),
                phase: self.phase(),
                rule: function.rule(self.flavour.standard, self.phase()),
            }),
        }
    }

    fn fail(&mut self, function: Function, e: &FmuError) {
        let status = e.status();
        self.log.emit(status, LogCategory::Errors, || {
            format!("{}: {e}", function.name(self.flavour.standard))
        });
        self.log.emit(status, LogCategory::Calls, || {
            format!("{} -> {status:?}", function.name(self.flavour.standard))
        });
        if status == Status::Error {
            self.life.enter(Phase::Error);
        }
    }

    /// After a panic inside a call: whatever was half done is discarded by entering Error.
    pub fn fail_after_panic(&mut self, function: Function, message: String) {
        let e = FmuError::Panic {
            function: self.name_of(function),
            message,
        };
        self.fail(function, &e);
        self.life.enter(Phase::Error);
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
        self.run(Function::SetInteger, |s| s.set_integer_body(vrs, values))
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
        self.run(Function::GetFmuState, |s| s.snapshot())
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
        self.start_clock(start);
        Ok(Status::Ok)
    }

    /// The instance's time at `start`, with nothing completed or entered yet to limit going back.
    fn start_clock(&mut self, start: f64) {
        self.time = start;
        self.time_marks = TimeMarks::at_start(start);
    }

    pub(crate) fn enter_initialization_mode_body(&mut self) -> Result<Status, FmuError> {
        self.life.enter(Phase::InitializationMode);
        self.start_clock(self.experiment.start_time);
        Ok(Status::Ok)
    }

    pub(crate) fn exit_initialization_mode_body(&mut self) -> Result<Status, FmuError> {
        if self.model.is_controller() {
            return self.exit_sampling_initialization();
        }
        if self.model.is_geared() {
            return self.gear_exit_initialization();
        }
        let preview = match &mut self.life {
            Lifecycle::Setup { preview, .. } => preview.take(),
            Lifecycle::Running { .. } | Lifecycle::Sampling { .. } | Lifecycle::Geared { .. } => None,
        };
        let sim = match preview {
            Some(sim) => sim,
            None => Simulation::build(self.model, &self.values)?,
        };
        // Every output, the state derivatives included, must be finite from here on.
        let inputs = adapter::inputs(sim.plant(), &self.values, &self.input_slopes);
        sim.rates(&sim.state, &inputs, format_args!("the initial accelerations overflow"))?;
        let unbounded = match (sim.clock.bound.sup(), sim.clock.bound.sup_t()) {
            _ if !sim.bounded() => Some((
                "bound, bound_sup, bound_T and bound_T_sup",
                FRICTION_UNBOUNDED.to_string(),
            )),
            (Err(why), Err(_)) => Some(("bound_sup and bound_T_sup", why.to_string())),
            (Err(why), _) => Some(("bound_sup", why.to_string())),
            (_, Err(why)) => Some(("bound_T_sup", why.to_string())),
            _ => None,
        };
        let slack = sim.clock.bound.sup_slack();
        let mut sim = sim;
        if self.flavour.interface == Interface::ModelExchange && sim.plant().damping() > 0.0 {
            sim.events = EventTerms::start(&sim.state);
        }
        self.start_clock(self.experiment.start_time);
        self.life = Lifecycle::Running {
            phase: self.initialized_phase(),
            sim,
        };
        self.initialization_warnings(unbounded, slack)
    }

    /// The end of fmi2ExitInitializationMode: a warning naming the bounds that are +∞ and why,
    /// or one on suprema that may exceed their integral by more than [`SUP_SLACK_WARNING`].
    fn initialization_warnings(&mut self, unbounded: Option<(&str, String)>, slack: f64) -> Result<Status, FmuError> {
        match unbounded {
            None if slack > SUP_SLACK_WARNING => {
                self.log.emit(Status::Warning, LogCategory::Warnings, || {
                    format!(
                        "the suprema are upper bounds that may exceed K*g*integral(|h|) by {:.2e} (relative): \
                         the loop decays too slowly for the integration horizon",
                        slack
                    )
                });
                Ok(Status::Warning)
            }
            None => Ok(Status::Ok),
            Some((name, why)) => {
                self.log.emit(Status::Warning, LogCategory::Warnings, || {
                    format!("{name} = +inf: {why}")
                });
                Ok(Status::Warning)
            }
        }
    }

    /// The state initialization ends in: Event Mode in Model Exchange and where the importer uses
    /// it, else Step Mode (FMI 2.0's stepComplete).
    fn initialized_phase(&self) -> Phase {
        match self.flavour.interface {
            Interface::CoSimulation if !self.options.event_mode_used => Phase::StepComplete,
            Interface::CoSimulation | Interface::ModelExchange => Phase::EventMode,
        }
    }

    pub(crate) fn terminate_body(&mut self) -> Result<Status, FmuError> {
        self.life.enter(Phase::Terminated);
        Ok(Status::Ok)
    }

    /// Back to the state right after fmi2Instantiate; the logging configuration is the
    /// importer's and stays.
    pub(crate) fn reset_body(&mut self) -> Result<Status, FmuError> {
        self.life = Lifecycle::instantiated();
        self.values = adapter::start_values(self.model);
        self.input_slopes = [0.0; adapter::MAX_INPUTS];
        self.experiment = Experiment::default();
        self.start_clock(0.0);
        Ok(Status::Ok)
    }
}

//! A controller's instance (docs/model.md §9): initialization builds the sampled controller from
//! the parameters, and each Co-Simulation step takes one sample of the inputs.

use super::lifecycle::Lifecycle;
use super::{CoSimulationOptions, Instance};
use crate::fmu::adapter::MAX_INPUTS;
use crate::fmu::error::{FmuError, Status};
use crate::fmu::state_machine::{Flavour, Function, Interface};
use crate::fmu::variables::ModelInfo;
use crate::fmu::variables::Symbol;
use crate::physics::{finite, ControllerParams, Reference, SampleError, SampledPi};

/// What a controller says when asked for an FMU state, naming both standards' spellings of the
/// flag (FMI 2.0 `canGetAndSetFMUstate`, FMI 3.0 `canGetAndSetFMUState`): the snapshot code that
/// refuses it does not know the standard.
pub(crate) const NO_FMU_STATE: &str =
    "a controller's FMU state (canGetAndSetFMUstate = false; FMI 3.0: canGetAndSetFMUState = false)";

/// How far a communication step may differ from the sample period, relative: a master's clock
/// in integer nanoseconds, or summed step by step, hands steps that differ from it by a few ulps.
const PERIOD_TOLERANCE: f64 = 1e-9;

impl Instance {
    /// Whether `model` serves an instance of `flavour` with `options`: a controller's description
    /// declares Co-Simulation only, without Event Mode (FMI 3.0.2 §2.3.1, eventModeUsed: "The flag
    /// may only be `fmi3True`, if `hasEventMode = true`, otherwise the FMU must raise an error.").
    pub fn offered(model: &ModelInfo, flavour: Flavour, options: CoSimulationOptions) -> Result<(), String> {
        if !model.is_controller() {
            return Ok(());
        }
        if flavour.interface != Interface::CoSimulation {
            return Err(format!(
                "{} is a controller: Co-Simulation only, its description declares no Model Exchange",
                model.identifier
            ));
        }
        if options.event_mode_used {
            return Err(format!(
                "eventModeUsed = true, but {} has no Event Mode (hasEventMode = false): nothing happens between \
                 its samples",
                model.identifier
            ));
        }
        Ok(())
    }

    /// A controller's refusal of the calls its description does not offer (canGetAndSetFMUstate,
    /// canSerializeFMUstate, canInterpolateInputs false; maxOutputDerivativeOrder 0), legal in the
    /// state table: checked in those calls' bodies, so that the calls every step makes carry no
    /// test of the kind. (fmi2FreeFMUstate stays: freeing nothing is always fine.)
    pub(crate) fn check_offered(&self, function: Function) -> Result<(), FmuError> {
        if !self.model.is_controller() {
            return Ok(());
        }
        let feature = match function {
            // Deserializing is refused by `Snapshot::from_bytes`, which knows the model only.
            Function::GetFmuState
            | Function::SetFmuState
            | Function::SerializedFmuStateSize
            | Function::SerializeFmuState => NO_FMU_STATE,
            Function::SetRealInputDerivatives => "input derivatives of a controller (canInterpolateInputs = false)",
            Function::GetRealOutputDerivatives => "output derivatives of a controller (maxOutputDerivativeOrder = 0)",
            _ => return Ok(()),
        };
        Err(FmuError::NotProvided(feature))
    }

    /// The value of the variable of `symbol`, stored.
    fn stored(&self, symbol: Symbol) -> f64 {
        self.values[symbol.index()]
    }

    /// fmi2ExitInitializationMode of a controller: at rest (integrators 0, no sample), holding
    /// `tau_m`'s start value until the first step ends.
    pub(super) fn exit_sampling_initialization(&mut self) -> Result<Status, FmuError> {
        let code = self.stored(Symbol::ReferenceKind);
        let reference = Reference::from_code(
            code as i32,
            self.stored(Symbol::Amplitude),
            self.stored(Symbol::Frequency),
            self.stored(Symbol::RampTime),
            self.stored(Symbol::HoldTime),
        )
        .ok_or_else(|| FmuError::InvalidArgument(format!("reference = {code} is no kind of reference")))?;
        let params = ControllerParams {
            kp: self.stored(Symbol::Kp),
            ki: self.stored(Symbol::Ki),
            kp_t: self.stored(Symbol::KpT),
            ki_t: self.stored(Symbol::KiT),
            t_ref: self.stored(Symbol::TRef),
            period: self.stored(Symbol::SamplePeriod),
            reference,
        };
        let pi = SampledPi::new(params, self.stored(Symbol::TorqueCommand));
        self.start_clock(self.experiment.start_time);
        self.life = Lifecycle::Sampling {
            phase: self.initialized_phase(),
            pi,
        };
        Ok(Status::Ok)
    }

    /// One step of a controller: the sample of the inputs at the communication point; its torque
    /// is the output from the end of the step on.
    pub(super) fn sample_step(&mut self, communication_point: f64, h: f64) -> Result<bool, FmuError> {
        let (omega_m, tension) = (self.stored(Symbol::MeasuredSpeed), self.stored(Symbol::MeasuredTension));
        let end = communication_point + h;
        let accepted = finite(communication_point)
            & (h > 0.0)
            & self.at_time(communication_point)
            & (end > communication_point)
            & (end <= self.step_limit());
        if !accepted {
            return Err(self.step_refusal(communication_point, h, &[0.0; MAX_INPUTS]));
        }
        let Lifecycle::Sampling { pi, .. } = &mut self.life else {
            return Err(FmuError::InvalidArgument(
                "the controller has not been initialized".into(),
            ));
        };
        let period = pi.params.period;
        if (h - period).abs() > PERIOD_TOLERANCE * period {
            return Err(FmuError::InvalidArgument(format!(
                "communicationStepSize {h} is not the sample period h = {period}: the controller takes one \
                 sample per step (canHandleVariableCommunicationStepSize = false)"
            )));
        }
        pi.sample(omega_m, tension)
            .map_err(|SampleError::Overflow { torque }| {
                FmuError::Overflow(format!(
                    "the sample at t = {communication_point} (omega_m = {omega_m}, T = {tension}) gives tau_m = \
                 {torque} or an integrator beyond f64"
                ))
            })?;
        self.time = end;
        Ok(false)
    }
}

//! fmi2GetXXXStatus: steps are synchronous, so only the final status kinds are answered.

use super::{Instance, StatusKind};
use crate::fmu::error::{FmuError, Status};

impl Instance {
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
}

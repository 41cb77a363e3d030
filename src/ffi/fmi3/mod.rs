//! The C ABI of FMI 3.0 (`fmi3Functions.h`), served by the same instances as FMI 2.0: the
//! FMI 3.0 archives carry this same library. Every function goes through [`guard3`], which
//! refuses an instance created through the FMI 2.0 functions.
//!
//! The models have Float64 variables and two Int32 (`contact`, `contact_law`); the typed
//! functions of the other types serve no variable. Clocks, Scheduled Execution, Configuration
//! Mode, adjoint derivatives and per-element dependencies are not provided: those functions are
//! refused with the reason.

mod co_simulation;
mod lifecycle;
mod model_exchange;
mod states;
pub mod types;
mod unsupported;
mod values;

pub use co_simulation::*;
pub use lifecycle::*;
pub use model_exchange::*;
pub use states::*;
pub use types::*;
pub use unsupported::*;
pub use values::*;

use super::guard::{guard_in, to_c_string};
use crate::fmu::{FmuError, Function, Instance, LogCategory, LogSink, Standard, Status};

impl From<Status> for fmi3Status {
    fn from(s: Status) -> fmi3Status {
        match s {
            Status::Ok => fmi3Status::fmi3OK,
            Status::Warning => fmi3Status::fmi3Warning,
            Status::Discard => fmi3Status::fmi3Discard,
            Status::Error => fmi3Status::fmi3Error,
        }
    }
}

/// The guard of every FMI 3.0 function (see [`super::guard::guard_in`]).
#[inline]
pub(crate) fn guard3(
    instance: fmi3Instance,
    function: Function,
    body: impl FnOnce(&mut Instance) -> Result<Status, FmuError>,
) -> fmi3Status {
    guard_in(Standard::Fmi3, instance, function, body).into()
}

/// A C `bool` written by the FMU.
fn boolean(b: bool) -> fmi3Boolean {
    b
}

/// The importer's logger of FMI 3.0: `logMessage(environment, status, category, message)`.
pub struct CLogger3 {
    pub log_message: LogMessageFn,
    pub environment: fmi3InstanceEnvironment,
}

impl LogSink for CLogger3 {
    fn log(&mut self, status: Status, category: LogCategory, message: &str) {
        let category = to_c_string(category.name());
        let message = to_c_string(message);
        // SAFETY: `log_message` is the non-NULL callback the importer passed at instantiation,
        // of type fmi3LogMessageCallback; both strings are NUL-terminated and live until the
        // call returns.
        unsafe { (self.log_message)(self.environment, status.into(), category.as_ptr(), message.as_ptr()) }
    }
}

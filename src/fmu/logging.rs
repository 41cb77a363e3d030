//! Log categories of the model description and the filter that decides what reaches the
//! importer's logger (FMI 2.0.4 §2.1.5 fmi2SetDebugLogging).

use super::error::{FmuError, Status};
use super::state_machine::Standard;

// `LogCategory` with `ALL` and `name`, generated from the description's `<LogCategories>`.
include!(concat!(env!("OUT_DIR"), "/log_categories.rs"));

impl LogCategory {
    pub fn from_name(name: &str) -> Option<LogCategory> {
        LogCategory::ALL.into_iter().find(|c| c.name() == name)
    }
}

/// Where log messages go: the importer's logger (see `ffi`) or, in Rust tests, a collector.
pub trait LogSink {
    fn log(&mut self, status: Status, category: LogCategory, message: &str);
}

/// A sink that keeps every message, for tests and Rust callers.
#[derive(Clone, Debug, Default)]
pub struct Collected(pub std::rc::Rc<std::cell::RefCell<Vec<(Status, LogCategory, String)>>>);

impl LogSink for Collected {
    fn log(&mut self, status: Status, category: LogCategory, message: &str) {
        self.0.borrow_mut().push((status, category, message.to_string()));
    }
}

pub struct Logging {
    enabled: [bool; LogCategory::ALL.len()],
    sink: Option<Box<dyn LogSink>>,
}

impl Logging {
    /// FMI 2.0: errors and warnings reach the logger from the start, so every refusal comes
    /// with its reason; contact events and call traces only when `logging_on` (fmi2Instantiate).
    /// FMI 3.0.2 §2.3.1: "If loggingOn = fmi3False, then any logging is disabled and the
    /// logMessage callback function must not be called by the FMU" (fmi3SetDebugLogging can
    /// enable categories later).
    pub fn new(sink: Option<Box<dyn LogSink>>, logging_on: bool, standard: Standard) -> Logging {
        let mut enabled = [false; LogCategory::ALL.len()];
        for c in LogCategory::ALL {
            let always = standard == Standard::Fmi2 && matches!(c, LogCategory::Errors | LogCategory::Warnings);
            enabled[c as usize] = logging_on || always;
        }
        Logging { enabled, sink }
    }

    /// fmi2SetDebugLogging: no categories means all of them. Unknown names are refused
    /// before anything changes.
    pub fn configure(&mut self, logging_on: bool, categories: &[&str]) -> Result<(), FmuError> {
        let mut chosen = Vec::with_capacity(categories.len());
        for name in categories {
            chosen.push(LogCategory::from_name(name).ok_or_else(|| FmuError::UnknownLogCategory(name.to_string()))?);
        }
        if chosen.is_empty() {
            chosen.extend(LogCategory::ALL);
        }
        for c in chosen {
            self.enabled[c as usize] = logging_on;
        }
        Ok(())
    }

    pub fn is_enabled(&self, category: LogCategory) -> bool {
        self.sink.is_some() && self.enabled[category as usize]
    }

    /// Formats the message only if it will be delivered.
    pub fn emit(&mut self, status: Status, category: LogCategory, message: impl FnOnce() -> String) {
        if self.is_enabled(category) {
            if let Some(sink) = self.sink.as_mut() {
                sink.log(status, category, &message());
            }
        }
    }
}

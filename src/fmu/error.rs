//! Why a call failed, and the FMI status it maps to. Every message names the offending
//! variable, argument or value, so the importer's log says what to fix.

use super::state_machine::Phase;
use super::variables::VarType;
use crate::physics::bound::BoundError;
use crate::physics::{ParamError, StepError};
use thiserror::Error;

/// Outcome of a call, in FMI's order of severity (fmi2Fatal is never returned: instances
/// share nothing, so no error can spoil another one).
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub enum Status {
    Ok,
    Warning,
    Discard,
    Error,
}

#[derive(Clone, Debug, PartialEq, Error)]
pub enum FmuError {
    /// `rule`: the standard's sentence behind the refusal, where the state table alone would
    /// leave the importer guessing.
    #[error("{function} is not allowed in state {phase}{}", rule.map_or(String::new(), |r| format!(": {r}")))]
    IllegalCall {
        function: &'static str,
        phase: Phase,
        rule: Option<&'static str>,
    },
    /// fmi2SetTime / fmi3SetTime back over a completed integrator step or an event.
    #[error("time {time} is before {earliest}, the time of {mark}: {rule}")]
    TimeGoesBack {
        time: f64,
        earliest: f64,
        mark: &'static str,
        rule: &'static str,
    },
    #[error("{function} belongs to FMI for {belongs_to}; this instance was instantiated for {serves}")]
    OtherInterface {
        function: &'static str,
        belongs_to: &'static str,
        serves: &'static str,
    },
    #[error("argument {argument} is NULL but {length} values were announced")]
    NullArgument { argument: &'static str, length: usize },
    #[error("argument {argument} is not aligned for its element type")]
    Misaligned { argument: &'static str },
    #[error("argument {argument}: {length} values do not fit in memory")]
    TooLong { argument: &'static str, length: usize },
    #[error("{what}: {length} values given, {expected} expected")]
    LengthMismatch {
        what: &'static str,
        length: usize,
        expected: usize,
    },
    #[error("value reference {vr} is not a variable of {model}")]
    UnknownValueReference { vr: u32, model: &'static str },
    #[error("variable {name} (value reference {vr}) is of type {actual:?}, not {requested}")]
    WrongType {
        name: &'static str,
        vr: u32,
        actual: VarType,
        requested: &'static str,
    },
    #[error("variable {name} cannot be set in state {phase}: {reason}")]
    NotSettable {
        name: &'static str,
        phase: Phase,
        reason: &'static str,
    },
    #[error("value {value} refused for {name}: it must be {range}")]
    ValueRefused {
        name: &'static str,
        value: f64,
        range: std::borrow::Cow<'static, str>,
    },
    #[error("invalid parameter: {0}")]
    Parameter(#[from] ParamError),
    #[error("the step failed: {0}")]
    Step(#[from] StepError),
    #[error("the bounds failed: {0}")]
    Bound(#[from] BoundError),
    #[error("invalid argument: {0}")]
    InvalidArgument(String),
    /// Finite inputs, parameters or start values whose consequences exceed f64: refused
    /// rather than letting ∞ or NaN into the state or the outputs.
    #[error("floating-point overflow: {0}")]
    Overflow(String),
    #[error("{0}")]
    StatusUnavailable(String),
    #[error("{0} is not provided by this FMU")]
    NotProvided(&'static str),
    /// A function of a feature the FMU does not declare; the text says which and why.
    #[error("{0}")]
    Unsupported(&'static str),
    #[error("FMU state refused: {0}")]
    StateRefused(String),
    #[error("unknown log category {0:?}; the categories are listed in modelDescription.xml")]
    UnknownLogCategory(String),
    #[error(
        "internal error in {function}: {message}; the instance is in state Error, call fmi2Reset or fmi2SetFMUstate"
    )]
    Panic { function: &'static str, message: String },
}

impl FmuError {
    /// fmi2Discard only where FMI 2.0 asks for it (status queries the FMU cannot answer,
    /// FMI 2.0.4 §4.2.3); everything else is fmi2Error and puts the instance into state Error.
    pub fn status(&self) -> Status {
        match self {
            FmuError::StatusUnavailable(_) => Status::Discard,
            _ => Status::Error,
        }
    }
}

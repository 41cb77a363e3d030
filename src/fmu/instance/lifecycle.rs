//! Where an instance is in its state machine, with what it holds there: before initialization
//! has ended its values only, from then on the simulation too (a controller's: the sampled
//! controller). Holding the simulation in the variant of the states that have one, rather than
//! beside the phase, makes "this state has a simulation" a fact of the type.

use crate::fmu::error::FmuError;
use crate::fmu::geared::Geared;
use crate::fmu::simulation::Simulation;
use crate::fmu::state_machine::Phase;
use crate::physics::SampledPi;

pub(super) enum Lifecycle {
    /// Instantiated or Initialization Mode, or Error entered from them: the values, and the
    /// plant they describe, built on demand for reads and dropped on every set.
    /// A two-stage gearbox's preview is `geared`.
    Setup {
        phase: Phase,
        preview: Option<Simulation>,
        geared: Option<Box<Geared>>,
    },
    /// Every state from fmi2ExitInitializationMode on, Error included: the simulation. In Model
    /// Exchange its plant state is the one the importer set, and its bound is brought to the
    /// instance's time when read.
    Running { phase: Phase, sim: Simulation },
    /// A controller's every state from fmi2ExitInitializationMode on: the sampled controller.
    Sampling { phase: Phase, pi: SampledPi },
    /// A two-stage gearbox's every state from fmi2ExitInitializationMode on: its physics.
    Geared { phase: Phase, sim: Box<Geared> },
}

impl Lifecycle {
    /// A fresh instance's.
    pub(super) fn instantiated() -> Lifecycle {
        Lifecycle::Setup {
            phase: Phase::Instantiated,
            preview: None,
            geared: None,
        }
    }

    pub(super) fn phase(&self) -> Phase {
        match self {
            Lifecycle::Setup { phase, .. }
            | Lifecycle::Running { phase, .. }
            | Lifecycle::Sampling { phase, .. }
            | Lifecycle::Geared { phase, .. } => *phase,
        }
    }

    /// Moves to `next`, a state of the same stage (a state table's transition).
    pub(super) fn enter(&mut self, next: Phase) {
        match self {
            Lifecycle::Setup { phase, .. }
            | Lifecycle::Running { phase, .. }
            | Lifecycle::Sampling { phase, .. }
            | Lifecycle::Geared { phase, .. } => *phase = next,
        }
    }

    pub(super) fn sim(&self) -> Option<&Simulation> {
        match self {
            Lifecycle::Running { sim, .. } => Some(sim),
            Lifecycle::Setup { .. } | Lifecycle::Sampling { .. } | Lifecycle::Geared { .. } => None,
        }
    }

    /// A two-stage gearbox's physics after initialization.
    pub(super) fn geared(&self) -> Option<&Geared> {
        match self {
            Lifecycle::Geared { sim, .. } => Some(sim),
            _ => None,
        }
    }

    pub(super) fn geared_mut(&mut self) -> Option<&mut Geared> {
        match self {
            Lifecycle::Geared { sim, .. } => Some(sim),
            _ => None,
        }
    }

    pub(super) fn sim_mut(&mut self) -> Option<&mut Simulation> {
        match self {
            Lifecycle::Running { sim, .. } => Some(sim),
            Lifecycle::Setup { .. } | Lifecycle::Sampling { .. } | Lifecycle::Geared { .. } => None,
        }
    }

    /// The simulation, for the calls that are legal only after initialization (the state table
    /// lets no other call through; the refusal is there instead of a panic).
    pub(super) fn running(&mut self) -> Result<&mut Simulation, FmuError> {
        match self {
            Lifecycle::Running { sim, .. } => Ok(sim),
            Lifecycle::Setup { .. } => Err(FmuError::InvalidArgument(
                "no simulation before initialization has ended".into(),
            )),
            Lifecycle::Sampling { .. } => Err(FmuError::InvalidArgument("a controller has no plant".into())),
            Lifecycle::Geared { .. } => Err(FmuError::InvalidArgument("a gearbox has no single-gap plant".into())),
        }
    }
}

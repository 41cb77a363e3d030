//! FMU states: the snapshot of an instance and its restoration (checked before anything
//! changes).

use super::lifecycle::Lifecycle;
use super::Instance;
use crate::fmu::error::{FmuError, Status};
use crate::fmu::simulation::Simulation;
use crate::fmu::snapshot::{check_values, PhysicsSnapshot, Snapshot};
use crate::fmu::state_machine::Function;
use crate::physics::chain::BodyMode;

impl Instance {
    /// Refused for a controller, which has no FMU state.
    pub(crate) fn snapshot(&self) -> Result<Snapshot, FmuError> {
        self.check_offered(Function::GetFmuState)?;
        Ok(Snapshot {
            model: self.model,
            flavour: self.flavour,
            phase: self.phase(),
            time: self.time,
            time_marks: self.time_marks,
            experiment: self.experiment,
            values: self.values,
            input_slopes: self.input_slopes,
            physics: self.life.sim().map(|sim| PhysicsSnapshot {
                plant: sim.state,
                bodies: sim.friction.as_ref().map_or([BodyMode::Forward; 2], |f| f.bodies()),
                bound: sim.bound.words(),
                bounds_behind: sim.bounds_behind,
                events: sim.events,
            }),
        })
    }

    pub(crate) fn restore_body(&mut self, snapshot: &Snapshot) -> Result<Status, FmuError> {
        self.check_offered(Function::SetFmuState)?;
        if snapshot.model.guid != self.model.guid {
            return Err(FmuError::StateRefused(format!(
                "it belongs to the model with guid {}, this instance is {} ({})",
                snapshot.model.guid, self.model.identifier, self.model.guid
            )));
        }
        if snapshot.flavour.standard != self.flavour.standard {
            return Err(FmuError::StateRefused(format!(
                "it was taken from an {} instance; this instance is {}",
                snapshot.flavour.name(),
                self.flavour.name()
            )));
        }
        if snapshot.flavour.interface != self.flavour.interface {
            return Err(FmuError::StateRefused(format!(
                "it was taken from a {} instance; this instance serves {}",
                snapshot.flavour.interface.name(),
                self.flavour.interface.name()
            )));
        }
        // A snapshot read from bytes was checked so; one built in Rust is checked here.
        check_values(self.model, &snapshot.values)?;
        let sim = match &snapshot.physics {
            Some(p) => Some(Simulation::restore(
                self.model,
                &snapshot.values,
                p.plant,
                p.bodies,
                &p.bound,
                p.bounds_behind,
                p.events,
            )?),
            None => None,
        };
        self.life = match sim {
            Some(sim) => Lifecycle::Running {
                phase: snapshot.phase,
                sim,
            },
            None => Lifecycle::Setup {
                phase: snapshot.phase,
                preview: None,
            },
        };
        self.time = snapshot.time;
        self.time_marks = snapshot.time_marks;
        self.experiment = snapshot.experiment;
        self.values = snapshot.values;
        self.input_slopes = snapshot.input_slopes;
        Ok(Status::Ok)
    }
}

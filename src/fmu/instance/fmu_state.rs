//! FMU states: the snapshot of an instance and its restoration (checked before anything
//! changes).

use super::lifecycle::Lifecycle;
use super::Instance;
use crate::fmu::error::{FmuError, Status};
use crate::fmu::geared::Geared;
use crate::fmu::simulation::EventTerms;
use crate::fmu::simulation::Simulation;
use crate::fmu::snapshot::{check_values, PhysicsSnapshot, Snapshot, NO_PLANT};
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
            physics: match (self.life.sim(), self.life.geared()) {
                (Some(sim), _) => Some(PhysicsSnapshot {
                    plant: sim.state,
                    bodies: sim.friction.as_ref().map_or([BodyMode::Forward; 2], |f| f.bodies()),
                    bound: sim.clock.bound.words(),
                    bounds_behind: sim.clock.behind,
                    events: sim.events,
                    geared: Vec::new(),
                }),
                (None, Some(g)) => Some(PhysicsSnapshot {
                    plant: NO_PLANT,
                    bodies: [BodyMode::Forward; 2],
                    bound: crate::fmu::bounds::two_stage::words_of(&g.clock.bound),
                    bounds_behind: g.clock.behind,
                    events: EventTerms::UNTRACKED,
                    geared: g.words(),
                }),
                (None, None) => None,
            },
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
        if self.model.is_geared() {
            let geared = match &snapshot.physics {
                Some(p) => Some(Box::new(Geared::restore(
                    self.model,
                    &snapshot.values,
                    &p.geared,
                    &p.bound,
                    p.bounds_behind,
                )?)),
                None => None,
            };
            self.life = match geared {
                Some(sim) => Lifecycle::Geared {
                    phase: snapshot.phase,
                    sim,
                },
                None => Lifecycle::Setup {
                    phase: snapshot.phase,
                    preview: None,
                    geared: None,
                },
            };
            self.restore_clock_and_values(snapshot);
            return Ok(Status::Ok);
        }
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
                geared: None,
            },
        };
        self.restore_clock_and_values(snapshot);
        Ok(Status::Ok)
    }

    /// The time, its marks, the experiment, the values and the input slopes of `snapshot`.
    fn restore_clock_and_values(&mut self, snapshot: &Snapshot) {
        self.time = snapshot.time;
        self.time_marks = snapshot.time_marks;
        self.experiment = snapshot.experiment;
        self.values = snapshot.values;
        self.input_slopes = snapshot.input_slopes;
    }
}

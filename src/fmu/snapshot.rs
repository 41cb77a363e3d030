//! FMU states (fmi2GetFMUstate) and their pointer-free serialized form.
//!
//! Byte format, version 5, all numbers little-endian, f64 as IEEE-754 bits:
//!
//! | offset | size | field |
//! |---|---|---|
//! | 0 | 8 | magic `BKLSHFMU` |
//! | 8 | 2 | format version (4) |
//! | 10 | 2 | length n of the guid |
//! | 12 | n | guid of the model description (ASCII) |
//! | 12+n | 1 | state-machine phase (0 Instantiated … 5 Error, 6 EventMode, 7 ContinuousTimeMode) |
//! | +1 | 1 | flags: bit 0 stop time defined, bit 1 tolerance defined, bit 2 physics present, bit 3 Model Exchange instance, bit 4 FMI 3.0 instance |
//! | +2 | 2 | number m of stored values (one per symbol of all models) |
//! | +4 | 8·4 | time, startTime, stopTime, tolerance |
//! | | 8·m | values by symbol: inputs, parameters (an Integer's as its f64), start values |
//! | | 8·4 | the input lines' slopes dτ_m/dt, dτ_L/dt, dv_in/dt, dT_in/dt |
//! | | 8·8 + 1 | θ_m, ω_m, θ_L, ω_L, T, u, u', V (∫|u'| off ordinary contact, with a damper), mode (signed byte: −1/0/+1 negative flank, free, positive flank; ±2 slack, ±3 capped) |
//! | | 2 | the friction mode of the motor and of the load (signed bytes: +1 sliding forward, 0 stuck, −1 sliding backward; +1 for a body without friction; docs/model.md §12) |
//! | | 8·b | bounds: elapsed, response[n], integral[n], l1, peak, variation of each loop bound; b = 42 for the drive trains (the speed bound, then the motor's and the load's friction terms, zeros without friction; n = 5), 36 for the web line (speed and tension, n = 7) |
//! | | 8 | how far the bounds lag behind the plant [s] (Co-Simulation: the steps since they were last read) |
//! | | 8·5 | the damped bound's terms gathered at events (Model Exchange): tracked (0/1), the phase's mode code, u at its start, Σ|Δu| over slack and capped phases, phases in the gap |
//! | | 8·3 | how far back the time may be set (Model Exchange): the times of the second-last and the last completed integrator step, and of the last event |
//! | end−8 | 8 | FNV-1a-64 checksum of all bytes before it |
//!
//! Loading checks, in order: length, magic, version, guid (a state of the other model is
//! refused), exact length, checksum, then every field (phase, finiteness, parameter ranges:
//! `contact_law` 1 or 2).

use super::adapter::{input_name, InputSlopes, Values, MAX_INPUTS};
use super::bounds::Bounds;
use super::error::FmuError;
use super::instance::{Experiment, TimeMarks};
use super::simulation::EventTerms;
use super::state_machine::{Flavour, Interface, Phase, Standard};
use super::variables::{ModelInfo, Symbol};
use crate::physics::chain::BodyMode;
use crate::physics::{ContactMode, PlantState};

pub const MAGIC: &[u8; 8] = b"BKLSHFMU";
pub const FORMAT_VERSION: u16 = 5;

/// The plant and bound state of an initialized instance.
#[derive(Clone, Debug, PartialEq)]
pub struct PhysicsSnapshot {
    /// A single gap's plant state ([`NO_PLANT`] on a gearbox).
    pub plant: PlantState,
    /// The friction mode of the motor and of the load (`Forward` without friction).
    pub bodies: [BodyMode; 2],
    /// [`Bounds::words`].
    pub bound: Vec<f64>,
    /// How far the bounds lag behind the plant ([`super::simulation::Simulation::bounds_behind`]).
    pub bounds_behind: f64,
    /// The damped bound's terms gathered at events (Model Exchange).
    pub events: EventTerms,
    /// A gearbox's chain state ([`crate::fmu::geared::Geared::words`]); empty on a single gap.
    pub geared: Vec<f64>,
}

/// The plant field of a gearbox's snapshot, which has none.
pub const NO_PLANT: PlantState = PlantState {
    theta_m: 0.0,
    omega_m: 0.0,
    theta_l: 0.0,
    omega_l: 0.0,
    tension: 0.0,
    u: 0.0,
    du: 0.0,
    variation: 0.0,
    mode: ContactMode::Free,
};

/// Everything needed to continue an instance bit-identically; derived objects (plant
/// matrices, exponentials) are rebuilt from the values on restore.
#[derive(Clone, Debug, PartialEq)]
pub struct Snapshot {
    /// The model it was taken of (its guid is written into the bytes).
    pub model: &'static ModelInfo,
    pub flavour: Flavour,
    pub phase: Phase,
    pub time: f64,
    pub time_marks: TimeMarks,
    pub experiment: Experiment,
    pub values: Values,
    pub input_slopes: InputSlopes,
    pub physics: Option<PhysicsSnapshot>,
}

const FLAG_STOP: u8 = 1;
const FLAG_TOLERANCE: u8 = 2;
const FLAG_PHYSICS: u8 = 4;
const FLAG_MODEL_EXCHANGE: u8 = 8;
const FLAG_FMI3: u8 = 16;

/// Bytes after the guid of a state of `model`: phase, flags, count, 4 times, values, slopes,
/// plant, bounds, their lag, the time marks, checksum.
fn body_len(model: &ModelInfo) -> usize {
    let (plant, bounds) = plant_and_bound_words(model);
    1 + 1 + 2 + 8 * 4 + 8 * Symbol::COUNT + 8 * MAX_INPUTS + plant + 8 * bounds + 8 + 8 * 5 + 8 * 3 + 8
}

/// The bytes of `model`'s plant state and the words of its bounds: a single gap's z, T, u, u',
/// V, its mode and the bodies' friction modes, and [`Bounds::words`]; a gearbox's chain words
/// ([`crate::fmu::geared::Geared::WORDS`]: z, each stage's u, u', V and mode code, each body's
/// friction mode) and its bound's ([`super::bounds::two_stage::WORDS`]).
fn plant_and_bound_words(model: &ModelInfo) -> (usize, usize) {
    match model.is_geared() {
        true => (8 * crate::fmu::geared::Geared::WORDS, super::bounds::two_stage::WORDS),
        false => ((8 * 8 + 1) + 2, Bounds::word_count(model.web)),
    }
}

fn fnv1a_64(bytes: &[u8]) -> u64 {
    let mut hash: u64 = 0xcbf29ce484222325;
    for b in bytes {
        hash ^= *b as u64;
        hash = hash.wrapping_mul(0x100000001b3);
    }
    hash
}

impl Snapshot {
    pub fn serialized_len(&self) -> usize {
        8 + 2 + 2 + self.model.guid.len() + body_len(self.model)
    }

    pub fn to_bytes(&self) -> Vec<u8> {
        let mut b = Vec::with_capacity(self.serialized_len());
        b.extend_from_slice(MAGIC);
        b.extend_from_slice(&FORMAT_VERSION.to_le_bytes());
        b.extend_from_slice(&(self.model.guid.len() as u16).to_le_bytes());
        b.extend_from_slice(self.model.guid.as_bytes());
        b.push(self.phase.code());
        let mut flags = 0;
        if self.experiment.stop_time.is_some() {
            flags |= FLAG_STOP;
        }
        if self.experiment.tolerance.is_some() {
            flags |= FLAG_TOLERANCE;
        }
        if self.physics.is_some() {
            flags |= FLAG_PHYSICS;
        }
        if self.flavour.interface == Interface::ModelExchange {
            flags |= FLAG_MODEL_EXCHANGE;
        }
        if self.flavour.standard == Standard::Fmi3 {
            flags |= FLAG_FMI3;
        }
        b.push(flags);
        b.extend_from_slice(&(Symbol::COUNT as u16).to_le_bytes());
        let mut put = |x: f64| b.extend_from_slice(&x.to_le_bytes());
        put(self.time);
        put(self.experiment.start_time);
        put(self.experiment.stop_time.unwrap_or(0.0));
        put(self.experiment.tolerance.unwrap_or(0.0));
        self.values.iter().for_each(|x| put(*x));
        self.input_slopes.iter().for_each(|x| put(*x));
        if self.model.is_geared() {
            let words = self
                .physics
                .as_ref()
                .map_or(vec![0.0; crate::fmu::geared::Geared::WORDS], |p| p.geared.clone());
            words.iter().for_each(|x| put(*x));
        }
        let plant = self.physics.as_ref().map(|p| p.plant);
        let z = plant
            .map(|s| {
                [
                    s.theta_m,
                    s.omega_m,
                    s.theta_l,
                    s.omega_l,
                    s.tension,
                    s.u,
                    s.du,
                    s.variation,
                ]
            })
            .unwrap_or([0.0; 8]);
        if !self.model.is_geared() {
            z.iter().for_each(|x| put(*x));
            b.push(plant.map(|s| s.mode.code() as i8).unwrap_or(0) as u8);
            let bodies = self.physics.as_ref().map_or([BodyMode::Forward; 2], |p| p.bodies);
            for body in bodies {
                b.push(body.sliding() as i8 as u8);
            }
        }
        let no_bounds = vec![0.0; plant_and_bound_words(self.model).1];
        let bound = self.physics.as_ref().map_or(&no_bounds, |p| &p.bound);
        bound.iter().for_each(|x| b.extend_from_slice(&x.to_le_bytes()));
        let behind = self.physics.as_ref().map_or(0.0, |p| p.bounds_behind);
        b.extend_from_slice(&behind.to_le_bytes());
        let events = self.physics.as_ref().map_or(EventTerms::UNTRACKED, |p| p.events);
        for x in events.words() {
            b.extend_from_slice(&x.to_le_bytes());
        }
        let marks = self.time_marks;
        for x in [marks.completed_steps[0], marks.completed_steps[1], marks.event] {
            b.extend_from_slice(&x.to_le_bytes());
        }
        let checksum = fnv1a_64(&b);
        b.extend_from_slice(&checksum.to_le_bytes());
        debug_assert_eq!(b.len(), self.serialized_len());
        b
    }

    /// Parses and validates bytes written by [`Snapshot::to_bytes`] for `model`: the frame
    /// (length, magic, version, guid, checksum) first, then every field in order.
    pub fn from_bytes(model: &'static ModelInfo, bytes: &[u8]) -> Result<Snapshot, FmuError> {
        if model.is_controller() {
            return Err(FmuError::NotProvided(super::instance::NO_FMU_STATE));
        }
        let (payload, at) = checked_payload(model, bytes)?;
        let mut r = Reader { bytes: payload, at };
        let (phase, flags, flavour) = r.state_machine()?;
        let (time, experiment) = r.times(flags)?;
        let (values, input_slopes) = r.values(model)?;
        let (plant, bodies, geared) = match model.is_geared() {
            true => {
                let mut words = vec![0.0; crate::fmu::geared::Geared::WORDS];
                for (x, name) in words.iter_mut().zip(crate::fmu::geared::Geared::WORD_NAMES) {
                    *x = r.finite(name)?;
                }
                crate::fmu::geared::Geared::check_words(&words)?;
                (NO_PLANT, [BodyMode::Forward; 2], words)
            }
            false => (
                r.plant()?,
                [r.body_mode("the motor")?, r.body_mode("the load")?],
                Vec::new(),
            ),
        };
        let mut bound = vec![0.0; plant_and_bound_words(model).1];
        for x in bound.iter_mut() {
            *x = r.finite("a bound's state")?;
        }
        let bounds_behind = r.finite("the bounds' lag")?;
        if bounds_behind < 0.0 {
            return refuse(format!("the bounds' lag {bounds_behind} s is negative"));
        }
        let mut words = [0.0; 5];
        for x in words.iter_mut() {
            *x = r.finite("the bound's terms of the trajectory")?;
        }
        let events = EventTerms::from_words(&words).map_err(FmuError::StateRefused)?;
        let time_marks = r.time_marks(experiment.start_time)?;
        debug_assert_eq!(r.at, payload.len());

        let has_physics = flags & FLAG_PHYSICS != 0;
        let consistent = match phase {
            Phase::Instantiated | Phase::InitializationMode => !has_physics,
            Phase::StepComplete
            | Phase::StepFailed
            | Phase::EventMode
            | Phase::ContinuousTimeMode
            | Phase::Terminated => has_physics,
            Phase::Error => true,
        };
        if !consistent {
            return refuse(format!("phase {phase} does not match the presence of a plant state"));
        }
        let physics = has_physics.then_some(PhysicsSnapshot {
            plant,
            bodies,
            bound,
            bounds_behind,
            events,
            geared,
        });
        Ok(Snapshot {
            model,
            flavour,
            phase,
            time,
            time_marks,
            experiment,
            values,
            input_slopes,
            physics,
        })
    }
}

fn refuse<T>(why: String) -> Result<T, FmuError> {
    Err(FmuError::StateRefused(why))
}

/// Every settable value of `model` (those with a start value) in its range, as a set would have
/// admitted it (`contact_law` 1 or 2): what a state brings must be what the instance could hold.
pub(crate) fn check_values(model: &ModelInfo, values: &Values) -> Result<(), FmuError> {
    for v in model.variables {
        let x = values[v.symbol.index()];
        if v.start.is_some() && !v.range.admits(x) {
            return refuse(format!("{} = {x} is not {}", v.name, v.range.describe()));
        }
    }
    Ok(())
}

/// The bytes before the checksum, once length, magic, version, guid and checksum are right for
/// `model`, and where the fields start.
fn checked_payload<'a>(model: &ModelInfo, bytes: &'a [u8]) -> Result<(&'a [u8], usize), FmuError> {
    if bytes.is_empty() {
        return refuse("the serialized state is empty (0 bytes)".into());
    }
    if bytes.len() < 12 {
        return refuse(format!(
            "{} bytes are too few for a serialized FMU state (header is 12)",
            bytes.len()
        ));
    }
    if &bytes[0..8] != MAGIC {
        return refuse("not a serialized state of this FMU (wrong magic bytes)".into());
    }
    let version = u16::from_le_bytes([bytes[8], bytes[9]]);
    if version != FORMAT_VERSION {
        return refuse(format!(
            "format version {version}; this binary reads version {FORMAT_VERSION}"
        ));
    }
    let guid_len = u16::from_le_bytes([bytes[10], bytes[11]]) as usize;
    let expected = 12 + guid_len + body_len(model);
    if bytes.len() < 12 + guid_len {
        return refuse(format!(
            "truncated: {} bytes, the guid alone needs {}",
            bytes.len(),
            12 + guid_len
        ));
    }
    let guid = &bytes[12..12 + guid_len];
    if guid != model.guid.as_bytes() {
        return refuse(format!(
            "it was saved by the model with guid {:?}; this instance is {} with guid {}",
            String::from_utf8_lossy(guid),
            model.identifier,
            model.guid
        ));
    }
    if bytes.len() != expected {
        return refuse(format!(
            "{} bytes, a version-{FORMAT_VERSION} state of {} has {expected}",
            bytes.len(),
            model.identifier
        ));
    }
    let (payload, tail) = bytes.split_at(expected - 8);
    let mut stored = [0u8; 8];
    stored.copy_from_slice(tail);
    if u64::from_le_bytes(stored) != fnv1a_64(payload) {
        return refuse("checksum mismatch: the bytes were altered or corrupted".into());
    }
    Ok((payload, 12 + guid_len))
}

/// Reads fields from a buffer whose length was checked beforehand.
struct Reader<'a> {
    bytes: &'a [u8],
    at: usize,
}

impl Reader<'_> {
    fn u8(&mut self) -> u8 {
        self.at += 1;
        self.bytes[self.at - 1]
    }

    fn f64(&mut self) -> f64 {
        let mut word = [0u8; 8];
        word.copy_from_slice(&self.bytes[self.at..self.at + 8]);
        let x = f64::from_le_bytes(word);
        self.at += 8;
        x
    }

    /// Phase, flags and the flavour they say, checked against each other.
    fn state_machine(&mut self) -> Result<(Phase, u8, Flavour), FmuError> {
        let phase_code = self.u8();
        let phase = Phase::from_code(phase_code)
            .ok_or_else(|| FmuError::StateRefused(format!("unknown phase code {phase_code}")))?;
        let flags = self.u8();
        if flags & !(FLAG_STOP | FLAG_TOLERANCE | FLAG_PHYSICS | FLAG_MODEL_EXCHANGE | FLAG_FMI3) != 0 {
            return refuse(format!("unknown flag bits {flags:#04x}"));
        }
        let flavour = Flavour {
            standard: if flags & FLAG_FMI3 != 0 {
                Standard::Fmi3
            } else {
                Standard::Fmi2
            },
            interface: if flags & FLAG_MODEL_EXCHANGE != 0 {
                Interface::ModelExchange
            } else {
                Interface::CoSimulation
            },
        };
        if !phase.belongs_to(flavour) {
            return refuse(format!(
                "phase {phase} is not a state of an {} instance",
                flavour.name()
            ));
        }
        let count = u16::from_le_bytes([self.u8(), self.u8()]) as usize;
        if count != Symbol::COUNT {
            return refuse(format!("{count} stored values, expected {}", Symbol::COUNT));
        }
        Ok((phase, flags, flavour))
    }

    /// The instance's time and its experiment.
    fn times(&mut self, flags: u8) -> Result<(f64, Experiment), FmuError> {
        let time = self.finite("time")?;
        let start_time = self.finite("startTime")?;
        let stop_time = self.finite("stopTime")?;
        let tolerance = self.f64();
        let experiment = Experiment {
            start_time,
            stop_time: (flags & FLAG_STOP != 0).then_some(stop_time),
            tolerance: (flags & FLAG_TOLERANCE != 0).then_some(tolerance),
        };
        Ok((time, experiment))
    }

    /// The stored values, each settable one in its range, and the input lines' slopes.
    fn values(&mut self, model: &ModelInfo) -> Result<(Values, InputSlopes), FmuError> {
        let mut values = [0.0; Symbol::COUNT];
        for slot in values.iter_mut() {
            *slot = self.finite("a variable value")?;
        }
        check_values(model, &values)?;
        let mut input_slopes = [0.0; MAX_INPUTS];
        for (slot, slope) in input_slopes.iter_mut().enumerate() {
            *slope = self.finite(&format!("d{}/dt", input_name(slot)))?;
        }
        Ok((values, input_slopes))
    }

    /// The plant state: z, T, u, u' and the contact mode.
    fn plant(&mut self) -> Result<PlantState, FmuError> {
        let mut z = [0.0; 8];
        for (x, name) in z
            .iter_mut()
            .zip(["theta_m", "omega_m", "theta_L", "omega_L", "T", "u", "du/dt", "V"])
        {
            *x = self.finite(name)?;
        }
        if z[7] < 0.0 {
            return refuse(format!("V = {} must be >= 0", z[7]));
        }
        let mode_code = self.u8() as i8 as i32;
        let mode = ContactMode::from_code(mode_code)
            .ok_or_else(|| FmuError::StateRefused(format!("unknown contact mode {mode_code}")))?;
        Ok(PlantState {
            theta_m: z[0],
            omega_m: z[1],
            theta_l: z[2],
            omega_l: z[3],
            tension: z[4],
            u: z[5],
            du: z[6],
            variation: z[7],
            mode,
        })
    }

    /// A body's friction mode, by its `sliding` code.
    fn body_mode(&mut self, body: &str) -> Result<BodyMode, FmuError> {
        let code = self.u8() as i8 as i32;
        BodyMode::ALL
            .into_iter()
            .find(|m| m.sliding() == code)
            .ok_or_else(|| FmuError::StateRefused(format!("unknown friction mode {code} of {body}")))
    }

    /// How far back the time may be set, none of it before the start time.
    fn time_marks(&mut self, start_time: f64) -> Result<TimeMarks, FmuError> {
        let mut marks = [0.0; 3];
        for (x, name) in marks.iter_mut().zip([
            "the second-last completed integrator step",
            "the last completed integrator step",
            "the last event",
        ]) {
            *x = self.finite(&format!("the time of {name}"))?;
            if *x < start_time {
                return refuse(format!(
                    "the time of {name}, {x}, is before the start time {start_time}"
                ));
            }
        }
        Ok(TimeMarks {
            completed_steps: [marks[0], marks[1]],
            event: marks[2],
        })
    }

    fn finite(&mut self, what: &str) -> Result<f64, FmuError> {
        let x = self.f64();
        if x.is_finite() {
            Ok(x)
        } else {
            Err(FmuError::StateRefused(format!("{what} = {x} is not finite")))
        }
    }
}

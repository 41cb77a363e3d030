//! A driver that calls the C ABI in random order with random arguments, valid and invalid, on
//! Co-Simulation and Model Exchange instances (half each), and checks after every call what
//! must always hold:
//! - the status is one of fmi2OK, fmi2Warning, fmi2Discard, fmi2Error (never Fatal/Pending);
//! - fmi2Discard and fmi2Error from a live instance come with a logged reason in logErrors,
//!   fmi2Warning with one in logWarnings;
//! - values read with fmi2OK are never NaN, and never infinite except bound_sup and bound_T_sup
//!   (`admissible`, docs/model.md §4, §8): variables, continuous states, derivatives, event
//!   indicators (u − g ≤ u + g), nominals (positive), directional derivatives; after every
//!   successful fmi2DoStep and fmi2ExitInitializationMode every variable is read and checked;
//!   after a successful fmi2SetContinuousStates the states read back bit for bit;
//!   fmi2NewDiscreteStates and fmi2CompletedIntegratorStep ask for nothing (no discrete states,
//!   no time events).
//!
//! Instances are of every model the library serves, the plants then the controller (unless
//! [`Driver::models`] says fewer), each with its own number of continuous states in Model
//! Exchange ([`nx`]); a controller's are Co-Simulation instances only. Model Exchange calls get
//! random finite, extreme and non-finite arguments and random vector lengths; mostly they
//! follow an explicit Euler integration, so that sequences reach Continuous-Time Mode with
//! moving states; their fmi2SetTime goes back no further than the standard allows (the previous
//! completed integrator step, the last event). Times are kept within `FAR_TIME` of the start time
//! unless [`Driver::far_times`] is set: fmi2SetTime accepts any finite time ahead, and reading the bounds
//! after a far one takes work proportional to the time (see
//! `model_exchange_far_times_are_refused_or_answered_promptly` in `crate::robustness::arguments`).
//!
//! A panic that unwinds out of an `extern "C"` function aborts the process, so "no panic
//! escapes" and "no crash" are checked by the process surviving; panics caught inside are
//! counted by the caller's panic hook.
//!
//! The randomness comes from a [`Source`]: the PRNG [`Prng`] in `cargo test`.

use super::*;
use backlash_fmu::fmu::variables::Causality;

pub trait Source {
    /// The next random word, or None when the input is exhausted.
    fn word(&mut self) -> Option<u64>;
}

/// xorshift64*: small, deterministic, good enough to pick calls and arguments.
pub struct Prng(pub u64);

impl Source for Prng {
    fn word(&mut self) -> Option<u64> {
        self.0 ^= self.0 >> 12;
        self.0 ^= self.0 << 25;
        self.0 ^= self.0 >> 27;
        Some(self.0.wrapping_mul(0x2545F4914F6CDD1D))
    }
}

const INTERESTING: [f64; 20] = [
    0.0,
    -0.0,
    1.0,
    -1.0,
    0.5,
    2.28,
    200.0,
    1e-3,
    1e3,
    1e-300,
    1e300,
    -1e300,
    f64::MAX,
    f64::MIN_POSITIVE,
    5e-324,
    f64::NAN,
    f64::INFINITY,
    f64::NEG_INFINITY,
    0.01,
    -5.0,
];

/// How far from the start time Model Exchange times go unless [`Driver::far_times`]: far enough
/// for the bounds to settle, near enough that bringing them to a time set backwards stays cheap.
pub const FAR_TIME: f64 = 1e3;

/// Ops (the numbers `one` dispatches on) added for Model Exchange.
const ENTER_EVENT_MODE: u64 = 30;
const NEW_DISCRETE_STATES: u64 = 31;
const ENTER_CONTINUOUS_TIME_MODE: u64 = 32;
const COMPLETED_INTEGRATOR_STEP: u64 = 33;
const SET_TIME: u64 = 34;
const SET_CONTINUOUS_STATES: u64 = 35;
const GET_CONTINUOUS_STATES: u64 = 36;
const GET_DERIVATIVES: u64 = 37;
const GET_EVENT_INDICATORS: u64 = 38;
const GET_NOMINALS: u64 = 39;
const GET_DIRECTIONAL_DERIVATIVE: u64 = 40;
const OPS: u64 = 41;

/// The knowns and (some) unknowns of the exact Jacobian of a drive train (docs/model.md §6).
const JACOBIAN_KNOWNS: [&str; 6] = ["theta_m", "omega_m", "theta_L", "omega_L", "tau_m", "tau_L"];
const JACOBIAN_UNKNOWNS: [&str; 8] = [
    "der(theta_m)",
    "der(omega_m)",
    "der(theta_L)",
    "der(omega_L)",
    "theta_L",
    "psi",
    "bound",
    "bound_paper",
];
/// Those a web span adds (BacklashWeb, docs/model.md §8): its state T and inputs v_in, T_in;
/// der(T), T and bound_T.
const WEB_JACOBIAN_KNOWNS: [&str; 3] = ["T", "v_in", "T_in"];
const WEB_JACOBIAN_UNKNOWNS: [&str; 3] = ["der(T)", "T", "bound_T"];

/// Whether a logged reason is a read's refusal for its bounds: "the bounds at t = …" (a
/// single-gap plant's two, or bounds out of reach), "the bound at t = …" (the gearbox's one).
fn names_the_bounds(message: &str) -> bool {
    message.contains("the bounds at") || message.contains("the bound at")
}

/// Whether some body with bearing friction (`tau_c_X` > 0) has speed `omega_X` exactly 0.
fn a_body_with_friction_rests(f: &Fmu) -> bool {
    let bodies = f.model.variables.iter().filter_map(|v| v.name.strip_prefix("tau_c_"));
    bodies.into_iter().any(|b| {
        let (tau_c, omega) = (f.get_real(&format!("tau_c_{b}")), f.get_real(&format!("omega_{b}")));
        tau_c.0 == fmi2Status::fmi2OK && omega.0 == fmi2Status::fmi2OK && tau_c.1 > 0.0 && omega.1 == 0.0
    })
}

/// The knowns and unknowns of `model` the driver mostly picks from.
fn jacobian_names(model: &backlash_fmu::fmu::ModelInfo) -> (Vec<&'static str>, Vec<&'static str>) {
    let (mut knowns, mut unknowns) = (JACOBIAN_KNOWNS.to_vec(), JACOBIAN_UNKNOWNS.to_vec());
    if model.web {
        knowns.extend(WEB_JACOBIAN_KNOWNS);
        unknowns.extend(WEB_JACOBIAN_UNKNOWNS);
    }
    (knowns, unknowns)
}

/// The ops a Model Exchange instance gets at random (apart from any op, now and then): those of
/// both interfaces and its own, twice as often.
const ME_RANDOM_OPS: [u64; 43] = [
    0, 1, 2, 3, 4, 5, 6, 7, 8, 9, 10, 11, 20, 21, 22, 23, 24, 25, 26, 27, 29, 30, 31, 32, 33, 34, 35, 36, 37, 38, 39,
    40, 30, 31, 32, 33, 34, 35, 36, 37, 38, 39, 40,
];

impl Slot {
    /// At the start time, before any step or event: back to the start time at most.
    fn at_start(&mut self) {
        (self.earliest, self.last_step) = (self.start, self.start);
    }
}

struct Slot {
    f: Fmu,
    /// Whether logErrors is on: fmi2SetDebugLogging(fmi2False) with no categories switches
    /// every category off, errors included; then a refusal has only its status.
    errors_logged: bool,
    /// Our belief of the instance's time, for communication points that match it.
    time: f64,
    /// Our belief of its state (0 Instantiated, 1 Initialization, 2 StepComplete or Event Mode,
    /// 3 other, 4 Continuous-Time Mode), used to pick the call that moves it on more often than
    /// chance would.
    phase: u8,
    /// Our belief of its start time (Model Exchange: times are picked around it).
    start: f64,
    /// Our belief of how far back fmi2SetTime may go (FMI 2.0.4 §3.2.2: not over the previous
    /// completed integrator step or the last event), and of the last completed step's time:
    /// careful calls go back no further. After an FMU state is loaded, its time (no further
    /// back than the state allows).
    earliest: f64,
    last_step: f64,
    /// The continuous states and derivatives last read or set (Model Exchange), from which
    /// the next states are stepped: [`nx`] of each.
    x: Vec<f64>,
    dx: Vec<f64>,
}

pub struct Driver<S: Source> {
    src: S,
    slots: Vec<Slot>,
    /// FMU state handles seen (live, freed or foreign) and the time and start time they were
    /// taken at.
    states: Vec<(fmi2FMUstate, f64, f64)>,
    blobs: Vec<Vec<u8>>,
    stale: Vec<fmi2Component>,
    pub calls: u64,
    pub ok_steps: u64,
    /// Of those, the steps of a controller.
    pub ok_controller_steps: u64,
    /// Whether parameters may take extreme finite magnitudes (1e±300, f64::MAX). Off by
    /// default: some such plants make the physics hang (see `crate::robustness::extremes`).
    pub extreme_parameters: bool,
    /// Whether Model Exchange times may lie any distance from the start time (off by default:
    /// see [`FAR_TIME`]).
    pub far_times: bool,
    /// Whether instances may be Model Exchange ones (half of them) and calls may cross
    /// interfaces. Off (and with `models` = 2), the driver makes exactly the Co-Simulation
    /// sequences it made before Model Exchange existed, so that seeds found then replay unchanged.
    pub model_exchange: bool,
    /// Whether the current call moves its instance along the lifecycle: its arguments are then
    /// mostly valid (the random calls get the wild ones), so that Model Exchange sequences stay
    /// in Continuous-Time Mode for a while.
    careful: bool,
    pub me_calls: u64,
    /// Successful fmi2SetContinuousStates calls.
    pub ok_state_sets: u64,
    /// How many of the served models ([`model_at`]), the first ones, instances are drawn from:
    /// all by default. Seeds
    /// found before BacklashWeb existed replay their sequences with 2.
    pub models: usize,
}

impl<S: Source> Driver<S> {
    pub fn new(src: S) -> Self {
        Driver {
            src,
            slots: Vec::new(),
            states: Vec::new(),
            blobs: Vec::new(),
            stale: Vec::new(),
            calls: 0,
            ok_steps: 0,
            ok_controller_steps: 0,
            extreme_parameters: false,
            far_times: false,
            model_exchange: true,
            careful: false,
            me_calls: 0,
            ok_state_sets: 0,
            models: served().count(),
        }
    }

    fn below(&mut self, n: u64) -> Option<u64> {
        Some(self.src.word()? % n.max(1))
    }

    fn chance(&mut self, percent: u64) -> Option<bool> {
        Some(self.below(100)? < percent)
    }

    fn real(&mut self) -> Option<f64> {
        Some(match self.below(4)? {
            0 | 1 => INTERESTING[self.below(INTERESTING.len() as u64)? as usize],
            2 => (self.below(2001)? as f64 - 1000.0) / 100.0,
            _ => f64::from_bits(self.src.word()?),
        })
    }

    fn step_size(&mut self) -> Option<f64> {
        Some(match self.below(10)? {
            0 => self.real()?,
            _ => 1e-4 * (1 + self.below(500)?) as f64,
        })
    }

    /// A time for fmi2SetTime or a start time: mostly a little after `now`, sometimes before it
    /// or before the start, sometimes anything (within `FAR_TIME` of the start unless
    /// `far_times`). Careful calls go back to `earliest` at most.
    fn time_near(&mut self, now: f64, start: f64, earliest: f64) -> Option<f64> {
        if self.careful {
            return Some(match self.below(20)? {
                0..=17 => now + 1e-4 * (1 + self.below(100)?) as f64,
                18 => (now - 1e-5 * (1 + self.below(100)?) as f64).max(earliest),
                _ => earliest,
            });
        }
        let t = match self.below(20)? {
            0..=11 => now + 1e-4 * (1 + self.below(500)?) as f64,
            12 | 13 => now - 1e-4 * (1 + self.below(500)?) as f64,
            14 => start,
            15 => now,
            16 => start + (self.below(1000)? as f64) * FAR_TIME / 1000.0,
            _ => self.real()?,
        };
        Some(if !self.far_times && t.is_finite() && (t - start).abs() > FAR_TIME {
            start + (t - start) % FAR_TIME
        } else {
            t
        })
    }

    /// Whether to pass a NULL pointer (or another wild argument): `percent` in random calls, 1 %
    /// in careful ones.
    fn wild(&mut self, percent: u64) -> Option<bool> {
        self.chance(if self.careful { 1 } else { percent })
    }

    /// A vector length: mostly `n`, sometimes anything up to 2n + 1.
    fn length(&mut self, n: usize) -> Option<usize> {
        Some(if !self.wild(15)? {
            n
        } else {
            self.below(2 * n as u64 + 2)? as usize
        })
    }

    /// A value reference: usually a variable of the model, sometimes none.
    fn vr(&mut self, model: &'static backlash_fmu::fmu::ModelInfo) -> Option<u32> {
        Some(match self.below(10)? {
            0 => self.src.word()? as u32,
            1 => self.below(40)? as u32,
            _ => model.variables[self.below(model.variables.len() as u64)? as usize].vr,
        })
    }

    /// Runs calls until the source is exhausted or `max_calls` are done; frees everything.
    pub fn run(&mut self, max_calls: u64) {
        while self.calls < max_calls {
            if self.one().is_none() {
                break;
            }
        }
        for s in self.slots.drain(..) {
            drop(s);
        }
    }

    fn one(&mut self) -> Option<()> {
        if self.slots.is_empty() || (self.slots.len() < 3 && self.chance(3)?) {
            return self.instantiate();
        }
        let i = self.below(self.slots.len() as u64)? as usize;
        // Half of the calls move the instance along the lifecycle (Reset from Error), so that
        // sequences reach stepping and FMU states; the other half are anything.
        let me = self.slots[i].f.model_exchange;
        // Model Exchange needs more calls in a row to reach Continuous-Time Mode and stay.
        self.careful = self.chance(if me { 75 } else { 50 })?;
        let op = if self.careful {
            match (self.slots[i].phase, me) {
                (0, _) => 1,
                (1, _) => [2, 5][self.below(2)? as usize],
                (2, false) => [14, 14, 14, 20, 21, 24, 26, 8][self.below(8)? as usize],
                // Not fmi2SetTime: FMI 2.0.4 §3.2.3, condition 8 (pure discrete-time FMUs only).
                (2, true) => [
                    NEW_DISCRETE_STATES,
                    ENTER_CONTINUOUS_TIME_MODE,
                    ENTER_CONTINUOUS_TIME_MODE,
                    NEW_DISCRETE_STATES,
                    5,
                    8,
                    20,
                    GET_DIRECTIONAL_DERIVATIVE,
                ][self.below(8)? as usize],
                (4, _) => [
                    SET_TIME,
                    SET_TIME,
                    SET_CONTINUOUS_STATES,
                    SET_CONTINUOUS_STATES,
                    SET_CONTINUOUS_STATES,
                    GET_DERIVATIVES,
                    GET_DERIVATIVES,
                    GET_CONTINUOUS_STATES,
                    COMPLETED_INTEGRATOR_STEP,
                    GET_EVENT_INDICATORS,
                    ENTER_EVENT_MODE,
                    GET_DIRECTIONAL_DERIVATIVE,
                    GET_NOMINALS,
                    5,
                    8,
                    20,
                    24,
                ][self.below(17)? as usize],
                _ => 4,
            }
        } else if self.model_exchange && self.chance(5)? {
            // Any call, also those of the other interface.
            self.below(OPS)?
        } else if me {
            ME_RANDOM_OPS[self.below(ME_RANDOM_OPS.len() as u64)? as usize]
        } else {
            self.below(30)?
        };
        self.calls += 1;
        if op >= ENTER_EVENT_MODE {
            self.me_calls += 1;
        }
        let model = self.slots[i].f.model;
        let c = self.slots[i].f.c;
        let before = self.slots[i].f.log_len();
        // Sometimes the call goes to a stale or NULL handle instead.
        if self.chance(2)? {
            let last = self.stale.last().copied();
            let bad = match last {
                Some(s) if self.chance(50)? => s,
                _ => null_mut(),
            };
            let s = fmi2DoStep(bad, 0.0, 1e-3, 1);
            assert_eq!(s, fmi2Status::fmi2Error, "a call on {bad:p} was not refused");
            return Some(());
        }
        let mut check_all = false;
        // Model Exchange: whether to read every variable after the call, accepting a refusal
        // with a reason (states or times may make a quantity overflow; the read says so).
        let mut read_all = false;
        // SAFETY (whole match): every pointer passed is NULL with a length the FMU must refuse
        // or check, or points to a live local of at least the announced length.
        let status = unsafe {
            match op {
                0 => {
                    let start = match (self.chance(80)?, me) {
                        (true, _) => 0.0,
                        (false, true) => self.time_near(0.0, 0.0, 0.0)?,
                        (false, false) => self.real()?,
                    };
                    let stop = self.real()?;
                    let s = fmi2SetupExperiment(
                        c,
                        self.below(2)? as i32,
                        self.real()?,
                        start,
                        self.below(2)? as i32,
                        stop,
                    );
                    if s == fmi2Status::fmi2OK {
                        self.slots[i].time = start;
                        self.slots[i].start = start;
                        self.slots[i].at_start();
                    }
                    s
                }
                1 => {
                    let s = fmi2EnterInitializationMode(c);
                    // (Not in the Co-Simulation-only driver, whose sequences must not change.)
                    if s == fmi2Status::fmi2OK && self.model_exchange {
                        self.slots[i].time = self.slots[i].start;
                        self.slots[i].at_start();
                    }
                    s
                }
                2 => {
                    let s = fmi2ExitInitializationMode(c);
                    check_all = matches!(s, fmi2Status::fmi2OK | fmi2Status::fmi2Warning);
                    if check_all {
                        self.slots[i].at_start();
                    }
                    s
                }
                3 => fmi2Terminate(c),
                4 => {
                    let s = fmi2Reset(c);
                    if s == fmi2Status::fmi2OK {
                        self.slots[i].time = 0.0;
                        self.slots[i].start = 0.0;
                        self.slots[i].at_start();
                    }
                    s
                }
                5..=7 => {
                    let n = self.below(4)? as usize;
                    let mut vrs = Vec::new();
                    let mut values = Vec::new();
                    for _ in 0..n {
                        vrs.push(self.vr(model)?);
                        // Mostly the variable's start value nudged, so that many sets succeed.
                        let start = model.by_vr(*vrs.last().unwrap()).and_then(|v| v.start).unwrap_or(1.0);
                        let parameter = model
                            .by_vr(*vrs.last().unwrap())
                            .is_some_and(|v| v.causality == Causality::Parameter);
                        let value = if self.chance(60)? {
                            start * (1.0 + 0.1 * self.below(5)? as f64)
                        } else if parameter && !self.extreme_parameters {
                            [0.0, -1.0, 1e-3, 1e3, f64::NAN, f64::INFINITY, -0.0][self.below(7)? as usize]
                        } else {
                            self.real()?
                        };
                        values.push(value);
                    }
                    let pass_null = n > 0 && self.chance(5)?;
                    fmi2SetReal(c, vrs.as_ptr(), n, if pass_null { null() } else { values.as_ptr() })
                }
                8 | 9 => {
                    let n = self.below(6)? as usize;
                    let mut vrs = Vec::new();
                    for _ in 0..n {
                        vrs.push(self.vr(model)?);
                    }
                    let mut out = vec![f64::NAN; n];
                    let s = fmi2GetReal(c, vrs.as_ptr(), n, out.as_mut_ptr());
                    if s == fmi2Status::fmi2OK {
                        for (vr, x) in vrs.iter().zip(&out) {
                            let name = model.by_vr(*vr).unwrap().name;
                            assert!(admissible(name, *x), "fmi2GetReal OK but {name} = {x}");
                        }
                    }
                    s
                }
                10 => {
                    let vr = [self.vr(model)?];
                    let mut out = [i32::MIN];
                    let s = fmi2GetInteger(c, vr.as_ptr(), 1, out.as_mut_ptr());
                    if s == fmi2Status::fmi2OK {
                        // Within the variable's range: contact's -1..=1, contact_law's and
                        // reference's kinds.
                        let v = model.by_vr(vr[0]).unwrap();
                        assert!(v.range.admits(f64::from(out[0])), "{} = {}", v.name, out[0]);
                    }
                    s
                }
                11 => {
                    let vr = [self.vr(model)?];
                    match self.below(6)? {
                        0 => fmi2SetInteger(c, vr.as_ptr(), 1, [1].as_ptr()),
                        1 => fmi2SetBoolean(c, vr.as_ptr(), 1, [1].as_ptr()),
                        2 => fmi2SetString(c, vr.as_ptr(), 1, [c"x".as_ptr()].as_ptr()),
                        3 => fmi2GetBoolean(c, vr.as_ptr(), 1, [0].as_mut_ptr()),
                        4 => fmi2GetString(c, vr.as_ptr(), 1, [null()].as_mut_ptr()),
                        _ => fmi2GetInteger(c, vr.as_ptr(), 1, null_mut()),
                    }
                }
                12 => {
                    let vr = [self.vr(model)?];
                    let order = [if self.chance(80)? { 1 } else { self.src.word()? as i32 }];
                    let value = [if self.chance(60)? {
                        self.below(100)? as f64 - 50.0
                    } else {
                        self.real()?
                    }];
                    fmi2SetRealInputDerivatives(c, vr.as_ptr(), 1, order.as_ptr(), value.as_ptr())
                }
                13 => {
                    let vr = [self.vr(model)?];
                    let order = [if self.chance(80)? { 1 } else { self.src.word()? as i32 }];
                    let mut out = [f64::NAN];
                    let s = fmi2GetRealOutputDerivatives(c, vr.as_ptr(), 1, order.as_ptr(), out.as_mut_ptr());
                    if s == fmi2Status::fmi2OK {
                        assert!(out[0].is_finite(), "output derivative = {}", out[0]);
                    }
                    s
                }
                14..=19 => {
                    let t = self.slots[i].time;
                    let cp = match self.below(20)? {
                        0 => self.real()?,
                        1 => t + 1e-3,
                        _ => t,
                    };
                    // A controller takes steps of its sample period only (1 ms unless set).
                    let controller = model.is_controller();
                    let h = match controller && self.chance(80)? {
                        true => 1e-3,
                        false => self.step_size()?,
                    };
                    let s = fmi2DoStep(c, cp, h, self.below(2)? as i32);
                    if s == fmi2Status::fmi2OK {
                        self.slots[i].time = cp + h;
                        self.ok_steps += 1;
                        self.ok_controller_steps += u64::from(controller);
                        check_all = true;
                    }
                    s
                }
                20 => {
                    let last = self.states.last().copied();
                    let mut s: fmi2FMUstate = match last {
                        Some((h, ..)) if self.chance(30)? => h,
                        _ => null_mut(),
                    };
                    let status = fmi2GetFMUstate(c, &mut s);
                    if status == fmi2Status::fmi2OK {
                        let (t, start) = (self.slots[i].time, self.slots[i].start);
                        self.states.push((s, t, start));
                    }
                    status
                }
                21 | 22 => {
                    let (h, t, start) = match self.states.len() {
                        0 => (self.src.word()? as usize as fmi2FMUstate, f64::NAN, f64::NAN),
                        n => {
                            let k = self.below(n as u64)? as usize;
                            self.states[k]
                        }
                    };
                    if me && !self.far_times && (t - start).abs() > FAR_TIME {
                        // A Model Exchange state far from its start time (see FAR_TIME).
                        return Some(());
                    }
                    let s = fmi2SetFMUstate(c, h);
                    if s == fmi2Status::fmi2OK {
                        self.slots[i].time = t;
                        self.slots[i].start = start;
                        (self.slots[i].earliest, self.slots[i].last_step) = (t, t);
                    }
                    s
                }
                23 => {
                    let mut h = match self.states.len() {
                        0 => null_mut(),
                        n => {
                            let k = self.below(n as u64)? as usize;
                            self.states[k].0
                        }
                    };
                    fmi2FreeFMUstate(c, &mut h)
                }
                24 | 25 => {
                    let h = match self.states.len() {
                        0 => null_mut(),
                        n => {
                            let k = self.below(n as u64)? as usize;
                            self.states[k].0
                        }
                    };
                    let mut size = 0usize;
                    let s = fmi2SerializedFMUstateSize(c, h, &mut size);
                    if s != fmi2Status::fmi2OK {
                        s
                    } else {
                        assert!(size > 12 && size < 1 << 16, "size {size}");
                        let short = self.chance(10)?;
                        let n = if short { self.below(size as u64)? as usize } else { size };
                        let mut buf = vec![0u8; size];
                        let s = fmi2SerializeFMUstate(c, h, buf.as_mut_ptr().cast(), n);
                        if s == fmi2Status::fmi2OK {
                            self.blobs.push(buf);
                        }
                        s
                    }
                }
                26 | 27 => {
                    let mut bytes = match self.blobs.len() {
                        0 => vec![],
                        n => {
                            let k = self.below(n as u64)? as usize;
                            self.blobs[k].clone()
                        }
                    };
                    // Mutations: none, flip, truncate, flip and reseal (reaches the field checks).
                    match self.below(5)? {
                        0 | 1 => {}
                        2 if !bytes.is_empty() => {
                            let at = self.below(bytes.len() as u64)? as usize;
                            bytes[at] ^= 1 << self.below(8)?;
                        }
                        3 => {
                            let n = self.below(bytes.len() as u64 + 1)? as usize;
                            bytes.truncate(n);
                        }
                        _ if bytes.len() > 40 => {
                            let at = 12 + self.below(bytes.len() as u64 - 20)? as usize;
                            bytes[at] = self.src.word()? as u8;
                            reseal(&mut bytes);
                        }
                        _ => {}
                    }
                    let mut h: fmi2FMUstate = null_mut();
                    let s = fmi2DeSerializeFMUstate(c, bytes.as_ptr().cast(), bytes.len(), &mut h);
                    if s == fmi2Status::fmi2OK {
                        assert!(!h.is_null());
                        // The time inside the bytes (documented format: after phase, flags, count).
                        let at = phase_offset(&bytes) + 4;
                        let time_at = |at: usize| f64::from_le_bytes(bytes[at..at + 8].try_into().unwrap());
                        self.states.push((h, time_at(at), time_at(at + 8)));
                    }
                    s
                }
                28 => {
                    let kind = self.below(5)? as i32;
                    match self.below(5)? {
                        0 => fmi2GetStatus(c, kind, &mut fmi2Status::fmi2OK),
                        1 => {
                            let mut t = f64::NAN;
                            let s = fmi2GetRealStatus(c, kind, &mut t);
                            if s == fmi2Status::fmi2OK {
                                assert!(t.is_finite(), "last successful time {t}");
                            }
                            s
                        }
                        2 => fmi2GetIntegerStatus(c, kind, &mut 0),
                        3 => fmi2GetBooleanStatus(c, kind, &mut 0),
                        _ => fmi2GetStringStatus(c, kind, &mut null()),
                    }
                }
                ENTER_EVENT_MODE => {
                    let s = fmi2EnterEventMode(c);
                    if s == fmi2Status::fmi2OK {
                        self.slots[i].earliest = self.slots[i].time;
                    }
                    s
                }
                NEW_DISCRETE_STATES => {
                    let mut info = event_info();
                    let out = if self.wild(5)? { null_mut() } else { &mut info as *mut _ };
                    let s = fmi2NewDiscreteStates(c, out);
                    if s == fmi2Status::fmi2OK {
                        let flags = [
                            info.newDiscreteStatesNeeded,
                            info.terminateSimulation,
                            info.nominalsOfContinuousStatesChanged,
                            info.nextEventTimeDefined,
                        ];
                        assert_eq!(
                            flags, [fmi2False; 4],
                            "fmi2NewDiscreteStates asks for something: {info:?}"
                        );
                        // The one change it makes to the continuous states: a body with bearing
                        // friction that sticks is set at rest (docs/model.md §12).
                        assert!(
                            info.valuesOfContinuousStatesChanged == fmi2False
                                || a_body_with_friction_rests(&self.slots[i].f),
                            "fmi2NewDiscreteStates changed the continuous states, and no body with \
                             friction is at rest: {info:?}"
                        );
                    }
                    s
                }
                ENTER_CONTINUOUS_TIME_MODE => fmi2EnterContinuousTimeMode(c),
                COMPLETED_INTEGRATOR_STEP => {
                    let (mut enter, mut terminate) = (7, 7);
                    let enter_ptr = if self.wild(3)? {
                        null_mut()
                    } else {
                        &mut enter as *mut _
                    };
                    let terminate_ptr = if self.wild(3)? {
                        null_mut()
                    } else {
                        &mut terminate as *mut _
                    };
                    let s = fmi2CompletedIntegratorStep(c, self.below(2)? as i32, enter_ptr, terminate_ptr);
                    if s == fmi2Status::fmi2OK {
                        let slot = &mut self.slots[i];
                        (slot.earliest, slot.last_step) = (slot.earliest.max(slot.last_step), slot.time);
                        assert_eq!(
                            (enter, terminate),
                            (fmi2False, fmi2False),
                            "fmi2CompletedIntegratorStep"
                        );
                    }
                    s
                }
                SET_TIME => {
                    let (now, start, earliest) = (self.slots[i].time, self.slots[i].start, self.slots[i].earliest);
                    let t = self.time_near(now, start, earliest)?;
                    let s = fmi2SetTime(c, t);
                    if s == fmi2Status::fmi2OK {
                        self.slots[i].time = t;
                        // Always after a far time: the bounds are brought to it when read.
                        read_all = self.chance(20)? || (t - start).abs() > FAR_TIME;
                    }
                    s
                }
                SET_CONTINUOUS_STATES => {
                    let nx = self.slots[i].x.len();
                    let n = self.length(nx)?;
                    let (x, dx) = (self.slots[i].x.clone(), self.slots[i].dx.clone());
                    let mut values = Vec::with_capacity(n);
                    let how = if self.careful { self.below(9)? } else { self.below(10)? };
                    for k in 0..n {
                        values.push(match how {
                            // An explicit Euler step from the last states and derivatives (a
                            // controller, called across interfaces, has none).
                            0..=5 if nx > 0 => x[k % nx] + 1e-4 * (1 + self.below(100)?) as f64 * dx[k % nx],
                            6 | 7 if nx > 0 => x[k % nx] * (1.0 + (self.below(21)? as f64 - 10.0) / 100.0),
                            _ => self.real()?,
                        });
                    }
                    let ptr = if n > 0 && self.wild(3)? {
                        null()
                    } else {
                        values.as_ptr()
                    };
                    let s = fmi2SetContinuousStates(c, ptr, n);
                    if s == fmi2Status::fmi2OK {
                        self.ok_state_sets += 1;
                        read_all = self.chance(20)?;
                        assert_eq!(n, nx, "{n} continuous states accepted, {nx} expected");
                        // Read back bit for bit (legal in Continuous-Time Mode, where the set was).
                        let (s, back) = self.slots[i].f.continuous_states();
                        assert_eq!(s, fmi2Status::fmi2OK, "fmi2GetContinuousStates after a set");
                        let bits = |x: &[f64]| x.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
                        assert_eq!(bits(&back), bits(&values), "states set {values:?}, read {back:?}");
                        self.slots[i].x = values;
                    }
                    s
                }
                GET_CONTINUOUS_STATES | GET_DERIVATIVES | GET_EVENT_INDICATORS | GET_NOMINALS => {
                    let expected = if op == GET_EVENT_INDICATORS {
                        self.slots[i].f.ni()
                    } else {
                        self.slots[i].x.len()
                    };
                    let n = self.length(expected)?;
                    let mut out = vec![f64::NAN; n];
                    let ptr = if n > 0 && self.wild(3)? {
                        null_mut()
                    } else {
                        out.as_mut_ptr()
                    };
                    let s = match op {
                        GET_CONTINUOUS_STATES => fmi2GetContinuousStates(c, ptr, n),
                        GET_DERIVATIVES => fmi2GetDerivatives(c, ptr, n),
                        GET_EVENT_INDICATORS => fmi2GetEventIndicators(c, ptr, n),
                        _ => fmi2GetNominalsOfContinuousStates(c, ptr, n),
                    };
                    if s == fmi2Status::fmi2OK {
                        assert_eq!(n, expected, "op {op}: a vector of length {n} accepted");
                        assert!(out.iter().all(|x| x.is_finite()), "op {op}: fmi2OK but {out:?}");
                        match op {
                            GET_CONTINUOUS_STATES => self.slots[i].x = out,
                            GET_DERIVATIVES => self.slots[i].dx = out,
                            // [u − g, u + g] with g ≥ 0 (each stage's, first): ordered after
                            // rounding too (monotonic).
                            GET_EVENT_INDICATORS => assert!(out[0] <= out[1], "indicators {out:?}"),
                            _ => assert!(out.iter().all(|x| *x > 0.0), "nominals {out:?}"),
                        }
                    }
                    s
                }
                GET_DIRECTIONAL_DERIVATIVE => {
                    let (nu, nk) = (self.below(5)? as usize, self.below(5)? as usize);
                    // Mostly unknowns and knowns of the Jacobian (docs/model.md §6), sometimes any
                    // reference.
                    let (jacobian_knowns, jacobian_unknowns) = jacobian_names(model);
                    // A controller has none of those names: any reference then.
                    let pick = |d: &mut Self, names: &[&str]| -> Option<u32> {
                        Some(if !d.wild(25)? {
                            match model.by_name(names[d.below(names.len() as u64)? as usize]) {
                                Some(v) => v.vr,
                                None => d.vr(model)?,
                            }
                        } else {
                            d.vr(model)?
                        })
                    };
                    let mut unknowns = Vec::new();
                    for _ in 0..nu {
                        unknowns.push(pick(self, &jacobian_unknowns)?);
                    }
                    let mut knowns = Vec::new();
                    let mut seeds = Vec::new();
                    for _ in 0..nk {
                        knowns.push(pick(self, &jacobian_knowns)?);
                        seeds.push(if !self.wild(30)? {
                            self.below(201)? as f64 / 100.0 - 1.0
                        } else {
                            self.real()?
                        });
                    }
                    let mut out = vec![f64::NAN; nu];
                    let null_at = if self.wild(5)? { self.below(4)? } else { 4 };
                    let s = fmi2GetDirectionalDerivative(
                        c,
                        if null_at == 0 && nu > 0 {
                            null()
                        } else {
                            unknowns.as_ptr()
                        },
                        nu,
                        if null_at == 1 && nk > 0 {
                            null()
                        } else {
                            knowns.as_ptr()
                        },
                        nk,
                        if null_at == 2 && nk > 0 { null() } else { seeds.as_ptr() },
                        if null_at == 3 && nu > 0 {
                            null_mut()
                        } else {
                            out.as_mut_ptr()
                        },
                    );
                    if s == fmi2Status::fmi2OK {
                        assert!(out.iter().all(|x| x.is_finite()), "directional derivative {out:?}");
                    }
                    s
                }
                _ => match self.below(4)? {
                    0 => {
                        let on = self.below(2)? as i32;
                        let s = fmi2SetDebugLogging(c, on, 0, null());
                        if s == fmi2Status::fmi2OK {
                            self.slots[i].errors_logged = on != 0;
                        }
                        s
                    }
                    1 => fmi2SetDebugLogging(c, 1, 1, [c"logContactEvents".as_ptr()].as_ptr()),
                    2 => fmi2CancelStep(c),
                    _ => {
                        // Free this instance; its handle becomes stale.
                        let slot = self.slots.swap_remove(i);
                        self.stale.push(slot.f.c);
                        return Some(());
                    }
                },
            }
        };
        self.slots[i].phase = match (op, status) {
            (_, fmi2Status::fmi2Error) => 3,
            (1, fmi2Status::fmi2OK) => 1,
            (2, fmi2Status::fmi2OK | fmi2Status::fmi2Warning) => 2,
            (4, fmi2Status::fmi2OK) => 0,
            (3, fmi2Status::fmi2OK) | (21 | 22, fmi2Status::fmi2OK) => 3,
            (ENTER_EVENT_MODE, fmi2Status::fmi2OK) => 2,
            (ENTER_CONTINUOUS_TIME_MODE, fmi2Status::fmi2OK) => 4,
            _ => self.slots[i].phase,
        };
        self.check(i, op, status, before, check_all);
        if read_all {
            self.read_all(i, op);
        }
        Some(())
    }

    fn instantiate(&mut self) -> Option<()> {
        self.calls += 1;
        let fmu_type = if self.model_exchange && self.chance(50)? {
            fmi2ModelExchange
        } else {
            fmi2CoSimulation
        };
        // Model Exchange instances of the plants only; Co-Simulation ones of every model.
        let served = if fmu_type == fmi2ModelExchange {
            MODELS.len()
        } else {
            served().count()
        };
        let model = self.below(self.models.min(served) as u64)? as usize;
        let name = if self.chance(50)? { "fuzz" } else { "a%s%n b" };
        let f = Fmu::instantiate(model, name, fmu_type);
        if self.chance(30)? {
            // SAFETY: no categories.
            assert_eq!(unsafe { fmi2SetDebugLogging(f.c, 1, 0, null()) }, fmi2Status::fmi2OK);
        }
        self.slots.push(Slot {
            f,
            time: 0.0,
            phase: 0,
            errors_logged: true,
            start: 0.0,
            earliest: 0.0,
            last_step: 0.0,
            x: vec![0.0; nx(model)],
            dx: vec![0.0; nx(model)],
        });
        Some(())
    }

    /// Reads every variable: fmi2OK with every value [`admissible`], or a refusal with a logged
    /// reason (then the instance is in state Error).
    fn read_all(&mut self, i: usize, op: u64) {
        let f = &self.slots[i].f;
        let before = f.log_len();
        let (s, values) = f.all_values();
        let new = &f.entries()[before..];
        let context = || {
            format!(
                "reading every variable after op {op}, call {}: {s:?}, log {new:?}",
                self.calls
            )
        };
        match s {
            fmi2Status::fmi2OK => {
                for (name, x) in values {
                    assert!(admissible(name, x), "{name} = {x} {}", context());
                }
            }
            fmi2Status::fmi2Error => {
                if self.slots[i].errors_logged {
                    assert!(
                        new.iter().any(|e| e.category == "logErrors" && !e.message.is_empty()),
                        "no logged reason {}",
                        context()
                    );
                }
                self.slots[i].phase = 3;
            }
            _ => panic!("unexpected status {}", context()),
        }
    }

    fn check(&mut self, i: usize, op: u64, status: fmi2Status, before: usize, check_all: bool) {
        let f = &self.slots[i].f;
        let new = &f.entries()[before..];
        let context = || format!("op {op}, call {}: {status:?}, log {new:?}", self.calls);
        match status {
            fmi2Status::fmi2OK => {}
            fmi2Status::fmi2Warning if self.slots[i].errors_logged => {
                assert!(new.iter().any(|e| e.category == "logWarnings"), "{}", context())
            }
            fmi2Status::fmi2Warning => {}
            fmi2Status::fmi2Discard | fmi2Status::fmi2Error if self.slots[i].errors_logged => assert!(
                new.iter()
                    .any(|e| e.category == "logErrors" && e.status == status && !e.message.is_empty()),
                "no logged reason: {}",
                context()
            ),
            fmi2Status::fmi2Discard | fmi2Status::fmi2Error => {}
            _ => panic!("status outside the FMI 2.0 set: {}", context()),
        }
        if check_all {
            // Every variable reads, admissible; but the bounds, brought up to the step only
            // when read (docs/model.md §3), may overflow there, or (extreme parameters) lie out
            // of their reach: then the read is refused with that reason ("the bounds at t = …"
            // of a single-gap plant, "the bound at t = …" of the gearbox, which has one) and
            // the instance is in Error.
            let before_read = f.log_len();
            let (s, values) = f.all_values();
            match s {
                fmi2Status::fmi2OK => {
                    for (name, x) in values {
                        assert!(admissible(name, x), "{name} = {x} after {}", context());
                    }
                }
                fmi2Status::fmi2Error => {
                    let read = &f.entries()[before_read..];
                    assert!(
                        !self.slots[i].errors_logged
                            || read
                                .iter()
                                .any(|e| e.category == "logErrors" && names_the_bounds(&e.message)),
                        "reading every variable: {s:?}, log {read:?} after {}",
                        context()
                    );
                    self.slots[i].phase = 3;
                }
                _ => panic!("reading every variable: {s:?} after {}", context()),
            }
        }
    }
}

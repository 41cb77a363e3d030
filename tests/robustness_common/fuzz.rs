//! A driver that calls the C ABI in random order with random arguments, valid and invalid,
//! and checks after every call what must always hold:
//! - the status is one of fmi2OK, fmi2Warning, fmi2Discard, fmi2Error (never Fatal/Pending);
//! - fmi2Discard and fmi2Error from a live instance come with a logged reason in logErrors,
//!   fmi2Warning with one in logWarnings;
//! - values read with fmi2OK are never NaN, and never infinite except bound_sup (docs/model.md §4);
//!   after every successful fmi2DoStep every variable is read and checked.
//!
//! A panic that unwinds out of an `extern "C"` function aborts the process, so "no panic
//! escapes" and "no crash" are checked by the process surviving; panics caught inside are
//! counted by the caller's panic hook.
//!
//! The randomness comes from a [`Source`]: a PRNG in `cargo test`, or any byte string (a
//! coverage-guided fuzzer's input) through [`Bytes`].

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

/// Fuzzer input read as little-endian words; shorter tails are zero-padded.
pub struct Bytes<'a>(pub &'a [u8]);

impl Source for Bytes<'_> {
    fn word(&mut self) -> Option<u64> {
        if self.0.is_empty() {
            return None;
        }
        let n = self.0.len().min(8);
        let mut w = [0u8; 8];
        w[..n].copy_from_slice(&self.0[..n]);
        self.0 = &self.0[n..];
        Some(u64::from_le_bytes(w))
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

struct Slot {
    f: Fmu,
    /// Whether logErrors is on: fmi2SetDebugLogging(fmi2False) with no categories switches
    /// every category off, errors included; then a refusal has only its status.
    errors_logged: bool,
    /// Our belief of the instance's time, for communication points that match it.
    time: f64,
    /// Our belief of its state (0 Instantiated, 1 Initialization, 2 StepComplete, 3 other),
    /// used to pick the call that moves it on more often than chance would.
    phase: u8,
}

pub struct Driver<S: Source> {
    src: S,
    slots: Vec<Slot>,
    /// FMU state handles seen (live, freed or foreign) and the time they were taken at.
    states: Vec<(fmi2FMUstate, f64)>,
    blobs: Vec<Vec<u8>>,
    stale: Vec<fmi2Component>,
    pub calls: u64,
    pub ok_steps: u64,
    /// Whether parameters may take extreme finite magnitudes (1e±300, f64::MAX). Off by
    /// default: some such plants make the physics hang (see tests/robustness_extremes.rs).
    pub extreme_parameters: bool,
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
            extreme_parameters: false,
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
        let op = if self.chance(50)? {
            match self.slots[i].phase {
                0 => 1,
                1 => [2, 5][self.below(2)? as usize],
                2 => [14, 14, 14, 20, 21, 24, 26, 8][self.below(8)? as usize],
                _ => 4,
            }
        } else {
            self.below(30)?
        };
        self.calls += 1;
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
        // SAFETY (whole match): every pointer passed is NULL with a length the FMU must refuse
        // or check, or points to a live local of at least the announced length.
        let status = unsafe {
            match op {
                0 => {
                    let start = if self.chance(80)? { 0.0 } else { self.real()? };
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
                    }
                    s
                }
                1 => fmi2EnterInitializationMode(c),
                2 => {
                    let s = fmi2ExitInitializationMode(c);
                    check_all = matches!(s, fmi2Status::fmi2OK | fmi2Status::fmi2Warning);
                    s
                }
                3 => fmi2Terminate(c),
                4 => {
                    let s = fmi2Reset(c);
                    self.slots[i].time = 0.0;
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
                            assert!(!x.is_nan(), "fmi2GetReal OK but {name} is NaN");
                            assert!(x.is_finite() || name == "bound_sup", "fmi2GetReal OK but {name} = {x}");
                        }
                    }
                    s
                }
                10 => {
                    let vr = [self.vr(model)?];
                    let mut out = [i32::MIN];
                    let s = fmi2GetInteger(c, vr.as_ptr(), 1, out.as_mut_ptr());
                    if s == fmi2Status::fmi2OK {
                        assert!((-1..=1).contains(&out[0]), "contact = {}", out[0]);
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
                    let h = self.step_size()?;
                    let s = fmi2DoStep(c, cp, h, self.below(2)? as i32);
                    if s == fmi2Status::fmi2OK {
                        self.slots[i].time = cp + h;
                        self.ok_steps += 1;
                        check_all = true;
                    }
                    s
                }
                20 => {
                    let last = self.states.last().copied();
                    let mut s: fmi2FMUstate = match last {
                        Some((h, _)) if self.chance(30)? => h,
                        _ => null_mut(),
                    };
                    let status = fmi2GetFMUstate(c, &mut s);
                    if status == fmi2Status::fmi2OK {
                        let t = self.slots[i].time;
                        self.states.push((s, t));
                    }
                    status
                }
                21 | 22 => {
                    let (h, t) = match self.states.len() {
                        0 => (self.src.word()? as usize as fmi2FMUstate, f64::NAN),
                        n => {
                            let k = self.below(n as u64)? as usize;
                            self.states[k]
                        }
                    };
                    let s = fmi2SetFMUstate(c, h);
                    if s == fmi2Status::fmi2OK {
                        self.slots[i].time = t;
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
                        let t = f64::from_le_bytes(bytes[at..at + 8].try_into().unwrap());
                        self.states.push((h, t));
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
            _ => self.slots[i].phase,
        };
        self.check(i, op, status, before, check_all);
        Some(())
    }

    fn instantiate(&mut self) -> Option<()> {
        self.calls += 1;
        let model = self.below(2)? as usize;
        let f = Fmu::named(model, if self.chance(50)? { "fuzz" } else { "a%s%n b" });
        if self.chance(30)? {
            // SAFETY: no categories.
            assert_eq!(unsafe { fmi2SetDebugLogging(f.c, 1, 0, null()) }, fmi2Status::fmi2OK);
        }
        self.slots.push(Slot {
            f,
            time: 0.0,
            phase: 0,
            errors_logged: true,
        });
        Some(())
    }

    fn check(&self, i: usize, op: u64, status: fmi2Status, before: usize, check_all: bool) {
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
            _ => panic!("status outside the FMI 2.0 Co-Simulation set: {}", context()),
        }
        if check_all {
            let (s, values) = f.all_values();
            assert_eq!(s, fmi2Status::fmi2OK, "{}", context());
            for (name, x) in values {
                let var = f.model.by_name(name).unwrap();
                assert!(!x.is_nan(), "{name} is NaN after {}", context());
                assert!(
                    x.is_finite() || var.causality == Causality::CalculatedParameter,
                    "{name} = {x} after {}",
                    context()
                );
            }
        }
    }
}

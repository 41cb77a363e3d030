//! The FMI 3.0 state machines through the C ABI, against tables written out here independently
//! of `src/fmu/state_machine.rs` from the FMI 3.0 standard (§3.2 Model Exchange, §4.2
//! Co-Simulation with eventModeUsed): every listed function in every state. An illegal call must
//! return fmi3Error and log why ("not allowed in state", or "belongs to FMI for" for a function
//! of the other interface); a legal one must return fmi3OK.
//!
//! Then a short seeded fuzz of the FMI 3.0 functions over both instance kinds: random order,
//! random finite/NaN/huge arguments, NULL pointers with positive lengths, wrong lengths. After
//! every call: no crash, the status is never fmi3Fatal, an fmi3Error comes with a logged
//! message, and after an accepted call every Float64 variable reads non-NaN (infinite only for
//! bound_sup and bound_T_sup) or the read is refused with a reason. Instances are of every model,
//! each with its own number of continuous states. FMI3_FUZZ_SECONDS=60 lengthens it.
//!
//! The controller ([`CONTROLLER`], docs/model.md §9) has Co-Simulation without Event Mode only:
//! the Co-Simulation table is checked on it in the states it has, with its own rows (no FMU
//! state, no continuous state to set), and its refused instantiations (Model Exchange,
//! eventModeUsed = true) are checked with their reasons. The fuzz draws plants only (the FMI 2.0
//! fuzz draws the controller).

use crate::robustness_common::{admissible, model_at, ni, nx, CONTROLLER};
use backlash_fmu::ffi::fmi3::*;
use backlash_fmu::fmu::variables::VarType;
use backlash_fmu::fmu::MODELS;
use std::ffi::{c_void, CStr, CString};
use std::ptr::{null, null_mut};
use std::sync::Mutex;
use std::time::{Duration, Instant};

const OK: fmi3Status = fmi3Status::fmi3OK;
const ERROR: fmi3Status = fmi3Status::fmi3Error;

type Log3 = Mutex<Vec<String>>;

unsafe extern "C" fn log3(env: fmi3InstanceEnvironment, _s: fmi3Status, _c: fmi3String, message: fmi3String) {
    // SAFETY: `env` is the &Log3 given at instantiation; the message is NUL-terminated.
    unsafe {
        let log = &*(env as *const Log3);
        log.lock()
            .unwrap()
            .push(CStr::from_ptr(message).to_string_lossy().into_owned());
    }
}

struct Inst {
    c: fmi3Instance,
    model: usize,
    me: bool,
    event_mode_used: bool,
    log: Box<Log3>,
}

impl Inst {
    fn new(model: usize, me: bool, event_mode_used: bool) -> Inst {
        Inst::try_new(model, me, event_mode_used).unwrap_or_else(|log| panic!("{log:?}"))
    }

    /// The instance, or the messages logged by its refused instantiation.
    fn try_new(model: usize, me: bool, event_mode_used: bool) -> Result<Inst, Vec<String>> {
        let log: Box<Log3> = Box::default();
        let token = CString::new(model_at(model).instantiation_token).unwrap();
        let env = &*log as *const Log3 as *mut c_void;
        // SAFETY: NUL-terminated strings; the log outlives the instance (freed in Drop).
        let c = unsafe {
            if me {
                fmi3InstantiateModelExchange(c"me".as_ptr(), token.as_ptr(), null(), false, true, env, Some(log3))
            } else {
                fmi3InstantiateCoSimulation(
                    c"cs".as_ptr(),
                    token.as_ptr(),
                    null(),
                    false,
                    true,
                    event_mode_used,
                    false,
                    null(),
                    0,
                    env,
                    Some(log3),
                    None,
                )
            }
        };
        if c.is_null() {
            return Err(log.lock().unwrap().clone());
        }
        Ok(Inst {
            c,
            model,
            me,
            event_mode_used,
            log,
        })
    }
    fn log_len(&self) -> usize {
        self.log.lock().unwrap().len()
    }
    fn since(&self, n: usize) -> Vec<String> {
        self.log.lock().unwrap()[n..].to_vec()
    }
    fn vr(&self, name: &str) -> u32 {
        crate::robustness_common::named(model_at(self.model), name)
    }
    /// Number of continuous states of its model.
    fn nx(&self) -> usize {
        nx(self.model)
    }
    fn ni(&self) -> usize {
        ni(self.model)
    }
    /// `plant` on a plant, `controller` on the controller: a variable of the same kind in each.
    fn named(&self, plant: &'static str, controller: &'static str) -> &'static str {
        if self.model == CONTROLLER {
            controller
        } else {
            plant
        }
    }
    /// The bits of every Float64 variable, or the status of a refused read.
    fn values(&self) -> Result<Vec<u64>, fmi3Status> {
        let vrs: Vec<u32> = model_at(self.model)
            .variables
            .iter()
            .filter(|v| v.ty == VarType::Real)
            .map(|v| v.vr)
            .collect();
        let mut out = vec![f64::NAN; vrs.len()];
        // SAFETY: arrays of the announced lengths.
        let s = unsafe { fmi3GetFloat64(self.c, vrs.as_ptr(), vrs.len(), out.as_mut_ptr(), out.len()) };
        match s {
            OK => Ok(out.iter().map(|x| x.to_bits()).collect()),
            s => Err(s),
        }
    }
}

impl Drop for Inst {
    fn drop(&mut self) {
        fmi3FreeInstance(self.c);
    }
}

const CS_STATES: [&str; 6] = [
    "Instantiated",
    "InitializationMode",
    "EventMode",
    "StepMode",
    "Terminated",
    "Error",
];
const ME_STATES: [&str; 6] = [
    "Instantiated",
    "InitializationMode",
    "EventMode",
    "ContinuousTimeMode",
    "Terminated",
    "Error",
];

fn init(f: &Inst) {
    assert_eq!(fmi3EnterInitializationMode(f.c, false, 0.0, 0.0, false, 0.0), OK);
}

/// An instance in state `index` of CS_STATES / ME_STATES (Co-Simulation with eventModeUsed).
fn in_state(me: bool, index: usize) -> Inst {
    in_state_of(0, me, true, index)
}

/// An instance of `model` in state `index` of CS_STATES / ME_STATES; without eventModeUsed
/// (Co-Simulation only) initialization leads straight to Step Mode, and there is no Event Mode.
fn in_state_of(model: usize, me: bool, event_mode_used: bool, index: usize) -> Inst {
    assert!(
        me || event_mode_used || index != 2,
        "no Event Mode without eventModeUsed"
    );
    let f = Inst::new(model, me, event_mode_used);
    if index >= 1 {
        init(&f);
    }
    if index >= 2 {
        // Event Mode, both kinds; Step Mode without eventModeUsed.
        assert_eq!(fmi3ExitInitializationMode(f.c), OK);
    }
    if index >= 3 && (me || event_mode_used) {
        let s = if me {
            fmi3EnterContinuousTimeMode(f.c)
        } else {
            fmi3EnterStepMode(f.c)
        };
        assert_eq!(s, OK);
    }
    if index == 4 {
        assert_eq!(fmi3Terminate(f.c), OK);
    }
    if index == 5 {
        // From Step / Continuous-Time Mode, so that values are there to be read.
        assert_eq!(fmi3EnterInitializationMode(f.c, false, 0.0, 0.0, false, 0.0), ERROR);
    }
    f
}

type Call = fn(&Inst) -> fmi3Status;

/// (function, call with valid arguments, legal in Co-Simulation states, legal in Model Exchange
/// states); `None`: the function belongs to the other interface.
#[rustfmt::skip]
fn table() -> Vec<(&'static str, Call, Option<[bool; 6]>, Option<[bool; 6]>)> {
    const ALL: Option<[bool; 6]> = Some([true; 6]);
    //                  I      M      V      C/N    T      E
    let only = |i: usize| { let mut m = [false; 6]; m[i] = true; Some(m) };
    // SAFETY (every entry): pointers to locals of the announced lengths.
    unsafe {
        vec![
            ("fmi3EnterInitializationMode", |f| fmi3EnterInitializationMode(f.c, false, 0.0, 0.0, false, 0.0), only(0), only(0)),
            ("fmi3ExitInitializationMode", |f| fmi3ExitInitializationMode(f.c), only(1), only(1)),
            ("fmi3EnterEventMode", |f| fmi3EnterEventMode(f.c), only(3), only(3)),
            ("fmi3EnterStepMode", |f| fmi3EnterStepMode(f.c), only(2), None),
            ("fmi3UpdateDiscreteStates", |f| {
                let (mut a, mut b, mut c, mut d, mut e, mut t) = (false, false, false, false, false, 0.0);
                fmi3UpdateDiscreteStates(f.c, &mut a, &mut b, &mut c, &mut d, &mut e, &mut t)
            }, only(2), only(2)),
            ("fmi3EnterContinuousTimeMode", |f| fmi3EnterContinuousTimeMode(f.c), None, only(2)),
            ("fmi3DoStep", |f| {
                let (mut a, mut b, mut c, mut t) = (false, false, false, 0.0);
                fmi3DoStep(f.c, 0.0, 1e-3, true, &mut a, &mut b, &mut c, &mut t)
            }, only(3), None),
            // FMI 3.0.2 §3.2.1 lists fmi3SetTime among Continuous-Time Mode's calls only.
            ("fmi3SetTime", |f| fmi3SetTime(f.c, 0.0), None, only(3)),
            ("fmi3SetContinuousStates", |f| {
                let mut x = vec![0.0; f.nx()];
                // Read in the same state; the values only matter where the set is legal.
                fmi3GetContinuousStates(f.c, x.as_mut_ptr(), x.len());
                fmi3SetContinuousStates(f.c, x.as_ptr(), x.len())
            }, None, only(3)),
            ("fmi3GetContinuousStateDerivatives", |f| fmi3GetContinuousStateDerivatives(f.c, vec![0.0; f.nx()].as_mut_ptr(), f.nx()),
                None, Some([false, true, true, true, true, true])),
            ("fmi3GetEventIndicators", |f| fmi3GetEventIndicators(f.c, vec![0.0; f.ni()].as_mut_ptr(), f.ni()),
                None, Some([false, true, true, true, true, true])),
            ("fmi3CompletedIntegratorStep", |f| fmi3CompletedIntegratorStep(f.c, true, &mut false, &mut false), None, only(3)),
            ("fmi3Terminate", |f| fmi3Terminate(f.c), Some([false, false, true, true, false, false]), Some([false, false, true, true, false, false])),
            ("fmi3Reset", |f| fmi3Reset(f.c), ALL, ALL),
            ("fmi3GetFloat64", |f| fmi3GetFloat64(f.c, [f.vr(f.named("theta_m", "tau_m"))].as_ptr(), 1, [0.0].as_mut_ptr(), 1),
                Some([false, true, true, true, true, true]), Some([false, true, true, true, true, true])),
            ("fmi3SetFloat64", |f| fmi3SetFloat64(f.c, [f.vr(f.named("tau_m", "omega_m"))].as_ptr(), 1, [0.5].as_ptr(), 1),
                Some([true, true, true, true, false, false]), Some([true, true, true, true, false, false])),
            // A continuous-time state: §2.3.5, Event Mode (either interface): "… and continuous-time
            // states with reinit = false"; §3.2.1, Continuous-Time Mode: "Only for variables with
            // causality = input and variability = continuous, and continuous-time states"; not in
            // Step Mode (§4.2.1: inputs and tunable parameters). The controller's output tau_m,
            // whose start value it holds until the first step ends, alike before Step Mode.
            ("fmi3SetFloat64(theta_m)", |f| fmi3SetFloat64(f.c, [f.vr(f.named("theta_m", "tau_m"))].as_ptr(), 1, [1e-4].as_ptr(), 1),
                Some([true, true, true, false, false, false]), Some([true, true, true, true, false, false])),
            ("fmi3GetFMUState", |f| {
                let mut s = null_mut();
                let status = fmi3GetFMUState(f.c, &mut s);
                fmi3FreeFMUState(f.c, &mut s);
                status
            }, ALL, ALL),
        ]
    }
}

/// On a shaft, both interfaces; the controller's table is the next test.
#[test]
fn every_call_in_every_fmi3_state_follows_the_standard_table() {
    let mut failures = Vec::new();
    let mut checked = 0;
    for (name, call, cs, me) in table() {
        for is_me in [false, true] {
            let (legal, states, other) = if is_me {
                (me, ME_STATES, "belongs to FMI for Co-Simulation")
            } else {
                (cs, CS_STATES, "belongs to FMI for Model Exchange")
            };
            for (i, state) in states.iter().enumerate() {
                checked += 1;
                let f = in_state(is_me, i);
                let before = f.log_len();
                let status = call(&f);
                let log = f.since(before);
                let kind = if is_me { "ME" } else { "CS" };
                match legal {
                    Some(m) if m[i] => {
                        if status != OK {
                            failures.push(format!("{kind} {name} in {state}: legal, got {status:?} {log:?}"));
                        }
                    }
                    _ => {
                        let reason = why_illegal(&f, name, legal.is_none(), other, state);
                        if status != ERROR || !log.iter().any(|m| m.contains(&reason)) {
                            failures.push(format!(
                                "{kind} {name} in {state}: illegal (\"{reason}\"), got {status:?} {log:?}"
                            ));
                        }
                    }
                }
            }
        }
    }
    println!("{checked} (function, state) cases checked");
    assert_eq!(checked, 18 * 12);
    assert!(
        failures.is_empty(),
        "{} disagreements:\n{}",
        failures.len(),
        failures.join("\n")
    );
}

/// The reason an illegal call of `name` in `state` must log: the other interface's, or, where the
/// function is legal but the variable is not settable there (Step Mode), the variable's.
fn why_illegal(f: &Inst, name: &str, other_interface: bool, other: &str, state: &str) -> String {
    if other_interface {
        other.to_string()
    } else if name.contains('(') && state == "StepMode" {
        format!("{} cannot be set in state StepComplete", f.named("theta_m", "tau_m"))
    } else {
        "not allowed in state".to_string()
    }
}

/// The controller's own answer to a call the Co-Simulation table allows (docs/model.md §9):
/// refused, naming why. It has no FMU state, and no Event Mode (eventModeUsed is false).
fn controller_refusal(function: &str) -> Option<&'static str> {
    match function {
        "fmi3GetFMUState" => Some("a controller's FMU state"),
        "fmi3EnterEventMode" => Some("eventModeUsed"),
        _ => None,
    }
}

/// The Co-Simulation table on the controller, in the states it has (no Event Mode: initialization
/// leads straight to Step Mode), with its own rows ([`controller_refusal`]): each such refusal is
/// fmi3Error with the reason, changes no value, and a fresh instance works after.
#[test]
fn every_call_in_every_fmi3_state_of_the_controller_follows_the_standard_table() {
    let mut failures = Vec::new();
    let mut checked = 0;
    for (name, call, cs, _) in table() {
        for (i, state) in CS_STATES.iter().enumerate().filter(|(i, _)| *i != 2) {
            checked += 1;
            let f = in_state_of(CONTROLLER, false, false, i);
            // Values are readable from Initialization Mode on: a refusal must change none.
            let values = (i > 0).then(|| f.values());
            let before = f.log_len();
            let status = call(&f);
            let log = f.since(before);
            let legal = cs.is_some_and(|m| m[i]);
            let reason = match (legal, controller_refusal(name)) {
                (true, None) => {
                    if status != OK {
                        failures.push(format!("{name} in {state}: legal, got {status:?} {log:?}"));
                    }
                    continue;
                }
                (true, Some(reason)) => reason.to_string(),
                (false, _) => why_illegal(&f, name, cs.is_none(), "belongs to FMI for Model Exchange", state),
            };
            if status != ERROR || !log.iter().any(|m| m.contains(&reason)) {
                failures.push(format!(
                    "{name} in {state}: refused (\"{reason}\"), got {status:?} {log:?}"
                ));
            }
            if values.is_some_and(|values| f.values() != values) {
                failures.push(format!("{name} in {state}: the refusal changed a value"));
            }
        }
    }
    println!("{checked} (function, state) cases checked on the controller");
    assert_eq!(checked, 18 * 5);
    assert!(
        failures.is_empty(),
        "{} disagreements:\n{}",
        failures.len(),
        failures.join("\n")
    );
    controller_works(&Inst::new(CONTROLLER, false, false));
}

/// A controller instance just instantiated (or reset) works: a step reference of 1, Kp = 2,
/// Ki = 4, h = 0.25 and a measured speed of 0.5 give, by docs/model.md §9, u_k = 1 + k/2 after
/// step k (the law worked out at `standard_controller_run_on`, here through FMI 3.0).
fn controller_works(f: &Inst) {
    let set = |name: &str, x: f64| {
        // SAFETY: arrays of length 1.
        unsafe { fmi3SetFloat64(f.c, [f.vr(name)].as_ptr(), 1, [x].as_ptr(), 1) }
    };
    init(f);
    // SAFETY: arrays of length 1.
    assert_eq!(
        unsafe { fmi3SetInt32(f.c, [f.vr("reference")].as_ptr(), 1, [1].as_ptr(), 1) },
        OK
    );
    for (name, x) in [("amplitude", 1.0), ("Kp", 2.0), ("Ki", 4.0), ("h", 0.25)] {
        assert_eq!(set(name, x), OK, "{name}");
    }
    assert_eq!(fmi3ExitInitializationMode(f.c), OK);
    assert_eq!(set("omega_m", 0.5), OK);
    for k in 0..4 {
        let (mut a, mut b, mut c, mut t) = (false, false, false, 0.0);
        // SAFETY: pointers to locals.
        let s = unsafe { fmi3DoStep(f.c, k as f64 * 0.25, 0.25, true, &mut a, &mut b, &mut c, &mut t) };
        assert_eq!((s, t), (OK, (k + 1) as f64 * 0.25), "sample {k}");
        assert_eq!(float64(f, &["tau_m"]), [(1.0 + k as f64 / 2.0).to_bits()], "sample {k}");
    }
}

/// On a plant and on the controller, which never has Event Mode.
#[test]
fn co_simulation_without_event_mode_refuses_event_mode_with_the_reason() {
    for model in [0, CONTROLLER] {
        let f = Inst::new(model, false, false);
        init(&f);
        assert_eq!(fmi3ExitInitializationMode(f.c), OK, "straight to Step Mode");
        let (mut a, mut b, mut c, mut t) = (false, false, false, 0.0);
        // SAFETY: pointers to locals.
        assert_eq!(
            unsafe { fmi3DoStep(f.c, 0.0, 1e-3, true, &mut a, &mut b, &mut c, &mut t) },
            OK
        );
        let before = f.log_len();
        assert_eq!(fmi3EnterEventMode(f.c), ERROR);
        assert!(
            f.since(before).iter().any(|m| m.contains("eventModeUsed")),
            "{:?}",
            f.since(before)
        );
    }
}

/// The controller's instantiations that its description does not offer return NULL and log why,
/// naming the cause (FMI 3.0.2 §2.3.1: eventModeUsed "may only be fmi3True, if hasEventMode =
/// true, otherwise the FMU must raise an error"); those it offers work after.
#[test]
fn the_controller_refuses_model_exchange_and_event_mode_at_instantiation() {
    let refused = |me: bool, event_mode_used: bool, reason: &str| match Inst::try_new(CONTROLLER, me, event_mode_used) {
        Ok(_) => panic!("instantiated despite {reason:?}"),
        Err(log) => assert!(log.iter().any(|m| m.contains(reason)), "{reason:?} not in {log:?}"),
    };
    refused(
        true,
        false,
        "BacklashController is a controller: Co-Simulation only, its description declares no Model Exchange",
    );
    refused(
        false,
        true,
        "eventModeUsed = true, but BacklashController has no Event Mode (hasEventMode = false)",
    );
    let f = Inst::new(CONTROLLER, false, false);
    controller_works(&f);
    // fmi3Reset leads back to a working instance.
    assert_eq!(fmi3Reset(f.c), OK);
    controller_works(&f);
}

/// An ME instance of `model` in Continuous-Time Mode at the start time 0.
fn me_continuous(model: usize) -> Inst {
    let f = Inst::new(model, true, true);
    init(&f);
    assert_eq!(fmi3ExitInitializationMode(f.c), OK);
    assert_eq!(fmi3EnterContinuousTimeMode(f.c), OK);
    f
}

/// Runs `call` and asserts it was refused with fmi3Error and a logged reason containing `reason`.
#[track_caller]
fn refuses(f: &Inst, reason: &str, call: impl FnOnce() -> fmi3Status) {
    let before = f.log_len();
    assert_eq!(call(), ERROR);
    let log = f.since(before);
    assert!(log.iter().any(|m| m.contains(reason)), "{reason:?} not in {log:?}");
}

fn float64(f: &Inst, names: &[&str]) -> Vec<u64> {
    let vrs: Vec<u32> = names.iter().map(|n| f.vr(n)).collect();
    let mut out = vec![f64::NAN; vrs.len()];
    // SAFETY: arrays of the announced lengths.
    let s = unsafe { fmi3GetFloat64(f.c, vrs.as_ptr(), vrs.len(), out.as_mut_ptr(), out.len()) };
    assert_eq!(s, OK);
    out.iter().map(|x| x.to_bits()).collect()
}

/// FMI 3.0.2 §3.2.1, fmi3SetTime: "time must be larger or equal to: startTime, the time at the
/// second last call to fmi3CompletedIntegratorStep, the time at the last call to
/// fmi3EnterEventMode", whatever needsCompletedIntegratorStep says; on every model (Model
/// Exchange: the plants only, the controller has none).
#[test]
fn fmi3_set_time_goes_back_no_further_than_the_text_allows() {
    for model in 0..MODELS.len() {
        let completed = |f: &Inst, t: f64| {
            assert_eq!(fmi3SetTime(f.c, t), OK);
            // SAFETY: pointers to locals.
            assert_eq!(
                unsafe { fmi3CompletedIntegratorStep(f.c, true, &mut true, &mut true) },
                OK
            );
        };
        let f = me_continuous(model);
        completed(&f, 0.01);
        completed(&f, 0.02);
        assert_eq!(fmi3SetTime(f.c, 0.01), OK, "the second-last completed step");
        refuses(
            &f,
            "time 0.005 is before 0.01, the time of the second-last completed integrator step: FMI 3.0.2 §3.2.1",
            || fmi3SetTime(f.c, 0.005),
        );
        // An instance in Event Mode entered at t = 0.04.
        let in_event_at_4 = || {
            let f = me_continuous(model);
            assert_eq!(fmi3SetTime(f.c, 0.04), OK);
            assert_eq!(fmi3EnterEventMode(f.c), OK);
            f
        };
        let f = in_event_at_4();
        // §3.2.1 lists fmi3SetTime among Continuous-Time Mode's calls only.
        refuses(
            &f,
            "fmi3SetTime is not allowed in state EventMode: FMI 3.0.2 §3.2.1",
            || fmi3SetTime(f.c, 0.04),
        );
        let f = in_event_at_4();
        assert_eq!(fmi3EnterContinuousTimeMode(f.c), OK);
        assert_eq!(fmi3SetTime(f.c, 0.04), OK, "the event's time itself");
        refuses(&f, "time 0.03 is before 0.04, the time of the last event", || {
            fmi3SetTime(f.c, 0.03)
        });
    }
}

/// A continuous-time state set by fmi3SetFloat64 is a state set: in Continuous-Time Mode (§3.2.1)
/// as fmi3SetContinuousStates with the other entries unchanged; in Event Mode of either
/// interface (§2.3.5, "continuous-time states with reinit = false"), and in Co-Simulation the
/// steps then start from it exactly as from that start value. Each pair computes the plant's
/// state from the same numbers by the same function, so the values agree bit for bit. The plants
/// only: the controller has no continuous state (its held torque: the controller's table).
#[test]
fn fmi3_continuous_states_set_by_value_reference_are_states_set() {
    for model in 0..MODELS.len() {
        let outputs = [
            "theta_m",
            "omega_m",
            "theta_L",
            "omega_L",
            "psi",
            "u_minus_g",
            "der(omega_m)",
            "der(omega_L)",
        ];
        for event_mode in [false, true] {
            let (by_name, by_vector) = (me_continuous(model), me_continuous(model));
            if event_mode {
                assert_eq!(fmi3EnterEventMode(by_name.c), OK);
                assert_eq!(fmi3EnterEventMode(by_vector.c), OK);
                assert_eq!(fmi3EnterContinuousTimeMode(by_vector.c), OK);
            }
            let mut x = vec![0.0; by_vector.nx()];
            x[0] = 3e-4;
            // SAFETY: arrays of the announced lengths.
            unsafe {
                assert_eq!(
                    fmi3SetFloat64(by_name.c, [by_name.vr("theta_m")].as_ptr(), 1, [3e-4].as_ptr(), 1),
                    OK
                );
                assert_eq!(fmi3SetContinuousStates(by_vector.c, x.as_ptr(), x.len()), OK);
            }
            assert_eq!(
                float64(&by_name, &outputs),
                float64(&by_vector, &outputs),
                "event mode: {event_mode}"
            );
        }
        // Co-Simulation: set in Event Mode at the start, then stepped, against an instance that
        // starts there.
        let set = Inst::new(model, false, true);
        let started = Inst::new(model, false, true);
        // SAFETY: arrays of length 1.
        unsafe {
            assert_eq!(
                fmi3SetFloat64(started.c, [started.vr("theta_m")].as_ptr(), 1, [3e-4].as_ptr(), 1),
                OK
            );
        }
        for f in [&set, &started] {
            init(f);
            assert_eq!(fmi3ExitInitializationMode(f.c), OK);
        }
        // SAFETY: arrays of length 1.
        unsafe {
            assert_eq!(
                fmi3SetFloat64(set.c, [set.vr("theta_m")].as_ptr(), 1, [3e-4].as_ptr(), 1),
                OK
            );
        }
        for f in [&set, &started] {
            assert_eq!(fmi3EnterStepMode(f.c), OK);
            for k in 0..20 {
                let (mut a, mut b, mut c, mut t) = (false, false, false, 0.0);
                // SAFETY: pointers to locals.
                let s = unsafe { fmi3DoStep(f.c, k as f64 * 0.01, 0.01, true, &mut a, &mut b, &mut c, &mut t) };
                assert_eq!(s, OK);
            }
        }
        let all: Vec<&str> = ["theta_m", "omega_m", "theta_L", "omega_L", "psi", "bound"].to_vec();
        assert_eq!(
            float64(&set, &all),
            float64(&started, &all),
            "{}",
            MODELS[model].identifier
        );
    }
}

unsafe extern "C" fn counting_logger(env: fmi3InstanceEnvironment, _s: fmi3Status, _c: fmi3String, _m: fmi3String) {
    // SAFETY: `env` is the &AtomicUsize given at instantiation.
    unsafe { &*(env as *const std::sync::atomic::AtomicUsize) }.fetch_add(1, std::sync::atomic::Ordering::SeqCst);
}

/// FMI 3.0.2 §2.3.1: "If loggingOn = fmi3False, then any logging is disabled and the logMessage
/// callback function must not be called by the FMU", errors included, until fmi3SetDebugLogging
/// enables categories. (FMI 2.0 reports errors and warnings whatever loggingOn says.) On a plant
/// (both interfaces) and on the controller (Co-Simulation), each refusing a parameter of its own.
#[test]
fn fmi3_logging_off_calls_no_logger_until_enabled() {
    use std::sync::atomic::{AtomicUsize, Ordering::SeqCst};
    for (model, me, positive) in [(0, false, "J_m"), (0, true, "J_m"), (CONTROLLER, false, "h")] {
        let calls = AtomicUsize::new(0);
        let env = &calls as *const AtomicUsize as *mut c_void;
        let token = CString::new(model_at(model).instantiation_token).unwrap();
        // SAFETY: NUL-terminated strings; `calls` outlives the instances (freed below).
        let instantiate = |token: &CStr| unsafe {
            if me {
                fmi3InstantiateModelExchange(
                    c"me".as_ptr(),
                    token.as_ptr(),
                    null(),
                    false,
                    false,
                    env,
                    Some(counting_logger),
                )
            } else {
                // Event Mode and early return where the model has them (not the controller).
                let plant = model != CONTROLLER;
                fmi3InstantiateCoSimulation(
                    c"cs".as_ptr(),
                    token.as_ptr(),
                    null(),
                    false,
                    false,
                    plant,
                    plant,
                    null(),
                    0,
                    env,
                    Some(counting_logger),
                    None,
                )
            }
        };
        assert!(instantiate(c"not a token").is_null());
        let c = instantiate(&token);
        assert!(!c.is_null());
        // An illegal call and a refused value: nothing logged.
        assert_eq!(fmi3ExitInitializationMode(c), ERROR);
        assert_eq!(fmi3Reset(c), OK);
        // SAFETY: arrays of length 1.
        assert_eq!(
            unsafe { fmi3SetFloat64(c, [model_at(model).vr(positive)].as_ptr(), 1, [-1.0].as_ptr(), 1) },
            ERROR
        );
        assert_eq!(calls.load(SeqCst), 0, "the logger was called with loggingOn = false");
        // Enabled for every category: the next refusal is logged.
        assert_eq!(fmi3Reset(c), OK);
        // SAFETY: no categories, NULL as §2.3.1 asks for nCategories = 0.
        assert_eq!(unsafe { fmi3SetDebugLogging(c, true, 0, null()) }, OK);
        assert_eq!(fmi3ExitInitializationMode(c), ERROR);
        assert!(calls.load(SeqCst) > 0, "no reason logged once logging was enabled");
        fmi3FreeInstance(c);
    }
}

// ---------------------------------------------------------------------------------------------
// Fuzz
// ---------------------------------------------------------------------------------------------

struct Prng(u64);

impl Prng {
    fn next(&mut self) -> u64 {
        self.0 ^= self.0 >> 12;
        self.0 ^= self.0 << 25;
        self.0 ^= self.0 >> 27;
        self.0.wrapping_mul(0x2545F4914F6CDD1D)
    }
    fn below(&mut self, n: u64) -> u64 {
        self.next() % n
    }
    fn chance(&mut self, percent: u64) -> bool {
        self.below(100) < percent
    }
    fn real(&mut self) -> f64 {
        const WILD: [f64; 12] = [
            0.0,
            -0.0,
            1e-3,
            1.0,
            -1.0,
            1e300,
            -1e300,
            f64::MAX,
            5e-324,
            f64::NAN,
            f64::INFINITY,
            f64::NEG_INFINITY,
        ];
        if self.chance(70) {
            (self.below(2001) as f64 - 1000.0) / 100.0
        } else {
            WILD[self.below(WILD.len() as u64) as usize]
        }
    }
    fn length(&mut self, n: usize) -> usize {
        if self.chance(80) {
            n
        } else {
            [0, n.saturating_sub(1), n + 1, 1000][self.below(4) as usize]
        }
    }
}

struct Slot {
    f: Inst,
    /// Still in Instantiated as far as we know (reads are illegal there: skip the check).
    fresh: bool,
    time: f64,
    /// Our belief of its state (index into CS_STATES / ME_STATES), to pick the call that moves
    /// it on more often than chance would.
    phase: usize,
}

struct Fuzz {
    rng: Prng,
    slots: Vec<Slot>,
    calls: u64,
    accepted: u64,
    ok_steps: u64,
}

impl Fuzz {
    fn slot(&mut self) -> usize {
        if self.slots.is_empty() || self.slots.len() < 4 && self.rng.chance(3) {
            let me = self.rng.chance(50);
            let model = self.rng.below(MODELS.len() as u64) as usize;
            let event_mode_used = self.rng.chance(50);
            self.slots.push(Slot {
                f: Inst::new(model, me, event_mode_used),
                fresh: true,
                time: 0.0,
                phase: 0,
            });
        }
        if self.slots.len() > 1 && self.rng.chance(1) {
            let i = self.rng.below(self.slots.len() as u64) as usize;
            self.slots.swap_remove(i);
        }
        self.rng.below(self.slots.len() as u64) as usize
    }

    /// An array pointer: NULL now and then (with whatever length was chosen).
    fn ptr<T>(&mut self, v: &mut [T]) -> *mut T {
        if self.rng.chance(5) {
            null_mut()
        } else {
            v.as_mut_ptr()
        }
    }

    fn one(&mut self) {
        let i = self.slot();
        let c = self.slots[i].f.c;
        let model = self.slots[i].f.model;
        let before = self.slots[i].f.log_len();
        let me = self.slots[i].f.me;
        let nx = self.slots[i].f.nx();
        let careful = self.rng.chance(60);
        let op = if careful {
            match (self.slots[i].phase, me) {
                (0, _) => 0,
                (1, _) => 1,
                (2, false) => 3,
                (2, true) => 5,
                (3, false) => [6, 6, 6, 15, 14][self.rng.below(5) as usize],
                (3, true) => [7, 8, 11, 9, 15][self.rng.below(5) as usize],
                _ => 13,
            }
        } else {
            self.rng.below(20)
        };
        let r = &mut self.rng;
        let t = if careful || r.chance(80) {
            self.slots[i].time
        } else {
            r.real()
        };
        let h = if careful || r.chance(80) {
            [1e-4, 1e-3, 1e-2][r.below(3) as usize]
        } else {
            r.real()
        };
        let x = if careful { r.below(11) as f64 - 5.0 } else { r.real() };
        let n_x = r.length(nx);
        let n_i = r.length(ni(model));
        let mut buf = vec![x; 1001];
        let mut vrs: Vec<u32> = MODELS[model].variables.iter().map(|v| v.vr).collect();
        vrs.push(9999);
        let pick = |r: &mut Prng| vrs[r.below(vrs.len() as u64) as usize];
        let vr1 = [pick(&mut self.rng), pick(&mut self.rng)];
        let n_vr = self.rng.length(1);
        let (n_x, n_i, n_vr) = if careful { (nx, ni(model), 1) } else { (n_x, n_i, n_vr) };
        let bp = if careful { buf.as_mut_ptr() } else { self.ptr(&mut buf) };
        let vp = if !careful && self.rng.chance(5) {
            null()
        } else {
            vr1.as_ptr()
        };
        let (mut a, mut b, mut cc, mut d, mut e, mut tt) = (false, false, false, false, false, 0.0);
        let null_out = !careful && self.rng.chance(5);
        macro_rules! out {
            ($v:expr) => {
                if null_out {
                    null_mut()
                } else {
                    &mut $v
                }
            };
        }
        // SAFETY: every pointer is NULL or valid for the largest length passed (1001 values).
        let status = unsafe {
            match op {
                0 => fmi3EnterInitializationMode(c, self.rng.chance(50), h, t, self.rng.chance(50), t + 10.0),
                1 => fmi3ExitInitializationMode(c),
                2 => fmi3EnterEventMode(c),
                3 => fmi3EnterStepMode(c),
                4 => fmi3UpdateDiscreteStates(c, out!(a), &mut b, &mut cc, &mut d, &mut e, &mut tt),
                5 => fmi3EnterContinuousTimeMode(c),
                6 => fmi3DoStep(c, t, h, true, out!(a), &mut b, &mut cc, &mut tt),
                7 => fmi3SetTime(c, t + h.abs().min(1.0)),
                8 => {
                    let mut xs = vec![0.0; nx];
                    fmi3GetContinuousStates(c, xs.as_mut_ptr(), nx);
                    for v in xs.iter_mut() {
                        *v += if careful || self.rng.chance(80) {
                            1e-3 * x.clamp(-1.0, 1.0)
                        } else {
                            x
                        };
                    }
                    let p = if !careful && self.rng.chance(5) {
                        null()
                    } else {
                        xs.as_ptr()
                    };
                    fmi3SetContinuousStates(c, p, n_x.min(nx + 1).min(if p.is_null() { 1000 } else { nx }))
                }
                9 => fmi3GetContinuousStateDerivatives(c, bp, n_x),
                10 => fmi3GetEventIndicators(c, bp, n_i),
                11 => fmi3CompletedIntegratorStep(c, true, out!(a), &mut b),
                12 => fmi3Terminate(c),
                13 => fmi3Reset(c),
                14 => {
                    let n = if careful { n_vr } else { self.rng.length(n_vr) };
                    fmi3GetFloat64(c, vp, n_vr, bp, n)
                }
                15 | 16 => {
                    // Mostly the input, sometimes any variable.
                    let vr = if self.rng.chance(70) {
                        [MODELS[model].vr("tau_m"), vr1[1]]
                    } else {
                        vr1
                    };
                    let vp = if vp.is_null() { null() } else { vr.as_ptr() };
                    let n = if careful { n_vr } else { self.rng.length(n_vr) };
                    fmi3SetFloat64(c, vp, n_vr, bp, n)
                }
                17 => {
                    let mut s = null_mut();
                    let p = if null_out { null_mut() } else { &mut s };
                    let status = fmi3GetFMUState(c, p);
                    if !s.is_null() {
                        fmi3FreeFMUState(c, &mut s);
                    }
                    status
                }
                18 => fmi3GetContinuousStates(c, bp, n_x),
                _ => fmi3GetNominalsOfContinuousStates(c, bp, n_x),
            }
        };
        self.calls += 1;
        let slot = &mut self.slots[i];
        let log = slot.f.since(before);
        let context = format!(
            "call {} op {op} ({}) on {}",
            self.calls,
            if slot.f.me { "ME" } else { "CS" },
            model
        );
        assert!(status != fmi3Status::fmi3Fatal, "{context}: Fatal {log:?}");
        if status == ERROR {
            assert!(!log.is_empty(), "{context}: fmi3Error without a logged reason");
            slot.phase = 5;
            return;
        }
        self.accepted += 1;
        match (op, slot.phase) {
            (0, _) => slot.phase = 1,
            (1, _) => slot.phase = if me || slot.f.event_mode_used { 2 } else { 3 },
            (3 | 5, 2) => slot.phase = 3,
            (2, 3) => slot.phase = 2,
            (12, _) => slot.phase = 4,
            (13, _) => slot.phase = 0,
            _ => {}
        }
        match op {
            0 => slot.fresh = false,
            13 => {
                slot.fresh = true;
                slot.time = 0.0;
            }
            6 if status == OK => {
                slot.time = tt;
                self.ok_steps += 1;
            }
            7 => slot.time = t + h.abs().min(1.0),
            _ => {}
        }
        if op == 0 {
            slot.time = t;
        }
        if !slot.fresh {
            check_all_values(&slot.f, &context);
        }
    }
}

/// Every Float64 variable reads [`admissible`] values (non-NaN, infinite only for bound_sup and
/// bound_T_sup), or the read is refused with a reason.
fn check_all_values(f: &Inst, context: &str) {
    let vars: Vec<_> = MODELS[f.model]
        .variables
        .iter()
        .filter(|v| v.ty == VarType::Real)
        .collect();
    let vrs: Vec<u32> = vars.iter().map(|v| v.vr).collect();
    let mut out = vec![0.0; vrs.len()];
    let before = f.log_len();
    // SAFETY: arrays of the announced lengths.
    let s = unsafe { fmi3GetFloat64(f.c, vrs.as_ptr(), vrs.len(), out.as_mut_ptr(), out.len()) };
    match s {
        OK | fmi3Status::fmi3Warning => {
            for (v, x) in vars.iter().zip(&out) {
                assert!(admissible(v.name, *x), "{context}: {} = {x}", v.name);
            }
        }
        _ => assert!(
            s != fmi3Status::fmi3Fatal && f.log_len() > before,
            "{context}: read refused ({s:?}) without a reason"
        ),
    }
}

#[test]
fn fmi3_fuzz_keeps_the_invariants() {
    let budget = std::env::var("FMI3_FUZZ_SECONDS")
        .ok()
        .and_then(|s| s.parse::<u64>().ok());
    let start = Instant::now();
    let (mut calls, mut accepted, mut steps, mut seeds) = (0, 0, 0, 0);
    let mut seed = 1u64;
    loop {
        let mut fuzz = Fuzz {
            rng: Prng(seed.wrapping_mul(0x9E3779B97F4A7C15) | 1),
            slots: Vec::new(),
            calls: 0,
            accepted: 0,
            ok_steps: 0,
        };
        for _ in 0..400 {
            fuzz.one();
        }
        calls += fuzz.calls;
        accepted += fuzz.accepted;
        steps += fuzz.ok_steps;
        seeds += 1;
        seed += 1;
        let done = match budget {
            Some(s) => start.elapsed() > Duration::from_secs(s),
            None => seeds >= 10,
        };
        if done {
            break;
        }
    }
    println!(
        "{seeds} seeds, {calls} calls ({accepted} accepted, {steps} fmi3DoStep OK) in {:.2?}",
        start.elapsed()
    );
    assert!(accepted > calls / 10, "the sequences must get somewhere");
}

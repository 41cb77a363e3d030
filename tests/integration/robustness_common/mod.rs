//! Shared by the robustness tests: an instance driven only through the C ABI, with a logger
//! that records every message, and the check that a refusal comes with a logged reason.

pub mod fuzz;

use backlash_fmu::ffi::*;
use backlash_fmu::fmu::{served, ModelInfo, MODELS};
use std::ffi::{CStr, CString};
use std::ptr::{null, null_mut};
use std::sync::Mutex;

/// One logger call: status, category, format, message.
#[derive(Clone, Debug)]
pub struct Entry {
    pub status: fmi2Status,
    pub category: String,
    pub format: String,
    pub message: String,
}

pub type Log = Mutex<Vec<Entry>>;

/// The logger with its one variadic argument spelled out. On the Linux x86-64 and AArch64
/// ABIs a variadic call passes these pointer arguments exactly as a fixed-arity call does.
unsafe extern "C" fn record(
    env: fmi2ComponentEnvironment,
    _name: fmi2String,
    status: fmi2Status,
    category: fmi2String,
    format: fmi2String,
    message: fmi2String,
) {
    // SAFETY: `env` is the `Log` passed in `callbacks`, alive as long as its instance; the
    // strings are NUL-terminated for the duration of the call.
    let log = unsafe { &*(env as *const Log) };
    let text = |p: fmi2String| unsafe { CStr::from_ptr(p) }.to_string_lossy().into_owned();
    log.lock().unwrap_or_else(|p| p.into_inner()).push(Entry {
        status,
        category: text(category),
        format: text(format),
        message: text(message),
    });
}

pub fn callbacks(log: *const Log) -> fmi2CallbackFunctions {
    type Fixed =
        unsafe extern "C" fn(fmi2ComponentEnvironment, fmi2String, fmi2Status, fmi2String, fmi2String, fmi2String);
    // SAFETY: see `record`.
    let logger: fmi2CallbackLogger = unsafe { std::mem::transmute::<Fixed, fmi2CallbackLogger>(record) };
    fmi2CallbackFunctions {
        logger: Some(logger),
        allocateMemory: None,
        freeMemory: None,
        stepFinished: None,
        componentEnvironment: log as *mut _,
    }
}

pub const SHAFT: usize = 0;
pub const BELT: usize = 1;
/// BacklashBelt's drive pulling a web span (docs/model.md §8).
pub const WEB: usize = 2;

/// BacklashController, the first controller: Co-Simulation only, no continuous state, no FMU
/// state, one sample per step of its period `h` (docs/model.md §9).
pub const CONTROLLER: usize = MODELS.len();

/// Number of event indicators of `model` in Model Exchange: u ∓ g, the damped force's and the
/// cap's surfaces (docs/model.md §6; a gearbox's per stage, §10), and the bodies' friction
/// surfaces (§12): its continuous locals that are no derivative (the descriptions declare them
/// so, `fmu::variables` tests).
pub fn ni(model: usize) -> usize {
    use backlash_fmu::fmu::variables::{Causality, Variability};
    model_at(model)
        .variables
        .iter()
        .filter(|v| v.causality == Causality::Local && v.variability == Variability::Continuous)
        .filter(|v| v.derivative_of.is_none())
        .count()
}

/// The value reference of the variable `name` of `model`, or on a gearbox (docs/model.md §10),
/// which has a variable per stage where a single gap has one, of its first stage's (`psi` is
/// `psi_1`, `contact` is `contact_1`, `Delta` is `Delta_1`). Panics on a name neither has.
pub fn named(model: &ModelInfo, name: &str) -> u32 {
    match model.by_name(name) {
        Some(v) => v.vr,
        None => model.vr(&format!("{name}_1")),
    }
}

/// Every model the library serves, by index: the plants in the order of `MODELS` (so that
/// [`SHAFT`], [`BELT`], [`WEB`] index both), then the controllers (Co-Simulation only, no
/// continuous state).
pub fn model_at(model: usize) -> &'static ModelInfo {
    served()
        .nth(model)
        .unwrap_or_else(|| panic!("no model {model}: the library serves {}", served().count()))
}

/// Number of continuous states of `model` in Model Exchange: its variables that are the
/// derivative of a state. Four, z = [θ_m, ω_m, θ_L, ω_L]; five in BacklashWeb, whose span's
/// tension T is the fifth (docs/model.md §6).
pub fn nx(model: usize) -> usize {
    model_at(model)
        .variables
        .iter()
        .filter(|v| v.derivative_of.is_some())
        .count()
}

/// The state variables of `model` in the order of its continuous states: that of their
/// derivatives, as `<Derivatives>` lists them.
pub fn state_names(model: usize) -> Vec<&'static str> {
    let m = model_at(model);
    m.variables
        .iter()
        .filter_map(|v| v.derivative_of)
        .map(|of| m.by_vr(of).expect("a derivative names a variable").name)
        .collect()
}

/// Continuous states of `model`: the drive train's `[θ_m, ω_m, θ_L, ω_L]`, then, where the
/// model has a web span, its tension `tension`; a gearbox's intermediate shaft halfway between
/// the motor and the load (angle and speed).
pub fn states(model: usize, drive_train: [f64; 4], tension: f64) -> Vec<f64> {
    let mut x = drive_train.to_vec();
    match state_names(model).as_slice() {
        [_, _, _, _] => {}
        [_, _, _, _, "T"] => x.push(tension),
        ["theta_m", "omega_m", "theta_i", "omega_i", "theta_L", "omega_L"] => {
            let [theta_m, omega_m, theta_l, omega_l] = drive_train;
            x = vec![
                theta_m,
                omega_m,
                (theta_m + theta_l) / 2.0,
                (omega_m + omega_l) / 2.0,
                theta_l,
                omega_l,
            ];
        }
        names => panic!("unexpected continuous states {names:?}"),
    }
    x
}

/// Whether `x` is an admissible value of the variable `name`: never NaN; finite, except for
/// the calculated parameters bound_sup and (BacklashWeb) bound_T_sup, which are +∞ when their
/// loop is not asymptotically stable (docs/model.md §4, §8), and every bound with Coulomb
/// friction (§12).
pub fn admissible(name: &str, x: f64) -> bool {
    x.is_finite() || (x == f64::INFINITY && matches!(name, "bound_sup" | "bound_T_sup" | "bound" | "bound_T"))
}

/// A fresh fmi2EventInfo with every flag set, so that a call that fills it is seen to.
pub fn event_info() -> fmi2EventInfo {
    fmi2EventInfo {
        newDiscreteStatesNeeded: fmi2True,
        terminateSimulation: fmi2True,
        nominalsOfContinuousStatesChanged: fmi2True,
        valuesOfContinuousStatesChanged: fmi2True,
        nextEventTimeDefined: fmi2True,
        nextEventTime: f64::NAN,
    }
}

/// An instance with its own log; freed on drop.
pub struct Fmu {
    pub c: fmi2Component,
    pub model: &'static ModelInfo,
    // Boxed: the logger environment pointer must not move.
    pub log: Box<Log>,
    /// Instantiated as fmi2ModelExchange (else fmi2CoSimulation).
    pub model_exchange: bool,
}

impl Fmu {
    /// A Co-Simulation instance.
    pub fn new(model: usize) -> Fmu {
        Fmu::named(model, "robust")
    }

    /// A Co-Simulation instance named `name`.
    pub fn named(model: usize, name: &str) -> Fmu {
        Fmu::instantiate(model, name, fmi2CoSimulation)
    }

    /// A Model Exchange instance.
    pub fn new_model_exchange(model: usize) -> Fmu {
        Fmu::instantiate(model, "robust ME", fmi2ModelExchange)
    }

    /// An instance of `model` for `fmu_type` (fmi2ModelExchange or fmi2CoSimulation).
    pub fn instantiate(model: usize, name: &str, fmu_type: fmi2Type) -> Fmu {
        let log: Box<Log> = Box::default();
        let info = model_at(model);
        let name = CString::new(name).unwrap();
        let guid = CString::new(info.guid).unwrap();
        let cb = callbacks(&*log);
        // SAFETY: every pointer is a live local; strings are NUL-terminated.
        let c = unsafe {
            fmi2Instantiate(
                name.as_ptr(),
                fmu_type,
                guid.as_ptr(),
                c"file:///tmp/r".as_ptr(),
                &cb,
                fmi2False,
                fmi2False,
            )
        };
        assert!(!c.is_null(), "instantiation of {} failed", info.identifier);
        Fmu {
            c,
            model: info,
            log,
            model_exchange: fmu_type == fmi2ModelExchange,
        }
    }

    /// Instantiated, experiment from 0 with the given stop time, initialized (StepComplete).
    pub fn initialized(model: usize, stop: Option<f64>) -> Fmu {
        let f = Fmu::new(model);
        assert_eq!(
            fmi2SetupExperiment(f.c, 0, 0.0, 0.0, stop.is_some() as i32, stop.unwrap_or(0.0)),
            fmi2Status::fmi2OK
        );
        assert_eq!(fmi2EnterInitializationMode(f.c), fmi2Status::fmi2OK);
        assert_eq!(fmi2ExitInitializationMode(f.c), fmi2Status::fmi2OK);
        f
    }

    /// A Model Exchange instance, experiment from 0 with the given stop time, initialized: in
    /// Event Mode.
    pub fn me_initialized(model: usize, stop: Option<f64>) -> Fmu {
        let f = Fmu::new_model_exchange(model);
        assert_eq!(
            fmi2SetupExperiment(f.c, 0, 0.0, 0.0, stop.is_some() as i32, stop.unwrap_or(0.0)),
            fmi2Status::fmi2OK
        );
        assert_eq!(fmi2EnterInitializationMode(f.c), fmi2Status::fmi2OK);
        assert_eq!(fmi2ExitInitializationMode(f.c), fmi2Status::fmi2OK);
        f
    }

    /// A Model Exchange instance initialized and in Continuous-Time Mode (after one
    /// fmi2NewDiscreteStates that asks for nothing).
    pub fn me_continuous(model: usize) -> Fmu {
        let f = Fmu::me_initialized(model, None);
        let mut info = event_info();
        // SAFETY: pointer to a local.
        assert_eq!(unsafe { fmi2NewDiscreteStates(f.c, &mut info) }, fmi2Status::fmi2OK);
        assert_eq!(info.newDiscreteStatesNeeded, fmi2False);
        assert_eq!(fmi2EnterContinuousTimeMode(f.c), fmi2Status::fmi2OK);
        f
    }

    /// Number of continuous states of its model ([`nx`]).
    pub fn nx(&self) -> usize {
        nx(self.model_index())
    }

    /// fmi2GetContinuousStates into a buffer of nx NaNs.
    pub fn continuous_states(&self) -> (fmi2Status, Vec<f64>) {
        let mut x = vec![f64::NAN; self.nx()];
        // SAFETY: room for x.len() values.
        let s = unsafe { fmi2GetContinuousStates(self.c, x.as_mut_ptr(), x.len()) };
        (s, x)
    }

    /// fmi2SetContinuousStates with all of `x` (its length is the nx passed).
    pub fn set_continuous_states(&self, x: &[f64]) -> fmi2Status {
        // SAFETY: x.len() readable values.
        unsafe { fmi2SetContinuousStates(self.c, x.as_ptr(), x.len()) }
    }

    /// fmi2GetDerivatives into a buffer of nx NaNs.
    pub fn derivatives(&self) -> (fmi2Status, Vec<f64>) {
        let mut dx = vec![f64::NAN; self.nx()];
        // SAFETY: room for dx.len() values.
        let s = unsafe { fmi2GetDerivatives(self.c, dx.as_mut_ptr(), dx.len()) };
        (s, dx)
    }

    /// Number of event indicators of its model ([`ni`]).
    pub fn ni(&self) -> usize {
        ni(self.model_index())
    }

    /// fmi2GetEventIndicators into a buffer of ni NaNs.
    pub fn event_indicators(&self) -> (fmi2Status, Vec<f64>) {
        let mut z = vec![f64::NAN; self.ni()];
        // SAFETY: room for z.len() values.
        let s = unsafe { fmi2GetEventIndicators(self.c, z.as_mut_ptr(), z.len()) };
        (s, z)
    }

    /// fmi2GetNominalsOfContinuousStates into a buffer of nx NaNs.
    pub fn nominals(&self) -> (fmi2Status, Vec<f64>) {
        let mut n = vec![f64::NAN; self.nx()];
        // SAFETY: room for n.len() values.
        let s = unsafe { fmi2GetNominalsOfContinuousStates(self.c, n.as_mut_ptr(), n.len()) };
        (s, n)
    }

    pub fn vr(&self, name: &str) -> u32 {
        named(self.model, name)
    }

    pub fn entries(&self) -> Vec<Entry> {
        self.log.lock().unwrap().clone()
    }

    pub fn log_len(&self) -> usize {
        self.log.lock().unwrap().len()
    }

    pub fn set_real(&self, name: &str, value: f64) -> fmi2Status {
        let vr = [self.vr(name)];
        // SAFETY: arrays of length 1.
        unsafe { fmi2SetReal(self.c, vr.as_ptr(), 1, [value].as_ptr()) }
    }

    pub fn get_real(&self, name: &str) -> (fmi2Status, f64) {
        let vr = [self.vr(name)];
        let mut y = [f64::NAN];
        // SAFETY: arrays of length 1.
        let s = unsafe { fmi2GetReal(self.c, vr.as_ptr(), 1, y.as_mut_ptr()) };
        (s, y[0])
    }

    /// Every Real variable's value (outputs, calculated parameter, parameters, inputs), then
    /// every Integer's (the contact indicator, `contact_law`) as an f64, read in one call each.
    pub fn all_values(&self) -> (fmi2Status, Vec<(&'static str, f64)>) {
        use backlash_fmu::fmu::variables::VarType;
        let of_type = |ty| -> Vec<_> { self.model.variables.iter().filter(|v| v.ty == ty).collect() };
        let (reals, integers) = (of_type(VarType::Real), of_type(VarType::Integer));
        let vrs: Vec<u32> = reals.iter().map(|v| v.vr).collect();
        let mut y = vec![f64::NAN; vrs.len()];
        // SAFETY: both arrays have vrs.len() elements.
        let s = unsafe { fmi2GetReal(self.c, vrs.as_ptr(), vrs.len(), y.as_mut_ptr()) };
        let mut out: Vec<_> = reals.iter().map(|v| v.name).zip(y).collect();
        let vrs: Vec<u32> = integers.iter().map(|v| v.vr).collect();
        let mut k = vec![i32::MIN; vrs.len()];
        // SAFETY: both arrays have vrs.len() elements.
        let s2 = unsafe { fmi2GetInteger(self.c, vrs.as_ptr(), vrs.len(), k.as_mut_ptr()) };
        out.extend(integers.iter().map(|v| v.name).zip(k.into_iter().map(f64::from)));
        (if s2 != fmi2Status::fmi2OK { s2 } else { s }, out)
    }

    /// The value of `name` by the get of its type (an Integer's as an f64).
    pub fn get_value(&self, name: &str) -> (fmi2Status, f64) {
        use backlash_fmu::fmu::variables::VarType;
        match self.model.by_name(name).map(|v| v.ty) {
            Some(VarType::Integer) => {
                let (s, k) = self.get_integer(name);
                (s, k as f64)
            }
            _ => self.get_real(name),
        }
    }

    pub fn set_integer(&self, name: &str, value: i32) -> fmi2Status {
        let vr = [self.vr(name)];
        // SAFETY: arrays of length 1.
        unsafe { fmi2SetInteger(self.c, vr.as_ptr(), 1, [value].as_ptr()) }
    }

    pub fn get_integer(&self, name: &str) -> (fmi2Status, i32) {
        let vr = [self.vr(name)];
        let mut y = [i32::MIN];
        // SAFETY: arrays of length 1.
        let s = unsafe { fmi2GetInteger(self.c, vr.as_ptr(), 1, y.as_mut_ptr()) };
        (s, y[0])
    }

    /// Reads every variable and asserts the read succeeds, every value is [`admissible`] (no
    /// NaN, nothing infinite but bound_sup and bound_T_sup), contact ∈ {−1, 0, 1} and
    /// contact_law ∈ {1, 2}.
    pub fn assert_all_finite(&self, context: &str) {
        let (s, values) = self.all_values();
        assert_eq!(
            s,
            fmi2Status::fmi2OK,
            "{context}: reading all variables failed: {:?}",
            self.entries().last()
        );
        for (name, x) in values {
            assert!(admissible(name, x), "{context}: {name} = {x}");
            if name.starts_with("contact") && name != "contact_law" {
                assert!([-1.0, 0.0, 1.0].contains(&x), "{context}: {name} = {x}");
            }
            if name == "contact_law" {
                assert!([1.0, 2.0].contains(&x), "{context}: contact_law = {x}");
            }
        }
    }

    pub fn time(&self) -> f64 {
        let mut t = f64::NAN;
        // SAFETY: pointer to a local.
        let s = unsafe { fmi2GetRealStatus(self.c, fmi2LastSuccessfulTime, &mut t) };
        assert_eq!(s, fmi2Status::fmi2OK);
        t
    }

    /// Asserts that `status` is a refusal (fmi2Error or fmi2Discard), and that the call logged
    /// exactly one new message in category logErrors with that status, through "%s",
    /// containing `reason`.
    #[track_caller]
    pub fn assert_refused(&self, status: fmi2Status, log_before: usize, reason: &str) {
        assert!(
            matches!(status, fmi2Status::fmi2Error | fmi2Status::fmi2Discard),
            "expected a refusal with reason {reason:?}, got {status:?}"
        );
        let entries = self.entries();
        let new: Vec<_> = entries[log_before..]
            .iter()
            .filter(|e| e.category == "logErrors")
            .collect();
        assert_eq!(
            new.len(),
            1,
            "expected one logged reason containing {reason:?}, got {new:?}"
        );
        let e = new[0];
        assert_eq!(e.status, status, "logged status differs from the returned one: {e:?}");
        assert_eq!(e.format, "%s");
        assert!(
            e.message.to_lowercase().contains(&reason.to_lowercase()),
            "reason {reason:?} not in {:?}",
            e.message
        );
    }

    /// Runs `call`, then asserts it was refused with a logged reason containing `reason`.
    #[track_caller]
    pub fn refuses(&self, reason: &str, call: impl FnOnce(fmi2Component) -> fmi2Status) -> fmi2Status {
        let before = self.log_len();
        let status = call(self.c);
        self.assert_refused(status, before, reason);
        status
    }

    /// Runs `call` on this instance, which must be past initialization (its values readable),
    /// then asserts it was refused with a logged reason containing `reason` and that no value
    /// changed: every variable reads the same bits before and after (fmi2GetXXX stays legal in
    /// state Error; both reads compute the outputs by the same code from the same stored values).
    #[track_caller]
    pub fn refuses_changing_nothing(&self, reason: &str, call: impl FnOnce(fmi2Component) -> fmi2Status) -> fmi2Status {
        let bits = |values: Vec<(&str, f64)>| values.into_iter().map(|(_, x)| x.to_bits()).collect::<Vec<_>>();
        let (s, before) = self.all_values();
        assert_eq!(s, fmi2Status::fmi2OK, "the values before the call");
        let status = self.refuses(reason, call);
        let (s, after) = self.all_values();
        assert_eq!(s, fmi2Status::fmi2OK, "the values after the refusal");
        assert_eq!(bits(before), bits(after), "the refused call changed a value ({reason})");
        status
    }

    /// fmi2Reset, then the standard run (of its interface): the instance must behave like a
    /// new one.
    pub fn reset_and_check(&self) {
        assert_eq!(fmi2Reset(self.c), fmi2Status::fmi2OK);
        if self.model_exchange {
            assert_eq!(standard_me_run_on(self), standard_me_run(self.model_index()));
        } else {
            assert_eq!(standard_run_on(self), standard_run(self.model_index()));
        }
    }

    pub fn model_index(&self) -> usize {
        served().position(|m| std::ptr::eq(m, self.model)).unwrap()
    }
}

impl Drop for Fmu {
    fn drop(&mut self) {
        fmi2FreeInstance(self.c);
    }
}

/// A short open-loop run from the start values (τ_m = 2, τ_L = 0.5, 20 steps of 5 ms), as the
/// bits of every variable at the end; a controller's is [`standard_controller_run_on`]. Used to
/// prove an instance works normally: a fresh one, or one reset after misuse, must reproduce the
/// run of an untouched instance bit for bit (the same calls with the same arguments in one
/// process: the same arithmetic by construction).
pub fn standard_run_on(f: &Fmu) -> Vec<u64> {
    if f.model.is_controller() {
        return standard_controller_run_on(f);
    }
    assert_eq!(fmi2SetupExperiment(f.c, 0, 0.0, 0.0, 0, 0.0), fmi2Status::fmi2OK);
    assert_eq!(fmi2EnterInitializationMode(f.c), fmi2Status::fmi2OK);
    assert_eq!(f.set_real("tau_m", 2.0), fmi2Status::fmi2OK);
    assert_eq!(f.set_real("tau_L", 0.5), fmi2Status::fmi2OK);
    assert_eq!(fmi2ExitInitializationMode(f.c), fmi2Status::fmi2OK);
    let h = 5e-3;
    for k in 0..20 {
        assert_eq!(fmi2DoStep(f.c, k as f64 * h, h, fmi2True), fmi2Status::fmi2OK);
    }
    f.assert_all_finite("standard run");
    let (_, values) = f.all_values();
    assert_momentum_balance(f, &values, 20.0 * h);
    values.into_iter().map(|(_, x)| x.to_bits()).collect()
}

/// A controller's standard run: a step reference of 1 (`reference` = 1, `amplitude` = 1), Kp = 2,
/// Ki = 4, h = 0.25, and a measured speed held at 0.5, for 20 samples. docs/model.md §9 with the
/// tension loop off (Kp_T = Ki_T = 0, its start values): e = 1 − 0.5 = 0.5 at every sample,
/// x_c = k h e = k/8 before sample k, so u_k = Kp e + Ki x_c = 1 + k/2, the torque from the end of
/// step k on, and `tau_m`'s start value before the first step ends. Binary fractions: every value
/// is exact. Returns the bits of every variable at the end, as [`standard_run_on`].
pub fn standard_controller_run_on(f: &Fmu) -> Vec<u64> {
    const OK: fmi2Status = fmi2Status::fmi2OK;
    assert_eq!(fmi2SetupExperiment(f.c, 0, 0.0, 0.0, 0, 0.0), OK);
    assert_eq!(fmi2EnterInitializationMode(f.c), OK);
    assert_eq!(f.set_integer("reference", 1), OK);
    for (name, value) in [("amplitude", 1.0), ("Kp", 2.0), ("Ki", 4.0), ("h", 0.25)] {
        assert_eq!(f.set_real(name, value), OK, "{name}");
    }
    assert_eq!(fmi2ExitInitializationMode(f.c), OK);
    let start = f
        .model
        .by_name("tau_m")
        .and_then(|v| v.start)
        .expect("tau_m has a start value");
    assert_eq!(f.get_real("tau_m"), (OK, start), "before the first step ends");
    assert_eq!(f.set_real("omega_m", 0.5), OK);
    // The tension loop is off: a measured tension changes nothing.
    assert_eq!(f.set_real("T", 7.0), OK);
    for k in 0..20 {
        assert_eq!(fmi2DoStep(f.c, k as f64 * 0.25, 0.25, fmi2True), OK, "sample {k}");
        assert_eq!(f.get_real("tau_m"), (OK, 1.0 + k as f64 / 2.0), "sample {k}");
    }
    assert_eq!(f.time(), 5.0);
    f.assert_all_finite("standard controller run");
    let (_, values) = f.all_values();
    values.into_iter().map(|(_, x)| x.to_bits()).collect()
}

/// The transmission ratios (r_m, r_L) of `model` (docs/model.md §1) from the values of its
/// parameters, read by `at`, through its plant: 1 and 1 on the shaft, R_1 and R_2 R_g2/R_g1 on
/// the belt drives.
pub fn transmission(model: &ModelInfo, at: impl Fn(&str) -> f64) -> (f64, f64) {
    let backlash_fmu::fmu::variables::Kind::Plant(mapping) = model.kind else {
        panic!("{} is no single-gap plant", model.identifier)
    };
    let plant = backlash_fmu::physics::Plant::new(mapping(&at)).expect("a valid plant");
    (plant.r_m(), plant.r_l())
}

/// The momentum balance of a run from rest at θ = 0 (and T = 0) with τ_m = 2, τ_L = 0.5 (and
/// v_in = T_in = 0) for `t` seconds.
pub fn assert_momentum_balance(f: &Fmu, values: &[(&'static str, f64)], t: f64) {
    let at = |name: &str| values.iter().find(|(n, _)| *n == name).map(|(_, x)| *x).unwrap();
    // docs/model.md §1: (J_m ω_m' + b_m ω_m − τ_m)/r_m + (J_L ω_L' + b_L ω_L − τ_L + R_w T)/r_L = 0
    // in every mode (ψ cancels; the web's pull R_w T only where there is a span, §8), so from
    // rest at θ = 0 the integral
    //   (J_m ω_m + b_m θ_m − τ_m t)/r_m + (J_L ω_L + b_L θ_L − τ_L t + R_w ∫T)/r_L
    // stays 0 whatever the contact history: an independent check that the run is physical. The
    // span, L_w T' = EA (R_w ω_L − v_in) + v_ref (T_in − T), gives ∫T = (EA R_w θ_L − L_w T)/v_ref
    // from T = 0 with v_in = T_in = 0.
    if f.model.is_geared() {
        // docs/model.md §10 with a = 1, c = n_j: ψ_1 and ψ_2 cancel in
        // n_1 (J_m ω_m' + b_m ω_m − τ_m) + (J_i ω_i' + b_i ω_i) + (J_L ω_L' + b_L ω_L − τ_L)/n_2 = 0.
        let motor = [at("J_m") * at("omega_m"), at("b_m") * at("theta_m"), -2.0 * t].map(|x| at("n_1") * x);
        let shaft = [at("J_i") * at("omega_i"), at("b_i") * at("theta_i")];
        let load = [at("J_L") * at("omega_L"), at("b_L") * at("theta_L"), -0.5 * t].map(|x| x / at("n_2"));
        let all: Vec<f64> = motor.iter().chain(&shaft).chain(&load).copied().collect();
        let balance: f64 = all.iter().sum();
        let scale: f64 = all.iter().map(|x| x.abs()).sum();
        assert!(
            balance.abs() <= 1e-9 * scale,
            "momentum balance violated: {balance:e} (scale {scale:e}) in {values:?}"
        );
        assert!(at("theta_m") > 0.0, "the motor did not turn: {values:?}");
        return;
    }
    let (r_m, r_l) = transmission(f.model, at);
    let motor = [at("J_m") * at("omega_m"), at("b_m") * at("theta_m"), -2.0 * t];
    let mut load = vec![at("J_L") * at("omega_L"), at("b_L") * at("theta_L"), -0.5 * t];
    if f.model.web {
        assert_eq!((at("v_in"), at("T_in")), (0.0, 0.0), "the span's inputs at rest");
        let r_w_over_v_ref = at("R_w") / at("v_ref");
        load.push(r_w_over_v_ref * at("EA") * at("R_w") * at("theta_L"));
        load.push(-r_w_over_v_ref * at("L_w") * at("T"));
    }
    let balance = motor.iter().sum::<f64>() / r_m + load.iter().sum::<f64>() / r_l;
    let scale = motor.iter().map(|x| x.abs()).sum::<f64>() / r_m + load.iter().map(|x| x.abs()).sum::<f64>() / r_l;
    assert!(
        balance.abs() <= 1e-9 * scale,
        "momentum balance violated: {balance:e} (scale {scale:e}) in {values:?}"
    );
    // (Not ω_m > 0: a web span pulling back makes the drive oscillate.)
    assert!(at("theta_m") > 0.0, "the motor did not turn: {values:?}");
}

/// A fresh initialized instance of `model` (StepComplete) for one refused call, since a refusal
/// puts it in state Error: the call is refused with `reason` and changes nothing
/// ([`Fmu::refuses_changing_nothing`]), and fmi2Reset gives a working instance.
#[track_caller]
pub fn refused_in_step_complete(model: usize, reason: &str, call: impl FnOnce(fmi2Component) -> fmi2Status) {
    let f = Fmu::initialized(model, None);
    f.refuses_changing_nothing(reason, call);
    f.reset_and_check();
}

/// The standard run on a brand-new instance.
pub fn standard_run(model: usize) -> Vec<u64> {
    let f = Fmu::new(model);
    standard_run_on(&f)
}

/// A fresh instance works normally after whatever came before: same bits as a second fresh one
/// (both runs happen now, so this also catches state shared between instances).
pub fn fresh_instance_works(model: usize) {
    let a = standard_run(model);
    let b = standard_run(model);
    assert_eq!(a, b);
}

/// The standard run as a Model Exchange importer does it, on an instance just instantiated or
/// reset: the same experiment and inputs, integrated over the same 0.1 s by classical
/// Runge-Kutta (step 0.2/ω₀, ω₀ the contact frequency, read from the nominals: ω_m's nominal
/// over θ_m's) through fmi2SetTime, fmi2SetContinuousStates, fmi2GetDerivatives and
/// fmi2CompletedIntegratorStep, with an event iteration whenever an event indicator changes
/// sign. Runge-Kutta keeps linear invariants, so the momentum balance holds as in the
/// Co-Simulation run. Returns the bits of every variable at the end (compared bit for bit, as
/// [`standard_run_on`]'s: the same calls, the same arithmetic).
pub fn standard_me_run_on(f: &Fmu) -> Vec<u64> {
    assert!(f.model_exchange, "a Model Exchange instance");
    const OK: fmi2Status = fmi2Status::fmi2OK;
    let (s, nominal) = f.nominals();
    assert_eq!(s, OK, "nominals in Instantiated");
    assert!(nominal.iter().all(|x| x.is_finite() && *x > 0.0), "{nominal:?}");
    assert_eq!(fmi2SetupExperiment(f.c, 0, 0.0, 0.0, 0, 0.0), OK);
    assert_eq!(fmi2EnterInitializationMode(f.c), OK);
    assert_eq!(f.set_real("tau_m", 2.0), OK);
    assert_eq!(f.set_real("tau_L", 0.5), OK);
    assert_eq!(fmi2ExitInitializationMode(f.c), OK);
    let event_iteration = || {
        let mut info = event_info();
        // SAFETY: pointer to a local.
        assert_eq!(unsafe { fmi2NewDiscreteStates(f.c, &mut info) }, OK);
        assert_eq!(
            (
                info.newDiscreteStatesNeeded,
                info.terminateSimulation,
                info.nominalsOfContinuousStatesChanged,
                info.valuesOfContinuousStatesChanged,
                info.nextEventTimeDefined
            ),
            (fmi2False, fmi2False, fmi2False, fmi2False, fmi2False)
        );
        assert_eq!(fmi2EnterContinuousTimeMode(f.c), OK);
    };
    event_iteration();
    let omega0 = nominal[1] / nominal[0];
    let end = 0.1;
    let steps = (end * omega0 / 0.2).ceil().max(20.0) as usize;
    let h = end / steps as f64;
    let rates = |t: f64, x: &[f64]| {
        assert_eq!(fmi2SetTime(f.c, t), OK);
        assert_eq!(f.set_continuous_states(x), OK);
        let (s, dx) = f.derivatives();
        assert_eq!(s, OK);
        assert!(dx.iter().all(|d| d.is_finite()), "{dx:?}");
        dx
    };
    let (s, mut x) = f.continuous_states();
    assert_eq!(s, OK);
    let (s, mut indicators) = f.event_indicators();
    assert_eq!(s, OK);
    for k in 0..steps {
        let t = k as f64 * h;
        let k1 = rates(t, &x);
        // x + c k, componentwise.
        let along = |c: f64, k: &[f64]| -> Vec<f64> { x.iter().zip(k).map(|(x, k)| x + c * k).collect() };
        let k2 = rates(t + h / 2.0, &along(h / 2.0, &k1));
        let k3 = rates(t + h / 2.0, &along(h / 2.0, &k2));
        let k4 = rates(t + h, &along(h, &k3));
        x = (0..x.len())
            .map(|i| x[i] + h / 6.0 * (k1[i] + 2.0 * k2[i] + 2.0 * k3[i] + k4[i]))
            .collect();
        assert_eq!(fmi2SetTime(f.c, (k + 1) as f64 * h), OK);
        assert_eq!(f.set_continuous_states(&x), OK);
        let (mut enter, mut terminate) = (fmi2True, fmi2True);
        // SAFETY: pointers to locals.
        assert_eq!(
            unsafe { fmi2CompletedIntegratorStep(f.c, fmi2True, &mut enter, &mut terminate) },
            OK
        );
        assert_eq!((enter, terminate), (fmi2False, fmi2False));
        let (s, now) = f.event_indicators();
        assert_eq!(s, OK);
        if now.iter().zip(&indicators).any(|(a, b)| (*a > 0.0) != (*b > 0.0)) {
            assert_eq!(fmi2EnterEventMode(f.c), OK);
            event_iteration();
        }
        indicators = now;
    }
    f.assert_all_finite("standard Model Exchange run");
    let (_, values) = f.all_values();
    assert_momentum_balance(f, &values, end);
    assert_eq!(fmi2Terminate(f.c), OK);
    values.into_iter().map(|(_, x)| x.to_bits()).collect()
}

/// The standard Model Exchange run on a brand-new instance.
pub fn standard_me_run(model: usize) -> Vec<u64> {
    let f = Fmu::new_model_exchange(model);
    standard_me_run_on(&f)
}

/// As [`fresh_instance_works`], for Model Exchange instances.
pub fn fresh_me_instance_works(model: usize) {
    let a = standard_me_run(model);
    let b = standard_me_run(model);
    assert_eq!(a, b);
}

/// [`fresh_instance_works`] and [`fresh_me_instance_works`] for every model.
pub fn fresh_instances_of_every_model_work() {
    for model in 0..MODELS.len() {
        fresh_instance_works(model);
        fresh_me_instance_works(model);
    }
}

// ---- FMU states as bytes (format documented in src/fmu/snapshot.rs) ----

/// fmi2GetFMUstate + serialize; the state is freed again.
pub fn serialized(f: &Fmu) -> Vec<u8> {
    let mut s: fmi2FMUstate = null_mut();
    // SAFETY: pointers to locals and a buffer of the size the FMU reported.
    unsafe {
        assert_eq!(fmi2GetFMUstate(f.c, &mut s), fmi2Status::fmi2OK);
        let mut size = 0;
        assert_eq!(fmi2SerializedFMUstateSize(f.c, s, &mut size), fmi2Status::fmi2OK);
        let mut bytes = vec![0u8; size];
        assert_eq!(
            fmi2SerializeFMUstate(f.c, s, bytes.as_mut_ptr().cast(), size),
            fmi2Status::fmi2OK
        );
        assert_eq!(fmi2FreeFMUstate(f.c, &mut s), fmi2Status::fmi2OK);
        bytes
    }
}

/// FNV-1a 64, the checksum of the byte format.
pub fn fnv1a_64(bytes: &[u8]) -> u64 {
    let mut hash: u64 = 0xcbf29ce484222325;
    for b in bytes {
        hash ^= *b as u64;
        hash = hash.wrapping_mul(0x100000001b3);
    }
    hash
}

/// Recomputes the trailing checksum after a deliberate edit, so that the edit reaches the
/// field checks behind the checksum.
pub fn reseal(bytes: &mut [u8]) {
    let n = bytes.len() - 8;
    let sum = fnv1a_64(&bytes[..n]);
    bytes[n..].copy_from_slice(&sum.to_le_bytes());
}

/// Offset of the phase byte: after magic (8), version (2), guid length (2) and the guid.
pub fn phase_offset(bytes: &[u8]) -> usize {
    12 + u16::from_le_bytes([bytes[10], bytes[11]]) as usize
}

/// Offset of the first f64 of the plant state (θ_m, ω_m, θ_L, ω_L, T, u, u', V).
pub fn plant_offset(bytes: &[u8]) -> usize {
    phase_offset(bytes) + 4 + 8 * 4 + 8 * backlash_fmu::fmu::Symbol::COUNT + 8 * 4
}

/// Number of f64 of the bound part of an FMU state of `model` (format in src/fmu/snapshot.rs):
/// 42 for a drive train's bound and its two bodies' friction terms, 36 for the web line's two,
/// 90 for a gearbox's two stages and three bodies.
pub fn bound_words(model: &ModelInfo) -> usize {
    match (model.web, model.is_geared()) {
        (_, true) => 90,
        (true, false) => 36,
        (false, false) => 42,
    }
}

/// The model whose guid an FMU state's bytes carry.
pub fn model_of_state(bytes: &[u8]) -> &'static ModelInfo {
    let guid = &bytes[12..phase_offset(bytes)];
    MODELS
        .iter()
        .find(|m| m.guid.as_bytes() == guid)
        .expect("the bytes of a state of one of the models")
}

/// Offset of the contact-mode byte of a state: counted from the end, before the bodies'
/// friction modes (two bytes), the bound part ([`bound_words`] f64), the bounds' lag (one f64),
/// the bound's terms gathered at events (five), the time marks (three) and the checksum (8
/// bytes).
pub fn mode_offset(bytes: &[u8]) -> usize {
    bound_offset(bytes) - 2 - 1
}

/// Offset of the bound part, after the contact mode and the two friction modes.
pub fn bound_offset(bytes: &[u8]) -> usize {
    lag_offset(bytes) - 8 * bound_words(model_of_state(bytes))
}

/// Offset of the bounds' lag behind the plant, the f64 before the bound's terms gathered at
/// events.
pub fn lag_offset(bytes: &[u8]) -> usize {
    events_offset(bytes) - 8
}

/// Offset of the damped bound's terms gathered at events (five f64: tracked, the phase's mode,
/// u at its start, Σ|Δu| over slack and capped phases, phases in the gap), before the marks.
pub fn events_offset(bytes: &[u8]) -> usize {
    marks_offset(bytes) - 8 * 5
}

/// Offset of the time marks (the times of the second-last and the last completed integrator
/// step, and of the last event: three f64), the last field before the checksum.
pub fn marks_offset(bytes: &[u8]) -> usize {
    bytes.len() - 8 - 8 * 3
}

/// fmi2DeSerializeFMUstate + fmi2SetFMUstate: (status of deserialize, status of set).
pub fn load(f: &Fmu, bytes: &[u8]) -> (fmi2Status, fmi2Status) {
    let mut s: fmi2FMUstate = null_mut();
    // SAFETY: `bytes` has the announced length; `s` is a local.
    unsafe {
        let d = fmi2DeSerializeFMUstate(f.c, bytes.as_ptr().cast(), bytes.len(), &mut s);
        if d != fmi2Status::fmi2OK {
            return (d, d);
        }
        let set = fmi2SetFMUstate(f.c, s);
        fmi2FreeFMUstate(f.c, &mut s);
        (d, set)
    }
}

/// An instance put into state StepFailed, which no call of this FMU enters by itself (every
/// step completes or fails with fmi2Error): through an FMU state whose phase byte says so.
pub fn in_step_failed(model: usize) -> Fmu {
    let donor = Fmu::initialized(model, None);
    assert_eq!(fmi2DoStep(donor.c, 0.0, 1e-3, 1), fmi2Status::fmi2OK);
    let mut bytes = serialized(&donor);
    let at = phase_offset(&bytes);
    bytes[at] = 3; // StepFailed in the documented numbering
    reseal(&mut bytes);
    let f = Fmu::new(model);
    assert_eq!(load(&f, &bytes), (fmi2Status::fmi2OK, fmi2Status::fmi2OK));
    f
}

//! A panic anywhere inside an export is caught at the C boundary (`ffi::guard::guard`, the
//! one guard every export runs through): fmi2Error, the reason logged, the instance left in
//! state Error until fmi2Reset, and other instances untouched.

use crate::robustness_common::*;
use backlash_fmu::ffi::guard::guard;
use backlash_fmu::ffi::*;
use backlash_fmu::fmu::{Function, Status};

const OK: fmi2Status = fmi2Status::fmi2OK;
const ERROR: fmi2Status = fmi2Status::fmi2Error;

fn quiet_panics() {
    // The default hook would print a backtrace line for each deliberate panic.
    static ONCE: std::sync::Once = std::sync::Once::new();
    ONCE.call_once(|| {
        let default = std::panic::take_hook();
        std::panic::set_hook(Box::new(move |info| {
            let deliberate = info
                .payload()
                .downcast_ref::<&str>()
                .is_some_and(|s| s.starts_with("deliberate"))
                || info
                    .payload()
                    .downcast_ref::<String>()
                    .is_some_and(|s| s.starts_with("deliberate"))
                || info.payload().downcast_ref::<i32>().is_some();
            if !deliberate {
                default(info)
            }
        }));
    });
}

#[test]
fn a_panic_in_any_function_and_any_state_is_caught_and_leaves_error() {
    quiet_panics();
    // Functions legal in the chosen state, so the panic happens inside the work itself.
    let cases = [
        (Function::SetupExperiment, "Instantiated"),
        (Function::EnterInitializationMode, "Instantiated"),
        (Function::SetReal, "InitializationMode"),
        (Function::ExitInitializationMode, "InitializationMode"),
        (Function::DoStep, "StepComplete"),
        (Function::GetReal, "StepComplete"),
        (Function::GetFmuState, "StepComplete"),
        (Function::DeSerializeFmuState, "StepComplete"),
        (Function::GetRealOutputDerivatives, "Terminated"),
        (Function::SetDebugLogging, "Terminated"),
    ];
    let other = Fmu::initialized(BELT, None);
    let twin = Fmu::initialized(BELT, None);
    for (k, (function, phase)) in cases.into_iter().enumerate() {
        let f = Fmu::new(SHAFT);
        if phase != "Instantiated" {
            assert_eq!(fmi2EnterInitializationMode(f.c), OK);
        }
        if phase == "StepComplete" || phase == "Terminated" {
            assert_eq!(fmi2ExitInitializationMode(f.c), OK);
        }
        if phase == "Terminated" {
            assert_eq!(fmi2Terminate(f.c), OK);
        }
        let before = f.log_len();
        // Three payload types: &str, String, and a non-text payload.
        let status = match k % 3 {
            0 => guard(f.c, function, |_| -> Result<Status, _> { panic!("deliberate {k}") }),
            1 => guard(f.c, function, |_| -> Result<Status, _> {
                std::panic::panic_any(format!("deliberate {k}"))
            }),
            _ => guard(f.c, function, |_| -> Result<Status, _> { std::panic::panic_any(7i32) }),
        };
        let reason = match k % 3 {
            0 | 1 => format!("internal error in {}: deliberate {k}", function.c_name()),
            _ => "panic with a non-text payload".to_string(),
        };
        f.assert_refused(status, before, &reason);
        assert_eq!(status, ERROR);
        f.refuses("not allowed in state Error", |c| fmi2EnterInitializationMode(c));
        // Values stay readable in Error (they are for debugging), and fmi2Reset recovers.
        f.reset_and_check();
        // Another instance stepping alongside is untouched: it matches its twin bit for bit (the
        // same calls with the same arguments: the same arithmetic by construction).
        let t = k as f64 * 1e-3;
        assert_eq!(fmi2DoStep(other.c, t, 1e-3, 1), OK);
        assert_eq!(fmi2DoStep(twin.c, t, 1e-3, 1), OK);
        let bits = |f: &Fmu| f.all_values().1.iter().map(|(_, x)| x.to_bits()).collect::<Vec<_>>();
        assert_eq!(bits(&other), bits(&twin));
    }
    fresh_instance_works(SHAFT);
}

#[test]
fn a_panic_without_a_logger_is_still_caught() {
    quiet_panics();
    let guid = std::ffi::CString::new(backlash_fmu::fmu::MODELS[0].guid).unwrap();
    let cb = fmi2CallbackFunctions {
        logger: None,
        allocateMemory: None,
        freeMemory: None,
        stepFinished: None,
        componentEnvironment: std::ptr::null_mut(),
    };
    // SAFETY: NUL-terminated strings and a live callback struct.
    let c = unsafe {
        fmi2Instantiate(
            c"q".as_ptr(),
            fmi2CoSimulation,
            guid.as_ptr(),
            std::ptr::null(),
            &cb,
            0,
            1,
        )
    };
    assert!(!c.is_null());
    let status = guard(c, Function::EnterInitializationMode, |_| -> Result<Status, _> {
        panic!("deliberate, no logger")
    });
    assert_eq!(status, ERROR);
    assert_eq!(fmi2EnterInitializationMode(c), ERROR, "state Error");
    assert_eq!(fmi2Reset(c), OK);
    assert_eq!(fmi2EnterInitializationMode(c), OK);
    assert_eq!(fmi2ExitInitializationMode(c), OK);
    assert_eq!(fmi2DoStep(c, 0.0, 1e-3, 1), OK);
    fmi2FreeInstance(c);
}

#[test]
fn a_panic_in_a_model_exchange_function_is_caught_and_leaves_error() {
    quiet_panics();
    // Model Exchange functions in states where they are legal, so the panic happens inside
    // the work itself.
    let cases = [
        (Function::GetNominalsOfContinuousStates, "Instantiated"),
        (Function::SetTime, "ContinuousTimeMode"),
        (Function::NewDiscreteStates, "EventMode"),
        (Function::EnterContinuousTimeMode, "EventMode"),
        (Function::SetContinuousStates, "ContinuousTimeMode"),
        (Function::GetDerivatives, "ContinuousTimeMode"),
        (Function::GetEventIndicators, "ContinuousTimeMode"),
        (Function::GetContinuousStates, "ContinuousTimeMode"),
        (Function::CompletedIntegratorStep, "ContinuousTimeMode"),
        (Function::EnterEventMode, "ContinuousTimeMode"),
        (Function::GetDirectionalDerivative, "Terminated"),
    ];
    // Bystanders of another model with another number of continuous states.
    let other = Fmu::me_continuous(WEB);
    let twin = Fmu::me_continuous(WEB);
    for (k, (function, phase)) in cases.into_iter().enumerate() {
        let f = match phase {
            "Instantiated" => Fmu::new_model_exchange(SHAFT),
            "EventMode" => Fmu::me_initialized(SHAFT, None),
            "ContinuousTimeMode" => Fmu::me_continuous(SHAFT),
            _ => {
                let f = Fmu::me_continuous(SHAFT);
                assert_eq!(fmi2Terminate(f.c), OK);
                f
            }
        };
        let before = f.log_len();
        let status = guard(f.c, function, |_| -> Result<Status, _> { panic!("deliberate ME {k}") });
        f.assert_refused(
            status,
            before,
            &format!("internal error in {}: deliberate ME {k}", function.c_name()),
        );
        assert_eq!(status, ERROR);
        f.refuses("not allowed in state Error", |c| fmi2EnterEventMode(c));
        f.assert_all_finite(&format!("after a panic in {}", function.c_name()));
        f.reset_and_check();
        // Another instance integrating alongside is untouched: it matches its twin bit for bit
        // (the same calls with the same arguments: the same arithmetic by construction).
        let x = states(WEB, [1e-4 * k as f64, 0.1, 0.0, 0.05], 5.0 * k as f64);
        for g in [&other, &twin] {
            assert_eq!(fmi2SetTime(g.c, 0.01 * k as f64), OK);
            assert_eq!(g.set_continuous_states(&x), OK);
        }
        let bits = |f: &Fmu| f.all_values().1.iter().map(|(_, x)| x.to_bits()).collect::<Vec<_>>();
        assert_eq!(bits(&other), bits(&twin));
        assert_eq!(other.derivatives(), twin.derivatives());
    }
    fresh_me_instance_works(SHAFT);
}

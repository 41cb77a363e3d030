//! The C ABI called directly through the rlib: instantiation refusals, the "%s" logger, NULL
//! arrays, stale pointers and panics (FMU states through bytes: `crate::fmu_state::c_abi`).

use backlash_fmu::ffi::guard::guard;
use backlash_fmu::ffi::*;
use backlash_fmu::fmu::{Function, MODELS};
use std::ffi::{CStr, CString};
use std::ptr::{null, null_mut};

use crate::robustness_common::{callbacks, Log};

pub(crate) fn instantiate(log: &Log, name: &str, kind: fmi2Type, guid: &str) -> fmi2Component {
    // SAFETY: every pointer passed points to a live local of the announced length, and
    // every string is NUL-terminated.
    unsafe {
        let name = CString::new(name).unwrap();
        let guid = CString::new(guid).unwrap();
        let resources = c"file:///tmp/with%20space/resources";
        let cb = callbacks(log);
        fmi2Instantiate(
            name.as_ptr(),
            kind,
            guid.as_ptr(),
            resources.as_ptr(),
            &cb,
            fmi2False,
            fmi2False,
        )
    }
}

pub(crate) fn messages(log: &Log) -> Vec<String> {
    log.lock().unwrap().iter().map(|e| e.message.clone()).collect()
}

#[test]
fn instantiate_refuses_what_it_cannot_serve_and_says_why() {
    // SAFETY: every pointer passed points to a live local of the announced length, and
    // every string is NUL-terminated.
    unsafe {
        let log = Log::default();
        let shaft = MODELS[0].guid;
        assert!(instantiate(&log, "x", 7, shaft).is_null());
        assert!(instantiate(&log, "   ", fmi2CoSimulation, shaft).is_null());
        assert!(instantiate(&log, "x", fmi2CoSimulation, "{00000000-0000-0000-0000-000000000000}").is_null());
        let m = messages(&log);
        assert_eq!(m.len(), 3);
        assert!(
            m[0].contains("neither fmi2ModelExchange nor fmi2CoSimulation")
                && m[1].contains("blank")
                && m[2].contains("fmuGUID"),
            "{m:?}"
        );
        assert!(log
            .lock()
            .unwrap()
            .iter()
            .all(|e| e.status == fmi2Status::fmi2Error && e.format == "%s"));

        let cb = callbacks(&log);
        let guid = CString::new(shaft).unwrap();
        assert!(fmi2Instantiate(null(), fmi2CoSimulation, guid.as_ptr(), null(), &cb, 0, 0).is_null());
        assert!(fmi2Instantiate(c"x".as_ptr(), fmi2CoSimulation, null(), null(), &cb, 0, 0).is_null());
        assert!(fmi2Instantiate(c"x".as_ptr(), fmi2CoSimulation, guid.as_ptr(), null(), null(), 0, 0).is_null());
        // A NULL logger is no logging, not a crash.
        let quiet = fmi2CallbackFunctions { logger: None, ..cb };
        let c = fmi2Instantiate(c"x".as_ptr(), fmi2CoSimulation, guid.as_ptr(), null(), &quiet, 0, 1);
        assert!(!c.is_null());
        assert_eq!(fmi2DoStep(c, 0.0, 1.0, 1), fmi2Status::fmi2Error);
        fmi2FreeInstance(c);
    }
}

#[test]
fn a_full_run_through_the_c_functions() {
    // SAFETY: every pointer passed points to a live local of the announced length, and
    // every string is NUL-terminated.
    unsafe {
        let log = Log::default();
        let c = instantiate(&log, "belt 1", fmi2CoSimulation, MODELS[1].guid);
        assert!(!c.is_null());
        assert_eq!(CStr::from_ptr(fmi2GetVersion()), c"2.0");
        assert_eq!(CStr::from_ptr(fmi2GetTypesPlatform()), c"default");
        let tau = [MODELS[1].vr("tau_m")];
        assert_eq!(fmi2SetupExperiment(c, 0, 0.0, 0.0, 1, 0.01), fmi2Status::fmi2OK);
        assert_eq!(fmi2EnterInitializationMode(c), fmi2Status::fmi2OK);
        assert_eq!(fmi2SetReal(c, tau.as_ptr(), 1, [0.02].as_ptr()), fmi2Status::fmi2OK);
        assert_eq!(fmi2ExitInitializationMode(c), fmi2Status::fmi2OK);
        let mut t = 0.0;
        for _ in 0..100 {
            assert_eq!(fmi2DoStep(c, t, 1e-4, 1), fmi2Status::fmi2OK);
            t += 1e-4;
        }
        let vrs = [MODELS[1].vr("omega_m"), MODELS[1].vr("bound")];
        let mut y = [0.0; 2];
        assert_eq!(fmi2GetReal(c, vrs.as_ptr(), 2, y.as_mut_ptr()), fmi2Status::fmi2OK);
        assert!(y[0] > 0.0 && y[1] > 0.0, "{y:?}");
        // Zero-length arrays may be NULL; announced values may not.
        assert_eq!(fmi2GetReal(c, null(), 0, null_mut()), fmi2Status::fmi2OK);
        let mut status = fmi2Status::fmi2Error;
        assert_eq!(fmi2GetStatus(c, fmi2DoStepStatus, &mut status), fmi2Status::fmi2OK);
        assert_eq!(status, fmi2Status::fmi2OK);
        let mut last = 0.0;
        assert_eq!(
            fmi2GetRealStatus(c, fmi2LastSuccessfulTime, &mut last),
            fmi2Status::fmi2OK
        );
        // The FMU's time is communicationPoint + stepSize: the same sums as `t += 1e-4`.
        assert_eq!(last, t);
        assert_eq!(
            fmi2GetIntegerStatus(c, fmi2DoStepStatus, &mut 0),
            fmi2Status::fmi2Discard
        );
        // The stop time 0.01 is reached: one more step is an error.
        assert_eq!(fmi2DoStep(c, t, 1e-4, 1), fmi2Status::fmi2Error);
        assert!(messages(&log).last().unwrap().contains("stopTime"));
        assert_eq!(fmi2GetReal(c, null(), 2, y.as_mut_ptr()), fmi2Status::fmi2Error);
        assert!(messages(&log).last().unwrap().contains("argument vr is NULL"));
        assert_eq!(fmi2Reset(c), fmi2Status::fmi2OK);
        assert_eq!(fmi2SetTime(c, 0.0), fmi2Status::fmi2Error);
        assert!(messages(&log).last().unwrap().contains("Model Exchange"));
        fmi2FreeInstance(c);
        // A freed instance is refused, and freeing twice is harmless.
        assert_eq!(fmi2Reset(c), fmi2Status::fmi2Error);
        fmi2FreeInstance(c);
        assert_eq!(fmi2Terminate(null_mut()), fmi2Status::fmi2Error);
    }
}

#[test]
fn messages_go_through_percent_s() {
    // SAFETY: every pointer passed points to a live local of the announced length, and
    // every string is NUL-terminated.
    unsafe {
        let log = Log::default();
        let c = instantiate(&log, "s", fmi2CoSimulation, MODELS[0].guid);
        let name = c"log%s%n%d";
        assert_eq!(
            fmi2SetDebugLogging(c, 1, 1, [name.as_ptr()].as_ptr()),
            fmi2Status::fmi2Error
        );
        let last = log.lock().unwrap().last().cloned().unwrap();
        assert_eq!((last.category.as_str(), last.format.as_str()), ("logErrors", "%s"));
        assert!(last.message.contains("\"log%s%n%d\""), "{}", last.message);
        fmi2FreeInstance(c);
    }
}

#[test]
fn a_panic_inside_a_call_leaves_the_instance_in_error() {
    let log = Log::default();
    let c = instantiate(&log, "p", fmi2CoSimulation, MODELS[0].guid);
    let status = guard(c, Function::SetupExperiment, |_| panic!("deliberate"));
    assert_eq!(status, fmi2Status::fmi2Error);
    assert!(messages(&log).last().unwrap().contains("deliberate"));
    assert_eq!(fmi2EnterInitializationMode(c), fmi2Status::fmi2Error, "state Error");
    assert_eq!(fmi2Reset(c), fmi2Status::fmi2OK);
    assert_eq!(fmi2EnterInitializationMode(c), fmi2Status::fmi2OK);
    fmi2FreeInstance(c);
}

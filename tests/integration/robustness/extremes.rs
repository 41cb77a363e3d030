//! Finite but extreme parameters, inputs and start values (f64::MAX, 1e300, 1e-300, the
//! smallest subnormal): each is either served with finite outputs or refused with a logged
//! reason, and no call may hang. Every case runs on its own thread with a deadline; a thread
//! stuck in a hung call is abandoned, and dies with the test process.

use crate::robustness_common::*;
use backlash_fmu::ffi::*;
use backlash_fmu::fmu::MODELS;
use std::sync::mpsc;
use std::time::Duration;

const OK: fmi2Status = fmi2Status::fmi2OK;

/// Far above the slowest case measured (under 1 s for b_m = 5e-324 with opt-level 2).
const DEADLINE: Duration = Duration::from_secs(10);

/// Sets `name = x` before initialization, initializes and steps 1 ms, 0.1 s, 1 s.
fn extreme_case(model: usize, name: &'static str, x: f64) {
    let m = &MODELS[model];
    let f = Fmu::new(model);
    assert_eq!(f.set_real(name, x), OK, "{name} = {x}");
    let before = f.log_len();
    assert_eq!(fmi2EnterInitializationMode(f.c), OK);
    let exit = fmi2ExitInitializationMode(f.c);
    let context = format!("{} {name} = {x:e}", m.identifier);
    match exit {
        OK | fmi2Status::fmi2Warning => {
            f.assert_all_finite(&context);
            let mut t = 0.0;
            for h in [1e-3, 0.1, 1.0] {
                let before = f.log_len();
                match fmi2DoStep(f.c, t, h, 1) {
                    OK => {
                        t += h;
                        f.assert_all_finite(&format!("{context}, step to {t}"));
                    }
                    s => {
                        f.assert_refused(s, before, "");
                        f.assert_all_finite(&format!("{context}, after a refused step"));
                        break;
                    }
                }
            }
        }
        s => f.assert_refused(s, before, ""),
    }
}

#[test]
fn extreme_finite_values_give_finite_outputs_or_a_reason_without_hanging() {
    let extreme = [f64::MAX, -f64::MAX, 1e300, 1e-300, 5e-324];
    for (model, m) in MODELS.iter().enumerate() {
        for v in m.variables.iter().filter(|v| v.start.is_some()) {
            for x in extreme.into_iter().filter(|x| v.range.admits(*x)) {
                let (done, wait) = mpsc::channel();
                let name = v.name;
                std::thread::spawn(move || {
                    let outcome = std::panic::catch_unwind(|| extreme_case(model, name, x));
                    let _ = done.send(outcome.map_err(|e| {
                        e.downcast_ref::<String>()
                            .cloned()
                            .or(e.downcast_ref::<&str>().map(|s| s.to_string()))
                    }));
                });
                match wait.recv_timeout(DEADLINE) {
                    Ok(Ok(())) => {}
                    Ok(Err(message)) => panic!("{} {name} = {x:e}: {message:?}", m.identifier),
                    Err(_) => panic!(
                        "{} {name} = {x:e}: initialization or a step did not return within {DEADLINE:?} (a hang)",
                        m.identifier
                    ),
                }
            }
        }
    }
    for model in 0..MODELS.len() {
        fresh_instance_works(model);
    }
}

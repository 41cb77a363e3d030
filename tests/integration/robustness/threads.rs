//! Instances used from many threads at once (each instance by one thread at a time, as FMI
//! 2.0 §2.1.5 requires) give bit-identical results to the same runs done one after another:
//! the live-instance table, the FMU-state table and the shared cache of built plants must
//! neither corrupt nor couple instances, of either interface. Bit for bit is the contract: a
//! run is the same calls with the same arguments in one process (one libm), the same
//! arithmetic whichever thread runs it, and a cached plant is a copy of a deterministic build.
//! The controller ([`CONTROLLER`], docs/model.md §9) runs beside the plants with a scenario of its
//! own (no FMU state, no input derivatives, one step size); Model Exchange runs are the plants'.

use crate::robustness_common::*;
use backlash_fmu::ffi::*;
use backlash_fmu::fmu::MODELS;
use std::ptr::null_mut;
use std::sync::{Arc, Barrier};

const OK: fmi2Status = fmi2Status::fmi2OK;
const RUNS: usize = 12;
/// Controller runs beside the plants' runs.
const CONTROLLER_RUNS: usize = 4;
/// Model Exchange runs, and Co-Simulation runs beside them.
const ME_RUNS: usize = 8;
const CS_BESIDE: usize = 2;

/// Run `i`: its own model, parameters (more distinct sets than the plant cache holds), inputs
/// and input ramp; an FMU state saved, serialized, restored into the same instance and into a
/// second one; a refused call, fmi2Reset and a rerun. Returns the bits of every variable
/// after every step.
fn scenario(i: usize, start: Option<&Barrier>) -> Vec<u64> {
    let model = i % MODELS.len();
    let f = Fmu::named(model, &format!("thread {i}"));
    let g = Fmu::named(model, &format!("copy {i}"));
    if let Some(b) = start {
        b.wait();
    }
    let mut trace = Vec::new();
    let mut record = |f: &Fmu| {
        let (s, v) = f.all_values();
        assert_eq!(s, OK);
        trace.extend(v.iter().map(|(_, x)| x.to_bits()));
    };
    for round in 0..2 {
        assert_eq!(fmi2EnterInitializationMode(f.c), OK);
        assert_eq!(f.set_real("J_m", 1.0 + 0.125 * (i % 10) as f64), OK);
        assert_eq!(f.set_real("Kp", 0.5 * (i % 3) as f64), OK);
        assert_eq!(f.set_real("tau_m", 1.0 + i as f64), OK);
        assert_eq!(f.set_real("tau_L", -0.25 * round as f64), OK);
        let s = fmi2ExitInitializationMode(f.c);
        assert!(matches!(s, OK | fmi2Status::fmi2Warning), "{s:?}");
        let vr = [f.vr("tau_L")];
        // SAFETY: arrays of length 1.
        assert_eq!(
            unsafe { fmi2SetRealInputDerivatives(f.c, vr.as_ptr(), 1, [1].as_ptr(), [3.0].as_ptr()) },
            OK
        );
        let h = 2e-3;
        let mut saved = Vec::new();
        for k in 0..40 {
            assert_eq!(fmi2DoStep(f.c, k as f64 * h, h, 1), OK);
            record(&f);
            if k == 19 {
                saved = serialized(&f);
            }
        }
        // Back to step 20 in this instance and in the copy; both continue identically.
        assert_eq!(load(&f, &saved), (OK, OK));
        assert_eq!(load(&g, &saved), (OK, OK));
        for k in 20..30 {
            assert_eq!(fmi2DoStep(f.c, k as f64 * h, h, 1), OK);
            assert_eq!(fmi2DoStep(g.c, k as f64 * h, h, 1), OK);
            record(&f);
            record(&g);
        }
        let mut s = null_mut();
        // SAFETY: pointer to a local.
        assert_eq!(unsafe { fmi2GetFMUstate(f.c, &mut s) }, OK);
        assert_eq!(
            fmi2DoStep(f.c, 0.0, h, 1),
            fmi2Status::fmi2Error,
            "wrong communication point"
        );
        assert_eq!(fmi2Reset(f.c), OK);
        assert_eq!(fmi2Reset(g.c), OK);
    }
    trace
}

/// Controller run `i`: its own gains, reference and sample period, measured speeds and tensions
/// that change every sample; a step of another size refused (the instance then in Error), fmi2Reset
/// and a rerun. Returns the bits of every variable after every step.
fn controller_scenario(i: usize, start: Option<&Barrier>) -> Vec<u64> {
    let f = Fmu::named(CONTROLLER, &format!("controller {i}"));
    if let Some(b) = start {
        b.wait();
    }
    let mut trace = Vec::new();
    for round in 0..2 {
        assert_eq!(fmi2EnterInitializationMode(f.c), OK);
        assert_eq!(f.set_integer("reference", 1 + (i % 3) as i32), OK);
        assert_eq!(f.set_real("Kp", 1.0 + 0.5 * i as f64), OK);
        assert_eq!(f.set_real("Ki", 10.0 * (i % 4) as f64), OK);
        assert_eq!(f.set_real("Kp_T", 0.01 * round as f64), OK);
        let h = 1e-3 * (1 + i % 3) as f64;
        assert_eq!(f.set_real("h", h), OK);
        assert_eq!(fmi2ExitInitializationMode(f.c), OK);
        for k in 0..40 {
            assert_eq!(f.set_real("omega_m", 0.01 * ((k + i) % 7) as f64 - 0.03), OK);
            assert_eq!(f.set_real("T", 0.5 * (k % 3) as f64), OK);
            assert_eq!(fmi2DoStep(f.c, k as f64 * h, h, 1), OK);
            let (s, v) = f.all_values();
            assert_eq!(s, OK);
            trace.extend(v.iter().map(|(_, x)| x.to_bits()));
        }
        let before = f.log_len();
        let s = fmi2DoStep(f.c, 40.0 * h, 2.0 * h, 1);
        f.assert_refused(s, before, "is not the sample period");
        assert_eq!(fmi2Reset(f.c), OK);
    }
    trace
}

/// The plants' runs and the controller's, all at once.
#[test]
fn concurrent_runs_are_bit_identical_to_sequential_ones() {
    let sequential: Vec<Vec<u64>> = (0..RUNS).map(|i| scenario(i, None)).collect();
    let controllers: Vec<Vec<u64>> = (0..CONTROLLER_RUNS).map(|i| controller_scenario(i, None)).collect();
    for round in 0..2 {
        let barrier = Arc::new(Barrier::new(RUNS + CONTROLLER_RUNS));
        let handles: Vec<_> = (0..RUNS)
            .map(|i| {
                let barrier = Arc::clone(&barrier);
                std::thread::spawn(move || scenario(i, Some(&barrier)))
            })
            .collect();
        let controller_handles: Vec<_> = (0..CONTROLLER_RUNS)
            .map(|i| {
                let barrier = Arc::clone(&barrier);
                std::thread::spawn(move || controller_scenario(i, Some(&barrier)))
            })
            .collect();
        for (i, h) in handles.into_iter().enumerate() {
            let concurrent = h.join().expect("no panic in a thread");
            assert_eq!(concurrent.len(), sequential[i].len());
            assert!(
                concurrent == sequential[i],
                "run {i} differs when run concurrently (round {round})"
            );
        }
        for (i, h) in controller_handles.into_iter().enumerate() {
            let concurrent = h.join().expect("no panic in a thread");
            assert!(
                concurrent == controllers[i],
                "controller run {i} differs when run concurrently (round {round})"
            );
        }
    }
    // Distinct runs of one model really differ (the comparison above is not between identical
    // constants).
    assert_ne!(sequential[0], sequential[MODELS.len()]);
    assert_ne!(controllers[0], controllers[1]);
    fresh_instance_works(SHAFT);
    fresh_instance_works(CONTROLLER);
}

/// Run `i` as Model Exchange (the plants only: the controller has no Model Exchange): its own
/// model, parameters and inputs; the importer's side of an
/// integration (explicit Euler through fmi2SetTime, fmi2SetContinuousStates, fmi2GetDerivatives,
/// with the event iteration at each sign change of an indicator), time set back and forth, an FMU
/// state restored into the same instance and into a second one, a refused call, fmi2Reset and a
/// rerun. Returns the bits of every variable, state, derivative and indicator after every step.
fn me_scenario(i: usize, start: Option<&Barrier>) -> Vec<u64> {
    let model = i % MODELS.len();
    let f = Fmu::instantiate(model, &format!("ME thread {i}"), fmi2ModelExchange);
    let g = Fmu::instantiate(model, &format!("ME copy {i}"), fmi2ModelExchange);
    if let Some(b) = start {
        b.wait();
    }
    let mut trace = Vec::new();
    let mut record = |f: &Fmu| {
        let (s, v) = f.all_values();
        assert_eq!(s, OK);
        trace.extend(v.iter().map(|(_, x)| x.to_bits()));
        for (s, x) in [f.continuous_states(), f.derivatives()] {
            assert_eq!(s, OK);
            trace.extend(x.iter().map(|x| x.to_bits()));
        }
        let (s, z) = f.event_indicators();
        assert_eq!(s, OK);
        trace.extend(z.into_iter().map(f64::to_bits));
    };
    for round in 0..2 {
        assert_eq!(fmi2EnterInitializationMode(f.c), OK);
        assert_eq!(f.set_real("J_m", 1.0 + 0.125 * (i % 10) as f64), OK);
        // Kp > 0: fmi2ExitInitializationMode of the belt takes seconds with Kp = 0.
        assert_eq!(f.set_real("Kp", 0.5 + 0.5 * (i % 3) as f64), OK);
        assert_eq!(f.set_real("tau_m", 1.0 + i as f64), OK);
        assert_eq!(f.set_real("tau_L", -0.25 * round as f64), OK);
        let s = fmi2ExitInitializationMode(f.c);
        assert!(matches!(s, OK | fmi2Status::fmi2Warning), "{s:?}");
        let events = |f: &Fmu| {
            let mut info = event_info();
            // SAFETY: pointer to a local.
            assert_eq!(unsafe { fmi2NewDiscreteStates(f.c, &mut info) }, OK);
            assert_eq!(fmi2EnterContinuousTimeMode(f.c), OK);
        };
        events(&f);
        let h = 1e-4;
        let (_, mut x) = f.continuous_states();
        let (_, mut z) = f.event_indicators();
        let mut saved = Vec::new();
        for k in 0..200 {
            let (s, dx) = f.derivatives();
            assert_eq!(s, OK);
            x = x.iter().zip(&dx).map(|(x, dx)| x + h * dx).collect();
            // A solver that looks ahead and comes back: time forwards, back, forwards.
            assert_eq!(fmi2SetTime(f.c, (k + 2) as f64 * h), OK);
            assert_eq!(fmi2SetTime(f.c, (k + 1) as f64 * h), OK);
            assert_eq!(f.set_continuous_states(&x), OK);
            let (_, now) = f.event_indicators();
            if now.iter().zip(&z).any(|(a, b)| (*a > 0.0) != (*b > 0.0)) {
                assert_eq!(fmi2EnterEventMode(f.c), OK);
                events(&f);
            }
            z = now;
            if k % 20 == 19 {
                record(&f);
            }
            if k == 99 {
                saved = serialized(&f);
            }
        }
        // Back to step 100 in this instance and in the copy; both continue identically.
        assert_eq!(load(&f, &saved), (OK, OK));
        assert_eq!(load(&g, &saved), (OK, OK));
        for k in 100..120 {
            for f in [&f, &g] {
                let (_, x) = f.continuous_states();
                let (_, dx) = f.derivatives();
                assert_eq!(fmi2SetTime(f.c, (k + 1) as f64 * h), OK);
                let next: Vec<f64> = x.iter().zip(&dx).map(|(x, dx)| x + h * dx).collect();
                assert_eq!(f.set_continuous_states(&next), OK);
            }
            record(&f);
            record(&g);
        }
        assert_eq!(
            fmi2DoStep(f.c, 0.0, h, 1),
            fmi2Status::fmi2Error,
            "a Co-Simulation call"
        );
        assert_eq!(fmi2Reset(f.c), OK);
        assert_eq!(fmi2Reset(g.c), OK);
    }
    trace
}

#[test]
fn concurrent_model_exchange_and_co_simulation_runs_are_bit_identical_to_sequential_ones() {
    let sequential: Vec<Vec<u64>> = (0..ME_RUNS).map(|i| me_scenario(i, None)).collect();
    let co_simulation: Vec<Vec<u64>> = (0..CS_BESIDE).map(|i| scenario(i, None)).collect();
    let barrier = Arc::new(Barrier::new(ME_RUNS + CS_BESIDE));
    // Both interfaces at once: Model Exchange runs beside Co-Simulation ones.
    let me: Vec<_> = (0..ME_RUNS)
        .map(|i| {
            let barrier = Arc::clone(&barrier);
            std::thread::spawn(move || me_scenario(i, Some(&barrier)))
        })
        .collect();
    let cs: Vec<_> = (0..CS_BESIDE)
        .map(|i| {
            let barrier = Arc::clone(&barrier);
            std::thread::spawn(move || scenario(i, Some(&barrier)))
        })
        .collect();
    for (i, h) in me.into_iter().enumerate() {
        let concurrent = h.join().expect("no panic in a thread");
        assert!(
            concurrent == sequential[i],
            "Model Exchange run {i} differs when run concurrently"
        );
    }
    for (i, h) in cs.into_iter().enumerate() {
        let concurrent = h.join().expect("no panic in a thread");
        assert!(
            concurrent == co_simulation[i],
            "Co-Simulation run {i} differs beside Model Exchange runs"
        );
    }
    assert_ne!(sequential[0], sequential[MODELS.len()]);
    for model in 0..MODELS.len() {
        fresh_me_instance_works(model);
    }
}

#[test]
fn instantiate_and_free_race_without_corrupting_the_tables() {
    let barrier = Arc::new(Barrier::new(4));
    let handles: Vec<_> = (0..4)
        .map(|t| {
            let barrier = Arc::clone(&barrier);
            std::thread::spawn(move || {
                barrier.wait();
                for k in 0..300 {
                    // Both interfaces, from every thread.
                    let fmu_type = [fmi2CoSimulation, fmi2ModelExchange][(t + k / 2) % 2];
                    let f = Fmu::instantiate((t + k) % MODELS.len(), "race", fmu_type);
                    let mut s = null_mut();
                    // SAFETY: pointer to a local.
                    assert_eq!(unsafe { fmi2GetFMUstate(f.c, &mut s) }, OK);
                    let c = f.c;
                    drop(f);
                    assert_eq!(fmi2Reset(c), fmi2Status::fmi2Error);
                    // A controller (Co-Simulation only), whose fmi2GetFMUstate is refused.
                    let g = Fmu::new(CONTROLLER);
                    let before = g.log_len();
                    // SAFETY: pointer to a local.
                    let s = unsafe { fmi2GetFMUstate(g.c, &mut null_mut()) };
                    g.assert_refused(s, before, "canGetAndSetFMUstate = false");
                    let c = g.c;
                    drop(g);
                    assert_eq!(fmi2Reset(c), fmi2Status::fmi2Error);
                }
            })
        })
        .collect();
    for h in handles {
        h.join().expect("no panic in a thread");
    }
    for model in 0..=CONTROLLER {
        fresh_instance_works(model);
    }
}

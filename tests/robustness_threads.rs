//! Instances used from many threads at once (each instance by one thread at a time, as FMI
//! 2.0 §2.1.5 requires) give bit-identical results to the same runs done one after another:
//! the live-instance table, the FMU-state table and the shared cache of built plants must
//! neither corrupt nor couple instances.
#![cfg(all(target_os = "linux", any(target_arch = "x86_64", target_arch = "aarch64")))]

mod robustness_common;

use backlash_fmu::ffi::*;
use robustness_common::*;
use std::ptr::null_mut;
use std::sync::{Arc, Barrier};

const OK: fmi2Status = fmi2Status::fmi2OK;
const RUNS: usize = 12;

/// Run `i`: its own model, parameters (more distinct sets than the plant cache holds), inputs
/// and input ramp; an FMU state saved, serialized, restored into the same instance and into a
/// second one; a refused call, fmi2Reset and a rerun. Returns the bits of every variable
/// after every step.
fn scenario(i: usize, start: Option<&Barrier>) -> Vec<u64> {
    let model = i % 2;
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

#[test]
fn concurrent_runs_are_bit_identical_to_sequential_ones() {
    let sequential: Vec<Vec<u64>> = (0..RUNS).map(|i| scenario(i, None)).collect();
    for round in 0..2 {
        let barrier = Arc::new(Barrier::new(RUNS));
        let handles: Vec<_> = (0..RUNS)
            .map(|i| {
                let barrier = Arc::clone(&barrier);
                std::thread::spawn(move || scenario(i, Some(&barrier)))
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
    }
    // Distinct runs really differ (the comparison above is not between identical constants).
    assert_ne!(sequential[0], sequential[2]);
    fresh_instance_works(SHAFT);
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
                    let f = Fmu::named((t + k) % 2, "race");
                    let mut s = null_mut();
                    // SAFETY: pointer to a local.
                    assert_eq!(unsafe { fmi2GetFMUstate(f.c, &mut s) }, OK);
                    let c = f.c;
                    drop(f);
                    assert_eq!(fmi2Reset(c), fmi2Status::fmi2Error);
                }
            })
        })
        .collect();
    for h in handles {
        h.join().expect("no panic in a thread");
    }
    fresh_instance_works(BELT);
}

//! FMU states under misuse: truncated, extended, bit-flipped, zero-length, random and
//! other-model bytes; fields made invalid behind a valid checksum; buffers too small for
//! serialization; handles that are stale, foreign or freed twice. Every refusal is fmi2Error
//! with a logged reason, nothing invalid reaches the instance, and the instance (after
//! fmi2Reset) and fresh ones work normally.
//!
//! The controller ([`CONTROLLER`]) has no FMU state (canGetAndSetFMUstate = false, docs/model.md
//! §9): its own rows refuse every state, whatever the bytes, the buffer or the handle, naming that.

use crate::robustness_common::*;
use backlash_fmu::ffi::*;
use backlash_fmu::fmu::MODELS;
use std::ptr::null_mut;

const OK: fmi2Status = fmi2Status::fmi2OK;

/// An initialized instance stepped into contact, and its serialized state.
fn stepped(model: usize) -> (Fmu, Vec<u8>) {
    let f = Fmu::initialized(model, None);
    assert_eq!(f.set_real("tau_m", 3.0), OK);
    let mut t = 0.0;
    for _ in 0..10 {
        assert_eq!(fmi2DoStep(f.c, t, 0.01, 1), OK);
        t += 0.01;
    }
    let bytes = serialized(&f);
    (f, bytes)
}

/// What the controller's refusals of FMU states name: the flag of its description.
const NO_FMU_STATE: &str = "a controller's FMU state (canGetAndSetFMUstate = false";

/// A controller initialized and stepped through five samples of a measured speed: values to
/// compare before and after a refusal.
fn controller_stepped() -> Fmu {
    let f = Fmu::initialized(CONTROLLER, None);
    assert_eq!(f.set_real("omega_m", -0.02), OK);
    for k in 0..5 {
        assert_eq!(fmi2DoStep(f.c, k as f64 * 1e-3, 1e-3, 1), OK);
    }
    f
}

/// `call` on a stepped controller is refused naming its lack of FMU state and changes nothing;
/// after fmi2Reset the controller works.
#[track_caller]
fn refused_by_the_controller(call: impl FnOnce(fmi2Component) -> fmi2Status) {
    let f = controller_stepped();
    f.refuses_changing_nothing(NO_FMU_STATE, call);
    f.reset_and_check();
}

/// Deserializing `bytes` into a controller is refused naming its lack of FMU state, hands out
/// no handle and changes nothing.
#[track_caller]
fn deserialize_refused_by_the_controller(bytes: &[u8]) {
    let mut s: fmi2FMUstate = null_mut();
    // SAFETY: `bytes` has the announced length; `s` is a local.
    refused_by_the_controller(|c| unsafe { fmi2DeSerializeFMUstate(c, bytes.as_ptr().cast(), bytes.len(), &mut s) });
    assert!(s.is_null(), "a refused state was handed out");
}

/// Deserializing `bytes` into `f` is refused with a reason containing `reason`, and no FMU
/// state handle is handed out.
#[track_caller]
fn refused(f: &Fmu, bytes: &[u8], reason: &str) {
    let mut s: fmi2FMUstate = null_mut();
    let before = f.log_len();
    // SAFETY: `bytes` has the announced length; `s` is a local.
    let status = unsafe { fmi2DeSerializeFMUstate(f.c, bytes.as_ptr().cast(), bytes.len(), &mut s) };
    f.assert_refused(status, before, reason);
    assert!(s.is_null(), "a refused state was handed out");
}

#[test]
fn truncated_extended_and_empty_bytes_are_refused() {
    for model in 0..MODELS.len() {
        let (_, bytes) = stepped(model);
        let f = Fmu::new(model);
        refused(&f, &[], "empty");
        for len in 1..bytes.len() {
            refused(&f, &bytes[..len], "");
        }
        let mut longer = bytes.clone();
        longer.push(0);
        refused(&f, &longer, "bytes, a version-5 state");
        // The instance, in state Error now, comes back with fmi2Reset.
        f.reset_and_check();
        // The controller's own rows: any length of any bytes, refused for lack of a state.
        for len in [0, 1, 12, bytes.len() / 2, bytes.len() - 1] {
            deserialize_refused_by_the_controller(&bytes[..len]);
        }
        deserialize_refused_by_the_controller(&longer);
    }
    fresh_instance_works(CONTROLLER);
}

/// The plants only: the controller has no state format (it refuses any bytes, see
/// `garbage_and_other_model_bytes_are_refused`).
#[test]
fn every_single_bit_flip_is_refused() {
    for model in 0..MODELS.len() {
        let (_, bytes) = stepped(model);
        let f = Fmu::new(model);
        for i in 0..bytes.len() {
            for bit in [0x01u8, 0x80] {
                let mut b = bytes.clone();
                b[i] ^= bit;
                refused(&f, &b, "");
            }
        }
        f.reset_and_check();
    }
}

#[test]
fn garbage_and_other_model_bytes_are_refused() {
    // A state of each model is refused by each other model.
    let states: Vec<Vec<u8>> = (0..MODELS.len()).map(|model| stepped(model).1).collect();
    for (model, bytes) in states.iter().enumerate() {
        let f = Fmu::new(model);
        for other in (0..MODELS.len()).filter(|other| *other != model) {
            refused(&f, &states[other], "saved by the model with guid");
        }
        // Its own model's state is accepted (also in state Error, which it leaves).
        assert_eq!(load(&f, bytes), (OK, OK));
        f.assert_all_finite(MODELS[model].identifier);
        f.reset_and_check();
    }
    let shaft = &states[SHAFT];
    let f = Fmu::new(SHAFT);
    refused(&f, &vec![0u8; shaft.len()], "magic");
    refused(&f, &vec![0xffu8; shaft.len()], "magic");
    let mut version = shaft.clone();
    version[8] = 6;
    refused(&f, &version, "format version 6");
    // A guid length pointing past the end.
    let mut long_guid = shaft.clone();
    long_guid[10..12].copy_from_slice(&u16::MAX.to_le_bytes());
    refused(&f, &long_guid, "truncated");
    // Random bytes, some behind the right magic and version.
    let mut rng = 0x9e3779b97f4a7c15u64;
    for k in 0..300 {
        let len = (k * 7) % (shaft.len() + 40);
        let mut b: Vec<u8> = (0..len)
            .map(|_| {
                rng ^= rng << 13;
                rng ^= rng >> 7;
                rng ^= rng << 17;
                rng as u8
            })
            .collect();
        if k % 2 == 0 && len >= 12 {
            b[..10].copy_from_slice(&shaft[..10]);
        }
        refused(&f, &b, "");
    }
    f.reset_and_check();
    fresh_instance_works(SHAFT);
    // The controller's own rows: every plant's state, and garbage, refused for lack of a state.
    for bytes in &states {
        deserialize_refused_by_the_controller(bytes);
    }
    deserialize_refused_by_the_controller(&vec![0u8; shaft.len()]);
    deserialize_refused_by_the_controller(&vec![0xffu8; shaft.len()]);
    fresh_instance_works(CONTROLLER);
}

/// Fields made invalid while the checksum is kept valid: the field checks behind the
/// checksum must catch them (the plants only: the controller has no state format).
#[test]
fn invalid_fields_behind_a_valid_checksum_are_refused() {
    for model in 0..MODELS.len() {
        invalid_fields_are_refused(model);
    }
}

fn invalid_fields_are_refused(model: usize) {
    let m = &MODELS[model];
    let (_, bytes) = stepped(model);
    let phase = phase_offset(&bytes);
    let values = phase + 4 + 8 * 4;
    let plant = plant_offset(&bytes);
    let f = Fmu::new(model);
    let edit = |at: usize, new: &[u8], reason: &str| {
        let mut b = bytes.clone();
        b[at..at + new.len()].copy_from_slice(new);
        reseal(&mut b);
        refused(&f, &b, reason);
    };
    edit(phase, &[8], "unknown phase code 8");
    // EventMode (6) is a Model Exchange state; the flags say Co-Simulation, and vice versa.
    edit(phase, &[6], "not a state of an FMI 2.0 Co-Simulation instance");
    edit(phase + 1, &[4 | 8], "not a state of an FMI 2.0 Model Exchange instance");
    edit(phase, &[255], "unknown phase code 255");
    edit(phase + 1, &[0x80 | 4], "unknown flag bits");
    edit(phase + 2, &23u16.to_le_bytes(), "23 stored values");
    // The phase says "not initialized" but a plant state is present.
    edit(phase, &[0], "does not match");
    edit(phase + 4, &f64::NAN.to_le_bytes(), "time = NaN");
    edit(phase + 4 + 8, &f64::INFINITY.to_le_bytes(), "startTime = inf");
    // Parameters out of range: the drive train's, and a web span's where there is one.
    let parameters = [
        ("J_m", -1.0),
        ("J_m", 0.0),
        ("b_L", -1e-9),
        ("Delta", -0.5),
        ("k", 0.0),
        ("K_b", -2.0),
        ("R_w", 0.0),
        ("EA", -1.0),
        ("v_ref", -0.0),
    ];
    for (name, x) in parameters {
        if let Some(v) = m.by_name(name) {
            edit(values + 8 * v.symbol.index(), &f64::to_le_bytes(x), name);
        }
    }
    edit(values, &f64::NEG_INFINITY.to_le_bytes(), "not finite");
    if m.is_geared() {
        // A gearbox's chain words: z, each stage's u, u', V and mode code, each body's mode.
        for (i, name) in backlash_fmu::fmu::geared::Geared::WORD_NAMES.iter().enumerate() {
            edit(plant + 8 * i, &f64::NAN.to_le_bytes(), &format!("{name} = NaN"));
        }
        edit(plant + 8 * 8, &(-1.0f64).to_le_bytes(), "V_1 = -1 must be >= 0");
        edit(
            plant + 8 * 9,
            &4.0f64.to_le_bytes(),
            "unknown contact mode 4 of stage 1",
        );
        edit(
            plant + 8 * 13,
            &0.5f64.to_le_bytes(),
            "unknown contact mode 0.5 of stage 2",
        );
        edit(
            plant + 8 * 14,
            &2.0f64.to_le_bytes(),
            "unknown friction mode 2 of the motor",
        );
        edit(
            plant + 8 * 16,
            &(-0.5f64).to_le_bytes(),
            "unknown friction mode -0.5 of the load",
        );
    } else {
        for (i, name) in ["theta_m", "omega_m", "theta_L", "omega_L", "T", "u", "du/dt", "V"]
            .iter()
            .enumerate()
        {
            edit(plant + 8 * i, &f64::NAN.to_le_bytes(), &format!("{name} = NaN"));
        }
        edit(plant + 8 * 7, &(-1.0f64).to_le_bytes(), "V = -1 must be >= 0");
        let mode = mode_offset(&bytes);
        edit(mode, &[4], "unknown contact mode 4");
        edit(mode, &[0x80], "unknown contact mode");
        edit(mode + 1, &[2], "unknown friction mode 2 of the motor");
        edit(mode + 2, &[0x80], "unknown friction mode -128 of the load");
    }
    // The first and the last word of the bound part.
    let bound = bound_offset(&bytes);
    edit(bound, &f64::NAN.to_le_bytes(), "a bound's state");
    let last = bound + 8 * (bound_words(m) - 1);
    edit(last, &f64::NAN.to_le_bytes(), "a bound's state");
    edit(lag_offset(&bytes), &f64::NAN.to_le_bytes(), "the bounds' lag");
    edit(lag_offset(&bytes), &(-1e-3f64).to_le_bytes(), "the bounds' lag");
    // The bound's terms gathered at events: finite, a known mode, counts >= 0.
    let events = events_offset(&bytes);
    edit(events, &0.5f64.to_le_bytes(), "tracking flag 0.5");
    edit(events + 8, &7.0f64.to_le_bytes(), "unknown contact mode 7");
    edit(events + 32, &(-1.0f64).to_le_bytes(), "not finite, >= 0 counts");
    edit(
        events + 16,
        &f64::NAN.to_le_bytes(),
        "the bound's terms of the trajectory",
    );
    // The time marks: finite, and not before the start time (0 here).
    let marks = marks_offset(&bytes);
    edit(marks, &f64::NAN.to_le_bytes(), "second-last completed integrator step");
    edit(marks + 8, &(-1e-3f64).to_le_bytes(), "is before the start time");
    edit(marks + 16, &f64::INFINITY.to_le_bytes(), "the last event");
    f.reset_and_check();
}

/// Finite but inconsistent plant states (u that does not match the angles, a contact mode
/// that does not match u, huge values) are either refused with a reason or, if accepted,
/// step to finite outputs or are refused at the step: never NaN (the plants only: the
/// controller has no plant state).
#[test]
fn inconsistent_but_finite_plant_states_never_produce_nan() {
    let (_, bytes) = stepped(SHAFT);
    let plant = plant_offset(&bytes);
    let cases: [(&str, usize, Vec<u8>); 7] = [
        ("u far outside the gap", plant + 40, 1e3f64.to_le_bytes().to_vec()),
        ("u inside the gap", plant + 40, 0.0f64.to_le_bytes().to_vec()),
        ("mode free", mode_offset(&bytes), vec![0]),
        ("mode negative", mode_offset(&bytes), vec![0xff]),
        ("huge omega_m", plant + 8, 1e300f64.to_le_bytes().to_vec()),
        ("huge theta_L", plant + 16, (-f64::MAX).to_le_bytes().to_vec()),
        ("huge u", plant + 40, f64::MAX.to_le_bytes().to_vec()),
    ];
    for (what, at, new) in cases {
        let f = Fmu::new(SHAFT);
        let mut b = bytes.clone();
        b[at..at + new.len()].copy_from_slice(&new);
        reseal(&mut b);
        let before = f.log_len();
        match load(&f, &b) {
            (OK, OK) => {
                f.assert_all_finite(what);
                let t = f.time();
                for k in 0..5 {
                    let before = f.log_len();
                    let s = fmi2DoStep(f.c, t + k as f64 * 0.05, 0.05, 1);
                    if s != OK {
                        f.assert_refused(s, before, "");
                        break;
                    }
                    f.assert_all_finite(&format!("{what}, step {k}"));
                }
                f.assert_all_finite(what);
            }
            (d, s) => f.assert_refused(if d != OK { d } else { s }, before, ""),
        }
        f.reset_and_check();
    }
}

#[test]
fn serializing_into_a_buffer_that_is_too_small_is_refused_and_writes_nothing() {
    let (f, bytes) = stepped(BELT);
    let mut s: fmi2FMUstate = null_mut();
    // SAFETY: buffers of the announced size; `s` is a local.
    unsafe {
        assert_eq!(fmi2GetFMUstate(f.c, &mut s), OK);
        for size in [0, 1, 12, bytes.len() - 1] {
            let mut buffer = vec![0xAAu8; bytes.len() + 16];
            let status = f.refuses("less than", |c| {
                fmi2SerializeFMUstate(c, s, buffer.as_mut_ptr().cast(), size)
            });
            assert_eq!(status, fmi2Status::fmi2Error);
            assert!(
                buffer.iter().all(|b| *b == 0xAA),
                "a refused call wrote into the buffer"
            );
            assert_eq!(fmi2Reset(f.c), OK);
        }
        // A larger buffer is fine; only the state's bytes are written.
        let mut buffer = vec![0xAAu8; bytes.len() + 16];
        assert_eq!(
            fmi2SerializeFMUstate(f.c, s, buffer.as_mut_ptr().cast(), buffer.len()),
            OK
        );
        assert_eq!(&buffer[..bytes.len()], &bytes[..]);
        assert!(buffer[bytes.len()..].iter().all(|b| *b == 0xAA));
        assert_eq!(fmi2FreeFMUstate(f.c, &mut s), OK);
        // The controller's own rows: refused whatever the buffer (a plant's live state passed),
        // before anything is written.
        let mut s = null_mut();
        assert_eq!(fmi2GetFMUstate(f.c, &mut s), OK);
        for size in [0, 1, bytes.len() - 1, bytes.len(), bytes.len() + 16] {
            let mut buffer = vec![0xAAu8; bytes.len() + 16];
            refused_by_the_controller(|c| fmi2SerializeFMUstate(c, s, buffer.as_mut_ptr().cast(), size));
            assert!(
                buffer.iter().all(|b| *b == 0xAA),
                "the controller wrote into the buffer"
            );
            let mut n = usize::MAX;
            refused_by_the_controller(|c| fmi2SerializedFMUstateSize(c, s, &mut n));
            assert_eq!(n, usize::MAX, "the controller wrote a size");
        }
        assert_eq!(fmi2FreeFMUstate(f.c, &mut s), OK);
    }
    f.reset_and_check();
    fresh_instance_works(CONTROLLER);
}

#[test]
fn stale_foreign_and_doubly_freed_handles_are_refused() {
    let (f, _) = stepped(SHAFT);
    let mut local = [0u8; 64];
    let foreign = local.as_mut_ptr() as fmi2FMUstate;
    // SAFETY: pointers to locals; handles are never dereferenced by the FMU.
    unsafe {
        for handle in [foreign, 1 as fmi2FMUstate, usize::MAX as fmi2FMUstate] {
            f.refuses("not a live FMU state", |c| fmi2SetFMUstate(c, handle));
            f.refuses("not a live FMU state", |c| {
                fmi2SerializedFMUstateSize(c, handle, &mut 0)
            });
            f.refuses("not a live FMU state", |c| {
                fmi2SerializeFMUstate(c, handle, [0; 4096].as_mut_ptr(), 4096)
            });
            let mut slot = handle;
            f.refuses("not a live FMU state", |c| fmi2FreeFMUstate(c, &mut slot));
            // fmi2GetFMUstate overwrites a state passed in: a handle that is none is refused.
            let mut slot = handle;
            f.refuses("not a live FMU state", |c| fmi2GetFMUstate(c, &mut slot));
            assert_eq!(slot, handle);
        }
        assert_eq!(local, [0u8; 64], "a foreign handle was written through");
        assert_eq!(fmi2Reset(f.c), OK);
        let mut s = null_mut();
        assert_eq!(fmi2GetFMUstate(f.c, &mut s), OK);
        let copy = s;
        assert_eq!(fmi2FreeFMUstate(f.c, &mut s), OK);
        assert!(s.is_null());
        let mut again = copy;
        f.refuses("not a live FMU state", |c| fmi2FreeFMUstate(c, &mut again));
        // NULL in the slot: nothing to free.
        assert_eq!(fmi2Reset(f.c), OK);
        assert_eq!(fmi2FreeFMUstate(f.c, &mut null_mut()), OK);
    }
    f.reset_and_check();
    fresh_instance_works(SHAFT);
}

/// The controller's own rows of the handle table: with no state of its own, fmi2GetFMUstate,
/// fmi2SetFMUstate of a live (plant's) state, fmi2SerializedFMUstateSize and fmi2SerializeFMUstate
/// are refused naming its lack of FMU state, and a handle passed in is never written; a handle
/// that is no live state is refused as such by fmi2SetFMUstate and fmi2FreeFMUstate; freeing
/// none is ignored. Each refusal changes nothing, and the controller works after fmi2Reset.
#[test]
fn the_controller_refuses_every_handle_with_the_reason() {
    let (plant, _) = stepped(SHAFT);
    let mut live = null_mut();
    // SAFETY: pointer to a local.
    assert_eq!(unsafe { fmi2GetFMUstate(plant.c, &mut live) }, OK);
    let mut local = [0u8; 64];
    let foreign = local.as_mut_ptr() as fmi2FMUstate;
    // SAFETY (all calls): pointers to locals; handles are never dereferenced by the FMU.
    unsafe {
        for handle in [null_mut(), live, foreign, usize::MAX as fmi2FMUstate] {
            let mut slot = handle;
            refused_by_the_controller(|c| fmi2GetFMUstate(c, &mut slot));
            assert_eq!(slot, handle, "a refused fmi2GetFMUstate wrote the handle");
            refused_by_the_controller(|c| fmi2SerializedFMUstateSize(c, handle, &mut 0));
            refused_by_the_controller(|c| fmi2SerializeFMUstate(c, handle, [0; 4096].as_mut_ptr(), 4096));
        }
        refused_by_the_controller(|c| fmi2SetFMUstate(c, live));
        for handle in [foreign, usize::MAX as fmi2FMUstate] {
            let f = controller_stepped();
            f.refuses_changing_nothing("not a live FMU state", |c| fmi2SetFMUstate(c, handle));
            f.reset_and_check();
            let f = controller_stepped();
            let mut slot = handle;
            f.refuses_changing_nothing("not a live FMU state", |c| fmi2FreeFMUstate(c, &mut slot));
            f.reset_and_check();
        }
        let f = controller_stepped();
        assert_eq!(fmi2FreeFMUstate(f.c, &mut null_mut()), OK);
        f.reset_and_check();
    }
    assert_eq!(local, [0u8; 64], "a foreign handle was written through");
    // The plant's state is still live and its own.
    assert_eq!(load(&plant, &serialized(&plant)), (OK, OK));
    // SAFETY: pointer to a local.
    assert_eq!(unsafe { fmi2FreeFMUstate(plant.c, &mut live) }, OK);
    fresh_instance_works(CONTROLLER);
}

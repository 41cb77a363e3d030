//! FMU states through the C functions: FMI 2.0 states through bytes into another instance, and
//! their refusals (bad bytes, another model's bytes, freed and foreign handles, the states of a
//! freed instance); an FMI 2.0 state is refused by an FMI 3.0 instance.

use crate::fmu::ffi::{instantiate, messages};
use crate::fmu::fmi3_ffi::{Fmu3, OK3};
use crate::robustness_common::{callbacks, Log};
use backlash_fmu::ffi::fmi3::*;
use backlash_fmu::ffi::*;
use backlash_fmu::fmu::MODELS;
use std::ffi::{c_char, CString};
use std::ptr::{null, null_mut};

#[test]
fn fmu_states_through_bytes_and_refusals() {
    // SAFETY: every pointer passed points to a live local of the announced length, and
    // every string is NUL-terminated.
    unsafe {
        let log = Log::default();
        let c = instantiate(&log, "a", fmi2CoSimulation, MODELS[0].guid);
        let tau = [MODELS[0].vr("tau_m")];
        assert_eq!(fmi2SetReal(c, tau.as_ptr(), 1, [2.0].as_ptr()), fmi2Status::fmi2OK);
        fmi2EnterInitializationMode(c);
        fmi2ExitInitializationMode(c);
        fmi2DoStep(c, 0.0, 0.1, 0);
        let mut state: fmi2FMUstate = null_mut();
        assert_eq!(fmi2GetFMUstate(c, &mut state), fmi2Status::fmi2OK);
        let mut size = 0;
        assert_eq!(fmi2SerializedFMUstateSize(c, state, &mut size), fmi2Status::fmi2OK);
        let mut bytes = vec![0 as c_char; size];
        assert_eq!(
            fmi2SerializeFMUstate(c, state, bytes.as_mut_ptr(), size),
            fmi2Status::fmi2OK
        );
        let vr = [MODELS[0].vr("omega_L")];
        let next = |c| {
            let mut y = [0.0];
            assert_eq!(fmi2DoStep(c, 0.1, 0.1, 0), fmi2Status::fmi2OK);
            fmi2GetReal(c, vr.as_ptr(), 1, y.as_mut_ptr());
            y[0].to_bits()
        };
        let expected = next(c);

        let other = instantiate(&log, "b", fmi2CoSimulation, MODELS[0].guid);
        let mut copy: fmi2FMUstate = null_mut();
        assert_eq!(
            fmi2DeSerializeFMUstate(other, bytes.as_ptr(), size, &mut copy),
            fmi2Status::fmi2OK
        );
        assert_eq!(fmi2SetFMUstate(other, copy), fmi2Status::fmi2OK);
        // The same state stepped by the same code.
        assert_eq!(next(other), expected);
        assert_eq!(fmi2FreeFMUstate(other, &mut copy), fmi2Status::fmi2OK);
        assert!(copy.is_null());

        let belt = instantiate(&log, "c", fmi2CoSimulation, MODELS[1].guid);
        let mut refused: fmi2FMUstate = null_mut();
        let mut garbage = bytes.clone();
        garbage[size - 20] ^= 0x10;
        for (bad, why) in [
            (&bytes[..0], "empty"),
            (&bytes[..size - 1], "bytes, a version-5 state"),
            (&garbage[..], "checksum"),
            (&[7 as c_char; 64][..], "magic"),
        ] {
            assert_eq!(
                fmi2DeSerializeFMUstate(other, bad.as_ptr(), bad.len(), &mut refused),
                fmi2Status::fmi2Error
            );
            assert!(
                messages(&log).last().unwrap().contains(why),
                "{why}: {:?}",
                messages(&log).last()
            );
            fmi2Reset(other);
        }
        assert_eq!(
            fmi2DeSerializeFMUstate(belt, bytes.as_ptr(), size, &mut refused),
            fmi2Status::fmi2Error
        );
        assert!(messages(&log).last().unwrap().contains("BacklashBelt"));
        // A handle that was freed, or never was one, is refused without being dereferenced.
        assert_eq!(fmi2SetFMUstate(other, copy), fmi2Status::fmi2Error);
        fmi2Reset(other);
        assert_eq!(fmi2SetFMUstate(other, 0x1234 as fmi2FMUstate), fmi2Status::fmi2Error);
        assert!(refused.is_null());
        for c in [c, other, belt] {
            fmi2FreeInstance(c);
        }
        // The state `c` allocated went with it.
        let d = instantiate(&log, "d", fmi2CoSimulation, MODELS[0].guid);
        assert_eq!(fmi2SetFMUstate(d, state), fmi2Status::fmi2Error);
        assert!(messages(&log).last().unwrap().contains("not a live FMU state"));
        fmi2FreeInstance(d);
    }
}

#[test]
fn states_and_calls_stay_with_their_standard() {
    // An FMI 2.0 state is refused by an FMI 3.0 instance, with the reason.
    let log = Log::default();
    let guid = CString::new(MODELS[0].guid).unwrap();
    let cb = callbacks(&log);
    // SAFETY: as in fmi2_run.
    let c2 = unsafe {
        fmi2Instantiate(
            c"fmi2".as_ptr(),
            fmi2CoSimulation,
            guid.as_ptr(),
            null(),
            &cb,
            fmi2False,
            fmi2False,
        )
    };
    let mut state2: fmi2FMUstate = null_mut();
    let mut size = 0usize;
    // SAFETY: pointers to locals; the buffer has `size` bytes.
    let bytes = unsafe {
        assert_eq!(fmi2GetFMUstate(c2, &mut state2), fmi2Status::fmi2OK);
        assert_eq!(fmi2SerializedFMUstateSize(c2, state2, &mut size), fmi2Status::fmi2OK);
        let mut bytes = vec![0u8; size];
        assert_eq!(
            fmi2SerializeFMUstate(c2, state2, bytes.as_mut_ptr().cast(), size),
            fmi2Status::fmi2OK
        );
        bytes
    };
    let f = Fmu3::co_simulation(0, false, false);
    let mut state3: fmi3FMUState = null_mut();
    // SAFETY: the bytes and a pointer to a local.
    let s = unsafe { fmi3DeserializeFMUState(f.c, bytes.as_ptr(), bytes.len(), &mut state3) };
    assert_eq!(s, OK3, "the bytes are a valid state of this model");
    assert_eq!(fmi3SetFMUState(f.c, state3), fmi3Status::fmi3Error);
    assert!(
        f.log
            .lock()
            .unwrap()
            .iter()
            .any(|(_, m)| m.contains("FMI 2.0 Co-Simulation instance")),
        "{:?}",
        f.log.lock().unwrap()
    );
    // An FMI 2.0 function on an FMI 3.0 instance, and the other way round.
    assert_eq!(fmi2Reset(f.c), fmi2Status::fmi2Error);
    assert_eq!(fmi3Reset(c2), fmi3Status::fmi3Error);
    assert!(log
        .lock()
        .unwrap()
        .iter()
        .any(|e| e.message.contains("call the functions of its own standard")));
    fmi2FreeInstance(c2);
}

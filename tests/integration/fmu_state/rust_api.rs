//! FMU states through the FMU's Rust API (`Instance`): a serialized state continues bit for bit
//! in another instance, and restoring rolls an instance back; BacklashWeb's state carries the
//! input slopes, the tension and the web bounds, and is not a state of BacklashBelt.

use crate::fmu::simulation::{run, shaft};
use crate::fmu::web::{apply, get, instance, ramps, trace};
use backlash_fmu::fmu::{Instance, Interface, MODELS};

#[test]
fn a_deserialized_state_continues_bit_identically_in_another_instance() {
    let mut a = shaft(&[], None, false);
    a.exit_initialization_mode().unwrap();
    run(&mut a, 30);
    let snap = a.get_fmu_state().unwrap();
    let bytes = a.serialize_fmu_state(&snap).unwrap();
    let t_snap = a.time();
    let continued = run(&mut a, 30);

    let mut b = Instance::new(&MODELS[0], None, false);
    let restored = b.deserialize_fmu_state(&bytes).unwrap();
    b.set_fmu_state(&restored).unwrap();
    // A stored value read back.
    assert_eq!(b.time().to_bits(), t_snap.to_bits());
    assert_eq!(run(&mut b, 30), continued);

    // Restoring into the same instance rolls it back as well.
    a.set_fmu_state(&snap).unwrap();
    assert_eq!(run(&mut a, 30), continued);
}

#[test]
fn a_serialized_fmu_state_continues_bit_for_bit() {
    let gains = [("Kp", 0.178805), ("Ki", 57.61789), ("Kp_T", 0.01), ("Ki_T", 0.05)];
    let mut inst = instance(Interface::CoSimulation, &gains, None);
    inst.exit_initialization_mode().unwrap();
    apply(&mut inst, &ramps(1, 1e-3)[0]);
    trace(&mut inst, 0.0, 40);
    // The input lines' slopes, T and both web bounds are part of the state.
    let snapshot = inst.get_fmu_state().unwrap();
    let bytes = inst.serialize_fmu_state(&snapshot).unwrap();
    let continued = trace(&mut inst, 0.04, 60);

    let mut other = instance(Interface::CoSimulation, &[], None);
    other.exit_initialization_mode().unwrap();
    let restored = other.deserialize_fmu_state(&bytes).unwrap();
    other.set_fmu_state(&restored).unwrap();
    // Same arithmetic by construction: the state's f64 words are carried byte for byte and the
    // same code (one process, one libm) continues from them with the same inputs.
    assert_eq!(trace(&mut other, 0.04, 60), continued);
    let t = get(&mut other, &["T", "bound_T"]);
    assert!(t[0] != 0.0 && t[1] > 0.0, "the web moved and its bound grew: {t:?}");

    // A state of the web line is not a state of the belt drive.
    let belt = MODELS.iter().find(|m| m.identifier == "BacklashBelt").unwrap();
    let mut belt = Instance::new(belt, None, false);
    let err = belt.deserialize_fmu_state(&bytes).unwrap_err().to_string();
    assert!(err.contains("saved by the model with guid"), "{err}");
}

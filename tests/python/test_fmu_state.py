"""FMU state (getFMUstate / serializeFMUstate / deSerializeFMUstate / setFMUstate) and
fmi2Reset: a restored or reset instance reproduces the original run bit for bit."""

from __future__ import annotations

import numpy as np
import archives
from rigs import RIGS
from signals import reversing_torques

H, N = 0.05, 160  # 8 s of reversing torques: many contact switches on both sides of the snapshot
SNAPSHOT = 80


def _params(model, scale=1.1):
    """The rig with its gaps and the gains scaled, so that two parameter sets differ everywhere
    a mix-up would show (plant, bound) and both initialise fast."""
    params, gains = RIGS[model]
    gaps = {name: params[name] * scale for name in archives.gap_parameters(model)}
    return {**params, **gaps, "Kp": gains["Kp"] * scale, "Ki": gains["Ki"] * scale}


def _drive(inst, k0, k1, tau_m, tau_L):
    """All outputs after each step k0..k1-1, as exact Python floats and ints."""
    rows = []
    for k in range(k0, k1):
        inst.step(inst.t0 + k * H, H, tau_m=float(tau_m[k]), tau_L=float(tau_L[k]))
        model = inst.archive.model
        rows.append((*inst.get(*archives.real_outputs(model)), *inst.integers(archives.contact_output(model))))
    return rows


def test_serialized_state_continues_bit_for_bit_in_a_fresh_instance(fmu):
    params = _params(fmu.model)
    tau_m, tau_L = reversing_torques(N, H, 1.5, 0.6)

    inst = fmu.co_simulation("original", params)
    try:
        _drive(inst, 0, SNAPSHOT, tau_m, tau_L)
        state = inst.fmu.getFMUstate()
        blob = inst.fmu.serializeFMUstate(state)
        continuation = _drive(inst, SNAPSHOT, N, tau_m, tau_L)
        # Same instance: roll back and redo. Exact equality throughout: the same library, state and
        # inputs give the same arithmetic (no BLAS; the FMU spawns no threads), hence the same bits.
        inst.fmu.setFMUstate(state)
        inst.fmu.freeFMUstate(state)
        assert _drive(inst, SNAPSHOT, N, tau_m, tau_L) == continuation
    finally:
        inst.free()
    contacts = {row[-1] for row in continuation}
    assert contacts == {-1, 0, 1}, "the continuation must switch contact"

    # A fresh instance from a separately unpacked copy, initialised with other parameters:
    # the serialized state must carry parameters, time, plant and bound state.
    fresh = archives.separate_copy(fmu.model).co_simulation("fresh", _params(fmu.model, 0.9))
    try:
        restored = fresh.fmu.deSerializeFMUstate(blob)
        fresh.fmu.setFMUstate(restored)
        fresh.fmu.freeFMUstate(restored)
        assert [float(x) for x in fresh.get(*params)] == list(params.values())  # values passed through
        assert _drive(fresh, SNAPSHOT, N, tau_m, tau_L) == continuation
    finally:
        fresh.free()


def test_reset_reproduces_the_first_run_bit_for_bit(fmu):
    params = _params(fmu.model)
    tau_m, tau_L = reversing_torques(N, H, 1.5, 0.6)
    inst = fmu.co_simulation("reset", params)
    try:
        first = _drive(inst, 0, N, tau_m, tau_L)
        # fmi2Reset returns every variable to its start value (read in initialisation mode,
        # before the FMU derives anything from them) ...
        inst.fmu.reset()
        inst.fmu.setupExperiment(startTime=0.0)
        inst.fmu.enterInitializationMode()
        starts = [float(fmu.variables[name].start) for name in params]
        # Passed through: the XML's start strings are the shortest round-trip text of these floats.
        assert inst.get(*params) == starts
        states = [v.name for v in fmu.md.modelVariables if v.causality == "output" and v.initial == "exact"]
        assert inst.get(*states) == [0.0] * len(states)
        # ... and the same experiment then reproduces the first run exactly.
        inst.fmu.reset()
        inst.initialise(0.0)
        assert _drive(inst, 0, N, tau_m, tau_L) == first
    finally:
        inst.free()
    assert np.isfinite(np.array([row[:-1] for row in first])).all()

"""Misuse of the packaged FMUs through fmpy, as an importer would commit it: every refusal is
fmi2Error (or fmi2Discard) with its reason delivered to the importer's logger, no NaN ever
reaches the outputs, and a fresh instance works normally afterwards."""

from __future__ import annotations

import copy
import ctypes
import math

import pytest
from backlash_fmu.fmu import STATES, Archive, CoSimulation
from fmpy.fmi2 import fmi2Error

import archives
from rigs import RIGS


def instantiated(fmu: Archive, name: str = "robust") -> CoSimulation:
    """An FMI 2.0 Co-Simulation instance, instantiated only (not initialised), whose logger
    records (status, category, message)."""
    return fmu.co_simulation(name, initialise=False)


def discard(inst: CoSimulation) -> None:
    """fmi2FreeInstance alone: the instance may be in a state (Instantiated, Initialization Mode,
    Error) where fmi2Terminate is not allowed."""
    inst.fmu.freeInstance()


def refused_once(inst: CoSimulation, call, reason: str) -> None:
    """call() is refused with fmi2Error and exactly one reason logged under logErrors, naming
    `reason`."""
    before = len(inst.messages)
    inst.refused(call, reason)
    new = [m for m in inst.messages[before:] if m[1] == "logErrors"]
    assert len(new) == 1 and reason in new[0][2], (reason, inst.messages[before:])


def real_outputs(inst: CoSimulation) -> list[float]:
    """Every Real variable (not the Integers `contact`, `contact_law`), in the order of the value
    references."""
    return inst.get(*[n for n in inst.vr if inst.archive.variables[n].type in ("Real", "Float64")])


def works_normally(fmu):
    """A fresh instance steps and gives finite outputs that match a second fresh one."""
    # The web line's span decoupled (rigs.WEB_DECOUPLED): with its default EA the span turns the
    # load back within these 0.1 s.
    params = {"EA": RIGS["BacklashWeb"][0]["EA"]} if fmu.model == "BacklashWeb" else {}
    runs = []
    for _ in range(2):
        inst = fmu.co_simulation(params=params)
        for k in range(20):
            inst.step(k * 5e-3, 5e-3, tau_m=2.0, tau_L=0.5)
        values = inst.get(*archives.real_outputs(fmu.model))
        assert all(math.isfinite(x) for x in values)
        assert values[1] > 0.0  # omega_m accelerated by the net torque
        runs.append(values)
        inst.free()
    assert runs[0] == runs[1]


def test_bad_step_sizes_are_refused_with_a_reason(fmu):
    for h in (0.0, -1e-3, math.nan, math.inf, -math.inf, 1e300):
        inst = instantiated(fmu)
        inst.initialise()
        refused_once(inst, lambda: inst.fmu.doStep(0.0, h), "communicationStepSize")
        assert all(not math.isnan(x) for x in real_outputs(inst))
        discard(inst)
    inst = instantiated(fmu)
    inst.initialise()
    refused_once(inst, lambda: inst.fmu.doStep(0.5, 1e-3), "currentCommunicationPoint")
    discard(inst)
    works_normally(fmu)


def test_non_finite_and_out_of_range_values_are_refused(fmu):
    for name, value in (("tau_m", math.nan), ("tau_L", math.inf), ("J_m", 0.0), ("J_L", -1.0), ("b_m", -1e-9)):
        inst = instantiated(fmu)
        inst.fmu.enterInitializationMode()
        refused_once(inst, lambda: inst.fmu.setReal([inst.vr[name]], [value]), f"refused for {name}")
        # The start value is still in force and every output is finite.
        assert inst.fmu.getReal([inst.vr[name]])[0] == float(fmu.variables[name].start)
        assert all(math.isfinite(x) or math.isinf(x) and n == "bound_sup" for n, x in zip(inst.vr, real_outputs(inst)))
        discard(inst)
    works_normally(fmu)


def test_wrong_calls_and_references_are_refused(fmu):
    inst = instantiated(fmu)
    refused_once(inst, lambda: inst.fmu.doStep(0.0, 1e-3), "not allowed in state Instantiated")
    inst.fmu.reset()
    inst.initialise()
    refused_once(inst, lambda: inst.fmu.setReal([inst.vr["J_m"]], [1.0]), "fixed parameter")
    inst.fmu.reset()
    inst.initialise()
    refused_once(inst, lambda: inst.fmu.getReal([4242]), "not a variable")
    inst.fmu.reset()
    inst.initialise()
    refused_once(inst, lambda: inst.fmu.getInteger([inst.vr["omega_m"]]), "not Integer")
    discard(inst)
    works_normally(fmu)


def test_a_wrong_guid_is_refused_with_a_reason(fmu):
    wrong = copy.copy(fmu)
    wrong.md = copy.copy(fmu.md)
    wrong.md.guid = "{00000000-0000-0000-0000-000000000000}"
    with pytest.raises(Exception, match="Failed to instantiate"):
        instantiated(wrong)
    works_normally(fmu)


def test_garbage_fmu_state_bytes_are_refused(fmu):
    inst = instantiated(fmu)
    inst.initialise()
    inst.fmu.doStep(0.0, 1e-2)
    state = inst.fmu.getFMUState()
    good = inst.fmu.serializeFMUState(state)
    for bad in (good[:-1], good[:12], b"\x00" * len(good), bytes(b ^ 0xFF for b in good)):
        refused_once(inst, lambda: inst.fmu.deserializeFMUState(bad), "FMU state refused")
        inst.fmu.reset()
    # The good bytes restore the state exactly.
    inst.initialise()
    restored = inst.fmu.deserializeFMUState(good)
    inst.fmu.setFMUState(restored)
    inst.fmu.doStep(1e-2, 1e-2)
    a = real_outputs(inst)
    inst.fmu.setFMUState(state)
    inst.fmu.doStep(1e-2, 1e-2)
    assert real_outputs(inst) == a
    discard(inst)
    works_normally(fmu)


def test_null_arrays_with_a_positive_length_are_refused(fmu):
    inst = instantiated(fmu)
    inst.initialise()
    before = len(inst.messages)
    status = inst.fmu.dll.fmi2GetReal(inst.c, None, ctypes.c_size_t(2), None)
    assert status == fmi2Error
    assert any("is NULL" in m[2] for m in inst.messages[before:])
    discard(inst)
    works_normally(fmu)

"""Misuse of the packaged FMUs through fmpy, as an importer would commit it: every refusal is
fmi2Error (or fmi2Discard) with its reason delivered to the importer's logger, no NaN ever
reaches the outputs, and a fresh instance works normally afterwards."""

from __future__ import annotations

import ctypes
import math

import pytest
from fmpy.fmi2 import FMU2Slave, fmi2CallbackFunctions, fmi2CallbackLoggerTYPE, fmi2Error
from fmpy.fmi2 import fmi2CallbackAllocateMemoryTYPE, fmi2CallbackFreeMemoryTYPE
from fmpy.fmi1 import FMICallException

import fmu_driver
from rigs import RIGS

LOGGER_WITH_ARGUMENT = ctypes.CFUNCTYPE(
    None, ctypes.c_void_p, ctypes.c_char_p, ctypes.c_int, ctypes.c_char_p, ctypes.c_char_p, ctypes.c_char_p
)


class Captured:
    """An instance whose logger records (status, category, message)."""

    def __init__(self, fmu: fmu_driver.Extracted, guid: str | None = None, name: str = "robust"):
        self.messages: list[tuple[int, str, str]] = []

        def log(env, instance, status, category, format, text):
            # The FMU logs through format "%s" with the message as the one variadic argument;
            # on x86-64 and AArch64 Linux it arrives like a sixth fixed argument.
            assert format == b"%s"
            self.messages.append((status, category.decode(), text.decode()))

        # Kept alive as long as the instance.
        self._logger = LOGGER_WITH_ARGUMENT(log)
        self.callbacks = fmi2CallbackFunctions()
        self.callbacks.logger = ctypes.cast(self._logger, fmi2CallbackLoggerTYPE)
        self.callbacks.allocateMemory = fmi2CallbackAllocateMemoryTYPE(0)
        self.callbacks.freeMemory = fmi2CallbackFreeMemoryTYPE(0)
        self.slave = FMU2Slave(
            guid=guid or fmu.md.guid,
            unzipDirectory=fmu.unzipdir,
            modelIdentifier=fmu.md.coSimulation.modelIdentifier,
            instanceName=name,
        )
        self.vr = fmu.vr
        self.slave.instantiate(callbacks=self.callbacks)

    def refused(self, call, reason: str):
        before = len(self.messages)
        with pytest.raises(FMICallException) as e:
            call()
        assert e.value.status == fmi2Error
        new = [m for m in self.messages[before:] if m[1] == "logErrors"]
        assert len(new) == 1 and reason in new[0][2], (reason, self.messages[before:])

    def initialise(self):
        self.slave.setupExperiment(startTime=0.0)
        self.slave.enterInitializationMode()
        self.slave.exitInitializationMode()

    def outputs(self) -> list[float]:
        names = [n for n in self.vr if n != "contact"]
        return self.slave.getReal([self.vr[n] for n in names])

    def free(self):
        self.slave.freeInstance()


def works_normally(fmu):
    """A fresh instance steps and gives finite outputs that match a second fresh one."""
    # The web line's span decoupled (rigs.WEB_DECOUPLED): with its default EA the span turns the
    # load back within these 0.1 s.
    params = {"EA": RIGS["BacklashWeb"][0]["EA"]} if fmu.model == "BacklashWeb" else {}
    runs = []
    for _ in range(2):
        inst = fmu.instance(params=params)
        for k in range(20):
            inst.step(k * 5e-3, 5e-3, 2.0, 0.5)
        values = inst.get(*fmu_driver.STATE_OUTPUTS, "psi", "bound", "bound_paper")
        assert all(math.isfinite(x) for x in values)
        assert values[1] > 0.0  # omega_m accelerated by the net torque
        runs.append(values)
        inst.free()
    assert runs[0] == runs[1]


def test_bad_step_sizes_are_refused_with_a_reason(fmu):
    for h in (0.0, -1e-3, math.nan, math.inf, -math.inf, 1e300):
        inst = Captured(fmu)
        inst.initialise()
        inst.refused(lambda: inst.slave.doStep(0.0, h), "communicationStepSize")
        assert all(not math.isnan(x) for x in inst.outputs())
        inst.free()
    inst = Captured(fmu)
    inst.initialise()
    inst.refused(lambda: inst.slave.doStep(0.5, 1e-3), "currentCommunicationPoint")
    inst.free()
    works_normally(fmu)


def test_non_finite_and_out_of_range_values_are_refused(fmu):
    for name, value in (("tau_m", math.nan), ("tau_L", math.inf), ("J_m", 0.0), ("J_L", -1.0), ("b_m", -1e-9)):
        inst = Captured(fmu)
        inst.slave.enterInitializationMode()
        inst.refused(lambda: inst.slave.setReal([inst.vr[name]], [value]), f"refused for {name}")
        # The start value is still in force and every output is finite.
        assert inst.slave.getReal([inst.vr[name]])[0] == float(fmu.variables[name].start)
        assert all(math.isfinite(x) or math.isinf(x) and n == "bound_sup" for n, x in zip(inst.vr, inst.outputs()))
        inst.free()
    works_normally(fmu)


def test_wrong_calls_and_references_are_refused(fmu):
    inst = Captured(fmu)
    inst.refused(lambda: inst.slave.doStep(0.0, 1e-3), "not allowed in state Instantiated")
    inst.slave.reset()
    inst.initialise()
    inst.refused(lambda: inst.slave.setReal([inst.vr["J_m"]], [1.0]), "fixed parameter")
    inst.slave.reset()
    inst.initialise()
    inst.refused(lambda: inst.slave.getReal([4242]), "not a variable")
    inst.slave.reset()
    inst.initialise()
    inst.refused(lambda: inst.slave.getInteger([inst.vr["omega_m"]]), "not Integer")
    inst.free()
    works_normally(fmu)


def test_a_wrong_guid_is_refused_with_a_reason(fmu):
    with pytest.raises(Exception, match="Failed to instantiate"):
        Captured(fmu, guid="{00000000-0000-0000-0000-000000000000}")
    works_normally(fmu)


def test_garbage_fmu_state_bytes_are_refused(fmu):
    inst = Captured(fmu)
    inst.initialise()
    inst.slave.doStep(0.0, 1e-2)
    state = inst.slave.getFMUState()
    good = inst.slave.serializeFMUState(state)
    for bad in (good[:-1], good[:12], b"\x00" * len(good), bytes(b ^ 0xFF for b in good)):
        inst.refused(lambda: inst.slave.deserializeFMUState(bad), "FMU state refused")
        inst.slave.reset()
    # The good bytes restore the state exactly.
    inst.initialise()
    restored = inst.slave.deserializeFMUState(good)
    inst.slave.setFMUState(restored)
    inst.slave.doStep(1e-2, 1e-2)
    a = inst.outputs()
    inst.slave.setFMUState(state)
    inst.slave.doStep(1e-2, 1e-2)
    assert inst.outputs() == a
    inst.free()
    works_normally(fmu)


def test_null_arrays_with_a_positive_length_are_refused(fmu):
    inst = Captured(fmu)
    inst.initialise()
    before = len(inst.messages)
    status = inst.slave.dll.fmi2GetReal(inst.slave.component, None, ctypes.c_size_t(2), None)
    assert status == fmi2Error
    assert any("is NULL" in m[2] for m in inst.messages[before:])
    inst.free()
    works_normally(fmu)

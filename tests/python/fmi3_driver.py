"""Loading and driving the FMI 3.0 archives (target/fmu/fmi3/, docs/model.md §7) with fmpy's
FMU3Slave and FMU3Model, as an importer would, with a logger that records every message.

Also the sampled-data PI loop that is updated at the communication points and at every contact
switch, closed around the exact plant of reference_continuous.py (the independent side of the
early-return loop test).
"""

from __future__ import annotations

import ctypes
import functools
import shutil
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import pytest
from fmpy import extract, read_model_description
from fmpy.fmi1 import FMICallException
from fmpy.fmi3 import FMU3Model, FMU3Slave, fmi3Error

import fmu_driver
import reference_continuous as rc
from reference import Plant

STATES = fmu_driver.STATE_OUTPUTS  # theta_m, omega_m, theta_L, omega_L: the continuous states
NX, NZ = 4, 2


def fmi3_path(model: str) -> Path:
    return fmu_driver.fmu_dir() / "fmi3" / f"{model}.fmu"


class Extracted3:
    """One unpacked copy of an FMI 3.0 archive and its model description."""

    def __init__(self, model: str):
        self.model = model
        self.path = fmi3_path(model)
        if not self.path.is_file():
            raise FileNotFoundError(f"{self.path} not found: run `cargo xtask fmu` first")
        self.md = read_model_description(str(self.path))
        self.unzipdir = extract(str(self.path))
        self.variables = {v.name: v for v in self.md.modelVariables}
        self.vr = {name: v.valueReference for name, v in self.variables.items()}

    def remove(self):
        shutil.rmtree(self.unzipdir, ignore_errors=True)


_extracted: list[Extracted3] = []


@functools.cache
def shared(model: str) -> Extracted3:
    e = Extracted3(model)
    _extracted.append(e)
    return e


def separate_copy(model: str) -> Extracted3:
    """A second unpacked copy: another library file, so the loader gives it its own code and data."""
    e = Extracted3(model)
    _extracted.append(e)
    return e


def require(model: str) -> Extracted3:
    """The shared copy; a missing archive fails the test, never skips it."""
    if not fmi3_path(model).is_file():
        pytest.fail(f"FMU archive not found: {fmi3_path(model)} (build with `cargo xtask fmu`)")
    return shared(model)


def remove_all():
    shared.cache_clear()
    while _extracted:
        _extracted.pop().remove()


class _Logged:
    """The logger every instance is created with: records (status, category, message)."""

    def _init_log(self):
        self.messages: list[tuple[int, str, str]] = []

        def log(env, status, category, message):
            self.messages.append((status, category.decode(), message.decode()))

        return log

    @staticmethod
    def _log_reasons(instance, everything: bool) -> None:
        """FMI 3.0.2 §2.3.1: with loggingOn = false the FMU calls no logger at all, so instances
        are made with it on; unless `everything`, only errors and warnings stay on."""
        if not everything:
            instance.setDebugLogging(False, ["logContactEvents", "logCalls"])

    def refused(self, call, *mentions: str) -> list[str]:
        """call() must fail with fmi3Error and log, under logErrors, a reason naming each of
        `mentions`; returns the new reasons."""
        before = len(self.messages)
        with pytest.raises(FMICallException) as e:
            call()
        assert e.value.status == fmi3Error, e.value.status
        reasons = [m[2] for m in self.messages[before:] if m[1] == "logErrors" and m[0] == fmi3Error]
        assert reasons, self.messages[before:]
        assert any(all(w in r for w in mentions) for r in reasons), (mentions, reasons)
        return reasons


class Slave3(_Logged):
    """An FMI 3.0 Co-Simulation instance (FMU3Slave), initialised and in Step Mode."""

    def __init__(
        self,
        fmu: Extracted3,
        name: str = "cs3",
        params: dict | None = None,
        start_time: float = 0.0,
        early_return: bool = False,
        event_mode: bool = False,
        initialise: bool = True,
        logging: bool = False,
    ):
        self.fmu, self.vr = fmu, fmu.vr
        self.early_return, self.event_mode = early_return, event_mode
        self.slave = FMU3Slave(
            guid=fmu.md.guid,
            unzipDirectory=fmu.unzipdir,
            modelIdentifier=fmu.md.coSimulation.modelIdentifier,
            instanceName=name,
        )
        self.slave.instantiate(
            loggingOn=True, eventModeUsed=event_mode, earlyReturnAllowed=early_return, logMessage=self._init_log()
        )
        self._log_reasons(self.slave, logging)
        self.params = dict(params or {})
        self.t0 = self.time = start_time
        self._in = (ctypes.c_uint * 2)(self.vr["tau_m"], self.vr["tau_L"])
        self._u = (ctypes.c_double * 2)()
        if initialise:
            self.initialise(start_time)

    def initialise(self, start_time: float = 0.0):
        """Parameters and start values, initialisation; with eventModeUsed initialisation ends in
        Event Mode (docs/model.md §7): one fmi3UpdateDiscreteStates, then Step Mode."""
        self.t0 = self.time = start_time
        self.set(self.params)
        self.slave.enterInitializationMode(startTime=start_time)
        self.slave.exitInitializationMode()
        if self.event_mode:
            self.initial_update = self.slave.updateDiscreteStates()
            self.slave.enterStepMode()

    def set(self, values: dict):
        if values:
            self.slave.setFloat64([self.vr[k] for k in values], [float(v) for v in values.values()])

    def get(self, *names: str) -> list[float]:
        return self.slave.getFloat64([self.vr[n] for n in names])

    def contact(self) -> int:
        return self.slave.getInt32([self.vr["contact"]])[0]

    def set_inputs(self, tau_m: float, tau_L: float):
        self._u[0], self._u[1] = tau_m, tau_L
        self.slave.fmi3SetFloat64(self.slave.component, self._in, 2, self._u, 2)

    def do_step(self, t: float, h: float):
        """fmi3DoStep: (eventHandlingNeeded, terminateSimulation, earlyReturn, lastSuccessfulTime);
        `time` follows lastSuccessfulTime."""
        answer = self.slave.doStep(currentCommunicationPoint=t, communicationStepSize=h)
        self.time = answer[3]
        return answer

    def step(self, t: float, h: float, tau_m: float, tau_L: float):
        self.set_inputs(tau_m, tau_L)
        return self.do_step(t, h)

    def free(self):
        self.slave.freeInstance()


class Model3(_Logged):
    """An FMI 3.0 Model Exchange instance (FMU3Model), initialised and in Continuous-Time Mode,
    with the calls an integrator makes (cf. me_driver.ModelInstance for FMI 2.0)."""

    def __init__(self, fmu: Extracted3, name: str = "me3", params: dict | None = None, start_time: float = 0.0):
        self.fmu, self.vr = fmu, fmu.vr
        self.model = FMU3Model(
            guid=fmu.md.guid,
            unzipDirectory=fmu.unzipdir,
            modelIdentifier=fmu.md.modelExchange.modelIdentifier,
            instanceName=name,
        )
        self.model.instantiate(loggingOn=True, logMessage=self._init_log())
        self._log_reasons(self.model, False)
        self.c = self.model.component
        self.nx = len(fmu.md.derivatives)
        self._x = (ctypes.c_double * self.nx)()
        self._dx = (ctypes.c_double * self.nx)()
        self._z = (ctypes.c_double * NZ)()
        self._u = (ctypes.c_double * 2)()
        self._in = (ctypes.c_uint * 2)(self.vr["tau_m"], self.vr["tau_L"])
        self.x_view = np.ctypeslib.as_array(self._x)
        self.set(params or {})
        self.model.enterInitializationMode(startTime=start_time)
        self.model.exitInitializationMode()
        self.initial_update = self.model.updateDiscreteStates()
        self.model.enterContinuousTimeMode()

    def set(self, values: dict):
        if values:
            self.model.setFloat64([self.vr[k] for k in values], [float(v) for v in values.values()])

    def get(self, *names: str) -> list[float]:
        return self.model.getFloat64([self.vr[n] for n in names])

    def contact(self) -> int:
        return self.model.getInt32([self.vr["contact"]])[0]

    def set_inputs(self, tau_m: float, tau_L: float):
        self._u[0], self._u[1] = tau_m, tau_L
        self.model.fmi3SetFloat64(self.c, self._in, 2, self._u, 2)

    def set_state(self, t: float, x):
        """Sets the drive train's states x[:4]; a web line's T is 0 (as me_driver)."""
        self.model.fmi3SetTime(self.c, t)
        self.x_view[:NX] = x[:NX]
        self.model.fmi3SetContinuousStates(self.c, self._x, self.nx)

    def derivatives(self, t: float, x, tau_m: float, tau_L: float) -> np.ndarray:
        """The drive train's derivatives at x[:4] (a web line's T at 0)."""
        self.set_state(t, x)
        self.set_inputs(tau_m, tau_L)
        self.model.fmi3GetContinuousStateDerivatives(self.c, self._dx, self.nx)
        return np.array(self._dx[:NX])

    def indicators(self, t: float, x) -> np.ndarray:
        self.set_state(t, x)
        self.model.fmi3GetEventIndicators(self.c, self._z, NZ)
        return np.array(self._z)

    def nominals(self) -> np.ndarray:
        """The drive train's nominals."""
        out = (ctypes.c_double * self.nx)()
        self.model.getNominalsOfContinuousStates(out, self.nx)
        return np.array(out[:NX])

    def free(self):
        self.model.freeInstance()


class LoggedSlave2:
    """An FMI 2.0 Co-Simulation instance (FMU2Slave) of the FMI 2.0 archive, initialised, whose
    logger records (status, category, message): the other standard's side of a comparison."""

    def __init__(self, fmu2: fmu_driver.Extracted, name: str, params: dict):
        from fmpy.fmi2 import (
            FMU2Slave,
            fmi2CallbackAllocateMemoryTYPE,
            fmi2CallbackFreeMemoryTYPE,
            fmi2CallbackFunctions,
            fmi2CallbackLoggerTYPE,
        )

        from me_driver import LOGGER_WITH_ARGUMENT

        self.vr = fmu2.vr
        self.messages: list[tuple[int, str, str]] = []

        def log(env, instance, status, category, format, text):
            self.messages.append((status, category.decode(), text.decode()))

        self._logger = LOGGER_WITH_ARGUMENT(log)  # kept alive as long as the instance
        self.callbacks = fmi2CallbackFunctions()
        self.callbacks.logger = ctypes.cast(self._logger, fmi2CallbackLoggerTYPE)
        self.callbacks.allocateMemory = fmi2CallbackAllocateMemoryTYPE(0)
        self.callbacks.freeMemory = fmi2CallbackFreeMemoryTYPE(0)
        self.slave = FMU2Slave(
            guid=fmu2.md.guid,
            unzipDirectory=fmu2.unzipdir,
            modelIdentifier=fmu2.md.coSimulation.modelIdentifier,
            instanceName=name,
        )
        self.slave.instantiate(callbacks=self.callbacks)
        self.slave.setReal([self.vr[k] for k in params], [float(v) for v in params.values()])
        self.slave.setupExperiment(startTime=0.0)
        self.slave.enterInitializationMode()
        self.slave.exitInitializationMode()

    def get(self, *names: str) -> list[float]:
        return self.slave.getReal([self.vr[n] for n in names])

    def contact(self) -> int:
        return self.slave.getInteger([self.vr["contact"]])[0]

    def free(self):
        self.slave.freeInstance()


def float64_names(fmu) -> list[str]:
    """Every Float64 (FMI 2.0: Real) variable the interface computes: outputs, locals
    (derivatives, event indicators) and the calculated parameter bound_sup."""
    kinds = ("output", "local", "calculatedParameter")
    return [n for n, v in fmu.variables.items() if v.type in ("Float64", "Real") and v.causality in kinds]


def bits(values) -> tuple[str, ...]:
    """Floats as exact hexadecimal strings: equal only if bit for bit equal (NaN included)."""
    return tuple(float(x).hex() for x in values)


# --- the sampled PI updated at every contact switch, closed around the exact plant -----------------


@dataclass
class SwitchSampledRun:
    """A run of the loop of `switch_sampled_pi`: states at the communication points, every
    sampling instant with the torque applied from it, and every switch (time, before, after)."""

    t: np.ndarray  # communication points t_0..t_N
    z: np.ndarray  # [theta_m, omega_m, theta_L, omega_L] at t_k
    xi: np.ndarray  # PI integral at t_k
    instants: list = field(default_factory=list)  # sampling instants: communication points and switches
    taus: list = field(default_factory=list)  # tau_m applied from each sampling instant on
    switches: list = field(default_factory=list)


class SwitchSampledPI:
    """PI on the motor speed sampled at the communication points AND at every contact switch.

    At each sampling instant s_j (sorted), with the next one s_j+1:
        e_j   = w_ref(s_j) - omega_m(s_j)
        tau_j = Kp e_j + Ki xi_j          held over [s_j, s_j+1)
        xi_j+1 = xi_j + (s_j+1 - s_j) e_j  (the exact integral of the held error)
    The next instant is not known when tau_j is chosen (a switch ends the interval early), so
    `sample` returns tau_j and `advance` adds the integral once the interval has ended."""

    def __init__(self, Kp: float, Ki: float, xi0: float = 0.0):
        self.Kp, self.Ki, self.xi = Kp, Ki, xi0
        self._e = None

    def sample(self, w_ref: float, omega_m: float) -> float:
        self._e = w_ref - omega_m
        return self.Kp * self._e + self.Ki * self.xi

    def advance(self, dt: float):
        self.xi += dt * self._e


def switch_sampled_pi(plant: Plant, Kp: float, Ki: float, h: float, n: int, w_ref, tau_L, z0=(0.0, 0.0, 0.0, 0.0)):
    """The loop of SwitchSampledPI around the exact plant of reference_continuous.py, built segment
    by segment because each hold depends on the switch that ends the previous one: from each
    sampling instant the exact solution (expm in the mode, Kp = Ki = 0 there: the torque is a
    held feed-forward) is searched for the first switch before the next communication point
    (ContinuousLoop._first_exit: grid, certified grazing search, brentq to ~1e-15 s). A switch
    ends the segment (state there with u exactly on +-g, the new mode in force), the PI is
    sampled there and a new hold starts; else the segment runs to the communication point.
    w_ref and tau_L are functions of the communication step index k (held over each step)."""
    loop = rc.ContinuousLoop(plant)  # the open plant: Kp = Ki = 0 in its matrix
    z0 = np.asarray(z0, dtype=float)
    y = np.array([z0[0], z0[1], plant.r_m * z0[0] - plant.r_L * z0[2], z0[3], 0.0, 1.0])
    pi = SwitchSampledPI(Kp, Ki)
    t_k = np.arange(n + 1) * h
    run = SwitchSampledRun(t_k, np.zeros((n + 1, 4)), np.zeros(n + 1))

    def record(k):
        run.z[k] = [y[rc.TH_M], y[rc.W_M], (plant.r_m * y[rc.TH_M] - y[rc.U]) / plant.r_L, y[rc.W_L]]
        run.xi[k] = pi.xi

    record(0)
    t, mode = 0.0, None
    for k in range(n):
        t_end = float(t_k[k + 1])
        while True:
            tau = pi.sample(w_ref(k), float(y[rc.W_M]))
            hold = rc.Hold(t, tau, tau_L(k), 0.0)
            if mode is None or abs(y[rc.U]) == plant.g:
                entered = loop.entering_mode(y, hold)
                assert mode is None or entered == mode, "a grazing switch: the test needs a transversal one"
                mode = entered
            run.instants.append(t)
            run.taus.append(tau)
            s, y_next, *target = loop._first_exit(loop.matrix(mode, hold), y, t_end - t, mode)
            if s is None:
                pi.advance(t_end - t)
                y, t = y_next, t_end
                break
            if s == 0.0:
                raise RuntimeError(f"switch at the start of a segment, t = {t}")
            run.switches.append((t + s, mode, target[0]))
            pi.advance(s)
            y, t, mode = y_next, t + s, target[0]
        record(k + 1)
    return run

"""Driving the packaged FMUs as FMI 2.0 Model Exchange through fmpy's FMU2Model, and the
continuous-time PI loop closed around any right-hand side with scipy's solve_ivp.

The loop integrator `run_loop` only needs an object with `derivatives`, `indicators` and the
importer's event hooks, so that the same code integrates the FMU (`ModelInstance`) and, in the
reference's own tests, the equations of docs/model.md §1 written in Python (`PythonPlant`).
"""

from __future__ import annotations

import ctypes
import math
from dataclasses import dataclass, field

import numpy as np
import pytest
from fmpy.fmi1 import FMICallException
from fmpy.fmi2 import (
    FMU2Model,
    fmi2CallbackAllocateMemoryTYPE,
    fmi2CallbackFreeMemoryTYPE,
    fmi2CallbackFunctions,
    fmi2CallbackLoggerTYPE,
    fmi2Error,
)
from scipy.integrate import solve_ivp

import fmu_driver
from reference import FREE, MINUS, PLUS, Plant
from reference_continuous import Hold

STATES = fmu_driver.STATE_OUTPUTS  # theta_m, omega_m, theta_L, omega_L: the continuous states, in order
DERIVATIVES = tuple(f"der({name})" for name in STATES)
# The drive train's states; BacklashWeb has its span's tension T as a fifth, which the drive-train
# tests hold at 0 (its web decoupled, rigs.WEB_DECOUPLED).
NX, NZ = 4, 2

# The FMU logs through format "%s" with the message as the one variadic argument; on x86-64 and
# AArch64 Linux it arrives like a sixth fixed argument (as in test_robustness.py).
LOGGER_WITH_ARGUMENT = ctypes.CFUNCTYPE(
    None, ctypes.c_void_p, ctypes.c_char_p, ctypes.c_int, ctypes.c_char_p, ctypes.c_char_p, ctypes.c_char_p
)


class ModelInstance:
    """An FMU2Model instance, initialised and in Continuous-Time Mode, whose logger records
    (status, category, message)."""

    def __init__(self, fmu: fmu_driver.Extracted, name: str = "me", params: dict | None = None, start_time: float = 0.0):
        self.fmu, self.vr = fmu, fmu.vr
        self.messages: list[tuple[int, str, str]] = []

        def log(env, instance, status, category, format, text):
            self.messages.append((status, category.decode(), text.decode()))

        self._logger = LOGGER_WITH_ARGUMENT(log)  # kept alive as long as the instance
        self.callbacks = fmi2CallbackFunctions()
        self.callbacks.logger = ctypes.cast(self._logger, fmi2CallbackLoggerTYPE)
        self.callbacks.allocateMemory = fmi2CallbackAllocateMemoryTYPE(0)
        self.callbacks.freeMemory = fmi2CallbackFreeMemoryTYPE(0)
        self.model = FMU2Model(
            guid=fmu.md.guid,
            unzipDirectory=fmu.unzipdir,
            modelIdentifier=fmu.md.modelExchange.modelIdentifier,
            instanceName=name,
        )
        self.model.instantiate(callbacks=self.callbacks)
        self.c = self.model.component
        self.nx = len(fmu.md.derivatives)
        self._x = (ctypes.c_double * self.nx)()
        self._dx = (ctypes.c_double * self.nx)()
        self._z = (ctypes.c_double * NZ)()
        self._u = (ctypes.c_double * 2)()
        self._input_vr = (ctypes.c_uint * 2)(self.vr["tau_m"], self.vr["tau_L"])
        self.x_view = np.ctypeslib.as_array(self._x)
        self.set(params or {})
        self.start_time = start_time
        self.model.setupExperiment(startTime=start_time)
        self.model.enterInitializationMode()
        self.model.exitInitializationMode()
        self.initial_event = self.model.newDiscreteStates()
        self.model.enterContinuousTimeMode()

    # --- values -------------------------------------------------------------------------------

    def set(self, values: dict):
        if values:
            self.model.setReal([self.vr[k] for k in values], [float(v) for v in values.values()])

    def get(self, *names: str) -> list[float]:
        return self.model.getReal([self.vr[n] for n in names])

    def contact(self) -> int:
        return self.model.getInteger([self.vr["contact"]])[0]

    def set_inputs(self, tau_m: float, tau_L: float):
        self._u[0], self._u[1] = tau_m, tau_L
        self.model.fmi2SetReal(self.c, self._input_vr, 2, self._u)

    def set_state(self, t: float, x):
        """Sets the drive train's states x[:4]; a web line's T is 0."""
        self.model.fmi2SetTime(self.c, t)
        self.x_view[:NX] = x[:NX]
        self.model.fmi2SetContinuousStates(self.c, self._x, self.nx)

    def derivatives(self, t: float, x, tau_m: float, tau_L: float) -> np.ndarray:
        """The drive train's derivatives at x[:4] (a web line's T at 0)."""
        self.set_state(t, x)
        self.set_inputs(tau_m, tau_L)
        self.model.fmi2GetDerivatives(self.c, self._dx, self.nx)
        return np.array(self._dx[:NX])

    def indicators(self, t: float, x) -> np.ndarray:
        self.set_state(t, x)
        self.model.fmi2GetEventIndicators(self.c, self._z, NZ)
        return np.array(self._z)

    def nominals(self) -> np.ndarray:
        """The drive train's nominals."""
        out = (ctypes.c_double * self.nx)()
        self.model.getNominalsOfContinuousStates(out, self.nx)
        return np.array(out[:NX])

    def continuous_states(self) -> np.ndarray:
        """The drive train's states."""
        out = (ctypes.c_double * self.nx)()
        self.model.getContinuousStates(out, self.nx)
        return np.array(out[:NX])

    # --- the importer's event handling (FMI 2.0 §3.2.2) ----------------------------------------

    def completed_step(self) -> tuple[bool, bool]:
        """fmi2CompletedIntegratorStep: (enterEventMode, terminateSimulation)."""
        return self.model.completedIntegratorStep()

    def event_iteration(self):
        """Event Mode, one fmi2NewDiscreteStates, back to Continuous-Time Mode: the event info."""
        self.model.enterEventMode()
        info = self.model.newDiscreteStates()
        self.model.enterContinuousTimeMode()
        return info

    # --- refusals -------------------------------------------------------------------------------

    def refused(self, call, *mentions: str) -> list[str]:
        """call() must fail with fmi2Error and log, under logErrors, a reason that names each of
        `mentions` (the culprit: a variable, a length); returns the new reasons."""
        before = len(self.messages)
        with pytest.raises(FMICallException) as e:
            call()
        assert e.value.status == fmi2Error
        reasons = [m[2] for m in self.messages[before:] if m[1] == "logErrors"]
        assert any(all(w in r for w in mentions) for r in reasons), (mentions, self.messages[before:])
        return reasons

    def free(self):
        self.model.freeInstance()


class PythonPlant:
    """The right-hand side and event indicators of docs/model.md §1 written directly in
    Python, with the same interface as ModelInstance: the double that tests run_loop itself."""

    def __init__(self, plant: Plant):
        self.p = plant

    def derivatives(self, t, x, tau_m, tau_L):
        p = self.p
        psi = p.K * p.dead_zone(p.r_m * x[0] - p.r_L * x[2])
        return np.array(
            [x[1], (tau_m - p.b_m * x[1] - p.r_m * psi) / p.J_m, x[3], (tau_L - p.b_L * x[3] + p.r_L * psi) / p.J_L]
        )

    def indicators(self, t, x):
        u = self.p.r_m * x[0] - self.p.r_L * x[2]
        return np.array([u - self.p.g, u + self.p.g])

    def set_state(self, t, x):
        pass

    def completed_step(self):
        return False, False

    def event_iteration(self):
        return (False, False, False, False, False, 0.0)


@dataclass
class LoopRun:
    """States at the output times (z: the model's four, xi: the PI integral), the motor torque
    there, and every located crossing of an event indicator as (time, mode before, mode after)."""

    t: np.ndarray
    z: np.ndarray
    xi: np.ndarray
    tau_m: np.ndarray
    switches: list = field(default_factory=list)
    event_infos: list = field(default_factory=list)
    step_answers: list = field(default_factory=list)


def _mode(sides) -> int:
    """Contact mode from the signs of the indicators [u - g, u + g]."""
    if sides[0] > 0:
        return PLUS
    if sides[1] < 0:
        return MINUS
    return FREE


def run_loop(model, Kp, Ki, holds: list[Hold], t_out, z0, xi0=0.0, rtol=1e-12, atol=1e-15, events=True) -> LoopRun:
    """The continuous-time PI of docs/model.md §3 closed around `model`:

        y = [theta_m, omega_m, theta_L, omega_L, xi],   xi' = w_ref - omega_m,
        tau_m = tau_ff + Kp (w_ref - omega_m) + Ki xi,

    integrated by solve_ivp (DOP853) from hold to hold (the signals jump there, so every hold
    starts a new integration), with the model's two event indicators as terminal events: each
    crossing stops the integration at the located root, the importer's event iteration runs
    there, and the integration restarts from the event state. After a crossing an indicator
    is watched only for the crossing back (its event direction is the opposite), so that the
    restart, which lies on the root to round-off, cannot fire the same event again.
    events=False integrates without events (for Delta = 0, where the right-hand side is linear
    and both indicators are u: there is nothing to locate). solve_ivp looks for sign changes at
    its step ends only, so a contact entered and left within one step would go unseen; the
    tests compare the whole switch sequence with the exact one, which would show it."""
    t_out = np.asarray(t_out, dtype=float)
    t_end = float(t_out[-1])
    y = np.array([*z0, xi0], dtype=float)
    t = holds[0].t
    Y_out = np.full((len(t_out), 5), np.nan)
    run = LoopRun(t_out, None, None, None)
    sides = np.sign(model.indicators(t, y)) if events else np.zeros(NZ)
    if events and np.any(sides == 0.0):
        raise ValueError("the run must not start on a switching surface")

    for k, hold in enumerate(holds):
        seg_end = min(holds[k + 1].t if k + 1 < len(holds) else math.inf, t_end)

        def rhs(s, yy, hold=hold):
            e = hold.w_ref - yy[1]
            tau = hold.tau_m + Kp * e + Ki * yy[4]
            return np.append(model.derivatives(s, yy, tau, hold.tau_L), e)

        while t < seg_end:
            functions = []
            if events:
                cache: dict = {}

                def indicator(s, yy, i, cache=cache):
                    key = (s, yy.tobytes())
                    if key not in cache:
                        cache.clear()
                        cache[key] = model.indicators(s, yy)
                    return cache[key][i]

                for i in range(NZ):
                    fn = lambda s, yy, i=i: indicator(s, yy, i)  # noqa: E731
                    fn.terminal, fn.direction = True, -sides[i]
                    functions.append(fn)
            sol = solve_ivp(
                rhs, (t, seg_end), y, method="DOP853", rtol=rtol, atol=atol, events=functions or None, dense_output=True
            )
            if sol.status == -1:
                raise RuntimeError(f"solve_ivp failed at t = {t}: {sol.message}")
            stop = float(sol.t[-1])
            mask = (t_out >= t) & (t_out <= stop)
            if np.any(mask):
                Y_out[mask] = sol.sol(t_out[mask]).T
            if sol.status == 1:
                fired = [i for i in range(NZ) if len(sol.t_events[i])]
                stop = min(float(sol.t_events[i][0]) for i in fired)
                fired = [i for i in fired if float(sol.t_events[i][0]) == stop]
                y = sol.y_events[fired[0]][0].copy()
                before = _mode(sides)
                for i in fired:
                    sides[i] = -sides[i]
                run.switches.append((stop, before, _mode(sides)))
                model.set_state(stop, y)
                run.event_infos.append(model.event_iteration())
            else:
                y = sol.y[:, -1].copy()
            if stop <= t:
                raise RuntimeError(f"events do not advance at t = {t}")
            t = stop
            model.set_state(t, y)
            run.step_answers.append(model.completed_step())
        if t >= t_end:
            break
    if np.any(np.isnan(Y_out)):
        raise ValueError("output times beyond the last hold's reach")
    starts = np.array([h.t for h in holds])
    idx = np.searchsorted(starts, t_out, side="right") - 1
    run.tau_m = np.array(
        [holds[i].tau_m + Kp * (holds[i].w_ref - w) + Ki * x for i, w, x in zip(idx, Y_out[:, 1], Y_out[:, 4])]
    )
    run.z, run.xi = Y_out[:, :4], Y_out[:, 4]
    return run


def outputs_along(inst: ModelInstance, run: LoopRun, names=("psi", "bound", "bound_paper")) -> dict[str, np.ndarray]:
    """The FMU's outputs at the run's output times, each read after fmi2SetTime and
    fmi2SetContinuousStates (in Continuous-Time Mode): Real outputs and `contact`. `inst` must
    be one that has not integrated past the first output time: time cannot go back over a
    completed integrator step or an event (FMI 2.0.4 §3.2.2), so a fresh instance reads them."""
    rows, contact = [], []
    for t, z in zip(run.t, run.z):
        inst.set_state(t, z)
        rows.append(inst.get(*names))
        contact.append(inst.contact())
    a = np.array(rows)
    out = {n: a[:, j] for j, n in enumerate(names)}
    out["contact"] = np.array(contact)
    return out


# ---- fmpy's CVode on a Model Exchange archive against the exact solution (FMI 2.0 and 3.0) ----

CVODE_RTOL = 1e-9
# Relative to each signal's largest value: CVode controls only its local error, and over 4 s of
# lightly damped oscillation and ~70 restarts its global error was measured at 560 rtol.
CVODE_TOL = 2000 * CVODE_RTOL


def state_with_u(plant: Plant, u: float, theta_m=0.2, omega_m=0.5, omega_L=-0.4) -> np.ndarray:
    """[theta_m, omega_m, theta_L, omega_L] with transmission coordinate u (docs/model.md §1)."""
    return np.array([theta_m, omega_m, (plant.r_m * theta_m - u) / plant.r_L, omega_L])


def held_table(tau_m, tau_L, h: float) -> np.ndarray:
    """Held torques as an fmpy input table: every switching time twice (value before, after)."""
    edges = np.arange(len(tau_m) + 1) * h
    rows = [
        row for k in range(len(tau_m)) for row in ((edges[k], tau_m[k], tau_L[k]), (edges[k + 1], tau_m[k], tau_L[k]))
    ]
    return np.array(rows, dtype=[("time", np.double), ("tau_m", np.double), ("tau_L", np.double)])


def check_cvode_against_exact(path: str, params: dict, plant: Plant):
    """fmpy.simulate_fmu(ModelExchange, CVode, rtol CVODE_RTOL) of the archive at `path` under
    torques reversing every 0.1 s for 4 s, from a moving start inside the gap, against the exact
    solution (reference_continuous.py) at the output points: states, u and psi within CVODE_TOL;
    every switch a state event (a repeated output time off the input edges) within the shift that
    error makes at the crossing speed; `contact` the side of the gap wherever that is clear."""
    from fmpy import simulate_fmu

    import reference_continuous as rc
    from signals import rel_err, reversing_torques

    h, n = 0.1, 40
    tau_m, tau_L = reversing_torques(n, h, 1.5, 0.6)
    edges = np.arange(n + 1) * h
    z0 = state_with_u(plant, 0.5 * plant.g, 0.01, 1.0, -0.5)
    result = simulate_fmu(
        path,
        fmi_type="ModelExchange",
        solver="CVode",
        relative_tolerance=CVODE_RTOL,
        start_time=0.0,
        stop_time=n * h,
        output_interval=0.01,
        input=held_table(tau_m, tau_L, h),
        start_values={**params, **dict(zip(STATES, z0))},
        output=[*STATES, "psi", "contact"],
    )
    t = result["time"]  # the 401 output points and, twice each, the events (record_events)
    # Exact: the start and stop times are the ones passed in, and fmpy records times in order.
    assert t[0] == 0.0 and t[-1] == n * h and np.all(np.diff(t) >= 0.0)
    assert np.all(np.min(np.abs(t[None, :] - np.linspace(0.0, n * h, 401)[:, None]), axis=1) <= 1e-12)
    exact = rc.solve(plant, rc.open_loop_holds(tau_m, tau_L, h), t, z0=z0)
    errors = {name: rel_err(result[name], exact.z[:, j]) for j, name in enumerate(STATES)}
    errors["u"] = rel_err(plant.r_m * result["theta_m"] - plant.r_L * result["theta_L"], exact.u)
    errors["psi"] = rel_err(result["psi"], [plant.K * plant.dead_zone(x) for x in exact.u])
    assert max(errors.values()) <= CVODE_TOL, errors

    repeated = t[1:][np.diff(t) == 0.0]
    state_events = [x for x in repeated if np.min(np.abs(x - edges)) > 1e-12]
    assert len(exact.switches) >= 20 and len(state_events) == len(exact.switches)
    u_max = np.max(np.abs(exact.u))
    for t_cv, (t_ref, _, _), rate in zip(state_events, exact.switches, exact.switch_rates):
        assert abs(t_cv - t_ref) <= CVODE_TOL * u_max / abs(rate), (t_cv, t_ref, rate)
    clear = np.abs(np.abs(exact.u) - plant.g) > CVODE_TOL * u_max
    side = np.where(exact.u > plant.g, PLUS, np.where(exact.u < -plant.g, MINUS, FREE))
    assert np.array_equal(result["contact"][clear], side[clear])

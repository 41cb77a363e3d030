"""Runs shared by several test modules, each computed once per session: the FMU through
backlash_fmu.fmu (fmpy) and the independent reference on the same inputs."""

from __future__ import annotations

import functools

import numpy as np
from backlash_fmu.fmu import STATES

import archives
import reference
import reference_friction
from loops import Record, run_open_loop, run_pi_loop
from rigs import RIGS, plant_of, with_delta
from signals import reversing_torques, sine_reference, step_reference

# Open-loop cases: (step h in s, number of steps, initial state z0). The coarse step puts
# several contact switches inside one communication step; the last case starts in contact.
OPEN_LOOP_CASES = {
    "fine": (0.02, 400, (0.0, 0.0, 0.0, 0.0)),
    "coarse": (0.25, 32, (0.0, 0.0, 0.0, 0.0)),
    "moving-start": (0.02, 250, (0.01, 1.0, 0.0, -0.5)),
}
# The reversing torques' amplitudes (tau_m, tau_L) in N.m, the same for every model.
TORQUE = (1.5, 0.6)


@functools.cache
def open_loop(model: str, case: str):
    """(FMU outputs, reference z, reference u, reference solver) under reversing held torques."""
    h, n, z0 = OPEN_LOOP_CASES[case]
    params, gains = RIGS[model]
    tau_m, tau_L = reversing_torques(n, h, *TORQUE)
    initial = dict(zip(STATES, z0))
    inst = archives.shared(model).co_simulation(f"open-{case}", {**params, **gains, **initial})
    try:
        out = run_open_loop(inst, tau_m, tau_L, h)
    finally:
        inst.free()
    z, u, ref = reference.run_open_loop(plant_of(model, params), tau_m, tau_L, h, z0=np.array(z0))
    return out, z, u, ref


# The PI loop closed outside the FMU: a reversing speed reference (rad/s) and a load step
# (N.m) at 4 s, sampled every 10 ms.
PI_STEP, PI_STEPS = 0.01, 800


def pi_inputs():
    return sine_reference(5.0, 0.5), (lambda t: -2.0 if t >= 4.0 else 0.0)


@functools.cache
def pi_loop(model: str):
    """(FMU outputs incl. tau_m, reference z, u, tau_m, solver) for the sampled PI loop."""
    params, gains = RIGS[model]
    w_ref, tau_L = pi_inputs()
    inst = archives.shared(model).co_simulation("pi-loop", {**params, **gains})
    try:
        out = run_pi_loop(inst, reference.SampledPI(gains["Kp"], gains["Ki"], PI_STEP), PI_STEP, PI_STEPS, w_ref, tau_L)
    finally:
        inst.free()
    z, u, taus, ref = reference.run_pi_loop(plant_of(model, params), gains["Kp"], gains["Ki"], PI_STEP, PI_STEPS, w_ref, tau_L)
    return out, z, u, taus, ref


# Twin runs for the bound (docs/model.md §3) on the paper's rig: step size and speed references.
TWIN_STEP = 1e-3
TWIN_REFERENCES = {
    "step": (step_reference(10.0), 3.0),  # rad/s, duration s
    "sine": (sine_reference(5.0, 1.0), 4.0),
}


@functools.cache
def twin(reference_name: str):
    """Two shaft FMU instances side by side, Delta > 0 and Delta = 0, stepped in lockstep,
    each under its own copy of the same sampled PI; the FMUs' Kp, Ki are the loop's gains so
    that `bound` refers to them. Returns the two output records."""
    model = "BacklashShaft"
    params, gains = RIGS[model]
    w_ref, duration = TWIN_REFERENCES[reference_name]
    n = int(round(duration / TWIN_STEP))
    fmu = archives.shared(model)
    insts = [fmu.co_simulation(f"twin-{d}", {**with_delta(params, d), **gains}) for d in (params["Delta"], 0.0)]
    try:
        pis = [reference.SampledPI(gains["Kp"], gains["Ki"], TWIN_STEP) for _ in insts]
        records = [Record() for _ in insts]
        for inst, rec in zip(insts, records):
            rec.add(inst)
        for k in range(n):
            t = k * TWIN_STEP
            for inst, pi, rec in zip(insts, pis, records):
                omega_m = rec.rows[-1][1]  # measured at t_k (Record column order)
                inst.step(t, TWIN_STEP, tau_m=pi(w_ref(t), omega_m), tau_L=0.0)
                rec.add(inst)
    finally:
        for inst in insts:
            inst.free()
    return records[0].arrays(), records[1].arrays()


# Bearing friction (docs/model.md §12): a slow reversal on each rig, the motor driven by
# 0.3 sin(2 pi 0.25 t) N.m held every 10 ms for 8 s, no load torque. The load's breakaway torque
# (1.4 x 0.15 N.m) exceeds the motor's (1.2 x 0.05 N.m), so at each reversal the load sticks while
# the motor turns back across the gap, until the compliant member pulls it away.
FRICTION = {"tau_c_m": 0.05, "tau_c_L": 0.15, "peak_m": 1.2, "peak_L": 1.4}
FRICTION_STEP, FRICTION_STEPS = 0.01, 800


def friction_torques():
    """(tau_m, tau_L) per step of the slow reversal."""
    t = np.arange(FRICTION_STEPS) * FRICTION_STEP
    return 0.3 * np.sin(2 * np.pi * 0.25 * t), np.zeros(FRICTION_STEPS)


@functools.cache
def friction_reversal_reference(model: str, rtol: float = 1e-12, atol: float = 1e-16, method: str = "DOP853"):
    """(outputs, solver) of reference_friction.py for the slow reversal on `model`'s rig."""
    params, _ = RIGS[model]
    return reference_friction.run_open_loop(plant_of(model, params), reference_friction.Friction(**FRICTION),
                                            *friction_torques(), FRICTION_STEP, rtol=rtol, atol=atol, method=method)

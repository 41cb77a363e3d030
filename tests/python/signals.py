"""Input signals and the error measure shared by the tests."""

from __future__ import annotations

import math

import numpy as np


def rel_err(actual, expected) -> float:
    """max |actual - expected| / max |expected| over a whole signal: a relative error that stays
    meaningful where the signal crosses zero (speeds reverse, psi is 0 in the gap)."""
    actual, expected = np.asarray(actual, dtype=float), np.asarray(expected, dtype=float)
    scale = np.max(np.abs(expected))
    assert scale > 0.0, "reference signal is identically zero"
    return float(np.max(np.abs(actual - expected)) / scale)


def reversing_torques(n: int, h: float, motor: float, load: float):
    """Zero-mean torque sequences (N.m), one value per step t_k = k h, that reverse the
    motor several times against a slowly reversing load: the gap is crossed again and again."""
    t = np.arange(n) * h
    tau_m = motor * (np.sin(2 * math.pi * 0.4 * t) + 0.5 * np.sin(2 * math.pi * 1.3 * t + 1.0))
    tau_L = -load * np.sin(2 * math.pi * 0.25 * t)
    return tau_m, tau_L


def step_reference(value: float):
    return lambda t: value


def sine_reference(amplitude: float, frequency: float):
    return lambda t: amplitude * math.sin(2 * math.pi * frequency * t)


def held_table(tau_m, tau_L, h: float) -> np.ndarray:
    """Held torques as an fmpy input table: every switching time twice (value before, after)."""
    edges = np.arange(len(tau_m) + 1) * h
    rows = [
        row for k in range(len(tau_m)) for row in ((edges[k], tau_m[k], tau_L[k]), (edges[k + 1], tau_m[k], tau_L[k]))
    ]
    return np.array(rows, dtype=[("time", np.double), ("tau_m", np.double), ("tau_L", np.double)])

"""Measured runs for the identification tests, made without the library under test.

The plant is docs/model.md §1 (shaft and belt), integrated by reference.py's event-located
DOP853 (a different method from the library's exact matrix-exponential stepping), with the
inputs held per sample (zero-order hold, docs/model.md §11). The run starts at rest with u(0) = u0 inside
the gap; the angle columns are measured from the start (θ(0) = 0), so the load's true starting
angle θ_L(0) = -u0 / r_L is not in the data. Then Gaussian noise and quantisation (an encoder's
counts on the angles, a resolution on the speeds) are added, and the run is written as the CSV
of docs/model.md §11: `time,tau_m[,tau_L],<measured outputs>`.

The excitation here (reversing torque steps plus a multisine, within a torque limit) is this
file's own, so that the tests do not rest on `backlash excite` alone.
"""

from __future__ import annotations

import csv
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from reference import Plant, run_open_loop

# The paper's rig in shaft form and the belt rig (tests/fixtures/rigs.toml, by FMU names).
from rigs import BELT, SHAFT

OUTPUTS = ("theta_m", "omega_m", "theta_L", "omega_L")


def plant(model: str, params: dict) -> Plant:
    if model == "shaft":
        return Plant.shaft(params["J_m"], params["J_L"], params["b_m"], params["b_L"], params["k"], params["Delta"])
    if model == "belt":
        keys = ("J_m", "J_L", "b_m", "b_L", "K_b", "R_1", "R_2", "R_g1", "R_g2", "Delta")
        return Plant.belt(*(params[k] for k in keys))
    raise ValueError(model)


def rig(model: str) -> dict:
    """The drive-train parameters of the test rig (no PI gains)."""
    base = SHAFT if model == "shaft" else BELT
    return {k: v for k, v in base.items() if k not in ("Kp", "Ki")}


def reversing_steps(n: int, h: float, amplitude: float, period: float, limit: float | None = None,
                    multisine: float = 0.0, seed: int = 0) -> np.ndarray:
    """A torque schedule of n samples: a square wave ±amplitude of the given period, starting with
    half a period at +amplitude so that the mean speed stays near zero, plus (optionally) a
    multisine of total amplitude `multisine` on five frequencies between 0.5 and 4 Hz with random
    phases; clipped to ±limit."""
    t = np.arange(n) * h
    half = period / 2
    # +A over the first quarter period, then the sign alternates every half period.
    phase = np.floor((t + half / 2) / half).astype(int)
    tau = amplitude * np.where(phase % 2 == 0, 1.0, -1.0)
    if multisine:
        rng = np.random.default_rng(seed)
        freqs = np.array([0.5, 1.1, 1.7, 2.6, 4.0])
        phases = rng.uniform(0, 2 * np.pi, freqs.size)
        tau = tau + multisine / freqs.size * np.sin(2 * np.pi * freqs[:, None] * t + phases[:, None]).sum(axis=0)
    if limit is not None:
        tau = np.clip(tau, -limit, limit)
    return tau


@dataclass
class Run:
    """A clean simulated run: the inputs per sample, the true outputs at the sample instants."""

    model: str
    params: dict
    u0: float
    h: float
    tau_m: np.ndarray
    tau_L: np.ndarray
    clean: dict = field(default_factory=dict)  # OUTPUTS -> values at t_0..t_{n-1}
    u: np.ndarray | None = None  # the transmission coordinate at the samples
    switches: int = 0

    @property
    def time(self) -> np.ndarray:
        return np.arange(self.tau_m.size) * self.h

    def truth(self) -> dict:
        """The true values by the names identify reports (stiffness as the model names it)."""
        stiff = "k" if self.model == "shaft" else "K_b"
        return {"Delta": self.params["Delta"], stiff: self.params[stiff], "J_L": self.params["J_L"],
                "b_L": self.params["b_L"], "u0": self.u0}


def simulate(model: str, params: dict, tau_m, h: float, u0: float, tau_L=None, rtol: float = 1e-11) -> Run:
    """The plant from rest with u(0) = u0, each row's torques held to the next row; outputs at
    every row's time (row 0: the start, θ = 0). The last row's inputs act after the last sample."""
    tau_m = np.asarray(tau_m, dtype=float)
    tau_L = np.zeros_like(tau_m) if tau_L is None else np.asarray(tau_L, dtype=float)
    p = plant(model, params)
    z0 = np.array([0.0, 0.0, -u0 / p.r_L, 0.0])  # u(0) = r_m 0 - r_L θ_L(0) = u0
    zs, us, ref = run_open_loop(p, tau_m[:-1], tau_L[:-1], h, z0=z0, rtol=rtol, atol=1e-16)
    clean = {
        "theta_m": zs[:, 0] - zs[0, 0],
        "omega_m": zs[:, 1],
        "theta_L": zs[:, 2] - zs[0, 2],
        "omega_L": zs[:, 3],
    }
    return Run(model, dict(params), u0, h, tau_m, tau_L, clean, us, len(ref.switches))


@dataclass(frozen=True)
class Sensors:
    """Which outputs are measured and how: speed noise σ [rad/s] and resolution, encoder counts
    per revolution (angle quantisation 2π/counts) and an angle noise σ [rad]."""

    outputs: tuple[str, ...]
    speed_sigma: float = 2e-3
    speed_resolution: float = 1e-3
    counts_per_rev: int = 1 << 16
    angle_sigma: float = 0.0

    def measure(self, run: Run, rng: np.random.Generator) -> dict:
        out = {}
        for name in self.outputs:
            x = run.clean[name]
            if name.startswith("omega"):
                y = x + self.speed_sigma * rng.standard_normal(x.size)
                q = self.speed_resolution
            else:
                y = x + self.angle_sigma * rng.standard_normal(x.size)
                q = 2 * np.pi / self.counts_per_rev
            y = q * np.round(y / q)
            if not name.startswith("omega"):
                y[0] = 0.0  # the encoder is zeroed at the start
            out[name] = y
        return out


def table(run: Run, sensors: Sensors, seed: int, with_tau_L: bool = False) -> dict[str, list[float]]:
    """The measured run as a table (column name -> values), in the order of the CSV header."""
    rng = np.random.default_rng(seed)
    cols = {"time": run.time, "tau_m": run.tau_m}
    if with_tau_L:
        cols["tau_L"] = run.tau_L
    measured = sensors.measure(run, rng)
    for name in OUTPUTS:
        if name in measured:
            cols[name] = measured[name]
    return {k: [float(v) for v in vals] for k, vals in cols.items()}


def write_csv(path: Path, cols: dict[str, list[float]]) -> Path:
    path = Path(path)
    names = list(cols)
    with path.open("w", newline="") as f:
        w = csv.writer(f)
        w.writerow(names)
        for row in zip(*(cols[n] for n in names)):
            w.writerow([repr(v) for v in row])
    return path


def read_csv(path: Path) -> dict[str, np.ndarray]:
    with Path(path).open() as f:
        rows = list(csv.reader(f))
    names = rows[0]
    data = np.array([[float(c) for c in r] for r in rows[1:]])
    return {n: data[:, i] for i, n in enumerate(names)}

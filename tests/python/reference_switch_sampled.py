"""The sampled-data PI loop that is updated at the communication points and at every contact
switch, closed around the exact plant of reference_continuous.py: the independent side of the
FMI 3.0 early-return loop test (test_fmi3.py)."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

import reference_continuous as rc
from reference import Plant


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

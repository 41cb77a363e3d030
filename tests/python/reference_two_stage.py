"""Independent reference solution of the two-stage gearbox (docs/model.md §10, BacklashTwoStage).

Written from the equations alone, with a method other than the FMU's exact stepping: scipy's
DOP853 (rtol 1e-13, atol 1e-17) inside each tuple of the meshes' modes, every switch of either
mesh located as a terminal event on u_j - Delta_j or u_j + Delta_j and the integration restarted
in the new mode there. Inputs held over each communication step. No damper, no bearing
friction: the plant of the equations

    u_1 = theta_m - n_1 theta_i,   psi_1 = k_1 dz(u_1, Delta_1)
    u_2 = theta_i - n_2 theta_L,   psi_2 = k_2 dz(u_2, Delta_2)
    J_m omega_m' = tau_m - b_m omega_m - psi_1
    J_i omega_i' =       - b_i omega_i + n_1 psi_1 - psi_2
    J_L omega_L' = tau_L - b_L omega_L + n_2 psi_2

The state is kept as x = [theta_m, omega_m, u_1, omega_i, u_2, omega_L] (each u integrated
directly, as reference.py does for the single gap); `z` gives [theta_m, omega_m, theta_i,
omega_i, theta_L, omega_L].
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.integrate import solve_ivp

FREE, PLUS, MINUS = 0, 1, -1


@dataclass(frozen=True)
class Gearbox:
    J_m: float
    J_i: float
    J_L: float
    b_m: float
    b_i: float
    b_L: float
    n_1: float
    n_2: float
    k_1: float
    k_2: float
    Delta_1: float
    Delta_2: float

    @classmethod
    def of(cls, params: dict) -> "Gearbox":
        """From the FMU's parameters by name; refused with a damper or friction (not this plant)."""
        for name in ("d_1", "d_2", "tau_c_m", "tau_c_i", "tau_c_L"):
            if params.get(name, 0.0) != 0.0:
                raise ValueError(f"{name} > 0: the reference solves the undamped plant without friction")
        return cls(*(params[f] for f in cls.__dataclass_fields__))

    def psi(self, j: int, u: float, mode: int) -> float:
        k, g = (self.k_1, self.Delta_1) if j == 0 else (self.k_2, self.Delta_2)
        return {FREE: 0.0, PLUS: k * (u - g), MINUS: k * (u + g)}[mode]

    def gap(self, j: int) -> float:
        return self.Delta_1 if j == 0 else self.Delta_2

    def to_internal(self, z) -> np.ndarray:
        th_m, w_m, th_i, w_i, th_L, w_L = z
        return np.array([th_m, w_m, th_m - self.n_1 * th_i, w_i, th_i - self.n_2 * th_L, w_L], dtype=float)

    def to_state(self, x) -> np.ndarray:
        th_m, w_m, u_1, w_i, u_2, w_L = x
        th_i = (th_m - u_1) / self.n_1
        return np.array([th_m, w_m, th_i, w_i, (th_i - u_2) / self.n_2, w_L])

    def rhs(self, modes: tuple[int, int], tau_m: float, tau_L: float):
        def f(_t, x):
            _, w_m, u_1, w_i, u_2, w_L = x
            psi_1, psi_2 = self.psi(0, u_1, modes[0]), self.psi(1, u_2, modes[1])
            return [
                w_m,
                (tau_m - self.b_m * w_m - psi_1) / self.J_m,
                w_m - self.n_1 * w_i,
                (-self.b_i * w_i + self.n_1 * psi_1 - psi_2) / self.J_i,
                w_i - self.n_2 * w_L,
                (tau_L - self.b_L * w_L + self.n_2 * psi_2) / self.J_L,
            ]

        return f

    def entering(self, x, tau_m: float, tau_L: float) -> tuple[int, int]:
        """Each mesh's mode at x: the side of its gap u_j is on; exactly on a flank, the mode its
        rate (then its acceleration, in the free mode) enters."""
        modes = []
        free = self.rhs((FREE, FREE), tau_m, tau_L)(0.0, x)
        for j, (ui, dui) in enumerate(((2, 2), (4, 4))):
            u, g = x[ui], self.gap(j)
            du = free[dui]
            if -g < u < g:
                modes.append(FREE)
            elif u > g:
                modes.append(PLUS)
            elif u < -g:
                modes.append(MINUS)
            elif u == g:
                modes.append(PLUS if du > 0.0 else FREE)
            else:
                modes.append(MINUS if du < 0.0 else FREE)
        return tuple(modes)


def _events(box: Gearbox, modes: tuple[int, int]):
    """Terminal switch events of each mesh in `modes`: (event, mesh, the mesh's next mode)."""
    out = []
    for j, index in ((0, 2), (1, 4)):
        g = box.gap(j)

        def upper(_t, x, i=index, g=g):
            return x[i] - g

        def lower(_t, x, i=index, g=g):
            return x[i] + g

        upper.terminal = lower.terminal = True
        if modes[j] == FREE:
            upper.direction, lower.direction = 1.0, -1.0
            out += [(upper, j, PLUS), (lower, j, MINUS)]
        elif modes[j] == PLUS:
            upper.direction = -1.0
            out.append((upper, j, FREE))
        else:
            lower.direction = 1.0
            out.append((lower, j, FREE))
    return out


class ReferenceGearbox:
    """Event-located integration of the gearbox, one communication step at a time."""

    def __init__(self, box: Gearbox, z0=None, rtol=1e-13, atol=1e-17):
        self.box, self.rtol, self.atol = box, rtol, atol
        self.x = box.to_internal(np.zeros(6) if z0 is None else z0)
        self.t = 0.0
        self.modes: tuple[int, int] | None = None
        self.switches: list[tuple[float, int, int, int]] = []  # (time, mesh, from, to)

    @property
    def z(self) -> np.ndarray:
        return self.box.to_state(self.x)

    def step(self, tau_m: float, tau_L: float, h: float) -> np.ndarray:
        if self.modes is None:
            self.modes = self.box.entering(self.x, tau_m, tau_L)
        t, t_end, x = self.t, self.t + h, self.x
        while t < t_end:
            events = _events(self.box, self.modes)
            sol = solve_ivp(
                self.box.rhs(self.modes, tau_m, tau_L),
                (t, t_end),
                x,
                method="DOP853",
                rtol=self.rtol,
                atol=self.atol,
                events=[e for e, _, _ in events],
            )
            if sol.status == -1:
                raise RuntimeError(f"reference integration failed: {sol.message}")
            if sol.status == 1:
                hit = next(i for i, te in enumerate(sol.t_events) if len(te))
                t_ev, x = float(sol.t_events[hit][0]), sol.y_events[hit][0].copy()
                _, mesh, to = events[hit]
                self.switches.append((t_ev, mesh, self.modes[mesh], to))
                modes = list(self.modes)
                modes[mesh] = to
                self.modes, t = tuple(modes), t_ev
            else:
                t, x = t_end, sol.y[:, -1].copy()
        self.t, self.x = t_end, x
        return self.z


def run_open_loop(box: Gearbox, tau_m, tau_L, h: float, z0=None):
    """z at every communication point (first row z0) under the held torques, and the solver."""
    ref = ReferenceGearbox(box, z0)
    rows = [ref.z]
    for a, b in zip(tau_m, tau_L):
        rows.append(ref.step(a, b, h))
    return np.array(rows), ref

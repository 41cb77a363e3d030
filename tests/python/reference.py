"""Independent reference solution of the compliance + backlash plant (docs/model.md §1).

Written from docs/model.md alone, with a different method from the FMU's exact stepping (§2):
a high-order explicit integrator (scipy DOP853, rtol 1e-13, atol 1e-17; Radau as a check)
inside each contact mode, with the mode switches located as terminal events on u - g and
u + g and the integration restarted in the new mode at each event. Inputs are held over each
communication step (zero-order hold, the FMI 2 co-simulation default).

Also the sampled-data PI speed controller that both this reference and the FMU test loops
use, so that both sides solve the same sampled-data system.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Callable

import numpy as np
from scipy.integrate import solve_ivp

# Contact modes, numbered as the FMU's `contact` output (docs/model.md §4).
FREE, PLUS, MINUS = 0, 1, -1


@dataclass(frozen=True)
class Plant:
    """Generic form of docs/model.md §1: inertias J (kg.m2), viscous frictions b (N.m.s/rad),
    transmission radii r_m, r_L, stiffness K and half gap g measured in u."""

    J_m: float
    J_L: float
    b_m: float
    b_L: float
    r_m: float
    r_L: float
    K: float
    g: float

    @classmethod
    def shaft(cls, J_m, J_L, b_m, b_L, k, Delta) -> "Plant":
        """Compliant shaft + gear backlash (paper Fig. 5/6, eqs. 11-12): r_m = r_L = 1."""
        return cls(J_m, J_L, b_m, b_L, 1.0, 1.0, k, Delta)

    @classmethod
    def belt(cls, J_m, J_L, b_m, b_L, K_b, R_1, R_2, R_g1, R_g2, Delta) -> "Plant":
        """Belt-pulley + gear backlash (paper Fig. 7, eqs. 20-21): r_m = R_1,
        r_L = alpha_1 = R_2 R_g2 / R_g1, g = alpha_2 Delta with alpha_2 = R_2 / R_g1."""
        return cls(J_m, J_L, b_m, b_L, R_1, R_2 * R_g2 / R_g1, K_b, (R_2 / R_g1) * Delta)

    def u(self, z) -> float:
        """Transmission coordinate u = r_m theta_m - r_L theta_L."""
        return self.r_m * z[0] - self.r_L * z[2]

    def du(self, z) -> float:
        return self.r_m * z[1] - self.r_L * z[3]

    def dead_zone(self, u: float) -> float:
        """dz(u, g) of docs/model.md §1."""
        if u >= self.g:
            return u - self.g
        if u <= -self.g:
            return u + self.g
        return 0.0

    def psi(self, z) -> float:
        """Force in the compliant member, psi = K dz(u, g)."""
        return self.K * self.dead_zone(self.u(z))

    def contact(self, z) -> int:
        """Contact indicator from the state alone (ties at |u| = g resolved as 0 here)."""
        u = self.u(z)
        if u > self.g:
            return PLUS
        if u < -self.g:
            return MINUS
        return FREE if self.g > 0.0 else 0

    def linear_matrices(self):
        """A_p and the input matrix [B_p C_p] of the backlash-free plant (docs/model.md §3)."""
        J_m, J_L, K, r_m, r_L = self.J_m, self.J_L, self.K, self.r_m, self.r_L
        A = np.array(
            [
                [0.0, 1.0, 0.0, 0.0],
                [-K * r_m**2 / J_m, -self.b_m / J_m, K * r_m * r_L / J_m, 0.0],
                [0.0, 0.0, 0.0, 1.0],
                [K * r_m * r_L / J_L, 0.0, -K * r_L**2 / J_L, -self.b_L / J_L],
            ]
        )
        B = np.array([[0.0, 0.0], [1.0 / J_m, 0.0], [0.0, 0.0], [0.0, 1.0 / J_L]])
        return A, B


def _rhs(plant: Plant, mode: int, tau_m: float, tau_L: float) -> Callable:
    """Right-hand side of docs/model.md §1 in the coordinates x = [theta_m, omega_m, u, omega_L].

    u is integrated directly (u' = r_m omega_m - r_L omega_L) rather than recovered from two
    large angles, so that the integrator's error control acts on the quantity that decides
    the contact and the force. FREE: psi = 0; PLUS: psi = K (u - g); MINUS: psi = K (u + g).
    With g = 0 the plant is linear and PLUS is used throughout."""
    offset = {FREE: None, PLUS: -plant.g, MINUS: plant.g}[mode]
    J_m, J_L, b_m, b_L, r_m, r_L, K = plant.J_m, plant.J_L, plant.b_m, plant.b_L, plant.r_m, plant.r_L, plant.K

    def f(_t, x):
        psi = 0.0 if offset is None else K * (x[2] + offset)
        return [
            x[1],
            (tau_m - b_m * x[1] - r_m * psi) / J_m,
            r_m * x[1] - r_L * x[3],
            (tau_L - b_L * x[3] + r_L * psi) / J_L,
        ]

    return f


def _to_internal(plant: Plant, z) -> np.ndarray:
    return np.array([z[0], z[1], plant.u(z), z[3]], dtype=float)


def _to_state(plant: Plant, x) -> np.ndarray:
    return np.array([x[0], x[1], (plant.r_m * x[0] - x[2]) / plant.r_L, x[3]])


def entering_mode(plant: Plant, z, tau_m: float, tau_L: float) -> int:
    """Mode in force at state z: the side of +-g that u is on, and exactly on +-g the mode
    the trajectory is entering (docs/model.md §4), from the sign of du/dt, then of d2u/dt2."""
    if plant.g == 0.0:
        return PLUS
    u = plant.u(z)
    if -plant.g < u < plant.g:
        return FREE
    if u > plant.g:
        return PLUS
    if u < -plant.g:
        return MINUS
    # On the boundary psi = 0 in every mode, so the free-mode acceleration is the true one.
    f = _rhs(plant, FREE, tau_m, tau_L)(0.0, _to_internal(plant, z))
    du = plant.du(z)
    ddu = plant.r_m * f[1] - plant.r_L * f[3]
    rate = du if du != 0.0 else ddu
    if u == plant.g:
        return PLUS if rate > 0.0 else FREE
    return MINUS if rate < 0.0 else FREE


def _events(plant: Plant, mode: int):
    """Terminal, directional switch events of one mode, each paired with the mode it leads to."""

    def upper(_t, x):
        return x[2] - plant.g

    def lower(_t, x):
        return x[2] + plant.g

    for e in (upper, lower):
        e.terminal = True
    if mode == FREE:
        upper.direction, lower.direction = 1.0, -1.0
        return [upper, lower], [PLUS, MINUS]
    if mode == PLUS:
        upper.direction = -1.0
        return [upper], [FREE]
    lower.direction = 1.0
    return [lower], [FREE]


class ReferencePlant:
    """Event-located integration of the plant, one communication step at a time.

    rtol 1e-13 and atol 1e-17 (u is ~1e-3 m or rad, so a larger atol would govern it).
    Measured on the test scenarios: runs at rtol 1e-12, 3e-13, 1e-13 and 3e-14 differ by up to
    5e-10 (rtol 1e-12, 0.25 s steps) and 2e-10 (rtol 1e-13) relative; DOP853 and Radau agree
    to 6e-12 at 0.1 s steps.

    The state is kept as x = [theta_m, omega_m, u, omega_L] between steps (see _rhs);
    `z` gives it as [theta_m, omega_m, theta_L, omega_L]."""

    def __init__(self, plant: Plant, z0=None, method="DOP853", rtol=1e-13, atol=1e-17):
        self.plant, self.method, self.rtol, self.atol = plant, method, rtol, atol
        self.x = _to_internal(plant, np.zeros(4) if z0 is None else z0)
        self.t = 0.0
        self.mode: int | None = None
        self.switches: list[tuple[float, int, int]] = []  # (time, from mode, to mode)

    @property
    def z(self) -> np.ndarray:
        return _to_state(self.plant, self.x)

    @property
    def u(self) -> float:
        return float(self.x[2])

    def step(self, tau_m: float, tau_L: float, h: float) -> np.ndarray:
        """Advance by h with inputs held; returns z at the end of the step."""
        if self.mode is None:
            self.mode = entering_mode(self.plant, self.z, tau_m, tau_L)
        t, t_end, x = self.t, self.t + h, self.x
        stalls = 0
        while t < t_end:
            events, targets = ([], []) if self.plant.g == 0.0 else _events(self.plant, self.mode)
            sol = solve_ivp(
                _rhs(self.plant, self.mode, tau_m, tau_L),
                (t, t_end),
                x,
                method=self.method,
                rtol=self.rtol,
                atol=self.atol,
                events=events or None,
            )
            if sol.status == -1:
                raise RuntimeError(f"reference integration failed: {sol.message}")
            if sol.status == 1:  # a switch: restart from the event state in the new mode
                hit = next(i for i, te in enumerate(sol.t_events) if len(te))
                t_ev, x = float(sol.t_events[hit][0]), sol.y_events[hit][0].copy()
                stalls = stalls + 1 if t_ev == t else 0
                if stalls > 3:
                    raise RuntimeError(f"switch events do not advance at t = {t}")
                self.switches.append((t_ev, self.mode, targets[hit]))
                self.mode, t = targets[hit], t_ev
            else:
                t, x = t_end, sol.y[:, -1].copy()
        self.t, self.x = t_end, x
        return self.z


class SampledPI:
    """PI speed controller on the motor speed, sampled at the communication points.

    Discretisation (forward Euler on x_c' = e, docs/model.md §3): at t_k
        e_k   = w_ref(t_k) - omega_m(t_k)
        tau_k = Kp e_k + Ki x_k        held over [t_k, t_k + h]
        x_k+1 = x_k + h e_k
    so x_k is the integral of the held error up to t_k, which is exactly what the
    continuous PI's state would be if the error were held too. Both the reference loop
    and the FMU loop use this class."""

    def __init__(self, Kp: float, Ki: float, h: float, x0: float = 0.0):
        self.Kp, self.Ki, self.h, self.x = Kp, Ki, h, x0

    def __call__(self, w_ref: float, omega_m: float) -> float:
        e = w_ref - omega_m
        tau = self.Kp * e + self.Ki * self.x
        self.x += self.h * e
        return tau


def run_open_loop(plant: Plant, tau_m, tau_L, h: float, z0=None, **kw):
    """States z and u at t_0..t_N (N = len(tau_m)) under torques held per step; also the solver."""
    ref = ReferencePlant(plant, z0, **kw)
    zs, us = [ref.z], [ref.u]
    for tm, tl in zip(tau_m, tau_L):
        zs.append(ref.step(tm, tl, h))
        us.append(ref.u)
    return np.array(zs), np.array(us), ref


def run_pi_loop(plant: Plant, Kp, Ki, h, n_steps, w_ref: Callable, tau_L: Callable, z0=None, **kw):
    """Sampled-data PI loop: z and u at t_0..t_N, the motor torque held over each step, the solver."""
    ref = ReferencePlant(plant, z0, **kw)
    pi = SampledPI(Kp, Ki, h)
    zs, us, taus = [ref.z], [ref.u], []
    for k in range(n_steps):
        t_k = k * h
        tau = pi(w_ref(t_k), ref.x[1])
        taus.append(tau)
        zs.append(ref.step(tau, tau_L(t_k), h))
        us.append(ref.u)
    return np.array(zs), np.array(us), np.array(taus), ref

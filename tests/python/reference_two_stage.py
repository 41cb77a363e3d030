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

For Model Exchange (test_model_exchange.py), from the same equations: the field in z's
coordinates, its exact Jacobian per tuple of modes, the 18 event indicators and the state
nominals of docs/model.md §6, §10 (`Gearbox`), and the continuous-time PI loop closed around the
equations (`run_pi_loop`).
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

    def dead_zone(self, j: int, u: float) -> float:
        """dz(u_j, Delta_j) of docs/model.md §1."""
        g = self.gap(j)
        return u - g if u >= g else (u + g if u <= -g else 0.0)

    def u(self, z) -> tuple[float, float]:
        """(u_1, u_2) of the angles of z = [theta_m, omega_m, theta_i, omega_i, theta_L, omega_L]."""
        return z[0] - self.n_1 * z[2], z[2] - self.n_2 * z[4]

    def state_with_u(self, u_1: float, u_2: float, theta_m=0.2, omega_m=0.5, omega_i=0.1, omega_L=-0.4) -> np.ndarray:
        """z with the meshes' coordinates u_1 and u_2."""
        return self.to_state([theta_m, omega_m, u_1, omega_i, u_2, omega_L])

    def field(self, z, tau_m: float, tau_L: float) -> np.ndarray:
        """z' of the equations at z, each mesh in the mode its u_j is in (`entering` on a flank),
        in z's coordinates: the angles' rates are the speeds, the speeds' those of `rhs`."""
        x = self.to_internal(z)
        f = self.rhs(self.entering(x, tau_m, tau_L), tau_m, tau_L)(0.0, x)
        return np.array([z[1], f[1], z[3], f[3], z[5], f[5]])

    def jacobian(self, modes: tuple[int, int]) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """The exact Jacobian of `field` inside `modes`, A = d z'/d z (6 x 6) and B = d z'/d
        [tau_m, tau_L] (6 x 2), and the rows of psi_1, psi_2 (2 x 6): each psi_j is k_j u_j
        (minus a constant) in contact, 0 in the gap."""
        c = [0.0 if m == FREE else 1.0 for m in modes]
        dpsi = np.array(
            [
                c[0] * self.k_1 * np.array([1.0, 0.0, -self.n_1, 0.0, 0.0, 0.0]),
                c[1] * self.k_2 * np.array([0.0, 0.0, 1.0, 0.0, -self.n_2, 0.0]),
            ]
        )
        A = np.zeros((6, 6))
        A[0, 1] = A[2, 3] = A[4, 5] = 1.0
        A[1, 1], A[3, 3], A[5, 5] = -self.b_m / self.J_m, -self.b_i / self.J_i, -self.b_L / self.J_L
        A[1] -= dpsi[0] / self.J_m
        A[3] += (self.n_1 * dpsi[0] - dpsi[1]) / self.J_i
        A[5] += self.n_2 * dpsi[1] / self.J_L
        B = np.zeros((6, 2))
        B[1, 0], B[5, 1] = 1.0 / self.J_m, 1.0 / self.J_L
        return A, B, dpsi

    def state_nominals(self) -> np.ndarray:
        """Nominals of z (docs/model.md §6, §10): each body's angle at the finest gap it must
        resolve, Delta_j of the mesh it drives (input side, a = 1) and Delta_j / n_j of the mesh
        driving it (1e-4 rad where neither has a gap); each speed that angle times
        omega_0 = sqrt(k_1 (1/J_m + n_1^2/J_i) + k_2 (1/J_i + n_2^2/J_L))."""
        sides = [[self.Delta_1], [self.Delta_1 / self.n_1, self.Delta_2], [self.Delta_2 / self.n_2]]
        angles = [min((g for g in body if g > 0.0), default=1e-4) for body in sides]
        w0 = np.sqrt(
            self.k_1 * (1.0 / self.J_m + self.n_1**2 / self.J_i) + self.k_2 * (1.0 / self.J_i + self.n_2**2 / self.J_L)
        )
        return np.array([x for a in angles for x in (a, w0 * a)])

    def indicators(self, z) -> np.ndarray:
        """The FMU's 18 event indicators of this plant (docs/model.md §6, §10): each mesh's
        u_j - Delta_j, u_j + Delta_j and its damper's four surfaces, then each body's two
        friction surfaces, the ones it has not (no damper, no friction) at 1."""
        out = np.ones(18)
        for j, u in enumerate(self.u(z)):
            out[6 * j : 6 * j + 2] = u - self.gap(j), u + self.gap(j)
        return out

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


@dataclass
class LoopResult:
    """A closed loop's states at the output times (z rows, xi the PI integral), the meshes'
    coordinates there (u: n x 2), every switch as (time, mesh, mode before, mode after) and the
    rate u_j' of the switching mesh at each."""

    t: np.ndarray
    z: np.ndarray
    xi: np.ndarray
    u: np.ndarray
    switches: list
    switch_rates: list


def run_pi_loop(box: Gearbox, Kp: float, Ki: float, holds, t_out, z0=None, rtol=1e-13, atol=1e-17) -> LoopResult:
    """The continuous-time PI of docs/model.md §3 on omega_m closed around the gearbox:

        y = [x, xi],   xi' = w_ref - omega_m,   tau_m = tau_ff + Kp (w_ref - omega_m) + Ki xi,

    with x the internal state (u_j integrated directly), the signals of each hold (.t, .tau_m
    the feed-forward, .tau_L, .w_ref) held until the next. DOP853 inside each tuple of modes, a
    new integration at every hold and every switch, located as a terminal event as in
    ReferenceGearbox. A mesh without a gap (Delta_j = 0) has psi_j = k_j u_j everywhere: the
    mode PLUS of its force law, never left, nothing to locate."""
    t_out = np.asarray(t_out, dtype=float)
    y = np.append(box.to_internal(np.zeros(6) if z0 is None else z0), 0.0)
    Y = np.full((len(t_out), 7), np.nan)
    switches, rates = [], []
    t, modes = holds[0].t, None
    for k, hold in enumerate(holds):
        end = min(holds[k + 1].t if k + 1 < len(holds) else np.inf, float(t_out[-1]))

        def tau(yy, hold=hold):
            return hold.tau_m + Kp * (hold.w_ref - yy[1]) + Ki * yy[6]

        if modes is None:
            modes = box.entering(y[:6], tau(y), hold.tau_L)
            modes = tuple(PLUS if box.gap(j) == 0.0 else m for j, m in enumerate(modes))
        while t < end:
            events = [e for e in _events(box, modes) if box.gap(e[1]) > 0.0]

            def f(s, yy, modes=modes, hold=hold):
                dx = box.rhs(modes, tau(yy), hold.tau_L)(s, yy[:6])
                return [*dx, hold.w_ref - yy[1]]

            sol = solve_ivp(f, (t, end), y, method="DOP853", rtol=rtol, atol=atol, dense_output=True,
                            events=[e for e, _, _ in events] or None)
            if sol.status == -1:
                raise RuntimeError(f"reference integration failed: {sol.message}")
            stop = float(sol.t[-1])
            inside = (t_out >= t) & (t_out <= stop)
            if np.any(inside):
                Y[inside] = sol.sol(t_out[inside]).T
            if sol.status == 1:
                hit = next(i for i, te in enumerate(sol.t_events) if len(te))
                stop, y = float(sol.t_events[hit][0]), sol.y_events[hit][0].copy()
                _, mesh, to = events[hit]
                du = box.rhs(modes, tau(y), hold.tau_L)(stop, y[:6])[2 + 2 * mesh]
                switches.append((stop, mesh, modes[mesh], to))
                rates.append(du)
                modes = tuple(to if j == mesh else m for j, m in enumerate(modes))
            else:
                y = sol.y[:, -1].copy()
            t = stop
    if np.any(np.isnan(Y)):
        raise ValueError("output times beyond the last hold's reach")
    z = np.array([box.to_state(row[:6]) for row in Y])
    return LoopResult(t_out, z, Y[:, 6], Y[:, [2, 4]], switches, rates)


"""Exact solution of the plant of docs/model.md §1 under a continuous-time PI on the motor speed.

The loop of docs/model.md §3 with piecewise-constant signals:

    e = w_ref - omega_m,    xi' = e,    tau_m = tau_ff + Kp e + Ki xi

with tau_ff, tau_L and w_ref held between breakpoints. Kp = Ki = 0 is the open plant driven by
tau_m = tau_ff. Written from the equations of docs/model.md §1 and §3 alone, with a different
method from reference.py (an ODE integrator with events) and from the FMU's Taylor stepping:

- Inside one contact mode and between two breakpoints the loop is affine, so in the coordinates
  y = [theta_m, omega_m, u, omega_L, xi, 1] it is y' = M y with a constant 6x6 matrix (the
  constant 1 carries the inputs and the offset -+K g of a flank) and y(t0 + s) = expm(M s) y(t0),
  computed with scipy.linalg.expm: no integrator, no step-size control.
- u = r_m theta_m - r_L theta_L is carried as a state (theta_L recovered from it), as in
  reference.py, so that the switch instants are found on u itself, not on a difference of two
  large angles.
- Mode switches (u crossing +g or -g) are bracketed on a grid of the exact solution and refined
  with brentq to round-off; the integration then restarts from the switch in the new mode with
  u set exactly to +-g. The grid cell is w = 0.05 / rho (rho: spectral radius of the loop).
  Grazing: a cell is split at a sign change of u' (its root found with brentq), so a touch
  around an extremum of u between two grid points is found; a cell on which u - (+-g) keeps
  its sign at both ends is accepted only when a bound on |u'''| proves that u cannot reach the
  level inside it, else it is quartered until that is proved or the possible excursion is
  below the round-off of u (class _Search; on the test loops at most 7 quarterings, ~700
  parts per run).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
from scipy.linalg import expm
from scipy.optimize import brentq

from reference import FREE, MINUS, PLUS, Plant

# Indices in the augmented state y.
TH_M, W_M, U, W_L, XI, ONE = range(6)

CELL = 0.05  # grid cell, in units of 1 / rho
CHUNK = 64  # grid cells evaluated per batched expm
ROOT_XTOL = 1e-15  # s: brentq's absolute tolerance; its relative one is 4 eps
MAX_DEPTH = 40  # quarterings of one cell (the test loops need at most 7)
EPS = np.finfo(float).eps


@dataclass(frozen=True)
class Hold:
    """Signals held from time t until the next Hold: feed-forward (open-loop) motor torque
    tau_m (N.m), load torque tau_L (N.m), speed reference w_ref (rad/s)."""

    t: float
    tau_m: float = 0.0
    tau_L: float = 0.0
    w_ref: float = 0.0


@dataclass
class Trajectory:
    """States at the requested times, and every switch as (time, mode before, mode after)."""

    t: np.ndarray
    z: np.ndarray  # [theta_m, omega_m, theta_L, omega_L] per row
    xi: np.ndarray  # PI integral state
    u: np.ndarray
    switches: list = field(default_factory=list)
    switch_rates: list = field(default_factory=list)  # u' at each switch
    tau_m: np.ndarray | None = None  # motor torque applied at each time (after the hold there)


def open_loop_holds(tau_m, tau_L, h: float, t0: float = 0.0) -> list[Hold]:
    """Torques held per step [t0 + k h, t0 + (k+1) h), as in reference.run_open_loop."""
    return [Hold(t0 + k * h, float(a), float(b), 0.0) for k, (a, b) in enumerate(zip(tau_m, tau_L))]


class ContinuousLoop:
    """The plant of docs/model.md §1 with the PI of §3 (gains Kp N.m.s/rad, Ki N.m/rad)."""

    def __init__(self, plant: Plant, Kp: float = 0.0, Ki: float = 0.0):
        self.plant, self.Kp, self.Ki = plant, float(Kp), float(Ki)
        contact = self.matrix(PLUS, Hold(0.0))[:5, :5]
        free = self.matrix(FREE, Hold(0.0))[:5, :5]
        rho = max(np.max(np.abs(np.linalg.eigvals(m))) for m in (contact, free))
        self.cell = CELL / max(float(rho), 1e-6)

    # --- the affine system of one mode ------------------------------------------------------

    def matrix(self, mode: int, hold: Hold) -> np.ndarray:
        """M of y' = M y in `mode` (docs/model.md §1: psi = 0 free, K (u -+ g) on a flank)."""
        p = self.plant
        c = 0.0 if mode == FREE else 1.0  # with g = 0 both flanks are psi = K u
        sigma = 1.0 if mode == PLUS else -1.0
        M = np.zeros((6, 6))
        M[TH_M, W_M] = 1.0
        # J_m omega_m' = tau_ff + Kp (w_ref - omega_m) + Ki xi - b_m omega_m - r_m K c (u - sigma g)
        M[W_M, W_M] = -(self.Kp + p.b_m) / p.J_m
        M[W_M, U] = -p.r_m * p.K * c / p.J_m
        M[W_M, XI] = self.Ki / p.J_m
        M[W_M, ONE] = (hold.tau_m + self.Kp * hold.w_ref + p.r_m * p.K * c * sigma * p.g) / p.J_m
        # u' = r_m omega_m - r_L omega_L
        M[U, W_M], M[U, W_L] = p.r_m, -p.r_L
        # J_L omega_L' = tau_L - b_L omega_L + r_L K c (u - sigma g)
        M[W_L, U] = p.r_L * p.K * c / p.J_L
        M[W_L, W_L] = -p.b_L / p.J_L
        M[W_L, ONE] = (hold.tau_L - p.r_L * p.K * c * sigma * p.g) / p.J_L
        # xi' = w_ref - omega_m
        M[XI, W_M], M[XI, ONE] = -1.0, hold.w_ref
        return M

    def _exits(self, mode: int):
        """(level, d, next mode) for each way out of `mode`: it is left when d (u - level) > 0."""
        g = self.plant.g
        if g == 0.0:
            return []  # one linear system: nothing to locate
        if mode == FREE:
            return [(g, 1.0, PLUS), (-g, -1.0, MINUS)]
        if mode == PLUS:
            return [(g, -1.0, FREE)]
        return [(-g, 1.0, FREE)]

    def entering_mode(self, y: np.ndarray, hold: Hold) -> int:
        """The side of +-g that u is on; exactly on +-g the mode the trajectory enters, from the
        sign of u', then u'' (psi = 0 on the boundary in every mode, so FREE gives them)."""
        g, u = self.plant.g, y[U]
        if g == 0.0:
            return PLUS
        if u > g:
            return PLUS
        if u < -g:
            return MINUS
        if -g < u < g:
            return FREE
        M = self.matrix(FREE, hold)
        dy = M @ y
        rate = dy[U] if dy[U] != 0.0 else (M @ dy)[U]
        if u == g:
            return PLUS if rate > 0.0 else FREE
        return MINUS if rate < 0.0 else FREE

    # --- switch search ---------------------------------------------------------------------

    def _first_exit(self, M: np.ndarray, y0: np.ndarray, length: float, mode: int):
        """First time s in (0, length] at which the trajectory expm(M s) y0 leaves `mode`, as
        (s, state there with u exactly on the level, next mode); else (None, state at length),
        the state at length being the grid's own last point, so that the next search starts
        from the very value this one judged to be inside the mode."""
        exits = self._exits(mode)
        if not exits:
            return None, expm(M * length) @ y0
        search = _Search(M, self.plant)
        n_cells = max(1, math.ceil(length / self.cell))
        grid = np.linspace(0.0, length, n_cells + 1)
        for start in range(0, n_cells, CHUNK):
            s = grid[start : min(start + CHUNK, n_cells) + 1]
            Y = expm(s[:, None, None] * M[None, :, :]) @ y0
            best = None
            for level, d, target in exits:
                if start == 0 and d * (y0[U] - level) > 0.0:
                    raise RuntimeError(f"state already outside mode {mode} (u = {y0[U]!r})")
                hit = search.first_crossing(s, Y, level, d)
                if hit is not None and (best is None or hit[0] < best[0]):
                    best = (*hit, target)
            if best is not None:
                return best
        return None, Y[-1]

    # --- the solution ----------------------------------------------------------------------

    def solve(self, holds: list[Hold], t_out, z0=(0.0, 0.0, 0.0, 0.0), xi0: float = 0.0) -> Trajectory:
        """States at the times t_out (non-decreasing, from holds[0].t on)."""
        p = self.plant
        t_out = np.asarray(t_out, dtype=float)
        t_end = float(t_out[-1])
        z0 = np.asarray(z0, dtype=float)
        y = np.array([z0[0], z0[1], p.r_m * z0[0] - p.r_L * z0[2], z0[3], xi0, 1.0])
        t = holds[0].t
        if t_out[0] < t:
            raise ValueError("output before the first hold")
        Y_out = np.full((len(t_out), 6), np.nan)
        switches: list[tuple[float, int, int]] = []
        rates: list[float] = []
        mode = self.entering_mode(y, holds[0])
        stalls = 0
        for k, hold in enumerate(holds):
            seg_end = min(holds[k + 1].t if k + 1 < len(holds) else math.inf, t_end)
            if k > 0 and abs(y[U]) == p.g:
                mode = self.entering_mode(y, hold)  # on the boundary at a change of input
            while t < seg_end:
                M = self.matrix(mode, hold)
                found = self._first_exit(M, y, seg_end - t, mode)
                piece_end = seg_end if found[0] is None else t + found[0]
                mask = (t_out >= t) & (t_out <= piece_end)
                if np.any(mask):
                    Y_out[mask] = expm((t_out[mask] - t)[:, None, None] * M[None, :, :]) @ y
                if found[0] is None:
                    y, t = found[1], seg_end
                    stalls = 0
                else:
                    s, y, target = found
                    stalls = stalls + 1 if s == 0.0 else 0
                    if stalls > 3:
                        raise RuntimeError(f"switches do not advance at t = {t}")
                    switches.append((piece_end, mode, target))
                    rates.append(p.r_m * y[W_M] - p.r_L * y[W_L])
                    mode, t = target, piece_end
            if t >= t_end:
                break
        if np.any(np.isnan(Y_out)):
            raise ValueError("output times beyond the last hold's reach")
        theta_L = (p.r_m * Y_out[:, TH_M] - Y_out[:, U]) / p.r_L
        z = np.column_stack([Y_out[:, TH_M], Y_out[:, W_M], theta_L, Y_out[:, W_L]])
        traj = Trajectory(t_out, z, Y_out[:, XI].copy(), Y_out[:, U].copy(), switches, rates)
        traj.tau_m = self.motor_torque(holds, t_out, Y_out)
        return traj

    def motor_torque(self, holds, t, Y) -> np.ndarray:
        """tau_m = tau_ff + Kp (w_ref - omega_m) + Ki xi with the hold in force at each t."""
        starts = np.array([h.t for h in holds])
        idx = np.searchsorted(starts, t, side="right") - 1
        ff = np.array([holds[i].tau_m for i in idx])
        w = np.array([holds[i].w_ref for i in idx])
        return ff + self.Kp * (w - Y[:, W_M]) + self.Ki * Y[:, XI]


class _Search:
    """Crossings of f(s) = d (u(s) - level) from <= 0 to > 0 along y(s) = expm(M s) y(0).

    A cell (or a part of one between an extremum of u and a cell end) on which f does not
    change sign may still hide a touch: f rising above 0 and falling back between two zeros of
    u'. If f' = d u' vanishes at s1 < s2, then |f'| <= B (s - s1)(s2 - s) / 2 between them
    (B >= |u'''| there: linear interpolation of f' through its two zeros), so f rises at most
    B len^3 / 12 above the larger of its end values. A part is accepted as free of crossings
    only if max(f(ends)) + B len^3 / 12 < 0; otherwise it is cut in four and each quarter is
    examined the same way, until that excursion is below the round-off of u. B comes from
    u''' = e_u M^3 expm(M sigma) y(a) and the entrywise inequality (non-negative series)
    |expm(M sigma) - I| <= expm(|M| sigma) - I <= |M| sigma expm(|M| sigma).
    """

    def __init__(self, M: np.ndarray, plant: Plant):
        self.M, self.r_m, self.r_L = M, plant.r_m, plant.r_L
        self.c3 = np.linalg.matrix_power(M, 3)[U]  # u''' = c3 . y
        self.abs_c3, self.abs_M = np.abs(self.c3), np.abs(M)
        self._growth: dict[float, np.ndarray] = {}

    def at(self, a: float, ya: np.ndarray, x: float) -> np.ndarray:
        return expm(self.M * (x - a)) @ ya

    def jerk_bound(self, y: np.ndarray, length: float):
        """Upper bound of |u'''| over [a, a + length] from the state y at a (or one per row)."""
        if length not in self._growth:
            E = (self.abs_M * length) @ expm(self.abs_M * length)
            self._growth[length] = self.abs_c3 @ E
        return (np.abs(y @ self.c3) + np.abs(y) @ self._growth[length]) * (1.0 + 1e-12)

    def first_crossing(self, s: np.ndarray, Y: np.ndarray, level: float, d: float):
        """Earliest crossing in the cells [s_j, s_j+1] (all of one length), as (s, y) or None."""
        f = d * (Y[:, U] - level)
        fp = d * (self.r_m * Y[:, W_M] - self.r_L * Y[:, W_L])
        width = s[1] - s[0]
        excursion = self.jerk_bound(Y[:-1], width) * width**3 / 12.0
        certified = (fp[:-1] * fp[1:] >= 0.0) & (np.maximum(f[:-1], f[1:]) + excursion < 0.0)
        for j in np.nonzero(~certified)[0]:
            hit = self._part(s[j], Y[j], s[j + 1], Y[j + 1], level, d)
            if hit is not None:
                return hit
        return None

    def _part(self, a, ya, b, yb, level, d, depth=0):
        def f(y):
            return d * (y[U] - level)

        def fp(y):
            return d * (self.r_m * y[W_M] - self.r_L * y[W_L])

        parts = [(a, ya)]
        if fp(ya) * fp(yb) < 0.0:  # u has an extremum inside: split there
            ext = brentq(lambda x: fp(self.at(a, ya, x)), a, b, xtol=ROOT_XTOL)
            parts.append((ext, self.at(a, ya, ext)))
        parts.append((b, yb))
        for (p, yp), (q, yq) in zip(parts, parts[1:]):
            fa, fb = f(yp), f(yq)
            if fa <= 0.0 < fb:
                root = brentq(lambda x: f(self.at(p, yp, x)), p, q, xtol=ROOT_XTOL) if fa < 0.0 else p
                y = self.at(p, yp, root)
                y[U] = level
                return root, y
            excursion = self.jerk_bound(yp, q - p) * (q - p) ** 3 / 12.0
            round_off = 16 * EPS * (abs(level) + abs(yp[U]))
            if max(fa, fb) + excursion < 0.0 or excursion <= round_off:
                continue
            if depth >= MAX_DEPTH:
                raise RuntimeError(f"cannot tell whether u touches {level} near s = {p}")
            sub = np.linspace(p, q, 5)
            Ys = expm((sub - p)[:, None, None] * self.M[None, :, :]) @ yp
            Ys[-1] = yq
            for k in range(4):
                hit = self._part(sub[k], Ys[k], sub[k + 1], Ys[k + 1], level, d, depth + 1)
                if hit is not None:
                    return hit
        return None


def solve(plant: Plant, holds: list[Hold], t_out, z0=(0.0, 0.0, 0.0, 0.0), xi0=0.0, Kp=0.0, Ki=0.0) -> Trajectory:
    return ContinuousLoop(plant, Kp, Ki).solve(holds, t_out, z0, xi0)

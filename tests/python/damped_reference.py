"""Independent numerical reference for a two-inertia drive train with backlash and a damped
compliant member whose force never pulls (contact laws 1 and 2).

The model
---------
State z = [theta_m, omega_m, theta_L, omega_L]; transmission coordinate
u = r_m theta_m - r_L theta_L, u' = r_m omega_m - r_L omega_L; half gap g >= 0, stiffness K > 0,
damping D >= 0:

    J_m omega_m' = tau_m - b_m omega_m - r_m psi        theta_m' = omega_m
    J_L omega_L' = tau_L - b_L omega_L + r_L psi        theta_L' = omega_L

with the member's force psi (law 1 = ElastoBacklash, law 2 = ElastoBacklash2 of the Modelica
Standard Library):

    |u| < g :  psi = 0
    u >= g  :  tau_c = K (u - g), tau_d = D u'
               law 2: psi = tau_c + tau_d              if tau_c + tau_d > 0, else 0
               law 1: psi = tau_c + min(tau_c, tau_d)  if tau_c + tau_d > 0, else 0
    u <= -g :  mirrored (tau_c = K (u + g), sign conditions reversed, max for min).

Modes and surfaces
------------------
With the inputs held constant between breakpoints every mode is affine:

    'gap'               |u| < g, psi = 0
    'clip+' / 'clip-'   past a flank, the member would pull, psi = 0
    'contact+/-'        psi = tau_c + tau_d
    'cap+/-'            (law 1 only) psi = 2 tau_c, where s tau_d >= s tau_c

Each mode is the set where a few functionals, all linear in the state, are strictly positive
(its "region"). The functionals, for a side s = +1 ('+') or -1 ('-'):

    'flank+/-'  s u - g                       (the surface u = s g)
    'zero+/-'   s (tau_c + tau_d)             (the surface tau_c + tau_d = 0)
    'equal+/-'  s (tau_d - tau_c)             (the surface tau_c = tau_d, law 1)

    gap:        -flank+ > 0, -flank- > 0
    clip s:     flank s > 0, -zero s > 0
    contact s:  flank s > 0,  zero s > 0  (law 1 also: -equal s > 0)
    cap s:      flank s > 0,  zero s > 0,  equal s > 0

A mode is left when one of its region functionals reaches zero; the surfaces reported with a
switch are the region functionals of the mode left that are zero at the switch (with D = 0 the
surfaces u = s g and tau_c + tau_d = 0 coincide and both are reported).

Two solvers, written separately
-------------------------------
Method A (`simulate`, `simulate_pi`): in each mode y' = M y for the augmented state
y = [theta_m, omega_m, theta_L, omega_L, u, xi, 1] (u is carried as its own state so that the
surfaces u = +-g are found on u itself, never on a difference of two large angles; xi is the PI
integrator, constant in open loop), advanced exactly with scipy.linalg.expm. Switch instants are
located on the exact solution: the functionals are sampled on a grid, a sign change is
bracketed and refined by brentq to round-off; a grid cell without a sign change is proved free of
crossings by a rigorous bound on the functional's second derivative (Taylor from both ends of the
cell; see `_Search`), and cells that cannot be proved are quartered until they can be, so a
grazing crossing (two roots inside one cell) is not missed. A bracket is only handed to brentq once
the functional is proved monotone in it, so the root found is the first one. The mode entered at a
switch is the one whose own flow stays in its region for small positive time, decided from the
lexicographic sign of (f, f', f'', ...) of its region functionals (`_classify`). On the surface
u = s g the state's u is set exactly to s g.

Method B (`simulate_ivp`, `simulate_pi_ivp`): scipy.integrate.solve_ivp (DOP853, rtol = 1e-13)
on the nonlinear right-hand side written with scalar arithmetic from the formulas above; the
surfaces of the current mode are terminal event functions; at each event the integration restarts
in the mode entered, found differently from A: the state is moved a short time delta along the
vector field of the mode left (first order, delta = 1e-8 s) and the literal law (its if/else
branches, `raw_mode`) is evaluated there. Nothing of A's matrices, functional table or
classification is used by B.

`linear_twin` / `linear_twin_pi`: the same plant with psi = K u + D u' everywhere (no gap, no
clipping, the member can pull), exact by expm: the backlash-free reference.

All inputs are piecewise constant: value i is held on [breakpoints[i], breakpoints[i+1]).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import NamedTuple

import numpy as np
from scipy.integrate import solve_ivp
from scipy.linalg import expm, matrix_balance
from scipy.optimize import brentq

# --------------------------------------------------------------------------------------------
# Rigs and parameters
# --------------------------------------------------------------------------------------------

SHAFT_RIG = dict(J_m=2.28, J_L=2.55, b_m=0.05, b_L=0.05, k=200.0, Delta=0.00269)
BELT_RIG = dict(J_m=2.28, J_L=2.55, b_m=0.05, b_L=0.05, K_b=2.0e4, R_1=0.1, R_2=0.08, R_g1=0.05,
                R_g2=0.075, Delta=2.0e-3)
SHAFT_GAINS = (42.0, 180.0)  # (Kp, Ki)
BELT_GAINS = (38.0, 150.0)


def effective_inertia(p: dict) -> float:
    """J_eff = 1 / (r_m^2/J_m + r_L^2/J_L): the inertia seen by the member in the u coordinate."""
    return 1.0 / (p["r_m"] ** 2 / p["J_m"] + p["r_L"] ** 2 / p["J_L"])


def damping_for_ratio(p: dict, zeta: float) -> float:
    """D = 2 zeta sqrt(K J_eff): contact damping of ratio zeta in the u coordinate."""
    return 2.0 * zeta * math.sqrt(p["K"] * effective_inertia(p))


def shaft_params(zeta: float = 0.0, *, d: float | None = None, Delta: float | None = None,
                 rig: dict = SHAFT_RIG) -> dict:
    """Generic parameters of the shaft: r_m = r_L = 1, K = k, g = Delta, D = d [N.m.s/rad]
    (d from the damping ratio zeta unless given)."""
    p = dict(J_m=rig["J_m"], J_L=rig["J_L"], b_m=rig["b_m"], b_L=rig["b_L"], r_m=1.0, r_L=1.0,
             K=rig["k"], g=rig["Delta"] if Delta is None else Delta, D=0.0)
    p["D"] = damping_for_ratio(p, zeta) if d is None else d
    return p


def belt_params(zeta: float = 0.0, *, D_b: float | None = None, Delta: float | None = None,
                rig: dict = BELT_RIG) -> dict:
    """Generic parameters of the belt: r_m = R_1, r_L = R_2 R_g2 / R_g1, K = K_b,
    g = (R_2/R_g1) Delta, D = D_b [N.s/m] (D_b from zeta unless given)."""
    delta = rig["Delta"] if Delta is None else Delta
    p = dict(J_m=rig["J_m"], J_L=rig["J_L"], b_m=rig["b_m"], b_L=rig["b_L"], r_m=rig["R_1"],
             r_L=rig["R_2"] * rig["R_g2"] / rig["R_g1"], K=rig["K_b"],
             g=rig["R_2"] / rig["R_g1"] * delta, D=0.0)
    p["D"] = damping_for_ratio(p, zeta) if D_b is None else D_b
    return p


# --------------------------------------------------------------------------------------------
# Modes, surfaces, the literal law
# --------------------------------------------------------------------------------------------

FREE_MODES = ("gap", "clip+", "clip-")


def modes_of(law: int) -> tuple[str, ...]:
    if law == 2:
        return ("gap", "clip+", "clip-", "contact+", "contact-")
    if law == 1:
        return ("gap", "clip+", "clip-", "contact+", "contact-", "cap+", "cap-")
    raise ValueError(f"law must be 1 or 2, not {law!r}")


def mode_kind(mode: str) -> str:
    """'free' (psi = 0: the gap or clipped past a flank), 'contact' (psi = tau_c + tau_d) or
    'cap' (psi = 2 tau_c)."""
    return "free" if mode in FREE_MODES else mode[:-1]


def mode_side(mode: str) -> int:
    return 0 if mode == "gap" else (1 if mode[-1] == "+" else -1)


def region(mode: str, law: int) -> tuple[tuple[str, int], ...]:
    """(functional, sign) pairs: the mode is the set where sign * functional > 0 for all."""
    if mode == "gap":
        return (("flank+", -1), ("flank-", -1))
    kind, s = mode[:-1], mode[-1]
    if kind == "clip":
        return (("flank" + s, 1), ("zero" + s, -1))
    if kind == "contact":
        base = (("flank" + s, 1), ("zero" + s, 1))
        return base if law == 2 else base + (("equal" + s, -1),)
    if kind == "cap" and law == 1:
        return (("flank" + s, 1), ("zero" + s, 1), ("equal" + s, 1))
    raise ValueError(f"no mode {mode!r} under law {law}")


def raw_force(p: dict, law: int, u: float, du: float) -> tuple[float, str]:
    """The law exactly as written (its if/else branches): (psi, mode of the branch taken).
    At g = 0, u = 0 both flank branches apply; the u >= g branch is tested first."""
    K, g, D = p["K"], p["g"], p["D"]
    if abs(u) < g:
        return 0.0, "gap"
    if u >= g:
        tc, td = K * (u - g), D * du
        if tc + td > 0.0:
            if law == 2:
                return tc + td, "contact+"
            return (2.0 * tc, "cap+") if td >= tc else (tc + td, "contact+")
        return 0.0, "clip+"
    tc, td = K * (u + g), D * du
    if tc + td < 0.0:
        if law == 2:
            return tc + td, "contact-"
        return (2.0 * tc, "cap-") if td <= tc else (tc + td, "contact-")
    return 0.0, "clip-"


def raw_mode(p: dict, law: int, u: float, du: float) -> str:
    return raw_force(p, law, u, du)[1]


class Switch(NamedTuple):
    time: float
    before: str
    after: str
    surfaces: tuple[str, ...]  # region functionals of `before` zero at the switch, sorted


@dataclass
class Result:
    """States at the output times. z: (n, 4) [theta_m, omega_m, theta_L, omega_L]; u, xi, psi,
    tau_m: (n,); contact: (n,) int in {-1, 0, 1} (sign of psi); mode: n mode names (at a switch
    instant, the mode entered); switches: every switch of the run, in time order."""
    t: np.ndarray
    z: np.ndarray
    u: np.ndarray
    xi: np.ndarray
    psi: np.ndarray
    tau_m: np.ndarray
    contact: np.ndarray
    mode: list[str]
    switches: list[Switch] = field(default_factory=list)


# --------------------------------------------------------------------------------------------
# Inputs
# --------------------------------------------------------------------------------------------

def _intervals(breakpoints, *values):
    """Breakpoints as floats and each input as one value per interval (a scalar is held)."""
    bp = np.asarray(breakpoints, dtype=float)
    if bp.ndim != 1 or bp.size < 2 or np.any(np.diff(bp) <= 0):
        raise ValueError("breakpoints must be increasing, at least two")
    out = []
    for v in values:
        a = np.broadcast_to(np.asarray(v, dtype=float), (bp.size - 1,)).copy()
        out.append(a)
    return bp, out


def _check_out(t_out, bp):
    t = np.asarray(t_out, dtype=float)
    if t.ndim != 1 or np.any(np.diff(t) < 0) or t[0] < bp[0] or t[-1] > bp[-1]:
        raise ValueError("t_out must be non-decreasing and inside [breakpoints[0], breakpoints[-1]]")
    return t


# ============================================================================================
# Method A: exact piecewise-affine solution (expm) with rigorous crossing search
# ============================================================================================

TM, WM, TL, WL, U, XI, ONE = range(7)
N = 7

# A functional whose value is within this fraction of the sum of the magnitudes of its terms
# is "on its surface": the classification then decides by its derivatives. brentq leaves a
# switching functional at ~1e-16 of that scale, the exact propagation adds ~1e-14 at most; a
# functional that truly is 1e-10 from its surface crosses it within ~1e-10 of the time it takes to
# change by its own scale, which is below what the A/B comparison resolves.
_TOL_ZERO = 1e-10
# A derivative of a functional smaller than this fraction of its term scale is round-off
# (~1e-15); the next derivative decides.
_TOL_JET = 1e-12
# Roots of two functionals this close (s) are one switch through both surfaces; brentq places
# each to ~1e-16 s.
_COINCIDENT = 1e-13


def _du_row(p):
    r = np.zeros(N)
    r[WM], r[WL] = p["r_m"], -p["r_L"]
    return r


def _functionals(p) -> dict[str, np.ndarray]:
    """Rows c with functional = c @ y (see the module docstring)."""
    K, g, D = p["K"], p["g"], p["D"]
    du = _du_row(p)
    rows = {}
    for name, s in (("+", 1.0), ("-", -1.0)):
        a = np.zeros(N)
        a[U], a[ONE] = s, -g
        rows["flank" + name] = a
        rows["zero" + name] = K * a + D * s * du
        rows["equal" + name] = D * s * du - K * a
    return rows


def _psi_row(p, mode: str) -> np.ndarray:
    """psi = row @ y in the mode ('twin': psi = K u + D u' everywhere)."""
    K, g, D = p["K"], p["g"], p["D"]
    row = np.zeros(N)
    if mode in FREE_MODES:
        return row
    if mode == "twin":
        row[U] = K
        return row + D * _du_row(p)
    s = mode_side(mode)
    row[U], row[ONE] = K, -K * s * g  # tau_c
    if mode[:-1] == "contact":
        return row + D * _du_row(p)
    if mode[:-1] == "cap":
        return 2.0 * row
    raise ValueError(mode)


def _tau_m_row(inp) -> np.ndarray:
    """tau_m = row @ y. inp = (tau_ff, tau_L, w_ref, Kp, Ki, loop)."""
    tau_ff, _, w_ref, Kp, Ki, loop = inp
    row = np.zeros(N)
    row[ONE] = tau_ff
    if loop:
        row[ONE] += Kp * w_ref
        row[WM], row[XI] = -Kp, Ki
    return row


def _matrix(p, mode: str, inp) -> np.ndarray:
    """M with y' = M y in the mode, inputs inp held."""
    _, tau_L, w_ref, _, _, loop = inp
    psi = _psi_row(p, mode)
    M = np.zeros((N, N))
    M[TM, WM] = 1.0
    M[TL, WL] = 1.0
    M[U] = _du_row(p)
    e_wm, e_wl, e_one = np.eye(N)[WM], np.eye(N)[WL], np.eye(N)[ONE]
    M[WM] = (_tau_m_row(inp) - p["b_m"] * e_wm - p["r_m"] * psi) / p["J_m"]
    M[WL] = (tau_L * e_one - p["b_L"] * e_wl + p["r_L"] * psi) / p["J_L"]
    if loop:
        M[XI, ONE], M[XI, WM] = w_ref, -1.0
    return M


def _is_zero(c, y) -> bool:
    return abs(c @ y) <= _TOL_ZERO * (np.abs(c) @ np.abs(y))


def _lexsign(c, y, M, zero: bool) -> int:
    """Sign of the functional c @ y(t) for small t > 0 under y' = M y: the first of
    f, f', f'', f''', f'''' that is not round-off (f itself skipped when `zero`)."""
    if not zero:
        return 1 if c @ y > 0 else -1
    ck = c
    for _ in range(4):
        ck = ck @ M
        v = ck @ y
        if abs(v) > _TOL_JET * (np.abs(ck) @ np.abs(y)):
            return 1 if v > 0 else -1
    return 0


def _classify(p, law, y, inp, rows, previous: str | None = None) -> str:
    """The mode whose own flow stays in its region for small t > 0 from y. Exactly one is
    expected; none or several (a sliding motion, or a contact exactly grazed to 4th order) raises
    rather than guessing."""
    fits = []
    for mode in modes_of(law):
        M = _matrix(p, mode, inp)
        if all(sgn * _lexsign(rows[name], y, M, _is_zero(rows[name], y)) > 0
               for name, sgn in region(mode, law)):
            fits.append(mode)
    if len(fits) != 1:
        raise RuntimeError(f"mode after {previous!r} at u={y[U]!r}, u'={_du_row(p) @ y!r} is not "
                           f"unique: {fits}")
    return fits[0]


class _Search:
    """First crossing of g_j(t) = sign_j c_j @ y(t) through zero (from > 0) on (0, H] for
    y(t) = expm(M t) y0.

    Grid: cells of width h <= 0.5 / ||B||_2, where B = T^-1 M T is M balanced by a diagonal T
    (the bound below then grows by at most e^0.5 across a cell). Exact samples by repeated
    multiplication with expm(M h) (round-off grows like the number of cells, ~1e-14).

    Proof of no crossing in a cell [a, b] of width w with g(a) > 0, g(b) > 0: with
    G2 = max |g''| on the cell <= ||sign c M^2 T||_2 e^{||B|| w} ||T^-1 y||_2 (y at either end),
    the concave quadratics g(a) + g'(a) s - G2 s^2/2 and g(b) - g'(b) s - G2 s^2/2 bound g from
    below on each half; a concave quadratic is positive on an interval iff at its two ends (the
    proof holds up to the round-off of the samples, ~1e-15 of the functional's scale). A
    functional that starts on its surface (zero_start: the classification gave it positive
    derivative sign) uses g(a) := 0, so its round-off value at the start is not a crossing.

    A cell with g(a) > 0 >= g(b) holds a root; it is handed to brentq once g' < 0 is proved on
    the whole cell (|g'(x) - g'(end)| <= G2 |x - end| from each end), so the root is the only
    one. Cells that cannot be decided are quartered (exact samples at the quarter points), down
    to `_MIN_WIDTH`, where a root is taken as is and an unproved cell as a touch within
    round-off."""

    # s; four orders below the 1e-9 agreement asked of switch times (brentq resolves ~1e-16 s)
    _MIN_WIDTH = 1e-13

    def __init__(self, M, rows, signs):
        self.M = M
        self.G = rows * signs[:, None]
        self.G1 = self.G @ M
        self.G2 = self.G1 @ M
        Bm, T = matrix_balance(M, permute=False)
        self.tdiag = np.diag(T).copy()
        self.nb = float(np.linalg.norm(Bm, 2))
        self.w2 = np.linalg.norm(self.G2 * self.tdiag[None, :], axis=1) * (1.0 + 1e-12)

    def _prop(self, y, dt):
        return expm(self.M * dt) @ y

    def _b2(self, j, y, w):
        return self.w2[j] * math.exp(self.nb * w) * np.linalg.norm(y / self.tdiag)

    def _no_root(self, j, ya, yb, w, zs):
        va, vb = self.G[j] @ ya, self.G[j] @ yb
        if vb <= 0 or (va <= 0 and not zs):
            return False
        ha = 0.5 * w
        b2a, b2b = self._b2(j, ya, w), self._b2(j, yb, w)
        left = (0.0 if zs else va) + (self.G1[j] @ ya) * ha - 0.5 * b2a * ha * ha
        right = vb - (self.G1[j] @ yb) * ha - 0.5 * b2b * ha * ha
        return left > 0 and right > 0

    def _monotone_down(self, j, ya, yb, w):
        ha = 0.5 * w
        return (self.G1[j] @ ya + self._b2(j, ya, w) * ha < 0
                and self.G1[j] @ yb + self._b2(j, yb, w) * ha < 0)

    def _cell(self, j, ta, ya, tb, yb, zs):
        """Local time of the first crossing of functional j in [ta, tb], or None."""
        g = self.G[j]
        va, vb = g @ ya, g @ yb
        w = tb - ta
        narrow = w <= self._MIN_WIDTH
        if va <= 0 and not zs:
            raise RuntimeError("crossing search entered a cell already past the surface")
        if vb > 0:
            if narrow or self._no_root(j, ya, yb, w, zs):
                return None
        elif va > 0 and (narrow or self._monotone_down(j, ya, yb, w)):
            return brentq(lambda s: g @ self._prop(ya, s), 0.0, w, xtol=1e-16, rtol=8.9e-16) + ta
        elif narrow:
            raise RuntimeError("functional leaves its side immediately after a switch")
        q = w / 4.0
        Pq = expm(self.M * q)
        ts = [ta, ta + q, ta + 2 * q, ta + 3 * q, tb]
        ys = [ya, Pq @ ya, None, None, yb]
        ys[2] = Pq @ ys[1]
        ys[3] = Pq @ ys[2]
        for i in range(4):
            r = self._cell(j, ts[i], ys[i], ts[i + 1], ys[i + 1], zs and i == 0)
            if r is not None:
                return r
        return None

    def first(self, y0, H, zero_start):
        """(tau, y(tau), indices of the functionals crossing at tau) of the first crossing on
        (0, H], or None."""
        k = self.G.shape[0]
        if k == 0:
            return None
        n = max(1, math.ceil(H * self.nb / 0.5))
        h = H / n
        P = expm(self.M * h)
        Y = np.empty((n + 1, N))
        Y[0] = y0
        for i in range(n):
            Y[i + 1] = P @ Y[i]
        V = Y @ self.G.T
        V1 = Y @ self.G1.T
        ny = np.linalg.norm(Y / self.tdiag[None, :], axis=1)
        b2 = self.w2[None, :] * math.exp(self.nb * h)
        ha = 0.5 * h
        b2a = b2 * ny[:-1, None]
        b2b = b2 * ny[1:, None]
        va = V[:-1].copy()
        va_eff = va.copy()
        va_eff[0, zero_start] = 0.0
        left = va_eff + V1[:-1] * ha - 0.5 * b2a * ha * ha
        right = V[1:] - V1[1:] * ha - 0.5 * b2b * ha * ha
        pos_a = va > 0
        pos_a[0, zero_start] = True
        proved = pos_a & (V[1:] > 0) & (left > 0) & (right > 0)
        for i in np.nonzero(~proved.all(axis=1))[0]:
            roots = []
            for j in np.nonzero(~proved[i])[0]:
                r = self._cell(j, i * h, Y[i], (i + 1) * h, Y[i + 1], bool(zero_start[j]) and i == 0)
                if r is not None:
                    roots.append((r, j))
            if roots:
                tau = min(r for r, _ in roots)
                # Surfaces crossed together (D = 0: u = g and tau_c + tau_d = 0 are one surface)
                # have roots that differ by round-off only.
                together = {j for r, j in roots if r - tau <= _COINCIDENT}
                return tau, expm(self.M * tau) @ y0, together
        return None


def _project(p, y, names):
    """On the surface u = s g, u is set exactly to s g."""
    y = y.copy()
    if "flank+" in names:
        y[U] = p["g"]
    elif "flank-" in names:
        y[U] = -p["g"]
    return y


def _run_exact(p, law, y0, bp, inputs, t_out, twin=False):
    """Method A core. inputs: per interval (tau_ff, tau_L, w_ref, Kp, Ki, loop)."""
    rows = _functionals(p)
    nt = t_out.size
    Y = np.empty((nt, N))
    modes = [""] * nt
    switches: list[Switch] = []
    y = np.array(y0, dtype=float)
    k = 0  # next output index

    def emit(t_seg, y_seg, M, mode, t_end, inclusive):
        nonlocal k
        while k < nt and (t_out[k] < t_end or (inclusive and t_out[k] <= t_end)):
            Y[k] = expm(M * (t_out[k] - t_seg)) @ y_seg
            modes[k] = mode
            k += 1

    mode = "twin" if twin else _classify(p, law, y, inputs[0], rows)
    for i in range(bp.size - 1):
        inp, t, t_end, last = inputs[i], bp[i], bp[i + 1], i == bp.size - 2
        if not twin:
            # A breakpoint changes M only; the mode changes there only if the state lies on a
            # surface that the new inputs drive it across.
            new = _classify(p, law, y, inp, rows, mode)
            if new != mode:
                names = tuple(sorted(n for n, _ in region(mode, law) if _is_zero(rows[n], y)))
                switches.append(Switch(t, mode, new, names))
                mode = new
        n_here = 0
        while True:
            M = _matrix(p, mode, inp)
            if twin:
                hit = None
            else:
                reg = region(mode, law)
                R = np.array([rows[n] for n, _ in reg])
                S = np.array([s for _, s in reg], dtype=float)
                zs = np.array([_is_zero(rows[n], y) for n, _ in reg])
                hit = _Search(M, R, S).first(y, t_end - t, zs)
            if hit is None:
                emit(t, y, M, mode, t_end, last)
                y = expm(M * (t_end - t)) @ y
                break
            tau, ys, together = hit
            ts = t + tau
            emit(t, y, M, mode, ts, False)
            names = tuple(sorted(n for j, (n, _) in enumerate(reg)
                                 if j in together or _is_zero(rows[n], ys)))
            ys = _project(p, ys, names)
            new = _classify(p, law, ys, inp, rows, mode)
            switches.append(Switch(ts, mode, new, names))
            mode, y, t = new, ys, ts
            n_here += 1
            if n_here > 10000:
                raise RuntimeError("more than 10000 switches in one input interval")
            if t >= t_end:
                emit(t, y, M, mode, t_end, last)
                break
    psi = np.array([_psi_row(p, m) @ yk for m, yk in zip(modes, Y)])
    tau_m = np.array([_tau_m_row(inputs[min(np.searchsorted(bp, tk, "right") - 1, bp.size - 2)]) @ yk
                      for tk, yk in zip(t_out, Y)])
    return Y, modes, switches, psi, tau_m


def _result(t_out, Y, modes, switches, psi, tau_m):
    contact = np.zeros(t_out.size, dtype=int)
    for i, m in enumerate(modes):
        s = mode_side(m) if m != "twin" else int(np.sign(psi[i]))
        if mode_kind(m) != "free" and s * psi[i] > 0:
            contact[i] = s
    return Result(t=t_out, z=Y[:, [TM, WM, TL, WL]].copy(), u=Y[:, U].copy(), xi=Y[:, XI].copy(),
                  psi=psi, tau_m=tau_m, contact=contact, mode=list(modes), switches=switches)


def _y0(p, z0, xi0):
    z0 = np.asarray(z0, dtype=float)
    y = np.zeros(N)
    y[[TM, WM, TL, WL]] = z0
    y[U] = p["r_m"] * z0[0] - p["r_L"] * z0[2]
    y[XI], y[ONE] = xi0, 1.0
    return y


def simulate(params: dict, law: int, z0, breakpoints, tau_m, tau_L, t_out) -> Result:
    """Method A, open loop. params: J_m, J_L, b_m, b_L, r_m, r_L, K, g, D (see shaft_params,
    belt_params); law: 1 or 2; z0: [theta_m, omega_m, theta_L, omega_L] at breakpoints[0];
    tau_m, tau_L: one value per interval (or a scalar), held on [breakpoints[i],
    breakpoints[i+1]); t_out: non-decreasing times inside the breakpoints' span."""
    bp, (tm, tl) = _intervals(breakpoints, tau_m, tau_L)
    t = _check_out(t_out, bp)
    inputs = [(tm[i], tl[i], 0.0, 0.0, 0.0, False) for i in range(tm.size)]
    return _result(t, *_run_exact(params, law, _y0(params, z0, 0.0), bp, inputs, t))


def simulate_pi(params: dict, law: int, z0, breakpoints, w_ref, tau_L, gains, t_out,
                xi0: float = 0.0) -> Result:
    """Method A with the continuous PI speed loop e = w_ref - omega_m, xi' = e,
    tau_m = Kp e + Ki xi (gains = (Kp, Ki)); w_ref, tau_L held between breakpoints. The loop is
    affine in each mode, so xi is one more state of the exact solution."""
    bp, (w, tl) = _intervals(breakpoints, w_ref, tau_L)
    t = _check_out(t_out, bp)
    Kp, Ki = gains
    inputs = [(0.0, tl[i], w[i], Kp, Ki, True) for i in range(w.size)]
    return _result(t, *_run_exact(params, law, _y0(params, z0, xi0), bp, inputs, t))


def linear_twin(params: dict, z0, breakpoints, tau_m, tau_L, t_out) -> Result:
    """The plant with psi = K u + D u' everywhere (no gap, no clipping: it can pull), exact by
    expm; mode 'twin' throughout, no switches; contact is the sign of psi."""
    bp, (tm, tl) = _intervals(breakpoints, tau_m, tau_L)
    t = _check_out(t_out, bp)
    inputs = [(tm[i], tl[i], 0.0, 0.0, 0.0, False) for i in range(tm.size)]
    return _result(t, *_run_exact(params, 0, _y0(params, z0, 0.0), bp, inputs, t, twin=True))


def linear_twin_pi(params: dict, z0, breakpoints, w_ref, tau_L, gains, t_out,
                   xi0: float = 0.0) -> Result:
    """The linear twin in the PI loop of simulate_pi."""
    bp, (w, tl) = _intervals(breakpoints, w_ref, tau_L)
    t = _check_out(t_out, bp)
    Kp, Ki = gains
    inputs = [(0.0, tl[i], w[i], Kp, Ki, True) for i in range(w.size)]
    return _result(t, *_run_exact(params, 0, _y0(params, z0, xi0), bp, inputs, t, twin=True))


def mode_matrix(params: dict, mode: str, tau_m: float = 0.0, tau_L: float = 0.0) -> np.ndarray:
    """The open-loop M (7 x 7) of y' = M y in a mode ('twin' for the linear twin), y =
    [theta_m, omega_m, theta_L, omega_L, u, xi, 1]."""
    return _matrix(params, mode, (tau_m, tau_L, 0.0, 0.0, 0.0, False))


def pi_eigenvalues(params: dict, mode: str, gains) -> np.ndarray:
    """Eigenvalues of the PI loop's dynamics in a mode ('twin' for the linear twin): the block
    of [omega_m, u, omega_L, xi] for a mode with force (the angles and the constant only feed
    forward), of [omega_m, omega_L, xi] for a free mode (there u only integrates u')."""
    Kp, Ki = gains
    M = _matrix(params, mode, (0.0, 0.0, 0.0, Kp, Ki, True))
    idx = [WM, WL, XI] if mode in FREE_MODES else [WM, U, WL, XI]
    return np.linalg.eigvals(M[np.ix_(idx, idx)])


# ============================================================================================
# Method B: solve_ivp (DOP853) with terminal events, restarted at each event
# ============================================================================================

_PROBE = 1e-8  # s; much longer than the round-off in an event time (~1e-16 s), much shorter
#                than the time between two switches in the scenarios (>~1e-4 s)
# solve_ivp looks at the event functions only at the ends of its steps, so a surface crossed and
# recrossed within one step is missed; in free flight (psi = 0, nearly polynomial motion) DOP853
# takes steps of tenths of a second, and without a cap one of the test scenarios (belt, law 2,
# zeta 1.5, square torque) steps over a return to the gap. With caps up to 2e-2 s every
# scenario's switch list matches A's; 5e-3 s keeps a factor 4. A deliberate graze (tests) needs a
# cap below its excursion, passed as max_step.
_MAX_STEP = 5e-3  # s
# Another event function of the mode left is on its surface too if it is within this fraction of
# the magnitude of its terms, or would reach zero within _COINCIDENT_B at its present rate (D = 0:
# u = +-g and tau_c + tau_d = 0 are one surface, found as two roots a few 1e-16 s apart).
_TOL_EVENT = 1e-10
_COINCIDENT_B = 1e-13  # s


def _ivp_core(p, law, z0, xi0, bp, u1, tl, gains, t_out, rtol=1e-13, max_step=_MAX_STEP):
    Jm, JL, bm, bL = p["J_m"], p["J_L"], p["b_m"], p["b_L"]
    rm, rL, K, g, D = p["r_m"], p["r_L"], p["K"], p["g"], p["D"]
    loop = gains is not None
    Kp, Ki = gains if loop else (0.0, 0.0)

    def force(mode, u, du):
        if mode in ("gap", "clip+", "clip-"):
            return 0.0
        s = 1.0 if mode[-1] == "+" else -1.0
        tc = K * (u - s * g)
        if mode[:-1] == "contact":
            return tc + D * du
        return 2.0 * tc  # cap

    def rhs(t, y, mode, a, tau_L):
        _, wm, _, wl, u, xi = y
        du = rm * wm - rL * wl
        f = force(mode, u, du)
        if loop:
            e = a - wm
            tm, dxi = Kp * e + Ki * xi, e
        else:
            tm, dxi = a, 0.0
        return [wm, (tm - bm * wm - rm * f) / Jm, wl, (tau_L - bL * wl + rL * f) / JL, du, dxi]

    # Event functions of each mode: (name, function(y), term scale(y)); each must stay > 0 in the
    # mode, and the mode is left when one falls through zero.
    def flank(s):
        return lambda y: s * y[4] - g, lambda y: abs(y[4]) + g

    def fscale(y):
        return K * (abs(y[4]) + g) + D * (rm * abs(y[1]) + rL * abs(y[3]))

    def zero(s, sgn):  # sgn * s * (tau_c + tau_d)
        return (lambda y: sgn * s * (K * (y[4] - s * g) + D * (rm * y[1] - rL * y[3]))), fscale

    def equal(s, sgn):  # sgn * s * (tau_d - tau_c)
        return (lambda y: sgn * s * (D * (rm * y[1] - rL * y[3]) - K * (y[4] - s * g))), fscale

    def events_of(mode):
        if mode == "gap":
            return [("flank+", lambda y: g - y[4], lambda y: abs(y[4]) + g),
                    ("flank-", lambda y: g + y[4], lambda y: abs(y[4]) + g)]
        s = 1.0 if mode[-1] == "+" else -1.0
        side, kind = mode[-1], mode[:-1]
        ev = [("flank" + side, *flank(s))]
        if kind == "clip":
            ev.append(("zero" + side, *zero(s, -1.0)))
        else:
            ev.append(("zero" + side, *zero(s, 1.0)))
            if law == 1:
                ev.append(("equal" + side, *equal(s, 1.0 if kind == "cap" else -1.0)))
        return ev

    def entered(mode, y, a, tau_L):
        """The literal law a short time after the switch, along the flow of the mode left."""
        yp = np.asarray(y) + _PROBE * np.asarray(rhs(0.0, y, mode, a, tau_L))
        return raw_mode(p, law, yp[4], rm * yp[1] - rL * yp[3])

    y = np.array([*np.asarray(z0, dtype=float), rm * z0[0] - rL * z0[2], xi0])
    mode = raw_mode(p, law, y[4], rm * y[1] - rL * y[3])
    nt = t_out.size
    Y = np.empty((nt, 6))
    modes = [""] * nt
    switches: list[Switch] = []
    k = 0
    atol = np.array([1e-15, 1e-15, 1e-15, 1e-15, 1e-18, 1e-15])
    for i in range(bp.size - 1):
        t, t_end, last = bp[i], bp[i + 1], i == bp.size - 2
        a, tau_L = u1[i], tl[i]
        while True:
            evs = events_of(mode)
            fns = []
            for _, fn, _ in evs:
                def ev(t_, y_, *args, fn=fn):
                    return fn(y_)
                ev.terminal, ev.direction = True, -1
                fns.append(ev)
            sol = solve_ivp(rhs, (t, t_end), y, method="DOP853", rtol=rtol, atol=atol, events=fns,
                            dense_output=True, max_step=max_step, args=(mode, a, tau_L))
            if sol.status < 0:
                raise RuntimeError(sol.message)
            fired = [(te[0], j) for j, te in enumerate(sol.t_events) if te.size]
            if not fired:
                while k < nt and (t_out[k] < t_end or (last and t_out[k] <= t_end)):
                    Y[k], modes[k] = sol.sol(t_out[k]), mode
                    k += 1
                y, t = sol.y[:, -1], t_end
                break
            te, j = min(fired)
            ye = sol.y_events[j][0].copy()
            while k < nt and t_out[k] < te:
                Y[k], modes[k] = sol.sol(t_out[k]), mode
                k += 1
            fe = np.asarray(rhs(te, ye, mode, a, tau_L))
            h = 1e-6  # s; the event functions are affine, so the difference quotient is exact

            def on_surface(fn, sc):
                v = abs(fn(ye))
                rate = abs(fn(ye + h * fe) - fn(ye)) / h
                return v <= _TOL_EVENT * sc(ye) or v <= _COINCIDENT_B * rate

            names = tuple(sorted({evs[j][0]} | {nm for nm, fn, sc in evs if on_surface(fn, sc)}))
            if "flank+" in names:
                ye[4] = g
            elif "flank-" in names:
                ye[4] = -g
            new = entered(mode, ye, a, tau_L)
            if new == mode:
                raise RuntimeError(f"event {names} at t={te} leaves the mode {mode} unchanged")
            switches.append(Switch(te, mode, new, names))
            mode, y, t = new, ye, te
            if t >= t_end:
                break
    du = rm * Y[:, 1] - rL * Y[:, 3]
    psi = np.array([force(m, yk[4], d) for m, yk, d in zip(modes, Y, du)])
    idx = np.clip(np.searchsorted(bp, t_out, "right") - 1, 0, bp.size - 2)
    tau_m = Kp * (u1[idx] - Y[:, 1]) + Ki * Y[:, 5] if loop else u1[idx]
    contact = np.array([mode_side(m) if mode_kind(m) != "free" and mode_side(m) * f > 0 else 0
                        for m, f in zip(modes, psi)], dtype=int)
    return Result(t=t_out, z=Y[:, :4].copy(), u=Y[:, 4].copy(), xi=Y[:, 5].copy(), psi=psi,
                  tau_m=np.asarray(tau_m, dtype=float), contact=contact, mode=modes,
                  switches=switches)


def simulate_ivp(params: dict, law: int, z0, breakpoints, tau_m, tau_L, t_out,
                 rtol: float = 1e-13, max_step: float = _MAX_STEP) -> Result:
    """Method B, open loop; same arguments and result as `simulate`."""
    bp, (tm, tl) = _intervals(breakpoints, tau_m, tau_L)
    return _ivp_core(params, law, z0, 0.0, bp, tm, tl, None, _check_out(t_out, bp), rtol, max_step)


def simulate_pi_ivp(params: dict, law: int, z0, breakpoints, w_ref, tau_L, gains, t_out,
                    xi0: float = 0.0, rtol: float = 1e-13, max_step: float = _MAX_STEP) -> Result:
    """Method B in the PI loop; same arguments and result as `simulate_pi`."""
    bp, (w, tl) = _intervals(breakpoints, w_ref, tau_L)
    return _ivp_core(params, law, z0, xi0, bp, w, tl, tuple(gains), _check_out(t_out, bp), rtol, max_step)


def twin_loop(p: dict, gains) -> tuple[np.ndarray, np.ndarray]:
    """A_cl and D_1 of the linear twin under the continuous PI (docs/model.md §3 with the damper)
    in [theta_m, omega_m, theta_L, omega_L, xi]: psi = K u + D u', tau_m = Kp (w_ref - omega_m) +
    Ki xi; the disturbance phi = (K u + D u') - psi enters through D_1. The impulse response of
    the bounds is h(s) = e_{omega_L} e^{A s} D_1."""
    J_m, J_L, b_m, b_L, r_m, r_L, K, D = (p[k] for k in ("J_m", "J_L", "b_m", "b_L", "r_m", "r_L", "K", "D"))
    Kp, Ki = gains
    # psi = K (r_m th_m - r_L th_L) + D (r_m w_m - r_L w_L)
    psi = np.array([K * r_m, D * r_m, -K * r_L, -D * r_L, 0.0])
    A = np.zeros((5, 5))
    A[0, 1] = 1.0
    A[1] = -r_m * psi / J_m
    A[1, 1] += -(b_m + Kp) / J_m
    A[1, 4] += Ki / J_m
    A[2, 3] = 1.0
    A[3] = r_L * psi / J_L
    A[3, 3] += -b_L / J_L
    A[4, 1] = -1.0
    # The disturbance phi enters as psi = (K u + D u') - phi.
    D_1 = np.array([0.0, r_m / J_m, 0.0, -r_L / J_L, 0.0])
    return A, D_1

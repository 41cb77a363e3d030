"""Independent reference for the web-tension drive train (docs/model.md §1, §3, §8).

The belt drive of §1 pulls a web span: with x = [u, omega_m, omega_L, x_c, T, x_T]
(u = r_m theta_m - r_L theta_L replaces the two angles, which enter only through u)

    u'       = r_m omega_m - r_L omega_L
    J_m w_m' = tau_m - b_m omega_m - r_m psi
    J_L w_L' = tau_L - b_L omega_L + r_L psi - R_w T
    L_w T'   = EA (R_w omega_L - v_in) + v_ref (T_in - T)
    x_c'     = e = w_ref - omega_m,      tau_m = Kp e + Ki x_c
    x_T'     = T_ref - T,                w_ref = w_ref0 + Kp_T (T_ref - T) + Ki_T x_T

The bounds integrate |h| by an exact antiderivative instead of quadrature: for a Hurwitz A,
H(s) = c A^-1 e^{As} d has H' = h and H(inf) = 0, so between consecutive sign changes
r_i < r_i+1 of h, int |h| = |H(r_i+1) - H(r_i)|. Only the sign changes are searched for
(on a grid of e^{A delta} steps, split at the extrema of h, then brentq); the sum stops when
the eigen-decomposition's envelope of the tail is below 1e-13 of the sum.

For test_web.py (the BacklashWeb FMU), below `simulate`: `l1_until` and `bounds_until`, the same
L1 integral to finite times; `reduced_loop` (the loop without x_c when Ki = 0); the open-loop
plant under held or ramped inputs by event-located DOP853 (`OpenLoop`) and by matrix
exponentials (`ExactOpenLoop`), both through `run_open_loop`.
"""

from __future__ import annotations

from typing import Callable

import numpy as np
from scipy.integrate import solve_ivp
from scipy.linalg import expm, matrix_balance
from scipy.optimize import brentq

# Drive: BacklashBelt's parameter start values. Web span: docs/model.md §8 design defaults.
WEB = {
    "J_m": 1e-4, "J_L": 5e-3, "b_m": 1e-4, "b_L": 1e-3, "K_b": 2e5,
    "R_1": 0.02, "R_2": 0.04, "R_g1": 0.015, "R_g2": 0.045, "Delta": 5e-5,
    "R_w": 0.05, "L_w": 1.0, "EA": 1e5, "v_ref": 2.0,
}
DRIVE = ("J_m", "J_L", "b_m", "b_L", "K_b", "R_1", "R_2", "R_g1", "R_g2", "Delta")


def transmission(p: dict) -> tuple[float, float, float, float]:
    """(r_m, r_L, K, g) of the belt form (docs/model.md §1 table)."""
    return p["R_1"], p["R_2"] * p["R_g2"] / p["R_g1"], p["K_b"], p["R_2"] / p["R_g1"] * p["Delta"]


def loop_matrices(p: dict, Kp: float, Ki: float, Kp_T: float = 0.0, Ki_T: float = 0.0, web: bool = True):
    """(A, d, c_T, c_w): backlash-free closed loop in x = [u, w_m, w_L, x_c, T, x_T], the column
    by which phi enters, and the rows picking T and omega_L. x_T is dropped when Ki_T = 0 (it
    would be a pure integrator that nothing reads), T and x_T without the web (the plain belt
    speed loop)."""
    r_m, r_L, K, _ = transmission(p)
    J_m, J_L, b_m, b_L = p["J_m"], p["J_L"], p["b_m"], p["b_L"]
    A = np.zeros((6, 6))
    e = np.array([0.0, -1.0, 0.0, 0.0, -Kp_T, Ki_T])  # homogeneous part of the speed error
    A[0, 1], A[0, 2] = r_m, -r_L
    A[1] = Kp * e / J_m
    A[1, 0] -= K * r_m / J_m
    A[1, 1] -= b_m / J_m
    A[1, 3] += Ki / J_m
    A[2, 0], A[2, 2] = K * r_L / J_L, -b_L / J_L
    A[3] = e
    if web:
        A[2, 4] = -p["R_w"] / J_L
        A[4, 2], A[4, 4] = p["EA"] * p["R_w"] / p["L_w"], -p["v_ref"] / p["L_w"]
        A[5, 4] = -1.0
    d = np.array([0.0, r_m / J_m, -r_L / J_L, 0.0, 0.0, 0.0])
    n = 4 if not web else 6 if Ki_T else 5  # x_T feeds back only through Ki_T
    eye = np.eye(6)
    return A[:n, :n], d[:n], eye[4, :n], eye[2, :n]


def l1_norm(A: np.ndarray, d: np.ndarray, c: np.ndarray, rtol: float = 1e-13, block: int = 2048) -> float:
    """int_0^inf |c e^{As} d| ds; ValueError unless every eigenvalue of A has Re < 0."""
    lam, V = np.linalg.eig(A)
    if np.max(lam.real) >= 0.0:
        raise ValueError(f"closed loop not asymptotically stable: max Re(lambda) = {np.max(lam.real)}")
    residue = np.abs((c @ V) * np.linalg.solve(V, d))

    def tail(t: float) -> float:  # int_t^inf of the envelope sum |r_i| e^{Re lambda_i s}
        return float(np.sum(residue * np.exp(lam.real * t) / -lam.real))

    delta = 0.05 / np.max(np.abs(lam))
    steps = np.empty((block + 1, len(d), len(d)))  # e^{A j delta}, j = 0..block, by doubling
    steps[0], steps[1], m = np.eye(len(d)), expm(A * delta), 1
    while m < block:
        steps[m + 1 : 2 * m + 1] = steps[1 : m + 1] @ steps[m]
        m *= 2
    c_int, c_der = np.linalg.solve(A.T, c), A.T @ c  # H = c_int . v, h' = c_der . v
    h_at = lambda v: lambda x: c @ expm(A * x) @ v  # noqa: E731
    dh_at = lambda v: lambda x: c_der @ expm(A * x) @ v  # noqa: E731

    total, H_last, v0, t0 = 0.0, c_int @ d, d.astype(float), 0.0
    while True:
        vs = steps @ v0
        h, dh = vs @ c, vs @ c_der
        candidates = np.nonzero((h[:-1] * h[1:] < 0.0) | (dh[:-1] * dh[1:] < 0.0))[0]
        for k in candidates:
            # Split the cell at an extremum of h, so that h is monotone on each part.
            cuts, f = [0.0, delta], h_at(vs[k])
            if dh[k] * dh[k + 1] < 0.0:
                cuts.insert(1, brentq(dh_at(vs[k]), 0.0, delta, xtol=1e-300, rtol=1e-15))
            for a, b in zip(cuts[:-1], cuts[1:]):
                fa, fb = (h[k] if a == 0.0 else f(a)), (h[k + 1] if b == delta else f(b))
                if fa * fb < 0.0:
                    r = brentq(f, a, b, xtol=1e-300, rtol=1e-15)
                    H = c_int @ expm(A * r) @ vs[k]
                    total, H_last = total + abs(H - H_last), H
        t0, v0 = t0 + block * delta, vs[-1]
        H_end = c_int @ v0
        if tail(t0) <= rtol * (total + abs(H_end - H_last)):
            return total + abs(H_end - H_last) + abs(H_end)


def bound_sups(p: dict, Kp: float, Ki: float, Kp_T: float = 0.0, Ki_T: float = 0.0) -> tuple[float, float]:
    """(bound_T_sup [N], bound_sup [rad/s]) = K g int_0^inf |h_T|, K g int_0^inf |h|."""
    _, _, K, g = transmission(p)
    A, d, c_T, c_w = loop_matrices(p, Kp, Ki, Kp_T, Ki_T)
    return K * g * l1_norm(A, d, c_T), K * g * l1_norm(A, d, c_w)


def _switch(sol, s: float, stalls: int) -> tuple[int, float, int]:
    """(event index, instant, stalls) of the terminal switch event that ended `sol`, which
    started at s; refuses a switch that does not advance time four times in a row."""
    hit = next(i for i, te in enumerate(sol.t_events) if len(te))
    s_ev = float(sol.t_events[hit][0])
    stalls = stalls + 1 if s_ev == s else 0
    if stalls > 3:
        raise RuntimeError(f"switch events do not advance at t = {s}")
    return hit, s_ev, stalls


def simulate(
    p: dict,
    gains: tuple[float, float, float, float],
    w_ref0: Callable[[float], float],
    t: np.ndarray,
    T_ref: float = 0.0,
    tau_L: float = 0.0,
    v_in: float = 0.0,
    T_in: float = 0.0,
    rtol: float = 1e-11,
    atol: float = 1e-15,
) -> tuple[np.ndarray, np.ndarray]:
    """(T, omega_L) at the times t (t[0] = 0, all states 0 there) of the web plant with backlash
    under the continuous speed PI and tension PI, gains = (Kp, Ki, Kp_T, Ki_T). DOP853 inside
    each contact mode; each switch u = +-g is a terminal event, and the integration restarts in
    the mode entered. With Delta = 0 the plant is linear (psi = K u) and there is one mode."""
    Kp, Ki, Kp_T, Ki_T = gains
    r_m, r_L, K, g = transmission(p)
    J_m, J_L, b_m, b_L = p["J_m"], p["J_L"], p["b_m"], p["b_L"]
    R_w, L_w, EA, v_ref = p["R_w"], p["L_w"], p["EA"], p["v_ref"]

    def rhs(offset: float | None):
        def f(s, x):
            u, w_m, w_L, x_c, T, x_T = x
            psi = 0.0 if offset is None else K * (u + offset)
            e = w_ref0(s) + Kp_T * (T_ref - T) + Ki_T * x_T - w_m
            return [
                r_m * w_m - r_L * w_L,
                (Kp * e + Ki * x_c - b_m * w_m - r_m * psi) / J_m,
                (tau_L - b_L * w_L + r_L * psi - R_w * T) / J_L,
                e,
                (EA * (R_w * w_L - v_in) + v_ref * (T_in - T)) / L_w,
                T_ref - T,
            ]

        return f

    def upper(_s, x):
        return x[0] - g

    def lower(_s, x):
        return x[0] + g

    upper.terminal = lower.terminal = True

    def mode_data(mode: int):
        """(psi offset, switch events, modes they lead to); free 0, contact + 1, contact - -1."""
        if mode == 0:
            upper.direction, lower.direction = 1.0, -1.0
            return None, [upper, lower], [1, -1]
        if mode == 1:
            upper.direction = -1.0
            return -g, [upper], [0]
        lower.direction = 1.0
        return g, [lower], [0]

    mode = 0 if g > 0.0 else 1
    x, s, out, stalls = np.zeros(6), 0.0, [np.zeros(6)], 0
    while len(out) < len(t):
        offset, events, targets = mode_data(mode)
        sol = solve_ivp(
            rhs(offset), (s, t[-1]), x, method="DOP853", rtol=rtol, atol=atol,
            t_eval=t[len(out):], events=None if g == 0.0 else events,
        )
        if sol.status == -1:
            raise RuntimeError(sol.message)
        out.extend(sol.y.T)
        if sol.status == 1:
            hit, s_ev, stalls = _switch(sol, s, stalls)
            s, x, mode = s_ev, sol.y_events[hit][0].copy(), targets[hit]
    y = np.array(out)
    return y[:, 4], y[:, 2]


def dominant_frequency(A: np.ndarray, d: np.ndarray, c: np.ndarray) -> float:
    """The angular frequency (rad/s) of the largest |c (jw - A)^-1 d| on a log grid."""
    w = np.logspace(-1, 5, 3000)
    gain = [abs(c @ np.linalg.solve(1j * wi * np.eye(len(d)) - A, d)) for wi in w]
    return float(w[int(np.argmax(gain))])


# --- Additions for test_web.py (the BacklashWeb FMU); the functions above are unchanged. ---


def reduced_loop(p: dict, Kp: float, Ki: float, Kp_T: float = 0.0, Ki_T: float = 0.0):
    """loop_matrices without the speed integrator x_c when Ki = 0: nothing reads it then, and its
    eigenvalue 0 would make the loop look unstable (docs/model.md §3, "Which modes count")."""
    A, d, c_T, c_w = loop_matrices(p, Kp, Ki, Kp_T, Ki_T)
    if Ki == 0.0:
        A, d, c_T, c_w = np.delete(np.delete(A, 3, 0), 3, 1), np.delete(d, 3), np.delete(c_T, 3), np.delete(c_w, 3)
    return A, d, c_T, c_w


def l1_until(A: np.ndarray, d: np.ndarray, c: np.ndarray, times) -> np.ndarray:
    """int_0^t |c e^{As} d| ds at each of the (non-negative) times, by the exact antiderivative of
    l1_norm: H(s) = c A^-1 e^{As} d (A invertible, not necessarily Hurwitz) has H' = h, so with
    the sign changes r_1 < r_2 < ... of h in [0, t] (r_0 = 0)
        int_0^t |h| = sum_i |H(r_i) - H(r_i-1)| + |H(t) - H(r_last)|.
    The sign changes are searched on a grid of e^{A delta} steps split at the extrema of h, as
    in l1_norm; H at the roots and at t comes from expm of the root's time."""
    times = np.asarray(times, dtype=float)
    lam = np.linalg.eigvals(A)
    delta = 0.05 / np.max(np.abs(lam))
    n = int(np.ceil(np.max(times) / delta)) + 1
    step = expm(A * delta)
    c_int, c_der = np.linalg.solve(A.T, c), A.T @ c
    vs = np.empty((n + 1, len(d)))
    vs[0] = d
    for k in range(n):
        vs[k + 1] = step @ vs[k]
    h, dh = vs @ c, vs @ c_der
    roots = []
    for k in np.nonzero((h[:-1] * h[1:] < 0.0) | (dh[:-1] * dh[1:] < 0.0))[0]:
        f = lambda x, v=vs[k]: c @ expm(A * x) @ v  # noqa: E731
        cuts = [0.0, delta]
        if dh[k] * dh[k + 1] < 0.0:
            cuts.insert(1, brentq(lambda x, v=vs[k]: c_der @ expm(A * x) @ v, 0.0, delta, xtol=1e-300, rtol=1e-15))
        for a, b in zip(cuts[:-1], cuts[1:]):
            fa, fb = (h[k] if a == 0.0 else f(a)), (h[k + 1] if b == delta else f(b))
            if fa * fb < 0.0:
                r = brentq(f, a, b, xtol=1e-300, rtol=1e-15)
                roots.append((k * delta + r, c_int @ expm(A * r) @ vs[k]))
    r_times = np.array([0.0] + [r for r, _ in roots])
    r_H = np.array([c_int @ d] + [H for _, H in roots])
    cumulative = np.concatenate([[0.0], np.cumsum(np.abs(np.diff(r_H)))])
    out = np.empty(len(times))
    for j, t in enumerate(times):
        i = int(np.searchsorted(r_times, t, side="right")) - 1  # last root at or before t
        out[j] = cumulative[i] + abs(c_int @ expm(A * t) @ d - r_H[i])
    return out


def bounds_until(p: dict, gains: tuple[float, float, float, float], times) -> tuple[np.ndarray, np.ndarray]:
    """(bound_T(t) [N], bound(t) [rad/s]) = K g int_0^t |h_T|, K g int_0^t |h| at the times."""
    _, _, K, g = transmission(p)
    A, d, c_T, c_w = reduced_loop(p, *gains)
    return K * g * l1_until(A, d, c_T, times), K * g * l1_until(A, d, c_w, times)


# Contact modes, numbered as the FMU's `contact` output (docs/model.md §4).
FREE, PLUS, MINUS = 0, 1, -1


class OpenLoop:
    """The web plant with backlash in open loop: inputs (tau_m, tau_L, v_in, T_in) held over each
    communication step or along a line, event-located DOP853 as in `simulate` (a terminal event
    at each switch u = +-g, restarted in the mode entered with u set exactly on +-g).

    State x = [u, omega_m, omega_L, T, theta_m, theta_L]: u is integrated itself (not recovered
    from the angles), so that the error control acts on what decides the contact."""

    def __init__(self, p: dict, z0: dict | None = None, rtol: float = 1e-13, atol=None):
        z0 = {"theta_m": 0.0, "omega_m": 0.0, "theta_L": 0.0, "omega_L": 0.0, "T": 0.0, **(z0 or {})}
        self.p = p
        self.r_m, self.r_L, self.K, self.g = transmission(p)
        u0 = self.r_m * z0["theta_m"] - self.r_L * z0["theta_L"]
        self.x = np.array([u0, z0["omega_m"], z0["omega_L"], z0["T"], z0["theta_m"], z0["theta_L"]])
        self.t = 0.0
        self.rtol = rtol
        # Far below round-off of each state at its scale (u ~ 1e-4 m, speeds ~ 1 rad/s, T ~ 10 N):
        # rtol governs. Measured on a 0.2 s open loop of test_web.py against the exact solution:
        # rtol 1e-12 / 1e-13 / 3e-14 left 3.6e-9 / 1.1e-10 / 2.2e-10 relative: 1e-13 is the floor.
        self.atol = np.array([1e-21, 1e-16, 1e-17, 1e-15, 1e-18, 1e-19]) if atol is None else atol
        self.mode = self._initial_mode()
        self.switches: list[tuple[float, int, int]] = []  # (time, from, to)

    def rhs(self, mode: int, inputs, slopes, t0: float):
        """The vector field in `mode` with the inputs (tau_m, tau_L, v_in, T_in) = inputs +
        (s - t0) slopes."""
        p, r_m, r_L, K = self.p, self.r_m, self.r_L, self.K
        J_m, J_L, b_m, b_L = p["J_m"], p["J_L"], p["b_m"], p["b_L"]
        R_w, L_w, EA, v_ref = p["R_w"], p["L_w"], p["EA"], p["v_ref"]
        offset = {FREE: None, PLUS: -self.g, MINUS: self.g}[mode]

        def f(s, x):
            u, w_m, w_L, T = x[0], x[1], x[2], x[3]
            tau_m, tau_L, v_in, T_in = (inputs[i] + (s - t0) * slopes[i] for i in range(4))
            psi = 0.0 if offset is None else K * (u + offset)
            return [
                r_m * w_m - r_L * w_L,
                (tau_m - b_m * w_m - r_m * psi) / J_m,
                (tau_L - b_L * w_L + r_L * psi - R_w * T) / J_L,
                (EA * (R_w * w_L - v_in) + v_ref * (T_in - T)) / L_w,
                w_m,
                w_L,
            ]

        return f

    def _events(self):
        g = self.g

        def upper(_s, x):
            return x[0] - g

        def lower(_s, x):
            return x[0] + g

        upper.terminal = lower.terminal = True
        if self.mode == FREE:
            upper.direction, lower.direction = 1.0, -1.0
            return [upper, lower], [PLUS, MINUS], [g, -g]
        if self.mode == PLUS:
            upper.direction = -1.0
            return [upper], [FREE], [g]
        lower.direction = 1.0
        return [lower], [FREE], [-g]

    def _initial_mode(self) -> int:
        u, du = self.x[0], self.r_m * self.x[1] - self.r_L * self.x[2]
        if self.g == 0.0:
            return PLUS  # psi = K u on both flanks: one linear mode
        if u > self.g or (u == self.g and du > 0.0):
            return PLUS
        if u < -self.g or (u == -self.g and du < 0.0):
            return MINUS
        return FREE

    def step(self, h: float, inputs, slopes=(0.0, 0.0, 0.0, 0.0)) -> None:
        """Advance by h under (tau_m, tau_L, v_in, T_in) = inputs, held (zero slopes) or along
        the lines inputs + (s - t) slopes (fmi2SetRealInputDerivatives, docs/model.md §2)."""
        t0 = self.t
        s, s_end, x, stalls = self.t, self.t + h, self.x, 0
        while s < s_end:
            events, targets, levels = ([], [], []) if self.g == 0.0 else self._events()
            sol = solve_ivp(
                self.rhs(self.mode, inputs, slopes, t0), (s, s_end), x, method="DOP853",
                rtol=self.rtol, atol=self.atol, events=events or None,
            )
            if sol.status == -1:
                raise RuntimeError(sol.message)
            if sol.status == 1:
                hit, s_ev, stalls = _switch(sol, s, stalls)
                x = sol.y_events[hit][0].copy()
                x[0] = levels[hit]
                self.switches.append((s_ev, self.mode, targets[hit]))
                self.mode, s = targets[hit], s_ev
            else:
                s, x = s_end, sol.y[:, -1].copy()
        self.t, self.x = s_end, x

    def outputs(self) -> dict:
        u, w_m, w_L, T, th_m, th_L = self.x
        return {"theta_m": th_m, "omega_m": w_m, "theta_L": th_L, "omega_L": w_L, "T": T, "u": u, "contact": self.mode}


def run_open_loop(
    p: dict,
    inputs: np.ndarray,
    h: float,
    z0: dict | None = None,
    slopes: np.ndarray | None = None,
    method: str = "dop853",
    **kw,
):
    """Outputs at t_0..t_N under inputs[k] = (tau_m, tau_L, v_in, T_in) over step k, held, or
    along lines of slopes[k] from t_k; by OpenLoop ("dop853") or ExactOpenLoop ("expm")."""
    ref = ExactOpenLoop(p, z0) if method == "expm" else OpenLoop(p, z0, **kw)
    rows = [ref.outputs()]
    for k in range(len(inputs)):
        ref.step(h, inputs[k], (0.0, 0.0, 0.0, 0.0) if slopes is None else slopes[k])
        rows.append(ref.outputs())
    return {name: np.array([r[name] for r in rows]) for name in rows[0]}, ref


class ExactOpenLoop:
    """The open loop of OpenLoop solved by matrix exponentials instead of DOP853: in one contact
    mode the web plant with inputs along lines is y' = M y for
        y = [u, omega_m, omega_L, T, theta_m, theta_L, tau_m, tau_L, v_in, T_in, (their 4 slopes), 1],
    so y(s) = e^{M s} y(0) (scipy's Pade expm, on M balanced by a diagonal similarity of powers
    of 2 so that u ~ 1e-4 m and T ~ 10 N keep their own round-off). Switches: each step is cut
    into pieces of at most 0.05/rho (rho the largest |eigenvalue|, about 1/125 of the fastest
    period, so u has at most one extremum per piece); a piece holds a switch where u - level
    changes sign in the mode's direction, or where it has an extremum beyond the level (a graze),
    and the first such instant is found by brentq on the exact e^{M s} y."""

    N = 15

    def __init__(self, p: dict, z0: dict | None = None):
        self.ode = OpenLoop(p, z0)  # its initial state, mode and parameters
        self.p, self.g = p, self.ode.g
        self.mats = {mode: self._matrix(mode) for mode in (FREE, PLUS, MINUS)}
        _, (scale, _) = matrix_balance(self.mats[PLUS], permute=False, separate=True)
        self.scale = scale  # y = scale * z
        self.scaled = {m: M * (1.0 / scale)[:, None] * scale[None, :] for m, M in self.mats.items()}
        rho = max(np.max(np.abs(np.linalg.eigvals(M[:6, :6]))) for M in self.mats.values())
        self.piece = 0.05 / rho
        self.cache: dict = {}
        y = np.zeros(self.N)
        y[:6], y[-1] = self.ode.x, 1.0
        self.z = y / scale
        self.t, self.mode = 0.0, self.ode.mode
        self.switches: list[tuple[float, int, int]] = []

    def _matrix(self, mode: int) -> np.ndarray:
        p = self.p
        r_m, r_L, K, g = transmission(p)
        J_m, J_L, b_m, b_L = p["J_m"], p["J_L"], p["b_m"], p["b_L"]
        R_w, L_w, EA, v_ref = p["R_w"], p["L_w"], p["EA"], p["v_ref"]
        M = np.zeros((self.N, self.N))
        M[0, 1], M[0, 2] = r_m, -r_L
        M[1, 1], M[1, 6] = -b_m / J_m, 1.0 / J_m
        M[2, 2], M[2, 3], M[2, 7] = -b_L / J_L, -R_w / J_L, 1.0 / J_L
        M[3, 2], M[3, 3], M[3, 8], M[3, 9] = EA * R_w / L_w, -v_ref / L_w, -EA / L_w, v_ref / L_w
        M[4, 1], M[5, 2] = 1.0, 1.0
        M[6:10, 10:14] = np.eye(4)
        if mode != FREE:  # psi = K (u + offset)
            offset = -g if mode == PLUS else g
            M[1, 0], M[1, -1] = -r_m * K / J_m, -r_m * K * offset / J_m
            M[2, 0], M[2, -1] = r_L * K / J_L, r_L * K * offset / J_L
        return M

    def _expm(self, mode: int, s: float) -> np.ndarray:
        key = (mode, s)
        if key not in self.cache:
            self.cache[key] = expm(self.scaled[mode] * s)
        return self.cache[key]

    def _events(self):
        """(level, direction, target) of the mode's switches: crossed when direction (u - level)
        goes from <= 0 to > 0."""
        g = self.g
        if self.mode == FREE:
            return [(g, 1.0, PLUS), (-g, -1.0, MINUS)]
        return [(g, -1.0, FREE)] if self.mode == PLUS else [(-g, 1.0, FREE)]

    def _first_switch(self, z0: np.ndarray, z1: np.ndarray, length: float):
        """(s, level, target) of the first switch in a piece from z0 to z1, or None."""
        sc = self.scale
        u = lambda s: sc[0] * (expm(self.scaled[self.mode] * s) @ z0)[0]  # noqa: E731
        du = lambda s: sc[0] * (self.scaled[self.mode] @ expm(self.scaled[self.mode] * s) @ z0)[0]  # noqa: E731
        u0, u1 = sc[0] * z0[0], sc[0] * z1[0]
        du0, du1 = sc[0] * (self.scaled[self.mode] @ z0)[0], sc[0] * (self.scaled[self.mode] @ z1)[0]
        first = None
        for level, direction, target in self._events():
            f0, f1 = direction * (u0 - level), direction * (u1 - level)
            end = None
            if f0 <= 0.0 < f1:
                end = length
            elif direction * du0 > 0.0 > direction * du1:  # an extremum of f inside: a graze?
                s_x = brentq(du, 0.0, length, xtol=1e-20, rtol=8.9e-16)
                if direction * (u(s_x) - level) > 0.0:
                    end = s_x
            if end is None:
                continue
            s = brentq(lambda s: u(s) - level, 0.0, end, xtol=1e-20, rtol=8.9e-16)
            while s < end and direction * (u(s) - level) <= 0.0:  # the side beyond the level
                s = np.nextafter(s, end)
            if first is None or s < first[0]:
                first = (s, level, target)
        return first

    def step(self, h: float, inputs, slopes=(0.0, 0.0, 0.0, 0.0)) -> None:
        """Advance by h under inputs + (s - t) slopes; the inputs move along their lines inside y."""
        self.z[6:10] = np.asarray(inputs, dtype=float) / self.scale[6:10]
        self.z[10:14] = np.asarray(slopes, dtype=float) / self.scale[10:14]
        n = max(1, int(np.ceil(h / self.piece)))
        k, s, on_grid = 0, 0.0, True  # piece k ends at (k + 1) h / n; s since the step's start
        while k < n:
            end = (k + 1) * h / n
            length = h / n if on_grid else end - s
            step = self._expm(self.mode, length) if on_grid else expm(self.scaled[self.mode] * length)
            z1 = step @ self.z
            hit = None if self.g == 0.0 else self._first_switch(self.z, z1, length)
            if hit is None:
                self.z, s, k, on_grid = z1, end, k + 1, True
                continue
            ds, level, target = hit
            self.z = expm(self.scaled[self.mode] * ds) @ self.z
            self.z[0] = level / self.scale[0]
            self.switches.append((self.t + s + ds, self.mode, target))
            self.mode, s, on_grid = target, s + ds, False
        self.t += h

    def outputs(self) -> dict:
        y = self.z * self.scale
        return {
            "theta_m": y[4], "omega_m": y[1], "theta_L": y[5], "omega_L": y[2], "T": y[3], "u": y[0],
            "contact": self.mode,
        }

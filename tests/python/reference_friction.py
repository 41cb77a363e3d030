"""Independent reference solution of the plant of docs/model.md §1 with bearing friction and
stiction on the motor and the load (docs/model.md §12).

Written from the law of §12 alone, with a different method from the FMU's exact stepping (§2):
scipy's DOP853 inside each mode, every switch located as a terminal event and the integration
restarted in the new mode. A mode is the contact mode (free, +, -) times each body's friction
mode (+1 sliding forward, -1 backward, 0 stuck). The switching surfaces:

- contact: u = +-g (as reference.py);
- a sliding body: omega = 0. There the law decides: it sticks if |tau_h| <= peak tau_c, else it
  slides on in the direction of tau_h (a reversal without sticking);
- a stuck body: |tau_h| = peak tau_c, where it breaks away in the direction of tau_h.

tau_h is every other torque on the body: tau_m - r_m psi on the motor, tau_L + r_L psi on the
load (the viscous b omega vanishes at rest). A stuck body has omega = 0 exactly and
omega' = 0. Inputs are held over each communication step (zero-order hold); a step may also
carry a slope (the input tau + rate (t - t_k) over the step), so that a breakaway under a
continuous ramp can be checked against its closed form. At each communication point the law is
applied with the step's inputs (a stuck body may break away at the step's start); the initial
mode follows the law with the start values.

Ties (|tau_h| = peak tau_c exactly, the case peak = 1 at a stop): the first non-zero time
derivative of |tau_h| with the body held at rest decides: growing, the body breaks away in
tau_h's direction; shrinking, it sticks. When the first and second derivatives are both 0 the
body sticks (|tau_h| <= peak tau_c holds it there). So a body that stops with tau_h = +-tau_c
and peak = 1 sticks unless the torque on it keeps growing beyond tau_c.

A body with tau_c = 0 has no friction modes and no friction events; its `sliding` is the sign
of omega (0 at rest), as §12 says.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy.integrate import solve_ivp

from reference import FREE, MINUS, PLUS, Plant

STUCK = 0
MOTOR, LOAD = 0, 1
BODIES = ("m", "L")
# Index of each body's speed in the internal state x = [theta_m, omega_m, u, omega_L].
_OMEGA = (1, 3)
OUTPUTS = ("theta_m", "omega_m", "theta_L", "omega_L", "psi", "contact", "sliding_m", "sliding_L")


@dataclass(frozen=True)
class Friction:
    """Coulomb friction with stiction in the bearings (docs/model.md §12): sliding torques tau_c
    (N.m, >= 0; 0: no friction on that body) and breakaway ratios peak (>= 1)."""

    tau_c_m: float = 0.0
    tau_c_L: float = 0.0
    peak_m: float = 1.0
    peak_L: float = 1.0

    def tau_c(self, body: int) -> float:
        return (self.tau_c_m, self.tau_c_L)[body]

    def breakaway(self, body: int) -> float:
        """peak tau_c: the largest |tau_h| that holds the body at rest."""
        return (self.peak_m * self.tau_c_m, self.peak_L * self.tau_c_L)[body]


def _sign(v: float) -> int:
    return int(v > 0.0) - int(v < 0.0)


class FrictionPlant:
    """Event-located integration of the plant with bearing friction, one communication step at a
    time. The state is kept as x = [theta_m, omega_m, u, omega_L] (u integrated directly, as in
    reference.py); `z` gives [theta_m, omega_m, theta_L, omega_L].

    `sliding` holds each body's friction mode (None for a body without friction), `contact` the
    contact mode; `events` every switch as (time, what, from, to) with `what` one of "contact",
    "m", "L"; `trace` the state z at the start, at every switch and at every step's end, as
    (time, z): between two consecutive entries no body changes its direction of motion."""

    def __init__(self, plant: Plant, friction: Friction, z0=None, tau0=(0.0, 0.0), method="DOP853",
                 rtol=1e-12, atol=1e-16):
        self.plant, self.friction = plant, friction
        self.method, self.rtol, self.atol = method, rtol, atol
        z = np.zeros(4) if z0 is None else np.asarray(z0, dtype=float)
        self.x = np.array([z[0], z[1], plant.r_m * z[0] - plant.r_L * z[2], z[3]])
        self.t = 0.0
        self.events: list[tuple[float, str, int, int]] = []
        self.trace: list[tuple[float, np.ndarray]] = []
        self.sliding: list[int | None] = [None if friction.tau_c(b) == 0.0 else _sign(self.x[_OMEGA[b]])
                                          for b in (MOTOR, LOAD)]
        self.contact = self._side(self.x[2])
        # The inputs over the current step: values at its start t_k and their rates.
        self._t_k, self._tau, self._rate = 0.0, np.array(tau0, dtype=float), np.zeros(2)
        self._apply_law_at_rest(record=False)
        self.contact = self._entering_contact()
        self.trace.append((self.t, self.z))

    # --- the plant in one mode ---------------------------------------------------------------

    def _state(self, x) -> np.ndarray:
        p = self.plant
        return np.array([x[0], x[1], (p.r_m * x[0] - x[2]) / p.r_L, x[3]])

    @property
    def z(self) -> np.ndarray:
        return self._state(self.x)

    def psi(self) -> float:
        return self.plant.K * self.plant.dead_zone(float(self.x[2]))

    def _side(self, u: float) -> int:
        g = self.plant.g
        if g == 0.0:
            return PLUS  # linear plant: psi = K u throughout
        return PLUS if u > g else MINUS if u < -g else FREE

    def _system(self, contact: int, sliding):
        """x' = A x + w + B tau(t) in one mode (docs/model.md §1 with the friction of §12)."""
        p, fr = self.plant, self.friction
        kc = 0.0 if contact == FREE else p.K
        offset = {FREE: 0.0, PLUS: -p.g, MINUS: p.g}[contact]
        A, w, B = np.zeros((4, 4)), np.zeros(4), np.zeros((4, 2))
        A[0, 1] = 1.0
        A[2, 1], A[2, 3] = p.r_m, -p.r_L
        # tau_h = tau + c psi: c = -r_m on the motor, +r_L on the load.
        for body, (J, b, c) in enumerate(((p.J_m, p.b_m, -p.r_m), (p.J_L, p.b_L, p.r_L))):
            mode = sliding[body]
            if mode == STUCK:
                continue  # omega = 0 and omega' = 0
            row = _OMEGA[body]
            friction = 0.0 if mode is None else fr.tau_c(body) * mode
            A[row, row] = -b / J
            A[row, 2] = c * kc / J
            w[row] = (c * kc * offset - friction) / J
            B[row, body] = 1.0 / J
        return A, w, B

    def _inputs(self, t: float) -> np.ndarray:
        return self._tau + self._rate * (t - self._t_k)

    def _psi_in(self, contact: int, u: float) -> float:
        p = self.plant
        return 0.0 if contact == FREE else p.K * (u - p.g if contact == PLUS else u + p.g)

    def _coupling(self, body: int) -> float:
        return -self.plant.r_m if body == MOTOR else self.plant.r_L

    def tau_h(self, body: int, t: float | None = None, x=None) -> float:
        """Every other torque on the body: the input and the coupling (docs/model.md §12)."""
        x = self.x if x is None else x
        psi = self.plant.K * self.plant.dead_zone(float(x[2]))
        return float(self._inputs(self.t if t is None else t)[body] + self._coupling(body) * psi)

    # --- the law -------------------------------------------------------------------------------

    def _law_at_rest(self, body: int, x, t: float, on_surface: bool = False) -> int:
        """The mode of a body at rest (omega = 0) by the law of §12, ties by the first non-zero
        derivative of |tau_h| with the body held (module docstring). `on_surface`: at a located
        root of |tau_h| = peak tau_c, taken as a tie (the root is exact only to round-off)."""
        limit = self.friction.breakaway(body)
        th = self.tau_h(body, t, x)
        if not on_surface:
            if abs(th) < limit:
                return STUCK
            if abs(th) > limit:
                return _sign(th)
        held = list(self.sliding)
        held[body] = STUCK
        A, w, B = self._system(self.contact, held)
        f = A @ x + w + B @ self._inputs(t)
        df = A @ f + B @ self._rate
        kc = 0.0 if self.contact == FREE else self.plant.K
        c = self._coupling(body)
        for derivative in (self._rate[body] + c * kc * f[2], c * kc * df[2]):
            if derivative != 0.0:
                return _sign(th) if _sign(th) * derivative > 0.0 else STUCK
        return STUCK

    def _apply_law_at_rest(self, record: bool = True) -> None:
        """At a communication point (and at the start): every body with friction that is at rest
        takes the mode the law gives with the step's inputs."""
        for body in (MOTOR, LOAD):
            if self.sliding[body] is None:
                continue
            omega = float(self.x[_OMEGA[body]])
            new = self._law_at_rest(body, self.x, self.t) if omega == 0.0 else _sign(omega)
            if new != self.sliding[body]:
                if record:
                    self.events.append((self.t, BODIES[body], self.sliding[body], new))
                self.sliding[body] = new

    def _entering_contact(self) -> int:
        """The contact mode at the start: the side of +-g that u is on; exactly on +-g the mode
        the trajectory enters, from the sign of u', then u'' (docs/model.md §4)."""
        g, u = self.plant.g, float(self.x[2])
        if g == 0.0 or abs(u) != g:
            return self._side(u)
        A, w, B = self._system(FREE, self.sliding)
        f = A @ self.x + w + B @ self._inputs(self.t)
        df = A @ f + B @ self._rate
        rate = f[2] if f[2] != 0.0 else df[2]
        if u == g:
            return PLUS if rate > 0.0 else FREE
        return MINUS if rate < 0.0 else FREE

    # --- events --------------------------------------------------------------------------------

    def _events(self):
        """Terminal, directional events of the current mode, each with what it switches."""
        g, fns, what = self.plant.g, [], []
        if g > 0.0:
            def upper(_t, x):
                return x[2] - g

            def lower(_t, x):
                return x[2] + g

            if self.contact == FREE:
                upper.direction, lower.direction = 1.0, -1.0
                fns += [upper, lower]
                what += [("contact", PLUS), ("contact", MINUS)]
            elif self.contact == PLUS:
                upper.direction = -1.0
                fns.append(upper)
                what.append(("contact", FREE))
            else:
                lower.direction = 1.0
                fns.append(lower)
                what.append(("contact", FREE))
        for body in (MOTOR, LOAD):
            mode = self.sliding[body]
            if mode is None:
                continue
            if mode != STUCK:
                def stop(_t, x, row=_OMEGA[body]):
                    return x[row]

                stop.direction = -float(mode)
                fns.append(stop)
                what.append((BODIES[body], "stop"))
            else:
                limit, c, contact = self.friction.breakaway(body), self._coupling(body), self.contact

                def above(t, x, body=body, c=c, contact=contact, limit=limit):
                    return self._inputs(t)[body] + c * self._psi_in(contact, x[2]) - limit

                def below(t, x, body=body, c=c, contact=contact, limit=limit):
                    return self._inputs(t)[body] + c * self._psi_in(contact, x[2]) + limit

                above.direction, below.direction = 1.0, -1.0
                fns += [above, below]
                what += [(BODIES[body], +1), (BODIES[body], -1)]
        for fn in fns:
            fn.terminal = True
        return fns, what

    def _switch(self, t: float, x, fired) -> np.ndarray:
        """Applies the switches that fired together at t: the contact first, then the bodies."""
        x = x.copy()
        for kind, target in sorted(fired, key=lambda w: ("contact", "m", "L").index(w[0])):
            if kind == "contact":
                self.events.append((t, kind, self.contact, target))
                self.contact = target
                continue
            body = BODIES.index(kind)
            before = self.sliding[body]
            x[_OMEGA[body]] = 0.0  # at rest exactly, whichever way it leaves
            # A stop, or a breakaway surface reached: the law decides at rest (a tie by the
            # derivatives, so that a torque that only touches peak tau_c does not break it away).
            self.sliding[body] = STUCK
            new = self._law_at_rest(body, x, t, on_surface=target != "stop")
            self.sliding[body] = new
            self.events.append((t, kind, before, new))
        return x

    # --- stepping ------------------------------------------------------------------------------

    def step(self, tau_m: float, tau_L: float, h: float, rate_m: float = 0.0, rate_L: float = 0.0) -> np.ndarray:
        """Advances by h under tau(t) = tau + rate (t - t_k) (rates 0: held inputs); returns z at
        the step's end."""
        self._t_k, self._tau, self._rate = self.t, np.array([tau_m, tau_L], float), np.array([rate_m, rate_L], float)
        self._apply_law_at_rest()
        t, t_end, x = self.t, self.t + h, self.x
        muted: set[int] = set()  # events that fired at t without changing the mode
        stalls = 0  # switches in a row without progress
        while t < t_end:
            fns, what = self._events()
            live = [i for i in range(len(fns)) if i not in muted]
            A, w, B = self._system(self.contact, self.sliding)
            sol = solve_ivp(lambda s, y: A @ y + w + B @ self._inputs(s), (t, t_end), x, method=self.method,
                            rtol=self.rtol, atol=self.atol, events=[fns[i] for i in live] or None)
            if sol.status == -1:
                raise RuntimeError(f"reference integration failed: {sol.message}")
            if sol.status != 1:
                t, x = t_end, sol.y[:, -1].copy()
                break
            times = [(float(sol.t_events[j][0]), j) for j in range(len(live)) if len(sol.t_events[j])]
            t_ev = min(te for te, _ in times)
            hits = [live[j] for te, j in times if te == t_ev]
            x_ev = sol.y_events[next(j for te, j in times if te == t_ev)][0]
            modes = (self.contact, tuple(self.sliding))
            x_new = self._switch(t_ev, x_ev, [what[i] for i in hits])
            if t_ev == t and (self.contact, tuple(self.sliding)) == modes:
                # No progress and no change (a tie held by the law, an input exactly at the
                # breakaway level): watch the rest of this segment without that surface.
                self.events = self.events[: len(self.events) - len(hits)]
                muted.update(hits)
                x = x_new
                continue
            if t_ev > t:
                muted.clear()
                stalls = 0
            else:
                stalls += 1
                if stalls > 16:
                    raise RuntimeError(f"switches do not advance at t = {t}")
            t, x = t_ev, x_new
            self.trace.append((t, self._state(x)))
        self.t, self.x = t_end, x
        self.trace.append((t_end, self.z))
        return self.z

    def outputs(self) -> dict[str, float]:
        """The FMU's outputs at the current communication point (docs/model.md §4, §12)."""
        z = self.z
        sliding = [_sign(z[_OMEGA[b]]) if self.sliding[b] is None else self.sliding[b] for b in (MOTOR, LOAD)]
        return dict(zip(OUTPUTS, (*z, self.psi(), self.contact, *sliding)))

    @property
    def event_times(self) -> list[float]:
        return [e[0] for e in self.events]


def run_open_loop(plant: Plant, friction: Friction, tau_m, tau_L, h: float, z0=None, rates=None, **kw):
    """Outputs at t_0..t_N (N = len(tau_m)) under torques held over each step (with `rates`, a
    pair of per-step sequences, each step's input is tau + rate (t - t_k)); returns a dict of
    arrays named as the FMU's outputs and the solver (its `events`, `event_times`)."""
    tau_m, tau_L = np.asarray(tau_m, float), np.asarray(tau_L, float)
    rate_m, rate_L = (np.zeros(len(tau_m)), np.zeros(len(tau_m))) if rates is None else rates
    sim = FrictionPlant(plant, friction, z0, **kw)
    rows = [sim.outputs()]
    for k in range(len(tau_m)):
        sim.step(tau_m[k], tau_L[k], h, rate_m[k], rate_L[k])
        rows.append(sim.outputs())
    out = {name: np.array([r[name] for r in rows]) for name in OUTPUTS}
    out["time"] = np.arange(len(rows)) * h
    return out, sim


def coasting_stop(J: float, b: float, tau: float, tau_c: float, omega0: float) -> tuple[float, float]:
    """A lone body sliding forward (omega0 > 0) under a constant tau < tau_c:
    J omega' = tau - b omega - tau_c stops at t* = (J/b) ln((b omega0 + tau_c - tau)/(tau_c - tau))
    after turning through theta* = w_inf t* + (omega0 - w_inf)(J/b)(1 - e^{-b t*/J}),
    w_inf = (tau - tau_c)/b. Returns (t*, theta*)."""
    w_inf = (tau - tau_c) / b
    t_star = (J / b) * math.log((b * omega0 + tau_c - tau) / (tau_c - tau))
    return t_star, w_inf * t_star + (omega0 - w_inf) * (J / b) * (-math.expm1(-b * t_star / J))

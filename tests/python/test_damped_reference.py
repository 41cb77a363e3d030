"""The damped drive-train reference (damped_reference.py): its two solvers against each other,
the surfaces each scenario crosses, and the model's own properties.

Agreement is measured per state component, relative to that component's scale over the run:
scale_i = max over the output times of |z_i| (for u: max(max |u|, g)). Switch times are compared
relative to the run's length. The two methods share no numerical code (only input handling and
the result types), so agreement means both solve the stated model, not the same mistake. The
measured disagreement is ~1e-14 (A is exact to round-off, B runs at rtol 1e-13); the bound 1e-9
leaves room for other libraries' round-off while a missed or misplaced switch is far above it
(with B's steps uncapped, one scenario lost a crossing and differed by half a state's scale).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from functools import lru_cache

import numpy as np
import pytest
from scipy.optimize import brentq

import damped_reference as dr

REL_STATE = 1e-9  # A vs B, each state component relative to its scale over the run
REL_TIME = 1e-9  # A vs B switch times, relative to the run's length
ZETAS = (0.05, 0.5, 1.5)


# --------------------------------------------------------------------------------------------
# Scenarios
# --------------------------------------------------------------------------------------------

@dataclass(frozen=True)
class Scenario:
    name: str
    rig: str  # 'shaft' | 'belt'
    law: int
    zeta: float  # contact damping ratio (0: D = 0)
    profile: str  # 'square' | 'stair' | 'rebound'
    gap: bool = True  # False: g = 0
    claims: frozenset = frozenset()

    def params(self) -> dict:
        delta = None if self.gap else 0.0
        return dr.shaft_params(self.zeta, Delta=delta) if self.rig == "shaft" else \
            dr.belt_params(self.zeta, Delta=delta)

    def inputs(self):
        """(z0, breakpoints, tau_m, tau_L, t_out)."""
        if self.profile == "square":  # tau_m = +-4 N.m, reversing every 0.3 s
            bp = np.linspace(0.0, 2.4, 9)
            tm = 4.0 * (-1.0) ** np.arange(8)
        elif self.profile == "stair":  # a sine held in steps of 0.05 s, with an offset
            bp = np.linspace(0.0, 2.5, 51)
            tm = 2.0 * np.sin(2 * np.pi * 1.2 * bp[:-1]) + 0.6
        elif self.profile == "rebound":  # a steady push after an approach at 0.05 rad/s
            bp = np.array([0.0, 1.0])
            tm = np.array([1.0])
        else:
            raise ValueError(self.profile)
        p = self.params()
        if self.profile == "rebound":
            z0 = (0.0, 0.05 / p["r_m"], 0.0, 0.0)
        elif not self.gap:
            z0 = (1e-3 / p["r_m"], 0.0, 0.0, 0.0)  # preloaded: off the surface u = 0 at the start
        else:
            z0 = (0.0, 0.0, 0.0, 0.0)
        return z0, bp, tm, 0.0, np.linspace(bp[0], bp[-1], 241)


def _claims(law, zeta, gap, extra=()):
    """The surfaces a scenario must cross (see `exercised`)."""
    if zeta == 0:
        c = {"impact", "flank_loss_direct", "never_clipped"}
    elif gap:
        c = {"impact", "force_zero", "flank_from_clip"}
    else:
        c = {"force_zero", "through_zero_gap"}
    if law == 1 and zeta > 0:
        c.add("cap_exit")
    return frozenset(c | set(extra))


# Beyond the rule of _claims: what particular scenarios also cross.
_EXTRA = {
    "shaft-law1-z0.5-g0-square": ("cap_entry",),  # law 1's cap entered from contact
    "belt-law2-z0.5-square": ("rebound",),
    "belt-law2-z1.5-stair": ("rebound",),
    "belt-law1-z1.5-stair": ("rebound",),
    "shaft-law1-z0.05-rebound": ("rebound",),
    "shaft-law2-z0.05-rebound": ("rebound",),
}


def _scenario(rig, law, zeta, profile, gap=True, tag=""):
    name = f"{rig}-law{law}-{'D0' if zeta == 0 else f'z{zeta}'}{tag}-{profile}"
    return Scenario(name, rig, law, zeta, profile, gap, _claims(law, zeta, gap, _EXTRA.get(name, ())))


# Both rigs, both laws, the three damping ratios, reversing square and staircase torques; D = 0;
# g = 0; an approach that rebounds from one flank and meets it again.
SCENARIOS = [_scenario(rig, law, zeta, profile) for rig in ("shaft", "belt") for law in (1, 2)
             for zeta in ZETAS for profile in ("square", "stair")]
SCENARIOS += [_scenario(rig, law, 0.0, "square") for rig in ("shaft", "belt") for law in (1, 2)]
SCENARIOS += [_scenario(rig, law, zeta, "square", gap=False, tag="-g0")
              for rig in ("shaft", "belt") for law in (1, 2) for zeta in (0.05, 0.5)]
SCENARIOS += [_scenario("shaft", law, 0.05, "rebound") for law in (1, 2)]
BY_NAME = {s.name: s for s in SCENARIOS}


@lru_cache(maxsize=None)
def runs(name: str):
    """(A, B) results of a scenario, computed once per test session."""
    s = BY_NAME[name]
    z0, bp, tm, tl, t = s.inputs()
    p = s.params()
    return dr.simulate(p, s.law, z0, bp, tm, tl, t), dr.simulate_ivp(p, s.law, z0, bp, tm, tl, t)


def scales(res: dr.Result, g: float) -> tuple[np.ndarray, float]:
    return np.abs(res.z).max(axis=0), max(np.abs(res.u).max(), g)


def exercised(switches, g) -> set[str]:
    """What a switch list shows of the surfaces:
    impact             gap -> contact/cap through u = s g
    force_zero         contact -> clip through tau_c + tau_d = 0 (u still past the flank:
                       checked on the state by the test)
    flank_from_clip    clip -> gap through u = s g (contact already lost: D > 0)
    flank_loss_direct  contact -> gap through u = s g (D = 0: the two surfaces are one)
    cap_exit/entry     cap <-> contact through tau_c = tau_d (law 1)
    through_zero_gap   g = 0: clip s -> contact/cap of the other side through u = 0
    rebound            two impacts on one flank with no impact on the other between
    never_clipped      no clip mode anywhere (D = 0: the force never needs clipping)"""
    out = set()
    last_impact = None
    for sw in switches:
        kb, ka = dr.mode_kind(sw.before), dr.mode_kind(sw.after)
        sb, sa = dr.mode_side(sw.before), dr.mode_side(sw.after)
        flank = any(n.startswith("flank") for n in sw.surfaces)
        if sw.before == "gap" and ka in ("contact", "cap") and flank:
            out.add("impact")
            if last_impact == sa:
                out.add("rebound")
            last_impact = sa
        if kb == "contact" and sw.after.startswith("clip") and sw.surfaces == ("zero" + sw.before[-1],):
            out.add("force_zero")
        if sw.before.startswith("clip") and sw.after == "gap" and flank:
            out.add("flank_from_clip")
        if kb == "contact" and sw.after == "gap" and flank:
            out.add("flank_loss_direct")
        if kb == "cap" and ka == "contact" and any(n.startswith("equal") for n in sw.surfaces):
            out.add("cap_exit")
        if kb == "contact" and ka == "cap" and any(n.startswith("equal") for n in sw.surfaces):
            out.add("cap_entry")
        if g == 0 and sw.before.startswith("clip") and ka in ("contact", "cap") and sa == -sb and flank:
            out.add("through_zero_gap")
    if not any(sw.before.startswith("clip") or sw.after.startswith("clip") for sw in switches):
        out.add("never_clipped")
    return out


def force_zero_switches(res: dr.Result):
    """(times, sides) of the contact -> clip switches."""
    sw = [s for s in res.switches if dr.mode_kind(s.before) == "contact" and s.after.startswith("clip")]
    return [s.time for s in sw], [dr.mode_side(s.before) for s in sw]


# --------------------------------------------------------------------------------------------
# A against B
# --------------------------------------------------------------------------------------------

@pytest.mark.parametrize("name", list(BY_NAME))
def test_methods_agree(name):
    s = BY_NAME[name]
    a, b = runs(name)
    p = s.params()
    zs, us = scales(a, p["g"])
    assert np.all(np.abs(a.z - b.z) <= REL_STATE * zs), (np.abs(a.z - b.z) / zs).max(axis=0)
    assert np.all(np.abs(a.u - b.u) <= REL_STATE * us)
    # The switch lists match one for one: same modes, same surfaces, same times.
    assert len(a.switches) == len(b.switches), (a.switches, b.switches)
    T = a.t[-1] - a.t[0]
    for sa, sb in zip(a.switches, b.switches):
        assert (sa.before, sa.after, sa.surfaces) == (sb.before, sb.after, sb.surfaces)
        assert abs(sa.time - sb.time) <= REL_TIME * T
    assert a.mode == b.mode
    assert np.array_equal(a.contact, b.contact)


@pytest.mark.parametrize("name", list(BY_NAME))
def test_scenario_crosses_what_it_claims(name):
    s = BY_NAME[name]
    a, _ = runs(name)
    p = s.params()
    u_scale = max(p["g"], np.abs(a.u).max())
    got = exercised(a.switches, p["g"])
    missing = set(s.claims) - got
    assert not missing, (missing, got)
    if "force_zero" in s.claims:
        # Contact lost by the force reaching zero with u still past the flank: the state at
        # each such switch, recomputed from the exact solution, is past the flank by a margin
        # far above round-off (1e-3 of the run's u scale).
        times, sides = force_zero_switches(a)
        assert times
        z0, bp, tm, tl, _ = s.inputs()
        at = dr.simulate(p, s.law, z0, bp, tm, tl, np.array(times))
        past = np.array(sides) * at.u - p["g"]
        assert np.all(past > 1e-3 * u_scale), past
    if s.zeta > 0:
        # With D > 0 contact never ends on u = +-g itself: there tau_c + tau_d = D u', which has
        # the sign of a separating u' only after tau_c + tau_d = 0 was crossed.
        assert not any(dr.mode_kind(sw.before) == "contact" and sw.after == "gap" for sw in a.switches)
    assert a.switches, "a scenario without switches proves nothing"


@pytest.mark.parametrize("name", list(BY_NAME))
def test_force_never_pulls_and_modes_follow_the_law(name):
    """At every sample, from both methods: psi * side >= 0, psi = 0 inside the gap, and the
    mode reported is the branch the law's literal if/else takes at that state, with the same
    force (1e-9 of the run's largest force: round-off of the two evaluations)."""
    s = BY_NAME[name]
    p = s.params()
    for res in runs(name):
        du = p["r_m"] * res.z[:, 1] - p["r_L"] * res.z[:, 3]
        side = np.where(res.u >= p["g"], 1, np.where(res.u <= -p["g"], -1, 0))
        assert np.all(res.psi * side >= 0)
        assert np.all(res.psi[side == 0] == 0)
        raw = [dr.raw_force(p, s.law, u, d) for u, d in zip(res.u, du)]
        assert [m for _, m in raw] == res.mode
        fscale = max(np.abs(res.psi).max(), 1.0)
        assert np.allclose([f for f, _ in raw], res.psi, rtol=0, atol=1e-9 * fscale)
        assert np.array_equal(res.contact, np.sign(res.psi).astype(int))


@pytest.mark.parametrize("rig", ["shaft", "belt"])
def test_without_damping_both_laws_switch_alike(rig):
    """D = 0: both laws give psi = K dz(u, g); the switch lists are the same (law 1 also names
    tau_c = tau_d, which with D = 0 is the surface u = +-g), and so are the states."""
    a1, _ = runs(f"{rig}-law1-D0-square")
    a2, _ = runs(f"{rig}-law2-D0-square")
    p = BY_NAME[f"{rig}-law1-D0-square"].params()
    T = a1.t[-1] - a1.t[0]
    assert len(a1.switches) == len(a2.switches) > 0
    for s1, s2 in zip(a1.switches, a2.switches):
        assert (s1.before, s1.after) == (s2.before, s2.after)
        assert tuple(n for n in s1.surfaces if not n.startswith("equal")) == s2.surfaces
        assert abs(s1.time - s2.time) <= 1e-12 * T
    zs, _ = scales(a1, p["g"])
    assert np.all(np.abs(a1.z - a2.z) <= 1e-12 * zs)
    g, K = p["g"], p["K"]
    dz = np.where(a1.u > g, a1.u - g, np.where(a1.u < -g, a1.u + g, 0.0))
    for res in (a1, a2):
        assert np.allclose(res.psi, K * dz, rtol=0, atol=1e-12 * np.abs(K * dz).max())


# --------------------------------------------------------------------------------------------
# Grazing: a crossing far shorter than A's grid cell
# --------------------------------------------------------------------------------------------

def _graze_start(p, tau0, overshoot, u0):
    """Motor speed v that carries u from u0 < g (the load at rest, no load torque, motor torque
    -tau0) to a peak of g (1 + overshoot). In the gap omega_L stays 0 and u = theta_m with
    theta_m(t) = u0 + T (v + tau0/b) (1 - e^(-t/T)) - tau0 t / b, T = J_m / b_m, peak at
    t* = T ln(1 + v b / tau0). Returns v, theta_m(t), t*."""
    J, b, g = p["J_m"], p["b_m"], p["g"]
    T = J / b

    def peak(v):
        return u0 + T * v - tau0 / b * T * math.log1p(v * b / tau0)

    v = brentq(lambda v: peak(v) - g * (1 + overshoot), 1e-9, 1.0, xtol=1e-17, rtol=1e-15)

    def theta(t):
        return u0 + T * (v + tau0 / b) * -math.expm1(-t / T) - tau0 * t / b

    return v, theta, T * math.log1p(v * b / tau0)


@pytest.mark.parametrize("law", [1, 2])
def test_graze_is_found_and_a_near_miss_is_not(law):
    """u just passes +g (by 1e-6 g, for ~2e-4 s) inside one cell of A's grid (the whole 0.04 s
    run: the gap mode's cells are ~0.5 s long): A must report the contact, at the instant the
    closed form gives, and B with its steps capped below the excursion must agree. The same
    approach falling short by 1e-6 g must report nothing."""
    p = dr.shaft_params(0.5)
    tau0, u0 = 1.0, p["g"] - 2e-5  # the peak ~0.01 s after the start
    t = np.linspace(0.0, 0.04, 9)
    v, theta, tpeak = _graze_start(p, tau0, 1e-6, u0)
    z0 = (u0, v, 0.0, 0.0)
    a = dr.simulate(p, law, z0, [0.0, 0.04], -tau0, 0.0, t)
    first = a.switches[0]
    assert first.before == "gap" and first.after == ("cap+" if law == 1 else "contact+")
    assert first.surfaces == ("flank+",)
    t_in = brentq(lambda s: theta(s) - p["g"], 0.0, tpeak, xtol=1e-17, rtol=1e-15)
    # The closed form is evaluated near its peak, where theta' ~ 5e-5 rad/s: its own round-off
    # (~1e-16 of theta ~ 3e-3 plus the terms of ~1e-2 that cancel) moves the crossing by ~1e-13 s.
    assert abs(first.time - t_in) < 1e-10
    # Back in the gap within about the excursion's duration (~2e-4 s).
    back = [sw for sw in a.switches if sw.after == "gap"]
    assert back and back[0].time - first.time < 1e-3
    b = dr.simulate_ivp(p, law, z0, [0.0, 0.04], -tau0, 0.0, t, max_step=2e-5)
    assert [(s.before, s.after, s.surfaces) for s in a.switches] == \
        [(s.before, s.after, s.surfaces) for s in b.switches]
    assert all(abs(x.time - y.time) < 1e-10 for x, y in zip(a.switches, b.switches))
    v, _, _ = _graze_start(p, tau0, -1e-6, u0)
    miss = dr.simulate(p, law, (u0, v, 0.0, 0.0), [0.0, 0.04], -tau0, 0.0, t)
    assert miss.switches == [] and set(miss.mode) == {"gap"}
    assert miss.u.max() < p["g"]


# --------------------------------------------------------------------------------------------
# Parameters, the linear twin, the PI loop
# --------------------------------------------------------------------------------------------

def test_effective_inertia_and_damping_ratio():
    """J_eff = 1/(r_m^2/J_m + r_L^2/J_L); D = 2 zeta sqrt(K J_eff) gives the relative motion of
    the frictionless twin the damping ratio zeta (eigenvalues of lambda^2 J_eff + D lambda + K)."""
    shaft, belt = dr.shaft_params(0.5), dr.belt_params(0.5)
    assert dr.effective_inertia(shaft) == pytest.approx(1 / (1 / 2.28 + 1 / 2.55), rel=1e-15)
    assert dr.effective_inertia(belt) == pytest.approx(1 / (0.1 ** 2 / 2.28 + 0.12 ** 2 / 2.55), rel=1e-14)
    assert belt["r_L"] == pytest.approx(0.12, rel=1e-15) and belt["g"] == pytest.approx(3.2e-3, rel=1e-15)
    for make in (dr.shaft_params, dr.belt_params):
        for zeta in ZETAS:
            p = make(zeta)
            p["b_m"] = p["b_L"] = 0.0
            idx = [1, 4, 3]  # omega_m, u, omega_L
            M = dr.mode_matrix(p, "twin")[np.ix_(idx, idx)]
            lam = sorted(np.linalg.eigvals(M), key=abs)[1:]  # the zero is the common motion
            wn2 = p["K"] / dr.effective_inertia(p)
            assert np.real(lam[0] * lam[1]) == pytest.approx(wn2, rel=1e-12)
            assert -np.real(lam[0] + lam[1]) == pytest.approx(2 * zeta * math.sqrt(wn2), rel=1e-12)


@pytest.mark.parametrize("rig", ["shaft", "belt"])
def test_plant_is_its_linear_twin_while_contact_holds(rig):
    """g = 0, law 2, a preloaded member and a torque that never reverses: the force stays
    positive, the mode stays contact+, and the plant is the twin (psi = K u + D u' with g = 0)
    to round-off; open loop and in the PI loop."""
    make = dr.shaft_params if rig == "shaft" else dr.belt_params
    gains = dr.SHAFT_GAINS if rig == "shaft" else dr.BELT_GAINS
    p = make(0.5, Delta=0.0)
    bp = np.linspace(0.0, 2.0, 9)
    tm = 2.0 + np.sin(np.arange(8))  # 1.2 .. 3.0 N.m
    t = np.linspace(0.0, 2.0, 101)
    z0 = (1.0 / p["K"] / p["r_m"], 0.0, 0.0, 0.0)
    a = dr.simulate(p, 2, z0, bp, tm, -1.0, t)
    tw = dr.linear_twin(p, z0, bp, tm, -1.0, t)
    assert a.switches == [] and set(a.mode) == {"contact+"}
    assert np.all(a.psi > 0)
    zs = np.abs(a.z).max(axis=0)
    assert np.all(np.abs(a.z - tw.z) <= 1e-12 * zs)
    assert np.allclose(a.psi, tw.psi, rtol=1e-12)
    w = 0.2 + 0.1 * np.arange(8) / 8
    a = dr.simulate_pi(p, 2, z0, bp, w, -1.0, gains, t)
    tw = dr.linear_twin_pi(p, z0, bp, w, -1.0, gains, t)
    assert a.switches == [] and set(a.mode) == {"contact+"}
    zs = np.abs(a.z).max(axis=0)
    assert np.all(np.abs(a.z - tw.z) <= 1e-12 * zs)


@pytest.mark.parametrize("rig", ["shaft", "belt"])
def test_pi_loop_is_stable(rig):
    """Every mode's loop dynamics and the twin's have eigenvalues in the open left half-plane,
    for each damping ratio and D = 0 (for a free mode, the block without u, which there only
    integrates u')."""
    make = dr.shaft_params if rig == "shaft" else dr.belt_params
    gains = dr.SHAFT_GAINS if rig == "shaft" else dr.BELT_GAINS
    for zeta in (0.0, *ZETAS):
        p = make(zeta)
        for mode in ("twin", *dr.modes_of(1)):
            ev = dr.pi_eigenvalues(p, mode, gains)
            assert ev.real.max() < -0.01, (zeta, mode, ev)


@pytest.mark.parametrize("rig", ["shaft", "belt"])
@pytest.mark.parametrize("law", [1, 2])
def test_pi_loop_methods_agree(rig, law):
    """simulate_pi (exact, xi a state) against simulate_pi_ivp, speed reference reversing; and
    the twin run alongside gives omega_L^0 at the same times."""
    make = dr.shaft_params if rig == "shaft" else dr.belt_params
    gains = dr.SHAFT_GAINS if rig == "shaft" else dr.BELT_GAINS
    p = make(0.5)
    bp = np.array([0.0, 0.5, 1.0, 1.5, 2.0, 2.5])
    w = [0.0, 0.5, -0.5, 0.3, -0.2]
    t = np.linspace(0.0, 2.5, 251)
    a = dr.simulate_pi(p, law, (0, 0, 0, 0), bp, w, 0.0, gains, t)
    b = dr.simulate_pi_ivp(p, law, (0, 0, 0, 0), bp, w, 0.0, gains, t)
    zs, us = scales(a, p["g"])
    assert np.all(np.abs(a.z - b.z) <= REL_STATE * zs)
    assert np.all(np.abs(a.u - b.u) <= REL_STATE * us)
    assert np.all(np.abs(a.xi - b.xi) <= REL_STATE * np.abs(a.xi).max())
    assert np.allclose(a.tau_m, b.tau_m, rtol=0, atol=REL_STATE * np.abs(a.tau_m).max())
    assert len(a.switches) == len(b.switches) >= 8
    for sa, sb in zip(a.switches, b.switches):
        assert (sa.before, sa.after, sa.surfaces) == (sb.before, sb.after, sb.surfaces)
        assert abs(sa.time - sb.time) <= REL_TIME * 2.5
    tw = dr.linear_twin_pi(p, (0, 0, 0, 0), bp, w, 0.0, gains, t)
    # The gap delays the load: the plant and its twin differ by far more than round-off, and
    # both track the reference's sign changes.
    assert np.abs(a.z[:, 3] - tw.z[:, 3]).max() > 1e-2
    assert tw.switches == [] and set(tw.mode) == {"twin"}


@pytest.mark.parametrize("rig", ["shaft", "belt"])
@pytest.mark.parametrize("law", [1, 2])
def test_pi_loop_settles_on_the_reference(rig, law):
    """Integral action: with w_ref held 6 s against a constant load torque, omega_m -> w_ref and
    omega_L -> (r_m / r_L) w_ref for the plant (resting in contact) and for the twin. The slowest
    loop pole has real part < -2.9 (test_pi_loop_is_stable's output), so after 6 s the transient
    is below 1e-7 of its start."""
    make = dr.shaft_params if rig == "shaft" else dr.belt_params
    gains = dr.SHAFT_GAINS if rig == "shaft" else dr.BELT_GAINS
    p = make(0.5)
    w = 0.5
    t = np.array([6.0])
    for res in (dr.simulate_pi(p, law, (0, 0, 0, 0), [0.0, 6.0], w, -1.0, gains, t),
                dr.linear_twin_pi(p, (0, 0, 0, 0), [0.0, 6.0], w, -1.0, gains, t)):
        assert res.z[0, 1] == pytest.approx(w, abs=1e-6)
        assert res.z[0, 3] == pytest.approx(w * p["r_m"] / p["r_L"], abs=1e-6)
        assert res.mode[0] in ("contact+", "twin")

"""The friction reference (reference_friction.py) against closed forms, against reference.py,
and against an energy balance (no FMU needed).

These tests justify using reference_friction.py as the yardstick for the FMUs' bearing friction
(docs/model.md §12, test_friction.py)."""

from __future__ import annotations

import math

import numpy as np
import pytest

import scenarios
from reference import FREE, run_open_loop as run_frictionless
from reference_friction import STUCK, Friction, FrictionPlant, coasting_stop, run_open_loop
from rigs import BELT, SHAFT, plant_of
from signals import rel_err, reversing_torques

GEOMETRIES = {"shaft": ("BacklashShaft", SHAFT), "belt": ("BacklashBelt", BELT)}
# A half gap no run below closes: each body then moves on its own (psi = 0 throughout).
WIDE = 1.0e3


def _plant(name: str, **changes):
    model, params = GEOMETRIES[name]
    return plant_of(model, {**params, **changes})


@pytest.mark.parametrize("name", GEOMETRIES)
@pytest.mark.parametrize("tau_m, after", [(0.1, "sticks"), (-0.4, "sticks"), (-0.5, "reverses")])
def test_coasting_bodies_stop_at_the_closed_form_then_stick_or_reverse(name, tau_m, after):
    """Inside a gap never closed each body obeys J w' = tau - b w - tau_c sign(w) alone. The motor
    (w0 = 2 rad/s forward, tau_c 0.3 N.m, peak 1.5) stops at t* = (J/b) ln((b w0 + tau_c - tau)/(tau_c - tau))
    after theta* (reference_friction.coasting_stop); then it sticks while |tau| <= 0.45 N.m, else it
    slides back: w = ((tau + tau_c)/b)(1 - e^{-b s/J}), s = t - t*. The load (w0 = -1 rad/s,
    tau_c 0.2 N.m, no torque) stops backward at the mirrored closed form and sticks."""
    plant = _plant(name, Delta=WIDE)
    friction = Friction(tau_c_m=0.3, peak_m=1.5, tau_c_L=0.2, peak_L=1.3)
    h, n = 0.1, 250
    out, sim = run_open_loop(plant, friction, [tau_m] * n, [0.0] * n, h, z0=[0.0, 2.0, 0.0, -1.0])
    t_m, theta_m = coasting_stop(plant.J_m, plant.b_m, tau_m, 0.3, 2.0)
    t_L, theta_L = coasting_stop(plant.J_L, plant.b_L, 0.0, 0.2, 1.0)
    theta_L = -theta_L
    motor = [e for e in sim.events if e[1] == "m"]
    load = [e for e in sim.events if e[1] == "L"]
    assert not [e for e in sim.events if e[1] == "contact"]
    assert load == [(pytest.approx(t_L, rel=1e-12), "L", -1, STUCK)]
    assert motor == [(pytest.approx(t_m, rel=1e-12), "m", 1, STUCK if after == "sticks" else -1)]
    t = out["time"]
    J, b, tau_c = plant.J_m, plant.b_m, 0.3
    w_inf = (tau_m - tau_c) / b
    before = t < t_m
    assert rel_err(out["omega_m"][before], w_inf + (2.0 - w_inf) * np.exp(-b * t[before] / J)) <= 1e-11
    if after == "sticks":
        assert np.all(out["omega_m"][~before] == 0.0) and np.all(out["sliding_m"][~before] == STUCK)
        assert np.max(np.abs(out["theta_m"][~before] - theta_m)) <= 1e-12 * theta_m
    else:
        s = t[~before] - t_m
        w_back = (tau_m + tau_c) / b
        assert rel_err(out["omega_m"][~before], w_back * -np.expm1(-b * s / J)) <= 1e-11
        theta = theta_m + w_back * (s + (J / b) * np.expm1(-b * s / J))
        assert np.max(np.abs(out["theta_m"][~before] - theta)) <= 1e-11 * theta_m
        assert np.all(out["sliding_m"][~before] == -1)
    stuck_L = t >= t_L
    assert np.all(out["omega_L"][stuck_L] == 0.0) and np.all(out["sliding_L"][stuck_L] == STUCK)
    assert np.max(np.abs(out["theta_L"][stuck_L] - theta_L)) <= 1e-12 * abs(theta_L)
    assert np.all(out["sliding_L"][~stuck_L] == -1)


@pytest.mark.parametrize("peak", [1.0, 1.5])
@pytest.mark.parametrize("body", ["m", "L"])
def test_a_body_at_rest_breaks_away_under_a_ramp_at_peak_tau_c_over_rate(body, peak):
    """From rest under tau = rho t (a ramp within each step, continuous across steps) a body held by
    tau_c = 0.3 N.m breaks away at t_b = peak tau_c / rho exactly, and then follows
    J w' + b w = rho s + (peak - 1) tau_c, s = t - t_b, w(t_b) = 0:
    w = w_p(s) - w_p(0) e^{-b s/J}, w_p(s) = (rho/b) s + ((peak - 1) tau_c - J rho/b)/b.
    On the load the ramp is negative and the body breaks away backward (mirror image)."""
    plant = _plant("shaft", Delta=WIDE)
    sign = 1.0 if body == "m" else -1.0
    friction = Friction(**{f"tau_c_{body}": 0.3, f"peak_{body}": peak})
    rho, h, n = 0.2, 0.1, 60
    ramp = sign * rho * np.arange(n) * h
    zero = np.zeros(n)
    rates = (np.full(n, rho), zero) if body == "m" else (zero, np.full(n, -rho))
    tau_m, tau_L = (ramp, zero) if body == "m" else (zero, ramp)
    out, sim = run_open_loop(plant, friction, tau_m, tau_L, h, rates=rates)
    t_b = peak * 0.3 / rho
    assert sim.events == [(pytest.approx(t_b, rel=1e-13), body, STUCK, int(sign))]
    J, b = (plant.J_m, plant.b_m) if body == "m" else (plant.J_L, plant.b_L)
    t = out["time"]
    theta, omega, sliding = out[f"theta_{body}"], out[f"omega_{body}"], out[f"sliding_{body}"]
    held = t < t_b
    assert np.all(theta[held] == 0.0) and np.all(omega[held] == 0.0) and np.all(sliding[held] == STUCK)
    s = t[~held] - t_b
    c0 = (peak - 1.0) * 0.3
    w_p0 = (c0 - J * rho / b) / b
    w = (rho / b) * s + w_p0 - w_p0 * np.exp(-b * s / J)
    th = (rho / (2 * b)) * s**2 + w_p0 * s + w_p0 * (J / b) * np.expm1(-b * s / J)
    assert rel_err(sign * omega[~held], w) <= 1e-11
    assert rel_err(sign * theta[~held], th) <= 1e-11
    assert np.all(sliding[~held] == int(sign))


@pytest.mark.parametrize("excess, expected", [(0.0, STUCK), (1e-9, -1)])
def test_stop_at_exactly_the_breakaway_torque_sticks(excess, expected):
    """peak = 1, a motor sliding forward against tau = -tau_c (1 + excess): at its stop
    |tau_h| = tau_c (1 + excess). At equality the torque on it stays constant (every derivative 0):
    the law holds it (reference_friction.py's tie rule); a hair above, it reverses."""
    plant = _plant("shaft", Delta=WIDE)
    out, sim = run_open_loop(plant, Friction(tau_c_m=0.3), [-0.3 * (1 + excess)] * 40, [0.0] * 40, 0.1,
                             z0=[0.0, 1.0, 0.0, 0.0])
    assert [e[1:] for e in sim.events] == [("m", 1, expected)]
    assert out["sliding_m"][-1] == expected


def test_input_at_the_breakaway_level_decides_by_its_rate():
    """At rest with tau_m = peak tau_c exactly at a communication point: held, the motor stays
    stuck; rising (a ramp from that level), it breaks away at the step's start."""
    plant = _plant("shaft", Delta=WIDE)
    friction = Friction(tau_c_m=0.3, peak_m=1.2)
    held = FrictionPlant(plant, friction)
    held.step(0.36, 0.0, 0.5)
    assert held.sliding[0] == STUCK and held.z[1] == 0.0 and held.events == []
    rising = FrictionPlant(plant, friction)
    rising.step(0.36, 0.0, 0.5, rate_m=0.1)
    assert rising.events == [(0.0, "m", STUCK, 1)] and rising.z[1] > 0.0


@pytest.mark.parametrize("name", GEOMETRIES)
def test_without_friction_it_is_reference_py(name):
    """tau_c = 0 on both bodies (peaks set, which then mean nothing): the same plant as
    reference.py's ReferencePlant, a different code; both DOP853 at rtol 1e-13 with located
    switches, on a reversing run across the gap. `sliding` is the sign of omega."""
    plant = _plant(name)
    h, n = 0.1, 30
    tau_m, tau_L = reversing_torques(n, h, 1.5, 0.6)
    z, u, ref = run_frictionless(plant, tau_m, tau_L, h)
    out, sim = run_open_loop(plant, Friction(peak_m=1.5, peak_L=2.0), tau_m, tau_L, h, rtol=1e-13, atol=1e-17)
    assert len(ref.switches) >= 3
    assert [e[0] for e in sim.events] == pytest.approx([s[0] for s in ref.switches], abs=1e-10)
    for j, state in enumerate(("theta_m", "omega_m", "theta_L", "omega_L")):
        assert rel_err(out[state], z[:, j]) <= 1e-10
    assert rel_err(out["psi"], [plant.K * plant.dead_zone(x) for x in u]) <= 1e-10
    assert np.array_equal(out["sliding_m"], np.sign(out["omega_m"]))
    assert np.array_equal(out["sliding_L"], np.sign(out["omega_L"]))


@pytest.mark.parametrize("name", GEOMETRIES)
def test_energy_balance_through_stick_slip_and_backlash(name):
    """Without viscous friction the energy E = J_m w_m^2/2 + J_L w_L^2/2 + K dz(u, g)^2/2 changes
    by the inputs' work, sum_k tau_k (theta(t_k+1) - theta(t_k)) per held step, less the bearings',
    tau_c x the angle each body slid through (a stuck body's bearing does no work). The angle slid
    is sum |delta theta| over the trace's segments, in each of which the body keeps its direction."""
    plant = _plant(name, b_m=0.0, b_L=0.0)
    friction = Friction(tau_c_m=0.2, tau_c_L=0.3, peak_m=1.3, peak_L=1.5)
    h, n = 0.05, 200
    tau_m, tau_L = reversing_torques(n, h, 1.5, 0.6)
    out, sim = run_open_loop(plant, friction, tau_m, tau_L, h)
    kinds = {(e[1], e[3]) for e in sim.events}
    assert ("contact", FREE) in kinds and {("m", STUCK), ("L", STUCK)} & kinds, "the run must stick and slip across the gap"
    assert {("m", 1), ("m", -1), ("L", 1), ("L", -1)} <= kinds

    def energy(z):
        return 0.5 * (plant.J_m * z[1] ** 2 + plant.J_L * z[3] ** 2 + plant.K * plant.dead_zone(plant.u(z)) ** 2)

    trace = np.array([z for _, z in sim.trace])
    slid_m = np.sum(np.abs(np.diff(trace[:, 0])))
    slid_L = np.sum(np.abs(np.diff(trace[:, 2])))
    work_in = np.sum(tau_m * np.diff(out["theta_m"]) + tau_L * np.diff(out["theta_L"]))
    work_bearings = friction.tau_c_m * slid_m + friction.tau_c_L * slid_L
    z0, z1 = trace[0], trace[-1]
    scale = work_in + work_bearings
    assert abs(energy(z1) - energy(z0) - (work_in - work_bearings)) <= 1e-10 * scale
    # The bearings took a large share: a friction of the wrong sign or size would show.
    assert work_bearings >= 0.2 * scale


@pytest.mark.parametrize("model", ["BacklashShaft", "BacklashBelt"])
def test_slow_reversal_sticks_the_load_while_the_motor_crosses_the_gap(model):
    """The scenario of test_friction.py obeys the law at every communication point: a stuck body
    has omega = 0 exactly and |tau_h| <= peak tau_c (tau_h under the step's held input); a
    sliding one moves in its direction. And it does what it is there for: at each reversal the
    load is stuck while the motor slides across the gap (contact free)."""
    out, sim = scenarios.friction_reversal_reference(model)
    friction = Friction(**scenarios.FRICTION)
    tau_m, tau_L = scenarios.friction_torques()
    params, _ = scenarios.RIGS[model]
    plant = plant_of(model, params)
    for k in range(1, len(out["time"])):
        psi = out["psi"][k]
        for body, tau_h, omega in (("m", tau_m[k - 1] - plant.r_m * psi, out["omega_m"][k]),
                                   ("L", tau_L[k - 1] + plant.r_L * psi, out["omega_L"][k])):
            mode = out[f"sliding_{body}"][k]
            if mode == STUCK:
                assert omega == 0.0 and abs(tau_h) <= friction.breakaway(("m", "L").index(body)) * (1 + 1e-12)
            else:
                assert np.sign(omega) == mode
    crossing = (out["sliding_L"] == STUCK) & (out["sliding_m"] != STUCK) & (out["contact"] == FREE)
    assert np.count_nonzero(crossing) >= 5
    assert {("L", STUCK), ("L", 1), ("L", -1), ("m", 1), ("m", -1)} <= {(e[1], e[3]) for e in sim.events}


@pytest.mark.parametrize("model", ["BacklashShaft", "BacklashBelt"])
def test_slow_reversal_is_tolerance_independent(model):
    """The reference's accuracy on the scenario of test_friction.py: DOP853 at rtol 1e-12 (atol
    1e-16) and at rtol 1e-13 (atol 1e-17) agree on every output to 1e-11 relative (measured: ~4e-12
    for psi, the most sensitive) and on the sequence of switches, so a tolerance of 1e-9 against
    the FMU is the reference's error with a wide margin."""
    out, sim = scenarios.friction_reversal_reference(model)
    for kw in ({"rtol": 1e-13, "atol": 1e-17},):
        other, other_sim = scenarios.friction_reversal_reference(model, **kw)
        assert [e[1:] for e in other_sim.events] == [e[1:] for e in sim.events], kw
        assert other_sim.event_times == pytest.approx(sim.event_times, abs=1e-9), kw
        for name in ("theta_m", "omega_m", "theta_L", "omega_L", "psi"):
            assert rel_err(out[name], other[name]) <= 1e-11, (kw, name)
        for name in ("contact", "sliding_m", "sliding_L"):
            assert np.array_equal(out[name], other[name]), (kw, name)

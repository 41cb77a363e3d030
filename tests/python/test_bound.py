"""The speed-error bound of docs/model.md §3 through the FMU.

Twin runs: two shaft instances side by side (Delta > 0 and Delta = 0) under the same external
sampled PI, whose gains are also the FMUs' Kp, Ki. The bound assumes a continuous-time PI; the
loop is sampled at h = 1e-3 s, where Kp h / J_m = 0.018 and h is 1/250 of the slowest
closed-loop time constant (0.25 s). No margin is allowed: the check is
|omega_L^b - omega_L^0| <= bound + 1e-12 (round-off at t = 0). Measured on the reference, the
step case reaches 0.988, 0.996 and 0.998 of the bound at h = 1e-2, 3e-3 and 1e-3 s: sampling
lowers the ratio here, and the bound is nearly attained, so the comparison is tight rather
than vacuous (through the FMU at 1e-3 s: 0.9985 for the step, 0.985 for the sine)."""

from __future__ import annotations

import math

import numpy as np
import pytest

import archives
import scenarios
from loops import run_open_loop
from reference_bound import BoundReference, loop_matrices
from rigs import BELT_GAINS, RIGS, SHAFT_GAINS, plant_of
from signals import rel_err

TOL = 1e-8


def _diff_and_bounds(name):
    backlash, linear = scenarios.twin(name)
    diff = np.abs(backlash["omega_L"] - linear["omega_L"])
    return diff, backlash, linear


@pytest.mark.parametrize("model, minimum", [("BacklashShaft", 0.5), ("BacklashBelt", 0.3)])
def test_loop_gains_are_well_damped(model, minimum):
    """The gains in rigs.py: every non-zero eigenvalue of A_cl has damping ratio >= minimum."""
    params, gains = RIGS[model]
    A, _, _ = loop_matrices(plant_of(model, params), gains["Kp"], gains["Ki"])
    lam = np.linalg.eigvals(A)
    lam = lam[np.abs(lam) > 1e-9]
    assert np.min(-lam.real / np.abs(lam)) >= minimum


@pytest.mark.parametrize("name", scenarios.TWIN_REFERENCES)
def test_twin_difference_never_exceeds_bound(shaft, name):
    diff, backlash, linear = _diff_and_bounds(name)
    bound = backlash["bound"]
    ratio = np.max(diff[1:] / bound[1:])
    # Exactly 0.0, not to round-off: the FMU's bound is K g times its integral, and K g = 0.
    assert np.all(linear["bound"] == 0.0), "Delta = 0 carries no disturbance"
    assert np.all(diff <= bound + 1e-12), f"{name}: max |dw_L| / bound = {ratio}"
    assert np.max(diff) > 1e-3, "the backlash must make a visible difference"
    if name == "step":
        assert ratio > 0.9, f"bound nearly attained on the step (measured {ratio})"


def test_reversing_reference_exceeds_printed_bound(shaft):
    """docs/model.md §3: the printed bound (37)/(41) is violated by more than 2x on the paper's rig."""
    diff, backlash, _ = _diff_and_bounds("sine")
    ratio = np.max(diff[1:] / backlash["bound_paper"][1:])
    assert ratio > 2.0, f"max |dw_L| / bound_paper = {ratio}"


@pytest.mark.parametrize("name", scenarios.TWIN_REFERENCES)
def test_twin_bound_outputs_match_reference(shaft, name):
    _, backlash, _ = _diff_and_bounds(name)
    n = len(backlash["bound"]) - 1
    br = BoundReference(plant_of("BacklashShaft", RIGS["BacklashShaft"][0]), **SHAFT_GAINS)
    bound, paper = br.bounds(scenarios.TWIN_STEP, n)
    assert rel_err(backlash["bound"], bound) <= TOL
    assert rel_err(backlash["bound_paper"], paper) <= TOL


# model, gains, start time: closed loop (5-state), P only (5-state, x_c not fed back),
# open plant (4-state A_p), and a start time other than 0 (bound counts from the start).
BOUND_CASES = {
    "shaft-pi": ("BacklashShaft", SHAFT_GAINS, 0.0),
    "belt-pi": ("BacklashBelt", BELT_GAINS, 0.0),
    "shaft-p-only": ("BacklashShaft", {"Kp": 20.0, "Ki": 0.0}, 0.0),
    "shaft-open": ("BacklashShaft", {"Kp": 0.0, "Ki": 0.0}, 0.0),
    "belt-open-late-start": ("BacklashBelt", {"Kp": 0.0, "Ki": 0.0}, 1.5),
}


@pytest.mark.parametrize("case", BOUND_CASES)
def test_bound_outputs_match_reference(case):
    model, gains, t0 = BOUND_CASES[case]
    fmu = archives.require(model)
    params = RIGS[model][0]
    h, n = 0.01, 500
    inst = fmu.co_simulation(case, {**params, **gains}, start_time=t0)
    try:
        out = run_open_loop(inst, np.full(n, 0.3), np.zeros(n), h)
    finally:
        inst.free()
    bound, paper = BoundReference(plant_of(model, params), gains["Kp"], gains["Ki"]).bounds(h, n)
    assert rel_err(out["bound"], bound) <= TOL
    assert rel_err(out["bound_paper"], paper) <= TOL


@pytest.mark.parametrize("model", archives.MODELS)
def test_bound_sup_is_the_limit_of_bound(model):
    fmu = archives.require(model)
    params, gains = RIGS[model]
    br = BoundReference(plant_of(model, params), gains["Kp"], gains["Ki"])
    # 12 s is 48 time constants of the slowest excited mode (decay rate ~4 /s).
    assert br.decay_rate() < -3.5
    h, n = 0.05, 240
    inst = fmu.co_simulation("sup", {**params, **gains})
    try:
        (sup,) = inst.get("bound_sup")
        out = run_open_loop(inst, np.zeros(n), np.zeros(n), h)
        (sup_after,) = inst.get("bound_sup")
    finally:
        inst.free()
    # The same stored number: bound_sup is a calculatedParameter, computed once at initialisation.
    assert sup == sup_after
    assert abs(sup - br.sup()) <= TOL * br.sup()
    bound = out["bound"]
    # Monotone by construction, so exact: bound = K g * (running sum of non-negative piece
    # integrals |int h|, src/physics/bound.rs), and a rounded sum never drops when a non-negative
    # term is added. bound(12 s) meets sup, its limit, in exact arithmetic (e^-48 short of it),
    # and sup errs upwards only (an upper bound, SUP_TOLERANCE 1e-13); both are sums of ~500
    # pieces (0.05 s steps cut at 0.5 / rho = 0.035 s, rho = 14 /s; sup on its own grid), each
    # within 500 eps = 1.1e-13 of exact, so they can round apart by 2.2e-13: 1e-12 covers it.
    assert np.all(np.diff(bound) >= 0.0) and np.all(bound <= sup * (1 + 1e-12))
    assert abs(bound[-1] - sup) <= 1e-9 * sup


def test_bound_sup_of_damped_open_plant_is_finite():
    """Kp = Ki = 0 with b > 0: the open plant's bound (A_p) is finite (docs/model.md §3)."""
    fmu = archives.require("BacklashShaft")
    params = {**RIGS["BacklashShaft"][0], "b_m": 2.0, "b_L": 2.0}
    gains = {"Kp": 0.0, "Ki": 0.0}
    inst = fmu.co_simulation("sup-open", {**params, **gains})
    try:
        (sup,) = inst.get("bound_sup")
    finally:
        inst.free()
    expected = BoundReference(plant_of("BacklashShaft", params)).sup()
    assert math.isfinite(expected) and abs(sup - expected) <= TOL * expected


@pytest.mark.parametrize("model", archives.MODELS)
def test_bound_sup_is_infinite_without_damping_or_control(model):
    fmu = archives.require(model)
    params = {**RIGS[model][0], "b_m": 0.0, "b_L": 0.0}
    inst = fmu.co_simulation("sup-inf", {**params, "Kp": 0.0, "Ki": 0.0})
    try:
        (sup,) = inst.get("bound_sup")
    finally:
        inst.free()
    assert sup == math.inf

"""`cargo xtask design --model web`: backlash and stiffness for a web-tension accuracy (docs/model.md §8).

The answer comes from the Rust design code through the CLI; every number is re-derived by
reference_web.py, which shares no code with it: its own closed-loop matrices, an L1 norm by
exact antiderivatives between sign changes (itself checked against reference_bound.py on the
belt speed loop), and an event-located simulation of twin plants (Delta and 0) under
continuous speed and tension PI loops.
"""

from __future__ import annotations

import functools
import json

import numpy as np
import pytest

from reference import Plant
from reference_bound import BoundReference
from reference_web import DRIVE, WEB, bound_sups, dominant_frequency, l1_norm, loop_matrices, simulate, transmission
from rigs import BELT, BELT_GAINS
from test_design import run_design

EPS_T = 20.0  # tension accuracy [N]: delta_max near the default Delta
EPS = 2.2  # load-speed accuracy [rad/s]: with it the speed limit binds first
TENSION_GAINS = (0.01, 0.05)  # Kp_T [rad/s/N], Ki_T [rad/s2/N]: slowest poles -4.3 +- 4.0j

# name -> (extra CLI arguments, the accuracy that binds at delta_max)
CASES = {
    "tension": ((), "tension"),
    "tension+speed": (("--accuracy", repr(EPS)), "speed"),
    "tension-loop": (("--kp-t", repr(TENSION_GAINS[0]), "--ki-t", repr(TENSION_GAINS[1])), "tension"),
}


@functools.cache
def design_json(case: str) -> dict:
    out = run_design("--model", "web", "--tension-accuracy", repr(EPS_T), *CASES[case][0], "--json")
    assert out.returncode == 0, out.stderr
    return json.loads(out.stdout)


@pytest.fixture(scope="module", params=list(CASES))
def case(request) -> tuple[str, dict]:
    return request.param, design_json(request.param)


def params_of(d: dict, **changes: float) -> dict:
    return {**{k: v for k, v in d["plant"].items() if k != "form"}, **changes}


def gains_of(d: dict) -> tuple[float, float, float, float]:
    return d["Kp"], d["Ki"], d["Kp_T"], d["Ki_T"]


def worst(d: dict, **changes: float) -> float:
    """The larger of bound_T_sup / EPS_T and (if a speed accuracy is given) bound_sup / EPS."""
    b_T, b = bound_sups(params_of(d, **changes), *gains_of(d))
    return max(b_T / EPS_T, b / EPS if d["accuracy"] is not None else 0.0)


@pytest.mark.parametrize(
    "params, kp, ki", [(BELT, BELT_GAINS["Kp"], BELT_GAINS["Ki"]), ({k: WEB[k] for k in DRIVE}, 0.18, 58.0)]
)
def test_l1_norm_agrees_with_the_bound_reference_on_the_belt_speed_loop(params, kp, ki):
    """The reduced 4-state loop [u, w_m, w_L, x_c] has the 5-state loop's h: both methods agree."""
    A, d, _, c_w = loop_matrices(params, kp, ki, web=False)
    _, _, K, g = transmission(params)
    ref = BoundReference(Plant.belt(**params), kp, ki).sup()
    assert K * g * l1_norm(A, d, c_w) == pytest.approx(ref, rel=1e-8)


def min_damping(A: np.ndarray) -> float:
    lam = np.linalg.eigvals(A)
    return float(np.min(-lam.real / np.abs(lam)))


def test_json_names_the_plant_the_accuracies_and_stable_gains(case):
    name, d = case
    # Exact: given or default numbers passed through (decimal literals in, shortest round-trip
    # JSON out), not computed.
    assert d["plant"] == {"form": "web", **WEB}
    assert d["tension_accuracy"] == EPS_T
    assert d["accuracy"] == (EPS if name == "tension+speed" else None)
    assert (d["Kp_T"], d["Ki_T"]) == (TENSION_GAINS if name == "tension-loop" else (0.0, 0.0))
    # The loop the bounds are taken on is asymptotically stable (numpy's eigenvalues).
    assert np.max(np.linalg.eigvals(loop_matrices(WEB, *gains_of(d))[0]).real) < 0.0


def test_default_speed_gains_are_the_belt_drives_best_damped(case):
    """No nearby gains give the belt speed loop a larger smallest damping ratio."""
    _, d = case
    kp, ki = d["Kp"], d["Ki"]
    best = min_damping(loop_matrices(WEB, kp, ki, web=False)[0])
    for fp, fi in [(1.02, 1), (0.98, 1), (1, 1.02), (1, 0.98), (1.02, 1.02), (0.98, 0.98)]:
        assert min_damping(loop_matrices(WEB, kp * fp, ki * fi, web=False)[0]) < best


def test_bounds_per_unit_delta_agree_with_the_reference(case):
    _, d = case
    b_T, b = bound_sups(params_of(d), *gains_of(d))
    delta = d["plant"]["Delta"]
    assert d["bound_T_sup_per_unit_delta"] == pytest.approx(b_T / delta, rel=1e-8)
    assert d["bound_sup_per_unit_delta"] == pytest.approx(b / delta, rel=1e-8)
    assert d["bound_T_sup_at_delta"] == pytest.approx(b_T, rel=1e-8)
    assert d["bound_sup_at_delta"] == pytest.approx(b, rel=1e-8)


def test_delta_max_is_where_the_first_accuracy_is_reached(case):
    name, d = case
    delta_max = d["delta_max"]
    b_T, b = bound_sups(params_of(d, Delta=delta_max), *gains_of(d))
    assert worst(d, Delta=delta_max) == pytest.approx(1.0, rel=1e-6)
    assert worst(d, Delta=1.01 * delta_max) > 1.0
    binding = "speed" if d["accuracy"] is not None and b / EPS > b_T / EPS_T else "tension"
    assert binding == CASES[name][1], f"bound_T_sup = {b_T} N, bound_sup = {b} rad/s"
    # delta_max is the smaller of the two limits, each linear in Delta.
    limits = [EPS_T / d["bound_T_sup_per_unit_delta"]]
    if d["accuracy"] is not None:
        limits.append(EPS / d["bound_sup_per_unit_delta"])
    assert delta_max == pytest.approx(min(limits), rel=1e-9)


def test_stiffness_window_edges_reach_the_accuracy(case):
    """Each edge that is not at the scan's end: the accuracy is just met there, missed outside."""
    _, d = case
    k_nom = d["plant"]["K_b"]
    edges = [(d["k_min"], 0.99), (d["k_max"], 1.01)]
    assert any(edge is not None for edge, _ in edges)
    for edge, outward in edges:
        if edge is None:
            continue
        assert worst(d, K_b=edge) == pytest.approx(1.0, rel=1e-6)
        assert worst(d, K_b=outward * edge) > 1.0
        assert worst(d, K_b=(2 - outward) * edge) < 1.0
    assert (d["k_min"] or 0.0) < k_nom < (d["k_max"] or np.inf)


def test_k_scan_agrees_with_the_reference(case):
    """Three scan points around the nominal stiffness (the far ends are slow to integrate here)."""
    _, d = case
    scan = np.array(d["k_scan"])
    k_nom = d["plant"]["K_b"]
    for target in (0.5 * k_nom, k_nom, 2.0 * k_nom):
        k, b_T, b = scan[np.argmin(np.abs(np.log(scan[:, 0] / target)))]
        ref_T, ref = bound_sups(params_of(d, K_b=k), *gains_of(d))
        assert (b_T, b) == (pytest.approx(ref_T, rel=1e-8), pytest.approx(ref, rel=1e-8))


@pytest.mark.parametrize("name", ["tension", "tension-loop"])
def test_twin_runs_at_delta_max_stay_within_the_tension_accuracy(name):
    """Reversing speed reference at the peak of |H_T(jw)| (phi -> T), 10 rad/s amplitude so that
    the gap is crossed every half period; twins with Delta = delta_max and Delta = 0."""
    d = design_json(name)
    p, gains = params_of(d, Delta=d["delta_max"]), gains_of(d)
    A, dist, c_T, _ = loop_matrices(p, *gains)
    w = dominant_frequency(A, dist, c_T)
    t = np.linspace(0.0, 1.0, 20001)
    T_b, w_b = simulate(p, gains, lambda s: 10.0 * np.sin(w * s), t)
    T_0, w_0 = simulate({**p, "Delta": 0.0}, gains, lambda s: 10.0 * np.sin(w * s), t)
    ratio = np.max(np.abs(T_b - T_0)) / EPS_T
    assert 0.2 < ratio <= 1.0, f"max |T^b - T^0| / EPS_T = {ratio} at w = {w} rad/s"
    speed_ratio = np.max(np.abs(w_b - w_0)) / (d["bound_sup_per_unit_delta"] * d["delta_max"])
    assert speed_ratio <= 1.0, f"max |w_L^b - w_L^0| / bound_sup = {speed_ratio}"

"""`backlash design --model two-stage` (docs/model.md §10): each mesh's bound_sup per unit of its
gap, the largest gaps, and the stage that dominates, checked against the loop written here from
the equations of two stages and integrated by reference_bound.py's quadrature (scipy's expm,
Gauss-Legendre cells cut at the sign changes of h), which shares no code with the design library.
"""

from __future__ import annotations

import json
import subprocess

import numpy as np
import pytest

import backlash_fmu
from reference_bound import BoundReference
from test_package import backlash_command, same_numbers

EPS = 0.3  # required load-speed accuracy [rad/s]
# A gearbox other than the default: ratios 2 and 1.5, unequal stiffnesses and gaps.
GEARBOX = {"J_m": 0.8, "J_i": 0.05, "J_L": 6.0, "b_m": 0.02, "b_i": 0.4, "b_L": 0.3, "n_1": 2.0,
           "n_2": 1.5, "k_1": 900.0, "k_2": 2500.0, "Delta_1": 0.6e-3, "Delta_2": 1.1e-3}
GAINS = {"Kp": 9.0, "Ki": 40.0}


def two_stage_loop(p: dict, Kp: float, Ki: float):
    """A, D_1, D_2, L of docs/model.md §10 on z = [theta_m, omega_m, theta_i, omega_i, theta_L,
    omega_L, x_c] with the PI on omega_m (tau_m = Kp e + Ki x_c, x_c' = e = -omega_m); with dampers
    d_j the twin's members are spring-dampers k_j u_j + d_j u_j' (docs/model.md §3)."""
    A = np.zeros((7, 7))
    A[0, 1] = A[2, 3] = A[4, 5] = 1.0
    # J_m w_m' = tau_m - b_m w_m - k_1 (th_m - n_1 th_i)
    A[1, :] = np.array([-p["k_1"], -p["b_m"] - Kp, p["k_1"] * p["n_1"], 0, 0, 0, Ki]) / p["J_m"]
    # J_i w_i' = -b_i w_i + n_1 k_1 (th_m - n_1 th_i) - k_2 (th_i - n_2 th_L)
    A[3, :] = np.array([p["n_1"] * p["k_1"], 0, -p["n_1"] ** 2 * p["k_1"] - p["k_2"], -p["b_i"],
                        p["k_2"] * p["n_2"], 0, 0]) / p["J_i"]
    # J_L w_L' = -b_L w_L + n_2 k_2 (th_i - n_2 th_L)
    A[5, :] = np.array([0, 0, p["n_2"] * p["k_2"], 0, -p["n_2"] ** 2 * p["k_2"], -p["b_L"], 0]) / p["J_L"]
    A[6, 1] = -1.0
    for j, (i, o, n) in enumerate([(1, 3, p["n_1"]), (3, 5, p["n_2"])]):
        # u_j' = omega_in - n_j omega_out; the damper acts like the spring: -d on the input body,
        # +n_j d on the output body.
        d = p.get(f"d_{j + 1}", 0.0)
        J_in, J_out = (p["J_m"], p["J_i"]) if j == 0 else (p["J_i"], p["J_L"])
        A[i, i] -= d / J_in
        A[i, o] += d * n / J_in
        A[o, i] += n * d / J_out
        A[o, o] -= n * n * d / J_out
    D = [np.array([0, 1 / p["J_m"], 0, -p["n_1"] / p["J_i"], 0, 0, 0]),
         np.array([0, 0, 0, 1 / p["J_i"], 0, -p["n_2"] / p["J_L"], 0])]
    L = np.zeros(7)
    L[5] = 1.0
    return A, D, L


def reference_per_delta(p: dict, Kp: float, Ki: float) -> list[float]:
    """s_j = k_j int_0^inf |h_j|, bound_sup per unit of stage j's half gap."""
    A, D, L = two_stage_loop(p, Kp, Ki)
    return [BoundReference.of_loop(A, D[j], L, p[f"k_{j + 1}"]).sup() for j in range(2)]


@pytest.fixture(scope="module")
def answer() -> dict:
    return backlash_fmu.design("two-stage", accuracy=EPS, **GEARBOX, **GAINS)


def test_each_stage_costs_what_its_response_integrates_to(answer):
    reference = reference_per_delta(GEARBOX, **GAINS)
    for stage, expected in zip(answer["stages"], reference):
        # Both are integrals to round-off (the reference's Gauss rule, the library's exact
        # flow with a 1e-13 tail): 1e-9 leaves room for the reference's brentq roots.
        assert stage["bound_sup_per_unit_delta"] == pytest.approx(expected, rel=1e-9)
    assert answer["plant"] == {"form": "two-stage", **GEARBOX, "d_1": 0.0, "d_2": 0.0, "contact_law": 1.0}


def test_with_dampers_each_stage_costs_its_spring_dampers_response():
    """With dampers the twin is the spring-damper chain, and bound_sup answers for the gaps
    (the damper's term follows the trajectory; docs/model.md §10)."""
    damped = {**GEARBOX, "d_1": 3.0, "d_2": 6.0}
    answer = backlash_fmu.design("two-stage", accuracy=EPS, contact_law=2, **damped, **GAINS)
    assert answer["plant"]["contact_law"] == 2.0
    for stage, expected in zip(answer["stages"], reference_per_delta(damped, **GAINS)):
        assert stage["bound_sup_per_unit_delta"] == pytest.approx(expected, rel=1e-9)


def test_the_gaps_form_a_triangle(answer):
    s = [stage["bound_sup_per_unit_delta"] for stage in answer["stages"]]
    d = [GEARBOX["Delta_1"], GEARBOX["Delta_2"]]
    assert answer["bound_sup"] == pytest.approx(s[0] * d[0] + s[1] * d[1], rel=1e-15)
    assert answer["meets"] == (answer["bound_sup"] <= EPS)
    assert answer["dominant_stage"] == 1 + int(s[1] * d[1] > s[0] * d[0])
    for j, stage in enumerate(answer["stages"]):
        assert stage["delta_max_alone"] == pytest.approx(EPS / s[j], rel=1e-15)
        rest = EPS - s[1 - j] * d[1 - j]
        if rest > 0:
            assert stage["delta_max"] == pytest.approx(rest / s[j], rel=1e-15)
        else:
            assert stage["delta_max"] is None
    # At Delta_1 max (Delta_2 at its value) a fresh design's bound is the accuracy.
    corner = backlash_fmu.design("two-stage", accuracy=EPS, **{**GEARBOX, "Delta_1": answer["stages"][0]["delta_max"]},
                                 **GAINS)
    assert corner["bound_sup"] == pytest.approx(EPS, rel=1e-12)


def test_the_poles_are_the_loops_without_the_rigid_rotation(answer):
    A, _, _ = two_stage_loop(GEARBOX, **GAINS)
    theirs = sorted(np.linalg.eigvals(A), key=lambda z: (round(z.real, 6), z.imag))
    # The rigid rotation of the whole train is the eigenvalue 0 the design leaves out.
    theirs = [z for z in theirs if abs(z) > 1e-9 * max(abs(w) for w in theirs)]
    ours = sorted((complex(re, im) for re, im in answer["poles"]), key=lambda z: (round(z.real, 6), z.imag))
    assert len(ours) == len(theirs) == 6
    for a, b in zip(ours, theirs):
        assert abs(a - b) <= 1e-9 * abs(b)


def test_the_rule_damps_the_loop_best_among_its_neighbours():
    answer = backlash_fmu.design("two-stage", accuracy=EPS, **GEARBOX)
    assert answer["gain_rule"].startswith("best-damped")

    def zeta(Kp, Ki):
        A, _, _ = two_stage_loop(GEARBOX, Kp, Ki)
        lam = [z for z in np.linalg.eigvals(A) if abs(z) > 1e-9]
        return min(-z.real / abs(z) for z in lam)

    best = zeta(answer["Kp"], answer["Ki"])
    assert best == pytest.approx(answer["min_damping_ratio"], rel=1e-9)
    for fk, fi in [(1.03, 1), (0.97, 1), (1, 1.03), (1, 0.97)]:
        assert zeta(answer["Kp"] * fk, answer["Ki"] * fi) <= best + 1e-9


def test_the_command_answers_as_the_function(answer):
    flags = ["--model", "two-stage", "--accuracy", repr(EPS), "--kp", "9", "--ki", "40", "--jm", "0.8", "--ji", "0.05",
             "--jl", "6", "--bm", "0.02", "--bi", "0.4", "--bl", "0.3", "--n1", "2", "--n2", "1.5", "--k1", "900",
             "--k2", "2500", "--delta1", "0.6e-3", "--delta2", "1.1e-3", "--json"]
    out = subprocess.run([backlash_command(), "design", *flags], capture_output=True, text=True)
    assert out.returncode == 0, out.stderr
    same_numbers(json.loads(out.stdout), answer)


@pytest.mark.parametrize("keywords, reason", [
    ({"accuracy": EPS, "Delta": 1e-3}, "Delta applies to model shaft or belt or web only"),
    ({"accuracy": EPS, "k_1": 0.0}, "k_1 = 0 must be > 0"),
    ({"accuracy": EPS, "n_2": -1.0}, "n_2 = -1 must be > 0"),
    ({"accuracy": EPS, "d_1": -1.0}, "d_1 = -1 must be >= 0"),
    ({"accuracy": EPS, "d": 1.0}, "d applies to model shaft only"),
    ({}, "accuracy is required for model two-stage"),
])
def test_bad_input_is_refused_with_the_reason(keywords, reason):
    with pytest.raises(ValueError) as refused:
        backlash_fmu.design("two-stage", **keywords)
    assert reason in str(refused.value)

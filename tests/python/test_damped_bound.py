"""The speed-error bound with a damper in the compliant member (docs/model.md §3, "With a damper"),
checked on the continuous PI loop computed by the independent reference (damped_reference.py),
apart from the FMU: the theorem itself.

    |omega_L(t) - omega_L0(t)| <= K g int_0^t |h| + D max_[0,t] |h| V(t)

omega_L0 is the linear twin (psi = K u + D u', which can pull), h the twin loop's impulse
response from the disturbance to omega_L, V(t) the integral of |u'| over the time the backlash
plant spent in the gap, slack (force clipped to 0 past a flank) or capped (law 1). Everything on
the right is computed here from its definition: h = L e^{A s} D_1 with scipy's expm on a grid of
1e-4 s (the integral by the trapezoid rule, the maximum over the grid), V as the sum of |du| over
the grid's intervals in those modes. The grid's error is far below the margins asserted (it is
second order in 1e-4 s against the loop's rates of ~20 /s).
"""

from __future__ import annotations

import numpy as np
import pytest
from scipy.linalg import expm

import damped_reference as ref

T_END = 3.0
GRID = 1e-4


def impulse_response(p: dict, gains, t: np.ndarray) -> np.ndarray:
    A, D_1 = ref.twin_loop(p, gains)
    step = expm(A * (t[1] - t[0]))
    v = D_1.copy()
    h = np.empty(t.size)
    for i in range(t.size):
        h[i] = v[3]
        v = step @ v
    return h


def disturbance_sets(p: dict, law: int, gains, w_ref, breakpoints):
    """(|omega_L - omega_L0|, K g int|h|, D max|h| V) on the grid."""
    t = np.arange(0.0, T_END + GRID / 2, GRID)
    b = ref.simulate_pi(p, law, (0, 0, 0, 0), breakpoints, w_ref, 0.0, gains, t)
    lin = ref.linear_twin_pi(p, (0, 0, 0, 0), breakpoints, w_ref, 0.0, gains, t)
    dev = np.abs(b.z[:, 3] - lin.z[:, 3])
    h = impulse_response(p, gains, t)
    l1 = np.concatenate([[0.0], np.cumsum(0.5 * (np.abs(h[1:]) + np.abs(h[:-1])) * GRID)])
    peak = np.maximum.accumulate(np.abs(h))
    off_contact = np.array([not m.startswith("contact") for m in b.mode])
    du = np.abs(np.diff(b.u))
    # An interval counts when the plant is off ordinary contact at either end (a switch inside
    # an interval is counted whole: more V, a larger right-hand side, never a smaller one).
    counted = off_contact[1:] | off_contact[:-1]
    V = np.concatenate([[0.0], np.cumsum(np.where(counted, du, 0.0))])
    return dev, p["K"] * p["g"] * l1, p["D"] * peak * V, b


def reversing_reference():
    """A staircase sine speed reference (held over 50 ms), 1.5 rad/s at 1 Hz: reversals that
    open the gap and drag the teeth across it each half period (its phase makes the first
    value non-zero, so that the drive leaves rest on a definite flank)."""
    breakpoints = np.arange(0.0, T_END + 1e-9, 0.05)
    return 1.5 * np.sin(2 * np.pi * 1.0 * breakpoints[:-1] + 0.3), breakpoints


CASES = [
    ("shaft zeta 0.5", ref.shaft_params(0.5), ref.SHAFT_GAINS),
    ("shaft zeta 1.5", ref.shaft_params(1.5), ref.SHAFT_GAINS),
    ("shaft zeta 0.5 no gap", ref.shaft_params(0.5, Delta=0.0), ref.SHAFT_GAINS),
    ("belt zeta 0.5", ref.belt_params(0.5), ref.BELT_GAINS),
]


@pytest.mark.parametrize("law", [1, 2])
@pytest.mark.parametrize("name, params, gains", CASES, ids=[c[0] for c in CASES])
def test_the_damped_bound_holds_on_the_continuous_loop(name, params, gains, law):
    w_ref, bp = reversing_reference()
    dev, gap_term, damper_term, run = disturbance_sets(params, law, gains, w_ref, bp)
    bound = gap_term + damper_term
    assert np.max(dev) > 1e-4, f"{name}: the backlash must make a visible difference"
    worst = np.max(dev[1:] / np.maximum(bound[1:], 1e-300))
    assert np.all(dev <= bound * (1 + 1e-9) + 1e-15), f"{name}, law {law}: max deviation / bound = {worst}"
    # The plant did leave contact in every way the bound accounts for.
    assert any(m.startswith("clip") for m in run.mode), f"{name}: {set(run.mode)}"


@pytest.mark.parametrize("law", [1, 2])
def test_the_undamped_rule_fails_and_the_damped_bound_holds(law):
    """With a contact damping ratio of 0.5 the deviation exceeds K g int|h| (the rule without a
    damper) by far; the damped bound still holds. Without a gap K g int|h| is 0 and the deviation
    is not: it comes from the clipping."""
    w_ref, bp = reversing_reference()
    dev, gap_term, damper_term, _ = disturbance_sets(ref.shaft_params(0.5), law, ref.SHAFT_GAINS, w_ref, bp)
    assert np.max(dev[1:] / gap_term[1:]) > 2.0
    assert np.all(dev <= (gap_term + damper_term) * (1 + 1e-9) + 1e-15)
    dev0, gap0, damper0, _ = disturbance_sets(ref.shaft_params(0.5, Delta=0.0), law, ref.SHAFT_GAINS, w_ref, bp)
    assert np.all(gap0 == 0.0) and np.max(dev0) > 1e-3
    assert np.all(dev0 <= damper0 * (1 + 1e-9) + 1e-15)

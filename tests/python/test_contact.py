"""`contact` and `psi` outputs against the FMU's own angle outputs (docs/model.md §1, §4).

u = r_m theta_m - r_L theta_L is recomputed from theta_m, theta_L as read through fmpy, while
the FMU computes psi and contact from its internal state: the two agree to round-off, taken as
1e-12 of |r_m theta_m| + |r_L theta_L| + g (measured: 4e-14 in the Delta = 0 twin). A wrong
force law is off by K g (~0.5 N.m on the rig), 1e10 times more. Points within that slack of
+-g are ambiguous for `contact` and skipped (they are counted: there must be few)."""

from __future__ import annotations

import numpy as np
import pytest

import archives
import scenarios
from reference import FREE, MINUS, PLUS
from rigs import RIGS, plant_of

# The single gap's reference (reference.py); the two-stage gearbox's counterpart is in
# test_two_stage.py.
single_gap = pytest.mark.parametrize("fmu", archives.SINGLE_GAP, indirect=True)


ROUND_OFF = 1e-12


def _u_and_slack(plant, out):
    a, b = plant.r_m * out["theta_m"], plant.r_L * out["theta_L"]
    return a - b, ROUND_OFF * (np.abs(a) + np.abs(b) + plant.g)


@single_gap
@pytest.mark.parametrize("case", scenarios.OPEN_LOOP_CASES)
def test_contact_is_the_side_of_the_gap(fmu, case):
    out, _, _, _ = scenarios.open_loop(fmu.model, case)
    plant = plant_of(fmu.model, RIGS[fmu.model][0])
    u, slack = _u_and_slack(plant, out)
    expected = np.where(u > plant.g, PLUS, np.where(u < -plant.g, MINUS, FREE))
    clear = np.abs(np.abs(u) - plant.g) > slack
    assert np.count_nonzero(~clear) <= 2
    assert np.array_equal(out["contact"][clear], expected[clear])
    assert {PLUS, MINUS, FREE} <= set(out["contact"][1:].tolist()), "all three modes must occur"


@single_gap
@pytest.mark.parametrize("case", scenarios.OPEN_LOOP_CASES)
def test_psi_is_K_times_dead_zone(fmu, case):
    out, _, _, _ = scenarios.open_loop(fmu.model, case)
    plant = plant_of(fmu.model, RIGS[fmu.model][0])
    u, slack = _u_and_slack(plant, out)
    expected = np.array([plant.K * plant.dead_zone(x) for x in u])
    assert np.all(np.abs(out["psi"] - expected) <= plant.K * slack)


def test_contact_without_backlash_is_sign_of_u(shaft):
    """Delta = 0 (docs/model.md §4): contact = sign(u); psi = K u."""
    _, linear = scenarios.twin("sine")
    plant = plant_of("BacklashShaft", {**RIGS["BacklashShaft"][0], "Delta": 0.0})
    u, slack = _u_and_slack(plant, linear)
    clear = np.abs(u) > slack
    assert np.array_equal(linear["contact"][clear], np.sign(u[clear]).astype(int))
    assert np.all(np.abs(linear["psi"] - plant.K * u) <= plant.K * slack)

"""PI speed loop closed outside the FMU (FMU2Slave, tau_m from the measured omega_m at every
communication point) against the reference solving the same sampled-data loop.

Tolerance 1e-8 relative: as open loop, plus the feedback, which passes each state error into
the next torques (Kp h / J_m = 0.18 per step); the reference is good to ~2e-10 (reference.py)."""

from __future__ import annotations

import pytest

import archives
import scenarios
from rigs import RIGS, plant_of
from signals import rel_err

# The single gap's reference (reference.py); the two-stage gearbox's counterpart is in
# test_two_stage.py.
pytestmark = pytest.mark.parametrize("fmu", archives.SINGLE_GAP, indirect=True)


TOL = 1e-8


def test_pi_loop_matches_reference(fmu):
    out, z, u, taus, ref = scenarios.pi_loop(fmu.model)
    plant = plant_of(fmu.model, RIGS[fmu.model][0])
    assert len(ref.switches) >= 6, "the loop must reverse through the gap several times"
    errors = {name: rel_err(out[name], z[:, j]) for j, name in enumerate(("theta_m", "omega_m", "theta_L", "omega_L"))}
    errors["u"] = rel_err(plant.r_m * out["theta_m"] - plant.r_L * out["theta_L"], u)
    errors["psi"] = rel_err(out["psi"], [plant.K * plant.dead_zone(x) for x in u])
    errors["tau_m"] = rel_err(out["tau_m"], taus)
    assert max(errors.values()) <= TOL, f"{fmu.model}: {errors}"

"""BacklashTwoStage (docs/model.md §10) against computations written independently of it: an
event-located DOP853 integration of its equations (reference_two_stage.py) in Co-Simulation,
fmpy's CVode on the FMU's own vector field and event indicators in Model Exchange, and, in FMI
3.0, an early return at every switch the reference finds.

Tolerance 1e-9 relative per signal (max abs error / max abs value), as the single gap's open
loop: the reference is good to ~2e-10 (its runs at rtol 1e-12 and 1e-13 differ by that much), an
FMU that stepped over a switch instead of locating it is off by ~1e-7."""

from __future__ import annotations

import numpy as np
import pytest

import archives
import reference_two_stage as ref2
from signals import rel_err, reversing_torques

MODEL = "BacklashTwoStage"
TOL = 1e-9
STATES = ("theta_m", "omega_m", "theta_i", "omega_i", "theta_L", "omega_L")

pytestmark = pytest.mark.skipif(MODEL not in archives.MODELS, reason="no BacklashTwoStage archive")


def defaults() -> dict:
    md = archives.shared(MODEL).md
    return {v.name: float(v.start) for v in md.modelVariables if v.causality == "parameter"}


@pytest.mark.parametrize("h,n", [(0.02, 300), (0.25, 24)], ids=["fine", "coarse"])
def test_open_loop_matches_the_reference(h, n):
    params = defaults()
    tau_m, tau_L = reversing_torques(n, h, 1.5, 0.6)
    inst = archives.shared(MODEL).co_simulation(f"two-stage-{h}", {})
    try:
        rows = [inst.get(*STATES)]
        for k, (a, b) in enumerate(zip(tau_m, tau_L)):
            inst.step(k * h, h, tau_m=float(a), tau_L=float(b))
            rows.append(inst.get(*STATES))
    finally:
        inst.free()
    box = ref2.Gearbox.of(params)
    z, ref = ref2.run_open_loop(box, tau_m, tau_L, h)
    meshes = {mesh for _, mesh, _, _ in ref.switches}
    assert meshes == {0, 1} and len(ref.switches) >= 8, ref.switches
    out = np.array(rows)
    errors = {name: rel_err(out[:, j], z[:, j]) for j, name in enumerate(STATES)}
    assert max(errors.values()) <= TOL, errors

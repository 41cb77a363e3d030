"""The damper in the compliant member through the interface (docs/model.md §4, §6): its damping
(`d` of BacklashShaft, `D_b` of BacklashBelt and BacklashWeb) and the Integer `contact_law`, given
as start values to fmpy's simulate_fmu, on the FMI 2.0 and FMI 3.0 archives, in Co-Simulation and
in Model Exchange (fmpy's CVode, with the six event indicators), under a reversing motor torque.

The force never pulls: `psi * contact >= 0`, and `psi == 0` where `contact == 0`; the damper clips
it (the bodies separate past the gap: `contact == 0` with |u| > g); and `psi` is the law's formula
of docs/model.md §1 at the recorded u and u', so both parameters reached the plant."""

from __future__ import annotations

import numpy as np
import pytest
from backlash_fmu.fmu import fmu_path
from fmpy import read_model_description, simulate_fmu

import archives

# The damping of each form (a shaft's N.m.s/rad, a belt's N.s/m): about a sixth of the critical
# damping of the contact oscillation at the default parameters, so that the damper's force is of
# the spring's size and both clip it. The torque: its amplitude [N.m] and frequency [rad/s], a
# few reversals through the gap; the horizon and the output interval [s].
RUNS = {
    "k": {"damping": ("d", 5.0), "torque": (1.0, 7.0), "stop": 3.0, "interval": 1e-3},
    "K_b": {"damping": ("D_b", 50.0), "torque": (0.3, 300.0), "stop": 0.05, "interval": 1e-5},
}
OUTPUTS = ["psi", "contact", "theta_m", "omega_m", "theta_L", "omega_L", "u_minus_g", "u_plus_g"]


def drive_train(md) -> tuple[float, float, float, float]:
    """r_m, r_L, K, g of the drive train at the description's start values (docs/model.md §1)."""
    p = {v.name: float(v.start) for v in md.modelVariables if v.causality == "parameter"}
    if "k" in p:
        return 1.0, 1.0, p["k"], p["Delta"]
    return p["R_1"], p["R_2"] * p["R_g2"] / p["R_g1"], p["K_b"], p["R_2"] / p["R_g1"] * p["Delta"]


def force(u, du, K, D, g, law):
    """psi of docs/model.md §1: past +g, with tau_c = K (u - g) and tau_d = D u', law 2 gives
    tau_c + tau_d and law 1 tau_c + min(tau_c, tau_d) while tau_c + tau_d > 0, else 0; mirrored
    past -g; 0 inside the gap."""
    psi = np.zeros_like(u)
    for side in (1.0, -1.0):
        tc, td = K * (u - side * g), D * du
        past = side * u >= g
        pushing = past & (side * (tc + td) > 0)
        capped = side * tc + np.minimum(side * tc, side * td)
        psi = np.where(pushing, side * capped if law == 1 else tc + td, psi)
    return psi


@pytest.mark.parametrize("law", [1, 2])
@pytest.mark.parametrize("fmi_type", ["CoSimulation", "ModelExchange"])
@pytest.mark.parametrize("fmi", [2, 3])
@pytest.mark.parametrize("model", archives.MODELS)
def test_a_damped_member_never_pulls(model, fmi, fmi_type, law):
    path = fmu_path(model, fmi)
    if not path.is_file():
        pytest.fail(f"FMU archive not found: {path} (build with `cargo xtask fmu`)")
    md = read_model_description(str(path))
    names = {v.name for v in md.modelVariables}
    run = next(run for form, run in RUNS.items() if form in names)
    damping, D = run["damping"]
    assert damping in names and "contact_law" in names, model
    amplitude, frequency = run["torque"]
    t = np.linspace(0.0, run["stop"], 2001)
    torques = np.zeros(len(t), dtype=[("time", np.float64), ("tau_m", np.float64), ("tau_L", np.float64)])
    torques["time"] = t
    torques["tau_m"] = amplitude * np.sin(frequency * t)
    torques["tau_L"] = -0.1 * torques["tau_m"]
    r = simulate_fmu(
        str(path),
        fmi_type=fmi_type,
        stop_time=run["stop"],
        step_size=run["interval"],
        output_interval=run["interval"],
        start_values={damping: D, "contact_law": law},
        input=torques,
        output=OUTPUTS,
    )
    psi, contact = r["psi"], r["contact"]
    assert set(np.unique(contact)) == {-1, 0, 1}, "the torque drives both flanks"
    # Never a pull: psi has the sign of contact, and is 0 when contact is.
    assert np.all(psi * contact >= 0.0), psi[psi * contact < 0.0]
    assert np.all(psi[contact == 0] == 0.0)
    # The damper at work: past the gap (u - g > 0 or u + g < 0) with no force.
    slack = (contact == 0) & ((r["u_minus_g"] > 0.0) | (r["u_plus_g"] < 0.0))
    assert np.count_nonzero(slack) > 0, "the damper never clipped the force"

    # psi is the law's formula at u and u' (docs/model.md §1): d or D_b and contact_law reached
    # the plant. Law 2 jumps by D u' where a contact begins: not compared on the gap's edges.
    r_m, r_l, K, g = drive_train(md)
    u = r_m * r["theta_m"] - r_l * r["theta_L"]
    du = r_m * r["omega_m"] - r_l * r["omega_L"]
    scale = K * (np.abs(r_m * r["theta_m"]) + np.abs(r_l * r["theta_L"]) + g) + D * (
        np.abs(r_m * r["omega_m"]) + np.abs(r_l * r["omega_L"])
    )
    compared = np.abs(np.abs(u) - g) > 1e-6 * g if law == 2 else np.ones(len(u), dtype=bool)
    error = np.abs(psi - force(u, du, K, D, g, law))[compared]
    assert np.all(error <= 1e-9 * scale[compared]), error.max()

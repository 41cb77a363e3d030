"""The damper in the compliant member through the interface (docs/model.md §4, §6): its damping
(`d` of BacklashShaft, `D_b` of BacklashBelt and BacklashWeb, each mesh's `d_1`, `d_2` of
BacklashTwoStage) and the Integer `contact_law`, given as start values to fmpy's simulate_fmu, on
the FMI 2.0 and FMI 3.0 archives, in Co-Simulation and in Model Exchange (fmpy's CVode, with the
event indicators), under a reversing motor torque.

The force never pulls: `psi * contact >= 0`, and `psi == 0` where `contact == 0`; the damper clips
it (the bodies separate past the gap: `contact == 0` with |u| > g); and `psi` is the law's formula
of docs/model.md §1 at the recorded u and u', so both parameters reached the plant. A gearbox:
each mesh on its own (its psi_j, contact_j, u_j = theta_in - n_j theta_out, k_j, Delta_j, d_j)."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pytest
from backlash_fmu.fmu import fmu_path
from fmpy import read_model_description, simulate_fmu

import archives

# The damping of each form (a shaft's N.m.s/rad, a belt's N.s/m): about a sixth of the critical
# damping of the contact oscillation at the default parameters, so that the damper's force is of
# the spring's size and both clip it. A gearbox's meshes (N.m.s/rad): each mesh's contact
# oscillation has the intermediate shaft's inertia nearly alone (J_i = 0.1 against 2.28 and
# 2.55: critical 2 sqrt(400 * 0.096) = 12.4 N.m.s/rad), d_1 a sixth of it and d_2 an eighth,
# unequal so that one mesh's damper taken for the other's shows. The torque: its amplitude [N.m] and
# frequency [rad/s], a few reversals through the gap(s); the horizon and the output interval [s].
RUNS = {
    "k": {"damping": {"d": 5.0}, "torque": (1.0, 7.0), "stop": 3.0, "interval": 1e-3},
    "K_b": {"damping": {"D_b": 50.0}, "torque": (0.3, 300.0), "stop": 0.05, "interval": 1e-5},
    "k_1": {"damping": {"d_1": 2.0, "d_2": 1.5}, "torque": (1.0, 7.0), "stop": 3.0, "interval": 1e-3},
}


def drive_train(md) -> tuple[float, float, float, float]:
    """r_m, r_L, K, g of the drive train at the description's start values (docs/model.md §1)."""
    p = {v.name: float(v.start) for v in md.modelVariables if v.causality == "parameter"}
    if "k" in p:
        return 1.0, 1.0, p["k"], p["Delta"]
    return p["R_1"], p["R_2"] * p["R_g2"] / p["R_g1"], p["K_b"], p["R_2"] / p["R_g1"] * p["Delta"]


@dataclass(frozen=True)
class Member:
    """One compliant member with its backlash: its outputs, the bodies it joins (angle and speed
    names) and u = r_in theta_in - r_out theta_out, its stiffness K, half gap g and damper."""

    psi: str
    contact: str
    indicators: tuple[str, str]  # u - g, u + g
    bodies: tuple[tuple[str, str], tuple[str, str]]  # (theta, omega) of the input and output body
    r_in: float
    r_out: float
    K: float
    g: float
    damping: str


def members(md) -> list[Member]:
    """The single gap's member (docs/model.md §1), or each mesh of a gearbox (§10: u_j =
    theta_in - n_j theta_out, k_j, Delta_j, d_j), at the description's start values."""
    p = {v.name: float(v.start) for v in md.modelVariables if v.causality == "parameter"}
    if "k_1" not in p:
        r_m, r_l, K, g = drive_train(md)
        damping = "d" if "k" in p else "D_b"
        motor, load = ("theta_m", "omega_m"), ("theta_L", "omega_L")
        return [Member("psi", "contact", ("u_minus_g", "u_plus_g"), (motor, load), r_m, r_l, K, g, damping)]
    bodies = [("theta_m", "omega_m"), ("theta_i", "omega_i"), ("theta_L", "omega_L")]
    return [
        Member(f"psi_{j}", f"contact_{j}", (f"u_minus_g_{j}", f"u_plus_g_{j}"), (bodies[j - 1], bodies[j]),
               1.0, p[f"n_{j}"], p[f"k_{j}"], p[f"Delta_{j}"], f"d_{j}")
        for j in (1, 2)
    ]


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
    """Every member: the single gap's, or each mesh of a gearbox with its own d_j. Measured on
    the gearbox: 24 to 59 slack points per mesh, psi_j within 3.8e-15 of the scale (0 in Model
    Exchange, where the outputs come from the state the solver set); with d_1 and d_2 swapped in
    the formula, 1.6e-2."""
    path = fmu_path(model, fmi)
    if not path.is_file():
        pytest.fail(f"FMU archive not found: {path} (build with `cargo xtask fmu`)")
    md = read_model_description(str(path))
    names = {v.name for v in md.modelVariables}
    run = next(run for form, run in RUNS.items() if form in names)
    dampers = run["damping"]
    assert set(dampers) <= names and "contact_law" in names, model
    meshes = members(md)
    assert {m.damping for m in meshes} == set(dampers), model
    outputs = list(dict.fromkeys(n for m in meshes for n in (m.psi, m.contact, *m.bodies[0], *m.bodies[1],
                                                              *m.indicators)))
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
        start_values={**dampers, "contact_law": law},
        input=torques,
        output=outputs,
    )
    for m in meshes:
        D = dampers[m.damping]
        psi, contact = r[m.psi], r[m.contact]
        assert set(np.unique(contact)) == {-1, 0, 1}, f"{m.psi}: the torque drives both flanks"
        # Never a pull: psi has the sign of contact, and is 0 when contact is.
        assert np.all(psi * contact >= 0.0), psi[psi * contact < 0.0]
        assert np.all(psi[contact == 0] == 0.0), m.psi
        # The damper at work: past the gap (u - g > 0 or u + g < 0) with no force.
        minus, plus = m.indicators
        slack = (contact == 0) & ((r[minus] > 0.0) | (r[plus] < 0.0))
        assert np.count_nonzero(slack) > 0, f"{m.psi}: the damper never clipped the force"

        # psi is the law's formula at u and u' (docs/model.md §1, §10): the member's damping and
        # contact_law reached the plant. Law 2 jumps by D u' where a contact begins: not compared
        # on the gap's edges.
        (th_in, w_in), (th_out, w_out) = m.bodies
        u = m.r_in * r[th_in] - m.r_out * r[th_out]
        du = m.r_in * r[w_in] - m.r_out * r[w_out]
        scale = m.K * (np.abs(m.r_in * r[th_in]) + np.abs(m.r_out * r[th_out]) + m.g) + D * (
            np.abs(m.r_in * r[w_in]) + np.abs(m.r_out * r[w_out])
        )
        compared = np.abs(np.abs(u) - m.g) > 1e-6 * m.g if law == 2 else np.ones(len(u), dtype=bool)
        error = np.abs(psi - force(u, du, m.K, D, m.g, law))[compared]
        assert np.all(error <= 1e-9 * scale[compared]), (m.psi, error.max())

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
from fmpy import simulate_fmu

import archives
import reference
import reference_two_stage as ref2
from rigs import RIGS
from scenarios import pi_inputs
from signals import held_table, rel_err, reversing_torques

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


@pytest.mark.parametrize("event_mode", [False, True], ids=["no-event-mode", "event-mode"])
def test_early_return_at_every_switch_of_either_mesh(event_mode):
    """FMI 3.0 Co-Simulation with earlyReturnAllowed (docs/model.md §7, §10): the FMU returns
    early at every switch of either mesh the reference finds, none missed, none extra, in order,
    each lastSuccessfulTime within 1e-11 s of the reference's instant (the reference locates its
    events on DOP853's dense output at rtol 1e-13; the meshes' contact periods are ~0.07 s), the
    mesh and its modes before and after as `contact_j` reads them. With eventModeUsed each early
    return asks for Event Mode. Measured: 62 returns (31 per mesh, up to 6 in one step), the
    instants within 7.9e-13 s of the reference's; the allowance is about 10 times that."""
    params = defaults()
    h, n = 0.1, 30
    tau_m, tau_L = reversing_torques(n, h, 1.5, 0.6)
    _, ref = ref2.run_open_loop(ref2.Gearbox.of(params), tau_m, tau_L, h)
    grid = np.arange(n + 1) * h
    expected = [s for s in ref.switches if np.min(np.abs(grid - s[0])) > 1e-9]
    assert {mesh for _, mesh, _, _ in expected} == {0, 1} and len(expected) >= 15, expected
    per_step = np.bincount(np.searchsorted(grid, [s[0] for s in expected]) - 1)
    assert per_step.max() >= 2, "some steps must hold several switches"
    inst = archives.shared(MODEL, fmi=3).co_simulation(
        f"early-{event_mode}", {}, early_return=True, event_mode=event_mode
    )
    returns = []
    try:
        for k in range(n):
            t, t_end = k * h, (k + 1) * h
            inst.set({"tau_m": float(tau_m[k]), "tau_L": float(tau_L[k])})
            while True:
                before = inst.integers("contact_1", "contact_2")
                event, terminate, early, last = inst.do_step(t, t_end - t)
                assert not terminate
                if not early:
                    break
                assert event == event_mode and t < last < t_end, (t, last, t_end)
                returns.append((last, before, inst.integers("contact_1", "contact_2")))
                if event_mode:
                    inst.fmu.enterEventMode()
                    inst.fmu.updateDiscreteStates()
                    inst.fmu.enterStepMode()
                t = last
    finally:
        inst.free()
    assert len(returns) == len(expected), ([r[0] for r in returns], [s[0] for s in expected])
    for (t_fmu, before, after), (t_ref, mesh, m0, m1) in zip(returns, expected):
        assert abs(t_fmu - t_ref) <= 1e-11, (t_fmu, t_ref)
        assert (before[mesh], after[mesh]) == (m0, m1), (t_ref, mesh, before, after)


@pytest.mark.parametrize("fmi", [2, 3])
def test_model_exchange_with_cvode_converges_to_the_reference(fmi):
    """fmpy's CVode integrates the Model Exchange interface (the FMU's vector field, its 18 event
    indicators as roots) under torques held for 0.1 s each. Every switch of either mesh is a
    state event of the run (a repeated output time off the input edges), at rtol 1e-9 and
    1e-11. At the communication points the states converge to the reference as rtol shrinks:
    the error at rtol 1e-11 is below a tenth of that at 1e-9 and below 1e-6 relative. Measured
    (FMI 2.0): 9.5e-6 at 1e-9, 4.6e-7 at 1e-11, both on the light intermediate shaft's speed,
    over 50 switches: CVode controls only its local error, and the shaft rattling through the
    gaps restarts it at every switch."""
    params = defaults()
    h, n = 0.1, 20
    tau_m, tau_L = reversing_torques(n, h, 1.5, 0.6)
    z, ref = ref2.run_open_loop(ref2.Gearbox.of(params), tau_m, tau_L, h)
    grid = np.arange(n + 1) * h
    path = archives.shared(MODEL, fmi=fmi).path

    def error(rtol: float) -> float:
        result = simulate_fmu(
            str(path),
            fmi_type="ModelExchange",
            solver="CVode",
            relative_tolerance=rtol,
            start_time=0.0,
            stop_time=n * h,
            output_interval=h,
            input=held_table(tau_m, tau_L, h),
            output=list(STATES),
        )
        t = result["time"]
        repeated = t[1:][np.diff(t) == 0.0]
        state_events = [x for x in repeated if np.min(np.abs(x - grid)) > 1e-12]
        assert len(state_events) == len(ref.switches), (rtol, len(state_events), len(ref.switches))
        # One row per grid time: the last at it (after any event there).
        last = np.r_[t[1:] != t[:-1], True]
        rows = {round(x / h): i for i, x in enumerate(t) if last[i] and np.min(np.abs(x - grid)) <= 1e-12}
        index = [rows[k] for k in range(n + 1)]
        return max(rel_err(result[name][index], z[:, j]) for j, name in enumerate(STATES))

    coarse, fine = error(1e-9), error(1e-11)
    assert fine <= coarse / 10 and fine <= 1e-6, (coarse, fine)


def test_sampled_pi_loop_matches_the_reference():
    """The sampled PI on omega_m (reference.SampledPI, the rig's gains, 10 ms) closed around the
    FMU and, separately, around the reference under a sine speed reference and a load step at
    4 s: the torques are equal only if every earlier output was. States within 1e-9 relative,
    as the open loop; both meshes switch."""
    params, gains = RIGS[MODEL]
    h, n = 0.01, 600
    w_ref, load = pi_inputs()
    inst = archives.shared(MODEL).co_simulation("pi", {**params, **gains})
    pi = reference.SampledPI(gains["Kp"], gains["Ki"], h)
    rows = [inst.get(*STATES)]
    try:
        for k in range(n):
            tau = pi(w_ref(k * h), inst.get("omega_m")[0])
            inst.step(k * h, h, tau_m=tau, tau_L=load(k * h))
            rows.append(inst.get(*STATES))
    finally:
        inst.free()
    ref = ref2.ReferenceGearbox(ref2.Gearbox.of(params))
    pi = reference.SampledPI(gains["Kp"], gains["Ki"], h)
    z = [ref.z]
    for k in range(n):
        tau = pi(w_ref(k * h), ref.z[1])
        z.append(ref.step(tau, load(k * h), h))
    z, out = np.array(z), np.array(rows)
    assert {mesh for _, mesh, _, _ in ref.switches} == {0, 1}, ref.switches
    errors = {name: rel_err(out[:, j], z[:, j]) for j, name in enumerate(STATES)}
    assert max(errors.values()) <= TOL, errors


def test_each_mesh_contact_and_psi_follow_its_gap():
    """Each mesh's `contact_j` is the side of its gap u_j is on and `psi_j` is
    k_j dz(u_j, Delta_j), with u_j recomputed from the angle outputs (u_1 = theta_m -
    n_1 theta_i, u_2 = theta_i - n_2 theta_L) while the FMU computes them from its own state:
    they agree to round-off, 1e-12 of the terms of u_j plus Delta_j (a wrong force law is off by
    k_j Delta_j, 1e12 times more); points within that of a flank are ambiguous for contact
    (at most two). Every mode of each mesh occurs."""
    params = defaults()
    h, n = 0.02, 300
    tau_m, tau_L = reversing_torques(n, h, 1.5, 0.6)
    inst = archives.shared(MODEL).co_simulation("contact-psi", {})
    rows, contacts = [], []
    try:
        for k, (a, b) in enumerate(zip(tau_m, tau_L)):
            inst.step(k * h, h, tau_m=float(a), tau_L=float(b))
            rows.append(inst.get("theta_m", "theta_i", "theta_L", "psi_1", "psi_2"))
            contacts.append(inst.integers("contact_1", "contact_2"))
    finally:
        inst.free()
    out, contacts = np.array(rows), np.array(contacts)
    for j, (a, b, n_j, k_j, g) in enumerate(
        [
            (out[:, 0], out[:, 1], params["n_1"], params["k_1"], params["Delta_1"]),
            (out[:, 1], out[:, 2], params["n_2"], params["k_2"], params["Delta_2"]),
        ]
    ):
        u = a - n_j * b
        slack = 1e-12 * (np.abs(a) + np.abs(n_j * b) + g)
        dead_zone = np.where(u >= g, u - g, np.where(u <= -g, u + g, 0.0))
        assert np.all(np.abs(out[:, 3 + j] - k_j * dead_zone) <= k_j * slack), j
        side = np.where(u > g, 1, np.where(u < -g, -1, 0))
        clear = np.abs(np.abs(u) - g) > slack
        assert np.count_nonzero(~clear) <= 2, j
        assert np.array_equal(contacts[clear, j], side[clear]), j
        assert set(contacts[:, j].tolist()) == {-1, 0, 1}, j


@pytest.mark.parametrize("fmi", [2, 3])
@pytest.mark.parametrize("damper", [None, "d_1", "d_2"])
def test_model_exchange_bound_is_infinite_exactly_when_a_mesh_is_damped(fmi, damper):
    """docs/model.md §10: a damper's term of `bound` follows the trajectory the FMU steps, which in
    Model Exchange the importer's solver takes, so there `bound` is +inf when d_1 or d_2 is above
    0, with a warning at initialization; Co-Simulation, which steps the trajectory itself, keeps
    it finite. Without a damper the bound does not depend on the trajectory (a sum of k_j Delta_j
    times integrals of the loop's responses, docs/model.md §11): Model Exchange's at t = 0.5 s
    (read at that time, the states where the instance started) equals Co-Simulation's after 50
    steps of 10 ms under other torques, to 1e-12 relative (the one integral evaluated to 0.5 s at
    once or in 50 pieces; measured 1.8e-15). A finite Model Exchange bound that leaves out the
    damper's term fails the test, as does +inf in Co-Simulation."""
    params = {"Kp": 42.0, "Ki": 180.0, **({damper: 0.05} if damper else {})}
    archive = archives.shared(MODEL, fmi=fmi)
    me = archive.model_exchange(f"me-bound-{damper}", params)
    try:
        me.set_state(0.5, me.continuous_states())
        me_bound = me.get("bound")[0]
        me_warnings = [text for status, _, text in me.messages if "bound = +inf" in text]
    finally:
        me.free()
    cs = archive.co_simulation(f"cs-bound-{damper}", params)
    try:
        for k in range(50):
            cs.step(k * 0.01, 0.01, tau_m=1.5 * np.sin(9.0 * k * 0.01), tau_L=0.4)
        cs_bound = cs.get("bound")[0]
        cs_warnings = [text for status, _, text in cs.messages if "bound = +inf" in text]
    finally:
        cs.free()
    assert np.isfinite(cs_bound) and cs_bound > 0.0 and not cs_warnings, (cs_bound, cs_warnings)
    if damper:
        assert me_bound == np.inf, me_bound
        assert len(me_warnings) == 1 and "d_1 or d_2 > 0" in me_warnings[0], me.messages
    else:
        assert not me_warnings, me_warnings
        assert abs(me_bound - cs_bound) <= 1e-12 * cs_bound, (me_bound, cs_bound)

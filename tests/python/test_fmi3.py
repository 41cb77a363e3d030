"""The FMI 3.0 archives (target/fmu/fmi3/, docs/model.md §7) loaded and run through fmpy:
Co-Simulation without early return against the FMI 2.0 archive bit for bit, early return at the
contact switches against independently computed switch instants, a PI loop updated at every
early return against an independent solution of the same sampled-data loop, Model Exchange
against the exact solution and against FMI 2.0 Model Exchange, FMU states kept apart by
standard, and misuse.

References (none takes a number from the FMU):
- reference_continuous.py: the exact solution of the plant under held torques (expm per mode,
  switches bracketed on a grid with a certified grazing search and refined by brentq to
  ~1e-15 s), checked in test_model_exchange.py against an event-located DOP853 integration.
- reference_switch_sampled.switch_sampled_pi: the PI loop sampled at the communication points and at every
  contact switch, closed around that exact plant segment by segment.
- The FMI 2.0 archive, where a claim is "the same as FMI 2.0" (docs/model.md §7).

"Relative" errors are signals.rel_err: max |actual - expected| over a run divided by
max |expected| over the run, per signal.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from backlash_fmu.fmu import STATES, CoSimulation, fmu_path
from fmpy import simulate_fmu
from fmpy.fmi1 import FMICallException
from fmpy.fmi3 import fmi3Error
from fmpy.validation import validate_fmu
from scipy.integrate import solve_ivp

import archives
import reference
import reference_continuous as rc
import reference_switch_sampled as rss
import reference_two_stage as ref2
from cvode_check import check_cvode_against_exact
from loops import state_with_u
from reference import FREE, MINUS, PLUS
from rigs import RIGS, plant_of
from scenarios import pi_inputs
from signals import held_table, rel_err, reversing_torques

MODELS = archives.MODELS


def contact(inst) -> int:
    """The contact output of an instance: `contact`, a gearbox's first mesh's `contact_1`."""
    return inst.integers(archives.contact_output(inst.archive.model))[0]


@pytest.fixture(params=MODELS)
def model(request) -> str:
    """Each model; its FMI 3.0 archive must exist (a missing one fails, never skips)."""
    archives.require(request.param, fmi=3)
    return request.param


def float64_names(fmu) -> list[str]:
    """Every Float64 (FMI 2.0: Real) variable the interface computes: outputs, locals
    (derivatives, event indicators) and the calculated parameter bound_sup."""
    kinds = ("output", "local", "calculatedParameter")
    return [n for n, v in fmu.variables.items() if v.type in ("Float64", "Real") and v.causality in kinds]


def bits(values) -> tuple[str, ...]:
    """Floats as exact hexadecimal strings: equal only if bit for bit equal (NaN included)."""
    return tuple(float(x).hex() for x in values)


def _rig(model: str) -> dict:
    params, gains = RIGS[model]
    return {**params, **gains}


# --- 1. fmpy loads, validates and simulates the archives -------------------------------------------

SIM_H, SIM_N, SIM_OUT = 0.1, 40, 0.02


def test_fmpy_validates_and_simulates_the_fmi3_archive(model):
    """validate_fmu finds nothing; simulate_fmu runs the FMI 3.0 archive as Co-Simulation under
    held reversing torques and records exactly what it records for the FMI 2.0 archive (every
    column, bit for bit: the same steps, docs/model.md §7); with early return and Event Mode
    (fmpy's own handling: a sample at each early return, Event Mode there, inputs re-applied)
    every row on the output grid agrees with the plain run to 1e-11 relative (measured 2e-14 at
    most, see the early-return test for why they differ at all), and the run stops early inside
    steps: each extra time lies strictly between two grid points."""
    assert validate_fmu(str(fmu_path(model, 3))) == []
    tau_m, tau_L = reversing_torques(SIM_N, SIM_H, 1.5, 0.6)
    contact_name = archives.contact_output(model)
    reals = [n for n in archives.real_outputs(model) if n != "bound_sup"]
    outputs = [*reals, contact_name]

    def run(path, **kw):
        return simulate_fmu(
            str(path),
            fmi_type="CoSimulation",
            start_time=0.0,
            stop_time=SIM_N * SIM_H,
            output_interval=SIM_OUT,
            input=held_table(tau_m, tau_L, SIM_H),
            start_values=_rig(model),
            output=outputs,
            **kw,
        )

    fmi3 = run(fmu_path(model, 3))
    fmi2 = run(fmu_path(model))
    assert fmi3.dtype.names == fmi2.dtype.names and len(fmi3) == len(fmi2) == round(SIM_N * SIM_H / SIM_OUT) + 1
    for name in fmi2.dtype.names:
        assert bits(fmi3[name]) == bits(fmi2[name]), name
    assert len(set(fmi3[contact_name])) == 3, "the run must cross the gap"

    early = run(fmu_path(model, 3), early_return_allowed=True, use_event_mode=True)
    grid = fmi3["time"]
    on_grid = np.isin(early["time"], grid)
    extra = np.unique(early["time"][~on_grid])
    assert len(extra) >= 10
    cell = np.searchsorted(grid, extra)
    assert np.all((grid[cell - 1] < extra) & (extra < grid[cell]))
    # one row per grid time: the first sample at it
    _, first = np.unique(early["time"], return_index=True)
    rows = first[np.isin(early["time"][first], grid)]
    assert np.array_equal(early["time"][rows], grid)
    for name in outputs[:-1]:
        assert rel_err(early[name][rows], fmi3[name]) <= 1e-11, name
    assert np.array_equal(early[contact_name][rows], fmi3[contact_name])


# --- 2. Co-Simulation without early return: the FMI 2.0 step, bit for bit ----------------------------

OPEN_STEPS = 160


def _open_loop_steps():
    """Step sizes drawn from [0.02, 0.08] s (seeded): the step-size-keyed caches change often."""
    h = np.random.default_rng(3).uniform(0.02, 0.08, OPEN_STEPS)
    return h, np.concatenate([[0.0], np.cumsum(h)])


def _snapshot(inst, names) -> tuple:
    return (*bits(inst.get(*names)), contact(inst))


@pytest.mark.parametrize("loop", ["open", "closed"])
def test_cosimulation_without_early_return_is_the_fmi2_step(model, loop):
    """FMI 3.0 Co-Simulation instances without earlyReturnAllowed (one with eventModeUsed = false,
    one with eventModeUsed = true) against an FMI 2.0 instance of the same rig: every Float64
    variable the FMU computes (outputs, der(...), u -+ g, bound_sup) and `contact` after every
    step, compared bit for bit (float.hex). Open loop: reversing torques held over steps of
    random sizes; closed loop: reference.SampledPI on omega_m closed by the test around each
    instance separately (10 ms, sine reference, load step at 4 s), so that the torques are
    equal only if every earlier output was. Both cross the gap again and again (contact changes
    at 41 / 33 communication points open loop, shaft / belt; 10 / 11 closed loop). fmi3DoStep
    never reports an early return or an event, and its lastSuccessfulTime is the step's end."""
    fmu2, fmu3 = archives.require(model), archives.require(model, fmi=3)
    names = float64_names(fmu3)
    plus = "u_plus_g_1" if model == "BacklashTwoStage" else "u_plus_g"
    assert names == float64_names(fmu2) and "der(omega_L)" in names and plus in names
    params = _rig(model)
    gains = RIGS[model][1]
    two = fmu2.co_simulation("fmi2", params)
    threes = [fmu3.co_simulation("fmi3", params), fmu3.co_simulation("fmi3-event", params, event_mode=True)]
    try:
        if loop == "open":
            h, t = _open_loop_steps()
            tau_m, tau_L = reversing_torques(OPEN_STEPS, 0.05, 1.5, 0.6)
            inputs = [lambda k, inst: (float(tau_m[k]), float(tau_L[k]))] * 4
            steps = OPEN_STEPS
        else:
            h = np.full(500, 0.01)
            t = np.arange(501) * 0.01
            w_ref, load = pi_inputs()
            steps = len(h)

            def closed(pi):
                return lambda k, inst: (pi(w_ref(k * 0.01), inst.get("omega_m")[0]), load(k * 0.01))

            inputs = [closed(reference.SampledPI(gains["Kp"], gains["Ki"], 0.01)) for _ in range(3)]
        expected = _snapshot(two, names)
        assert all(_snapshot(i, names) == expected for i in threes)
        contacts = [expected[-1]]
        for k in range(steps):
            tau = inputs[0](k, two)
            two.step(float(t[k]), float(h[k]), tau_m=tau[0], tau_L=tau[1])
            expected = _snapshot(two, names)
            contacts.append(expected[-1])
            for j, inst in enumerate(threes):
                assert inputs[j + 1](k, inst) == tau, (k, j)
                answer = inst.step(float(t[k]), float(h[k]), tau_m=tau[0], tau_L=tau[1])
                assert answer == (False, False, False, float(t[k]) + float(h[k])), (k, answer)
                assert _snapshot(inst, names) == expected, (k, inst.fmu.instanceName)
    finally:
        two.free()
        for inst in threes:
            inst.free()
    changes = np.count_nonzero(np.diff(contacts))
    # contact changes seen at the communication points: 41, 33 open loop; 10, 11 closed loop
    assert changes >= (20 if loop == "open" else 8) and set(contacts) == {FREE, PLUS, MINUS}, changes


# --- 3. early return at the contact switches ---------------------------------------------------------

EARLY_STEPS = 40
EARLY_TORQUE = 2.0  # N.m at the motor's lever r_m = 1 m: divided by r_m (the belts': 0.1 m)
SWITCH_TIME_TOL = 1e-12  # s
ROUND_OFF_TOL = 1e-11  # relative, see test


def _early_scenario(model: str):
    """Torques reversed at every step of a quarter of the contact oscillation period
    2 pi / omega_0 (omega_0 = sqrt(K (r_m^2/J_m + r_L^2/J_L)), docs/model.md §2), amplitude
    varying, against a slowly varying load: the drive hits and leaves both flanks, sometimes
    twice in one step."""
    p = plant_of(model, RIGS[model][0])
    w0 = math.sqrt(p.K * (p.r_m**2 / p.J_m + p.r_L**2 / p.J_L))
    h = round(0.25 * 2 * math.pi / w0, 3)
    k = np.arange(EARLY_STEPS)
    tau_m = EARLY_TORQUE / p.r_m * np.where(k % 2 == 0, 1.0, -1.0) * (1.0 + 0.3 * np.sin(0.7 * k))
    tau_L = 0.4 * np.sin(0.3 * k)
    return p, h, tau_m, tau_L


_exact_cache: dict = {}


def _exact_early(model: str):
    if model not in _exact_cache:
        p, h, tau_m, tau_L = _early_scenario(model)
        holds = rc.open_loop_holds(tau_m, tau_L, h)
        t_k = np.arange(EARLY_STEPS + 1) * h
        at_points = rc.solve(p, holds, t_k)
        at_switches = rc.solve(p, holds, [0.0, *(s[0] for s in at_points.switches)])
        _exact_cache[model] = (at_points, at_switches)
    return _exact_cache[model]


def _early_run(fmu3, params, h, tau_m, tau_L, names, event_mode: bool):
    """Steps from each communication point t_k to t_k+1, continued from every early return
    with doStep(lastSuccessfulTime, t_k+1 - lastSuccessfulTime) (in Event Mode and back in
    between when eventModeUsed). Returns the rows at the t_k, and per early return
    (time, contact before, contact after, states, event indicators, step k)."""
    inst = fmu3.co_simulation(f"early-{event_mode}", params, early_return=True, event_mode=event_mode)
    rows, returns, updates = [inst.get(*names)], [], []
    try:
        for k in range(EARLY_STEPS):
            t, t_end = k * h, (k + 1) * h
            inst.set_inputs(tau_m=float(tau_m[k]), tau_L=float(tau_L[k]))
            while True:
                before = contact(inst)
                event, terminate, early, last = inst.do_step(t, t_end - t)
                assert not terminate
                if not early:
                    assert not event and last == t + (t_end - t)
                    break
                assert event == event_mode and t < last < t_end, (t, last, t_end)
                returns.append((last, before, contact(inst), inst.get(*STATES), inst.get("u_minus_g", "u_plus_g"), k))
                if event_mode:
                    inst.fmu.enterEventMode()
                    updates.append(inst.fmu.updateDiscreteStates())
                    inst.fmu.enterStepMode()
                t = last
            rows.append(inst.get(*names))
    finally:
        inst.free()
    return np.array(rows), returns, updates


# The two-stage gearbox's: test_two_stage.py::test_early_return_at_every_switch_of_either_mesh.
@pytest.mark.parametrize("model", archives.SINGLE_GAP, indirect=True)
@pytest.mark.parametrize("event_mode", [False, True], ids=["no-event-mode", "event-mode"])
def test_early_return_at_every_switch(model, event_mode):
    """earlyReturnAllowed (docs/model.md §7), open loop, rig parameters, torques reversed every
    quarter period of the contact oscillation (30 switches for the shaft, 31 for the belt, up to
    two in one step): the FMU returns early exactly at the switches of the exact solution, none
    missed, none extra, in order; each lastSuccessfulTime within 1e-12 s of the exact instant
    (measured 4e-14 s shaft, 6e-15 s belt); mode before and after as `contact` reads them before
    the step and after the early return; the state there within 1e-11 relative of the exact
    state at the exact instant (measured 1.7e-13 shaft, 6e-14 belt), with u exactly on the
    flank (the event indicator u -+ g reads 0.0: the FMU sets u to +-g at a located switch,
    docs/model.md §2).
    With eventModeUsed each early return asks for Event Mode and fmi3UpdateDiscreteStates asks
    for nothing.

    At the communication points every Float64 variable agrees with the run without early return
    (an FMI 3.0 instance of the same rig) to 1e-11 of each signal's largest magnitude. The two
    runs compute the same exact solution but restart the propagation at different instants (the
    early-return run cuts the step at each switch, and its continuation step has another
    length, hence other exponentials and other pieces), so they differ by round-off carried
    along the lightly damped oscillation: measured 2.3e-13 at most (shaft: der(omega_L) and psi,
    i.e. K (u -+ g), whose round-off is that of u against its small range; belt 4e-14), 6e-16
    for bound and bound_paper. The allowance is 40 times the largest measurement."""
    params = _rig(model)
    p, h, tau_m, tau_L = _early_scenario(model)
    exact, exact_sw = _exact_early(model)
    t_k = exact.t
    switch_times = np.array([s[0] for s in exact.switches])
    # The scenario itself: enough switches, some steps with two, none on a communication point
    # (a switch there to round-off is not an early return, docs/model.md §7).
    assert len(switch_times) >= 15
    assert np.max(np.bincount(np.searchsorted(t_k, switch_times) - 1)) >= 2
    assert np.min(np.abs(switch_times[:, None] - t_k[None, :])) > 1e-6

    fmu3 = archives.require(model, fmi=3)
    names = float64_names(fmu3)
    rows, returns, updates = _early_run(fmu3, params, h, tau_m, tau_L, names, event_mode)

    assert len(returns) == len(exact.switches), ([r[0] for r in returns], list(switch_times))
    for (t_fmu, before, after, z, ind, _), (t_ref, m0, m1) in zip(returns, exact.switches):
        assert abs(t_fmu - t_ref) <= SWITCH_TIME_TOL, (t_fmu, t_ref)
        assert (before, after) == (m0, m1), (t_ref, before, after, m0, m1)
        level = 0 if PLUS in (m0, m1) else 1  # u - g on the positive flank, u + g on the negative
        assert ind[level] == 0.0, (t_ref, ind)
    z_fmu = np.array([r[3] for r in returns])
    for j, name in enumerate(STATES):
        assert rel_err(z_fmu[:, j], exact_sw.z[1:, j]) <= ROUND_OFF_TOL, name
    if event_mode:
        assert len(updates) == len(returns)
        assert all(not u[0] and not u[1] and not u[2] and not u[3] and not u[4] for u in updates), updates

    plain = fmu3.co_simulation("plain", params)
    try:
        ref_rows = [plain.get(*names)]
        for k in range(EARLY_STEPS):
            plain.step(k * h, h, tau_m=float(tau_m[k]), tau_L=float(tau_L[k]))
            ref_rows.append(plain.get(*names))
    finally:
        plain.free()
    ref_rows = np.array(ref_rows)
    for j, name in enumerate(names):
        if name == "bound_sup":
            assert np.array_equal(rows[:, j], ref_rows[:, j])
            continue
        assert rel_err(rows[:, j], ref_rows[:, j]) <= ROUND_OFF_TOL, name
    # and the plain run is the exact solution at the communication points
    for j, name in enumerate(STATES):
        assert rel_err(ref_rows[:, names.index(name)], exact.z[:, j]) <= ROUND_OFF_TOL, name


# --- 4. a PI loop updated at every early return --------------------------------------------------------

PI_H = 0.01
PI_PERIOD = 40  # steps per value of the speed reference
PI_REFERENCE = (3.0, -2.0, 4.0, -4.0, 1.5, -3.0, 2.5, -1.0)  # rad/s, reversing: the gap is crossed
PI_N = PI_PERIOD * len(PI_REFERENCE)
PI_TOL = 1e-9


def _pi_w_ref(k: int) -> float:
    return PI_REFERENCE[k // PI_PERIOD]


def _pi_load(k: int) -> float:
    return 0.3 if k < 120 else (-1.0 if k < 220 else 0.5)


def _fmu_switch_sampled_loop(fmu3, params, gains, states=STATES, read_contact=contact):
    """The loop of reference_switch_sampled.SwitchSampledPI closed by an importer through fmpy: at t_k the PI
    is sampled from the omega_m read there and tau_m set (Step Mode); at each early return the
    importer enters Event Mode, samples the PI from the omega_m at the switch, sets tau_m
    (applied from the switch on), calls fmi3UpdateDiscreteStates and returns to Step Mode.
    `states` are recorded at the t_k; each switch as (time, read_contact before, after)."""
    inst = fmu3.co_simulation("switch-pi", params, early_return=True, event_mode=True)
    pi = rss.SwitchSampledPI(gains["Kp"], gains["Ki"])
    z, xi, instants, switches, updates = [inst.get(*states)], [pi.xi], [], [], []
    try:
        t = 0.0
        for k in range(PI_N):
            t_end = (k + 1) * PI_H
            instants.append(t)
            inst.set_inputs(tau_m=pi.sample(_pi_w_ref(k), inst.get("omega_m")[0]), tau_L=_pi_load(k))
            while True:
                before = read_contact(inst)
                event, terminate, early, last = inst.do_step(t, t_end - t)
                assert not terminate
                if not early:
                    assert not event
                    pi.advance(t_end - t)
                    t = t_end
                    break
                assert event and t < last < t_end
                pi.advance(last - t)
                t = last
                switches.append((t, before, read_contact(inst)))
                inst.fmu.enterEventMode()
                instants.append(t)
                inst.set_inputs(tau_m=pi.sample(_pi_w_ref(k), inst.get("omega_m")[0]), tau_L=_pi_load(k))
                updates.append(inst.fmu.updateDiscreteStates())
                inst.fmu.enterStepMode()
            z.append(inst.get(*states))
            xi.append(pi.xi)
    finally:
        inst.free()
    return np.array(z), np.array(xi), instants, switches, updates


TWO_STAGE = "BacklashTwoStage"
TWO_STAGE_STATES = ("theta_m", "omega_m", "theta_i", "omega_i", "theta_L", "omega_L")
# reference_two_stage's resolution (test_two_stage.py): its DOP853 at rtol 1e-13 locates a switch
# within ~1e-12 s (measured 7.9e-13 against the FMU) and its states are good to ~2e-10 relative.
TWO_STAGE_SWITCH_TOL = 1e-11  # s


def _meshes(inst) -> tuple[int, ...]:
    """A gearbox's contact_1 and contact_2."""
    return tuple(inst.integers("contact_1", "contact_2"))


def _two_stage_switch_sampled_pi(params: dict, Kp: float, Ki: float) -> rss.SwitchSampledRun:
    """The loop of SwitchSampledPI closed around reference_two_stage's plant (the equations of
    docs/model.md §10 integrated by DOP853 at rtol 1e-13 in each tuple of the meshes' modes):
    from each sampling instant to the first switch of either mesh (a terminal event on
    u_j -+ Delta_j, as reference_two_stage locates them) or the next communication point; at a
    switch the mesh's mode changes, the PI is sampled there and a new hold starts. Switches as
    (time, mesh 0 or 1, mode before, mode after)."""
    box = ref2.Gearbox.of(params)
    x = box.to_internal(np.zeros(6))
    pi = rss.SwitchSampledPI(Kp, Ki)
    run = rss.SwitchSampledRun(np.arange(PI_N + 1) * PI_H, np.zeros((PI_N + 1, 6)), np.zeros(PI_N + 1))
    run.z[0], run.xi[0] = box.to_state(x), pi.xi
    t, modes = 0.0, None
    for k in range(PI_N):
        t_end = float(run.t[k + 1])
        while True:
            run.instants.append(t)
            tau = pi.sample(_pi_w_ref(k), float(x[1]))
            run.taus.append(tau)
            if modes is None:
                modes = box.entering(x, tau, _pi_load(k))
            events = []  # (event, mesh, the mesh's next mode)
            for mesh, index in ((0, 2), (1, 4)):
                g = box.gap(mesh)
                for side, next_mode in ((1.0, PLUS), (-1.0, MINUS)):
                    if modes[mesh] not in (FREE, next_mode):
                        continue

                    def crossing(_t, y, i=index, level=side * g):
                        return y[i] - level

                    crossing.terminal = True
                    # free: entering contact outwards; in contact: leaving it inwards
                    crossing.direction = side if modes[mesh] == FREE else -side
                    events.append((crossing, mesh, next_mode if modes[mesh] == FREE else FREE))
            sol = solve_ivp(box.rhs(modes, tau, _pi_load(k)), (t, t_end), x, method="DOP853", rtol=1e-13, atol=1e-17,
                            events=[e for e, _, _ in events])
            assert sol.status in (0, 1), sol.message
            if sol.status == 0:
                pi.advance(t_end - t)
                t, x = t_end, sol.y[:, -1].copy()
                break
            hit = min((float(te[0]), i) for i, te in enumerate(sol.t_events) if len(te))[1]
            t_ev, x = float(sol.t_events[hit][0]), sol.y_events[hit][0].copy()
            _, mesh, to = events[hit]
            run.switches.append((t_ev, mesh, modes[mesh], to))
            modes = tuple(to if j == mesh else m for j, m in enumerate(modes))
            pi.advance(t_ev - t)
            t = t_ev
        run.z[k + 1], run.xi[k + 1] = box.to_state(x), pi.xi
    return run


def test_pi_loop_updated_at_every_early_return(model):
    """The loop (reference_switch_sampled.SwitchSampledPI): a PI on omega_m sampled at the communication
    points t_k = k 10 ms AND at every contact switch, tau_m = Kp e + Ki xi held from each sampling
    instant to the next, xi the exact integral of the held error; w_ref (reversing every 0.4 s)
    and tau_L held per step. Closed by the importer at the early returns (eventModeUsed), against
    reference_switch_sampled.switch_sampled_pi, which closes the same loop around the exact plant of
    reference_continuous.py and finds each switch itself (the hold changes there, so the exact
    solution is built segment by segment from one sampling instant to the next).

    Same switches in the same order (15 shaft, 17 belt, modes as `contact` reads them), the same
    sampling instants within 1e-12 s, and the states and xi at the t_k within 1e-9 relative
    (measured: switch times within 4e-16 s, states 3e-15). fmi3UpdateDiscreteStates never asks
    for anything. The loop is not the plain sampled one: closing reference.SampledPI at the t_k
    only (no update at the switches) on a plain FMI 3.0 instance moves the states by far more
    than the tolerance (asserted > 1e3 PI_TOL), so the comparison tells the loops apart.

    The two-stage gearbox: the same loop around reference_two_stage's plant
    (_two_stage_switch_sampled_pi), every switch of either mesh a sampling instant; the FMU's
    switches read as the mesh whose contact_j changed at the early return. Same switches (mesh,
    modes) in order, switch and sampling instants within TWO_STAGE_SWITCH_TOL, the six states and
    xi within PI_TOL, 1e-9, as test_two_stage.py's loop against the same reference (measured:
    30 switches of both meshes, instants within 1.4e-14 s, states 4.3e-13 (omega_i), xi 8e-15;
    the plain loop differs by 2.6e-3 to 1e-2)."""
    params, gains = RIGS[model]
    fmu3 = archives.require(model, fmi=3)
    if model == TWO_STAGE:
        exact = _two_stage_switch_sampled_pi(params, gains["Kp"], gains["Ki"])
        assert {s[1] for s in exact.switches} == {0, 1}, "both meshes switch"
        z, xi, instants, raw, updates = _fmu_switch_sampled_loop(
            fmu3, {**params, **gains}, gains, TWO_STAGE_STATES, _meshes
        )
        switches = []
        for t, before, after in raw:
            changed = [j for j in range(2) if before[j] != after[j]]
            assert len(changed) == 1, (t, before, after)  # the scenario has no simultaneous switches
            switches.append((t, changed[0], before[changed[0]], after[changed[0]]))
        # One switch falls 1.2e-7 s from a communication point: 1e4 times the resolution, so the
        # FMU and the reference put it on the same side of it.
        states, switch_tol, margin = TWO_STAGE_STATES, TWO_STAGE_SWITCH_TOL, 1e3 * TWO_STAGE_SWITCH_TOL
    else:
        plant = plant_of(model, params)
        exact = rss.switch_sampled_pi(plant, gains["Kp"], gains["Ki"], PI_H, PI_N, _pi_w_ref, _pi_load)
        z, xi, instants, switches, updates = _fmu_switch_sampled_loop(fmu3, {**params, **gains}, gains)
        states, switch_tol, margin = STATES, SWITCH_TIME_TOL, 1e-6
    assert len(exact.switches) >= 10
    assert np.min(np.abs(np.array([s[0] for s in exact.switches])[:, None] - exact.t[None, :])) > margin

    assert [s[1:] for s in switches] == [s[1:] for s in exact.switches]
    assert max(abs(a[0] - b[0]) for a, b in zip(switches, exact.switches)) <= switch_tol
    assert len(instants) == len(exact.instants) == PI_N + len(exact.switches)
    assert max(abs(a - b) for a, b in zip(instants, exact.instants)) <= switch_tol
    errors = {name: rel_err(z[:, j], exact.z[:, j]) for j, name in enumerate(states)}
    errors["xi"] = rel_err(xi, exact.xi)
    assert max(errors.values()) <= PI_TOL, errors
    assert all(not any(u[:5]) for u in updates), updates

    # The same PI updated at the t_k only, on a plain instance: another loop.
    plain = fmu3.co_simulation("plain-pi", {**params, **gains})
    try:
        pi = reference.SampledPI(gains["Kp"], gains["Ki"], PI_H)
        zp = [plain.get(*states)]
        for k in range(PI_N):
            plain.step(k * PI_H, PI_H, tau_m=pi(_pi_w_ref(k), plain.get("omega_m")[0]), tau_L=_pi_load(k))
            zp.append(plain.get(*states))
    finally:
        plain.free()
    zp = np.array(zp)
    assert max(rel_err(zp[:, j], exact.z[:, j]) for j in range(len(states))) > 1e3 * PI_TOL


# --- 5. Model Exchange -----------------------------------------------------------------------------



# The two-stage gearbox's: test_two_stage.py::test_model_exchange_with_cvode_converges_to_the_reference.
@pytest.mark.parametrize("model", archives.SINGLE_GAP, indirect=True)
def test_simulate_fmu_model_exchange_with_cvode(model):
    """fmpy.simulate_fmu(fmi_type='ModelExchange', solver='CVode', rtol 1e-9) of the FMI 3.0
    archive (fmpy's FMU3Model: fmi3GetContinuousStateDerivatives, the event indicators u_minus_g
    and u_plus_g as CVode's roots, fmi3UpdateDiscreteStates at events) under reversing torques
    held for 0.1 s each (fmpy input events), from a moving start, against the exact solution at
    the output points. The tolerance is that of test_model_exchange.py for the FMI 2.0 archive
    through the same solver, 2000 rtol on states, u and psi: CVode controls only its local
    error, and over 4 s of lightly damped oscillation and ~70 restarts its global error was
    measured there at 560 rtol; measured here 5.6e-7 (shaft), 4.4e-7 (belt), the same as FMI 2.0.
    Every switch is reported as a state event (a repeated output time off the input edges),
    each within the shift that error makes at the crossing speed, 2e-6 max|u| / |u'|."""
    params = RIGS[model][0]
    check_cvode_against_exact(str(fmu_path(model, 3)), params, plant_of(model, params))


def _two_stage_me_cases(params: dict, rng) -> list:
    """60 (time, z, torques) of the gearbox: each mesh's u_j = theta_in - n_j theta_out within
    +-3 Delta_j, angles up to 10 rad, speeds up to 5 rad/s; the first 6 with one mesh on a flank
    to round-off, each mesh on each flank (u_j = +-Delta_j exactly: its input angle is +-Delta_j
    and its output angle 0)."""
    n, gap = (params["n_1"], params["n_2"]), (params["Delta_1"], params["Delta_2"])
    cases = []
    for i in range(60):
        u = [rng.uniform(-3.0, 3.0) * g for g in gap]
        theta_L = rng.uniform(-10, 10)
        if i < 6:
            side = 1.0 if (i // 2) % 2 == 0 else -1.0
            if i % 2 == 0:  # the first mesh: theta_i = 0, theta_m = +-Delta_1
                theta_i, theta_m = 0.0, side * gap[0]
                theta_L = -u[1] / n[1]
            else:  # the second: theta_L = 0, theta_i = +-Delta_2
                theta_L, theta_i = 0.0, side * gap[1]
                theta_m = u[0] + n[0] * theta_i
        else:
            theta_i = u[1] + n[1] * theta_L
            theta_m = u[0] + n[0] * theta_i
        w = rng.uniform(-5, 5, 3)
        z = np.array([theta_m, w[0], theta_i, w[1], theta_L, w[2]])
        cases.append((float(rng.uniform(0.0, 3.0)), z, rng.uniform(-3, 3, 2)))
    return cases


def test_model_exchange_equals_fmi2_model_exchange(model):
    """At 60 seeded states (u within +-3 g, angles up to 10 rad, and 6 states on +-g to
    round-off, where the mode being entered counts) and inputs: the FMI 3.0 instance's derivatives,
    event indicators, every Float64 variable (psi, der(...), u_minus_g, u_plus_g, bounds at the
    set time), contact and the directional derivatives of the derivatives with respect to
    states and inputs equal the FMI 2.0 instance's bit for bit; so do the nominals and the
    answers after initialisation (no discrete-state update, no next event time) and of
    fmi3CompletedIntegratorStep (no Event Mode).

    The two-stage gearbox: the same at its six states (_two_stage_me_cases: each mesh's u_j within
    +-3 Delta_j, six states with one mesh on a flank), its 18 event indicators, both contact_j
    (each mesh in all three modes) and the directional derivatives with respect to its six
    states. Bit for bit is right here: one Rust binary, the same arithmetic behind both
    standards' calls."""
    params = _rig(model)
    fmu2, fmu3 = archives.require(model), archives.require(model, fmi=3)
    names = float64_names(fmu3)
    two = fmu2.model_exchange("me2", params)
    three = fmu3.model_exchange("me3", params)
    rng = np.random.default_rng(11)
    if model == TWO_STAGE:
        states, contacts_of = TWO_STAGE_STATES, _meshes
        cases = _two_stage_me_cases(params, rng)
        assert three.nx == len(states)
    else:
        states, contacts_of = STATES, contact
        plant = plant_of(model, params)
        cases = []
        for i in range(60):
            u = rng.uniform(-3.0, 3.0) * plant.g if i >= 6 else (plant.g if i % 2 else -plant.g)
            z = state_with_u(plant, u, rng.uniform(-10, 10), rng.uniform(-5, 5), rng.uniform(-5, 5))
            if i < 6:  # on a flank to round-off: theta_L = 0, theta_m = +-g / r_m
                z[0], z[2] = u / plant.r_m, 0.0
            cases.append((float(rng.uniform(0.0, 3.0)), z, rng.uniform(-3, 3, 2)))
    knowns = [*states, "tau_m", "tau_L"]
    ders = [f"der({s})" for s in states]
    try:
        assert not any(three.initial_update[:5])
        assert bits(three.nominals()) == bits(two.nominals())
        # In time order: each case ends with fmi3CompletedIntegratorStep, and time may not go back
        # over the second-last one (FMI 3.0.2 §3.2.1).
        cases.sort(key=lambda case: case[0])
        contacts = set()
        for t, z, tau in cases:
            (d2, i2), (d3, i3) = ((inst.derivatives(t, z, *tau), inst.indicators(t, z)) for inst in (two, three))
            assert bits(d3) == bits(d2), (t, z, tau)
            assert bits(i3) == bits(i2), (t, z)
            assert bits(three.get(*names)) == bits(two.get(*names)), (t, z)
            contacts.add(contacts_of(three))
            assert contacts_of(three) == contacts_of(two)
            for k in knowns:
                j2 = two.fmu.getDirectionalDerivative([two.vr[n] for n in ders], [two.vr[k]], [1.0])
                j3 = three.fmu.getDirectionalDerivative([three.vr[n] for n in ders], [three.vr[k]], [1.0])
                assert bits(j3) == bits(j2), (k, z)
            assert three.fmu.completedIntegratorStep() == (False, False)
        if model == TWO_STAGE:
            assert all({c[j] for c in contacts} == {FREE, PLUS, MINUS} for j in range(2)), contacts
        else:
            assert contacts == {FREE, PLUS, MINUS}
    finally:
        two.free()
        three.free()


# --- 6. FMU states carry their standard ----------------------------------------------------------------

STATE_H, STATE_N, STATE_AT = 0.05, 120, 60


def _drive3(inst: CoSimulation, k0: int, k1: int, tau_m, tau_L, names) -> list:
    """Every doStep answer and every output after it, as exact floats (early returns continued)."""
    rows = []
    for k in range(k0, k1):
        t, t_end = k * STATE_H, (k + 1) * STATE_H
        inst.set_inputs(tau_m=float(tau_m[k]), tau_L=float(tau_L[k]))
        while True:
            answer = inst.do_step(t, t_end - t)
            rows.append((answer, bits(inst.get(*names)), contact(inst)))
            if not answer[2]:
                break
            t = answer[3]
    return rows


def test_fmi2_state_is_refused_and_fmi3_state_continues_bit_for_bit(model):
    """An FMI 2.0 Co-Simulation instance's serialized state given to an FMI 3.0 Co-Simulation
    instance is refused (fmi3DeserializeFMUState or fmi3SetFMUState: fmi3Error) with a logged
    reason naming both standards, and changes nothing (every Float64 variable and contact as
    before, none NaN); likewise the other way round, and an FMI 3.0 Co-Simulation state given
    to an FMI 3.0 Model Exchange instance. An FMI 3.0 state (taken with early return allowed, in
    the middle of a run that keeps switching contact) continues bit for bit: in the same
    instance after fmi3SetFMUState, and, serialized, in a fresh instance of a separately
    unpacked copy initialised with other parameters: every answer of fmi3DoStep (early returns,
    lastSuccessfulTime) and every output after it."""
    params = _rig(model)
    gaps = {name: params[name] * 0.9 for name in archives.gap_parameters(model)}
    other = {**params, **gaps, "Kp": params["Kp"] * 0.9}
    fmu2, fmu3 = archives.require(model), archives.require(model, fmi=3)
    names = float64_names(fmu3)
    tau_m, tau_L = reversing_torques(STATE_N, STATE_H, 1.5, 0.6)
    if model != "BacklashShaft":
        tau_m = tau_m * 10.0  # the belt's motor acts through r_m = 0.1 m

    # FMI 2.0 state -> FMI 3.0 instance
    two = fmu2.co_simulation("fmi2-state", params)
    try:
        for k in range(STATE_AT):
            two.step(k * STATE_H, STATE_H, tau_m=float(tau_m[k]), tau_L=float(tau_L[k]))
        state2 = two.fmu.getFMUstate()
        blob2 = two.fmu.serializeFMUstate(state2)
        two.fmu.freeFMUstate(state2)
    finally:
        two.free()
    three = fmu3.co_simulation("refuses-fmi2", params)
    try:
        three.step(0.0, STATE_H, tau_m=1.0, tau_L=0.0)
        before = (bits(three.get(*names)), contact(three))

        def load_fmi2_state():
            restored = three.fmu.deserializeFMUState(blob2)
            three.fmu.setFMUState(restored)

        three.refused(load_fmi2_state, "FMI 2.0", "FMI 3.0")
        assert (bits(three.get(*names)), contact(three)) == before
        assert not any(math.isnan(x) for x in three.get(*names))
    finally:
        three.free()

    # FMI 3.0 run with early return; state at a communication point
    original = fmu3.co_simulation("original", params, early_return=True)
    try:
        _drive3(original, 0, STATE_AT, tau_m, tau_L, names)
        state = original.fmu.getFMUState()
        blob3 = original.fmu.serializeFMUState(state)
        continuation = _drive3(original, STATE_AT, STATE_N, tau_m, tau_L, names)
        original.fmu.setFMUState(state)
        original.fmu.freeFMUState(state)
        assert _drive3(original, STATE_AT, STATE_N, tau_m, tau_L, names) == continuation
    finally:
        original.free()
    assert sum(1 for row in continuation if row[0][2]) >= 10, "the continuation must return early"
    assert {row[2] for row in continuation} == {FREE, PLUS, MINUS}

    fresh = archives.separate_copy(model, fmi=3).co_simulation("fresh", other, early_return=True)
    try:
        restored = fresh.fmu.deserializeFMUState(blob3)
        fresh.fmu.setFMUState(restored)
        fresh.fmu.freeFMUState(restored)
        assert fresh.get(*params) == [float(v) for v in params.values()]
        assert _drive3(fresh, STATE_AT, STATE_N, tau_m, tau_L, names) == continuation
    finally:
        fresh.free()

    # FMI 3.0 Co-Simulation state -> FMI 2.0 Co-Simulation and FMI 3.0 Model Exchange instances
    two = fmu2.co_simulation("refuses-fmi3", params)
    try:
        two.fmu.doStep(0.0, STATE_H)
        before = (bits(two.get(*names)), contact(two))
        with pytest.raises(FMICallException) as refusal:
            two.fmu.setFMUstate(two.fmu.deSerializeFMUstate(blob3))
        assert refusal.value.status == fmi3Error  # fmi2Error, the same code
        reasons = [m[2] for m in two.messages if m[1] == "logErrors"]
        assert any("FMI 2.0" in r and "FMI 3.0" in r for r in reasons), two.messages
        assert (bits(two.get(*names)), contact(two)) == before
    finally:
        two.fmu.freeInstance()  # in the Error state, where fmi2Terminate is not allowed
    me = fmu3.model_exchange("refuses-cs", params)
    try:
        me.refused(lambda: me.fmu.setFMUState(me.fmu.deserializeFMUState(blob3)), "Co-Simulation", "Model Exchange")
    finally:
        me.free()


# --- 7. misuse ---------------------------------------------------------------------------------------


MISUSE = {
    # name: (instance options, call, words the logged reason must contain)
    "doStep with a NaN step": ({}, lambda s: s.do_step(s.time, math.nan), ("communicationStepSize",)),
    "doStep with a NaN time": ({}, lambda s: s.do_step(math.nan, 0.01), ("currentCommunicationPoint",)),
    "enterEventMode without eventModeUsed": ({}, lambda s: s.fmu.enterEventMode(), ("eventModeUsed",)),
    "fmi3GetClock": ({}, lambda s: s.fmu.getClock([s.vr[archives.contact_output(s.archive.model)]]), ("clocks",)),
    "fmi3SetClock": (
        {},
        lambda s: s.fmu.setClock([s.vr[archives.contact_output(s.archive.model)]], [True]),
        ("clocks",),
    ),
    "doStep in Event Mode": (
        {"event_mode": True},
        lambda s: (s.fmu.enterEventMode(), s.do_step(s.time, 0.01)),
        ("fmi3DoStep", "EventMode"),
    ),
}


@pytest.mark.parametrize("case", MISUSE)
def test_misuse_is_refused_with_a_reason(model, case):
    """Each misuse on an instance that has taken a few steps (so that its outputs are not the
    start values): fmi3Error with a reason under logErrors; every Float64 variable and contact
    unchanged after it, none NaN; fmi3Reset from the Error state, the same experiment again,
    and the instance reproduces a fresh instance bit for bit."""
    options, call, mentions = MISUSE[case]
    fmu3 = archives.require(model, fmi=3)
    names = float64_names(fmu3)
    params = _rig(model)

    def run(inst):
        out = []
        for k in range(5):
            if inst.event_mode:
                inst.fmu.enterEventMode()
            inst.set_inputs(tau_m=50.0 * (k - 1.5), tau_L=0.2)
            if inst.event_mode:
                inst.fmu.updateDiscreteStates()
                inst.fmu.enterStepMode()
            assert not inst.do_step(k * 0.02, 0.02)[2]
            out.append((bits(inst.get(*names)), contact(inst)))
        return out

    reference_run = fmu3.co_simulation("reference", params, **options)
    try:
        expected = run(reference_run)
    finally:
        reference_run.free()
    inst = fmu3.co_simulation("misuse", params, **options)
    try:
        assert run(inst) == expected
        before = (bits(inst.get(*names)), contact(inst))
        inst.refused(lambda: call(inst), *mentions)
        assert (bits(inst.get(*names)), contact(inst)) == before
        assert not any(math.isnan(x) for x in inst.get(*names))
        assert inst.fmu.reset() == 0
        inst.initialise(0.0)
        assert run(inst) == expected
    finally:
        inst.free()

"""FMI 2.0 Model Exchange of every FMU (the web line's web decoupled): the right-hand side of
docs/model.md §1 as an importer's integrator sees it, against independent references.

References (none takes a number from the FMU; the two-stage gearbox's, docs/model.md §10, are
its equations in reference_two_stage.py: its field, exact Jacobian, nominals and a loop closed
around it by an event-located DOP853):
- reference_continuous.py: the exact solution (matrix exponentials, switches found with brentq)
  of the plant under a continuous-time PI; checked first, below, against reference.py (an
  event-located DOP853 integration), a direct expm of the linear loop and a grazing touch.
- The Jacobians of docs/model.md §3 (Plant.linear_matrices), central differences of the FMU's
  own getDerivatives, and the Co-Simulation archive's `bound` at the same time.

Normalisation of every "relative" error below: signals.rel_err, max |actual - expected| over
the run divided by max |expected| over the run, per signal (stays meaningful where a signal
crosses zero: speeds reverse, psi is 0 in the gap)."""

from __future__ import annotations

import ctypes
import functools
import math

import numpy as np
import pytest
from backlash_fmu.fmu import EVENT_INDICATORS, STATES, ModelExchange
from fmpy.validation import validate_fmu
from scipy.integrate import solve_ivp
from scipy.linalg import expm

import archives
import reference
import reference_continuous as rc
import reference_two_stage as ref2
from cvode_check import check_cvode_against_exact
from loops import DERIVATIVES, LoopRun, PythonGearbox, PythonPlant, outputs_along, run_loop, state_with_u
from reference import FREE, MINUS, PLUS
from reference_bound import loop_matrices
from rigs import RIGS, TWO_STAGE_GEARED, plant_of, with_delta
from signals import rel_err, reversing_torques

MODELS = archives.MODELS
# The gearboxes (docs/model.md §10: BacklashTwoStage), whose expectations come from the
# equations of its stages (reference_two_stage.py) rather than the single gap's plant.
GEARBOXES = tuple(m for m in MODELS if m not in archives.SINGLE_GAP)
EPS = np.finfo(float).eps


def state_names(archive) -> tuple[str, ...]:
    """The continuous states of a model, as its <Derivatives> list them."""
    return tuple(d.variable.derivative.name for d in archive.md.derivatives)


def gear_indicators(archive) -> tuple[str, ...]:
    """The event indicators' variables of a gearbox in their order (docs/model.md §10: the locals
    other than the derivatives, u_minus_g_1 ... breakaway_L, in value-reference order)."""
    locals_ = [v for v in archive.md.modelVariables if v.causality == "local" and v.derivative is None]
    names = tuple(v.name for v in sorted(locals_, key=lambda v: v.valueReference))
    assert len(names) == archive.md.numberOfEventIndicators
    return names

# --- scenarios ----------------------------------------------------------------------------------

# Continuous-time PI loop (docs/model.md §3): a speed reference (rad/s) that reverses every 0.4 s
# and a load torque (N.m) that changes twice, both held; the drive crosses the gap at every
# reversal: 23 contact switches for the shaft, 25 for the belt.
LOOP_PERIOD = 0.4
LOOP_REFERENCE = (3.0, -2.0, 4.0, -4.0, 1.5, -3.0, 2.5, -1.0, 3.5, -2.5, 1.0, -0.5)
LOOP_TIMES = np.round(np.linspace(0.0, LOOP_PERIOD * len(LOOP_REFERENCE), 481), 12)


def loop_holds() -> list[rc.Hold]:
    def load(t):
        return 0.3 if t < 2.0 else (-1.0 if t < 3.6 else 0.5)

    return [rc.Hold(k * LOOP_PERIOD, 0.0, load(k * LOOP_PERIOD), w) for k, w in enumerate(LOOP_REFERENCE)]


def held_linear_loop(M: np.ndarray) -> np.ndarray:
    """y' = M y from y = 0, the last two entries of y being [tau_L, w_ref] held as loop_holds()
    holds them: the other entries at LOOP_TIMES, one augmented expm per hold."""
    n = M.shape[0] - 2
    holds, y = loop_holds(), np.zeros(n + 2)
    out = np.zeros((len(LOOP_TIMES), n))
    for k, hold in enumerate(holds):
        end = holds[k + 1].t if k + 1 < len(holds) else LOOP_TIMES[-1]
        y[n:] = hold.tau_L, hold.w_ref
        inside = (LOOP_TIMES >= hold.t) & (LOOP_TIMES <= end)
        out[inside] = (expm((LOOP_TIMES[inside] - hold.t)[:, None, None] * M) @ y)[:, :n]
        y = expm(M * (end - hold.t)) @ y
    return out

@functools.cache
def exact_loop(model: str, delta: float | None = None) -> rc.Trajectory:
    params, gains = RIGS[model]
    params = params if delta is None else with_delta(params, delta)
    return rc.solve(plant_of(model, params), loop_holds(), LOOP_TIMES, **gains)


@functools.cache
def fmu_loop(model: str, delta: float | None = None):
    """The same loop closed around the FMU (Model Exchange, solve_ivp DOP853 rtol 1e-12, atol
    1e-15, the FMU's event indicators as events): the run and the FMU's outputs along it."""
    params, gains = RIGS[model]
    params = params if delta is None else with_delta(params, delta)
    inst = archives.require(model).model_exchange(f"loop-{delta}", {**params, **gains})
    # The outputs along the run are read by a second instance from the start: the first has
    # completed steps and events, over which time cannot go back (FMI 2.0.4 §3.2.2).
    reader = archives.require(model).model_exchange(f"read-{delta}", {**params, **gains})
    try:
        # Delta = 0: linear right-hand side, nothing to locate (run_loop's events=False)
        events = params["Delta"] > 0.0
        run = run_loop(inst, gains["Kp"], gains["Ki"], loop_holds(), LOOP_TIMES, (0.0, 0.0, 0.0, 0.0), events=events)
        out = outputs_along(reader, run)
    finally:
        inst.free()
        reader.free()
    return run, out


@functools.cache
def gear_loop(model: str, delta: float | None = None):
    """fmu_loop for a gearbox: the loop closed around the FMU by run_loop (both gaps at
    `delta` if given), and its outputs along the run read by a second instance."""
    params, gains = RIGS[model]
    params = params if delta is None else with_delta(params, delta)
    inst = archives.require(model).model_exchange(f"gear-loop-{delta}", {**params, **gains})
    reader = archives.require(model).model_exchange(f"gear-read-{delta}", {**params, **gains})
    try:
        # Both gaps 0: a linear right-hand side, nothing to locate (as fmu_loop)
        events = delta != 0.0
        run = run_loop(
            inst, gains["Kp"], gains["Ki"], loop_holds(), LOOP_TIMES, np.zeros(6), events=events, meshes=2
        )
        rows, contacts = [], []
        for t, z in zip(run.t, run.z):
            reader.set_state(t, z)
            rows.append(reader.get("psi_1", "psi_2", "bound"))
            contacts.append(reader.integers("contact_1", "contact_2"))
    finally:
        inst.free()
        reader.free()
    rows = np.array(rows)
    return run, {"psi": rows[:, :2], "bound": rows[:, 2], "contact": np.array(contacts)}


@functools.cache
def reference_gear_loop(model: str, delta: float | None = None) -> ref2.LoopResult:
    """The same loop around the equations (reference_two_stage.run_pi_loop: DOP853 at rtol
    1e-13 inside each tuple of modes, u_j integrated directly, switches as terminal events)."""
    params, gains = RIGS[model]
    params = params if delta is None else with_delta(params, delta)
    return ref2.run_pi_loop(ref2.Gearbox.of(params), gains["Kp"], gains["Ki"], loop_holds(), LOOP_TIMES)


# --- the exact reference itself (no FMU) -----------------------------------------------------


# (step s, steps, initial state) as in scenarios.py: several switches per step when coarse
OPEN_LOOP_CASES = {
    "fine": (0.02, 400, (0.0, 0.0, 0.0, 0.0)),
    "coarse": (0.25, 32, (0.0, 0.0, 0.0, 0.0)),
    "moving": (0.02, 250, (0.01, 1.0, 0.0, -0.5)),
}


@pytest.mark.parametrize("model", archives.SINGLE_GAP)
@pytest.mark.parametrize("case", OPEN_LOOP_CASES)
def test_reference_open_loop_matches_event_located_integrator(model, case):
    """Kp = Ki = 0, torques held per step: reference_continuous against reference.py (DOP853 with
    events, good to ~2e-10 relative by its own tests). Tolerance 1e-9 relative, switch times
    1e-9 s, identical switch sequence. Measured: 1e-10 (belt, 0.25 s steps), 1.3e-11 s."""
    h, n, z0 = OPEN_LOOP_CASES[case]
    plant = plant_of(model, RIGS[model][0])
    tau_m, tau_L = reversing_torques(n, h, 1.5, 0.6)
    z, u, ref = reference.run_open_loop(plant, tau_m, tau_L, h, z0=np.array(z0, dtype=float))
    exact = rc.solve(plant, rc.open_loop_holds(tau_m, tau_L, h), np.arange(n + 1) * h, z0=z0)
    errors = [rel_err(exact.z[:, j], z[:, j]) for j in range(4)] + [rel_err(exact.u, u)]
    assert max(errors) <= 1e-9, errors
    assert len(ref.switches) >= 20
    assert [s[1:] for s in exact.switches] == [s[1:] for s in ref.switches]
    assert max(abs(a[0] - b[0]) for a, b in zip(exact.switches, ref.switches)) <= 1e-9


@pytest.mark.parametrize("model", archives.SINGLE_GAP)
def test_reference_without_backlash_is_the_linear_loop(model):
    """Delta = 0: the loop is linear, z_cl' = A_cl z_cl + G [tau_L, w_ref] with A_cl of
    reference_bound.loop_matrices (theta_L coordinates, built separately from the reference's
    u coordinates); one augmented expm per hold. Tolerance 1e-12 (measured 4e-15)."""
    params, gains = RIGS[model]
    plant = plant_of(model, with_delta(params, 0.0))
    exact = exact_loop(model, 0.0)
    A, _, _ = loop_matrices(plant, gains["Kp"], gains["Ki"])
    _, B = plant.linear_matrices()
    G = np.zeros((5, 2))
    G[:4, 0], G[:4, 1], G[4, 1] = B[:, 1], gains["Kp"] * B[:, 0], 1.0
    M = np.zeros((7, 7))
    M[:5, :5], M[:5, 5:] = A, G
    direct = held_linear_loop(M)
    errors = [rel_err(exact.z[:, j], direct[:, j]) for j in range(4)] + [rel_err(exact.xi, direct[:, 4])]
    assert max(errors) <= 1e-12, errors
    assert exact.switches == []


@pytest.mark.parametrize("depth", [1e-6, 1e-9, 1e-12, -1e-9, -1e-6])
def test_reference_finds_a_grazing_touch(depth):
    """A free motor decelerated through omega_m = 0 (load at rest): u = theta_m - theta_L peaks
    at t* = (J_m/b_m) ln(1 + w0 b_m/|tau|), and the start is chosen so that the peak is
    g (1 + depth). A positive depth is a touch of the flank lasting 2 sqrt(2 g depth / |u''|),
    u'' = tau/J_m (0.2 ms down to 0.2 us, far inside one search cell of 4 ms); a negative one
    never touches. Timing to 1e-3 of the touch's length (the spring acts during it, K g depth
    against |tau| = 1 N.m: 5e-7 and less). Measured: length within 7e-7, 3e-8 and 9e-5 (at depth
    1e-12 the start value itself is rounded by ~1e-4 of the depth), midpoint within 6e-6."""
    plant = plant_of("BacklashShaft", RIGS["BacklashShaft"][0])
    J, b, g, w0, tau = plant.J_m, plant.b_m, plant.g, 0.01, -1.0
    t_peak = (J / b) * math.log1p(w0 * b / -tau)
    # theta_m(t*) - theta_m(0) = (J |tau| / b^2) (x - ln(1 + x)), x = w0 b / |tau|, summed as
    # its series (x = 5e-4): the closed form cancels to ~5e-17 rad, 2 % of the 1e-12 depth.
    x = w0 * b / -tau
    rise = (J * -tau / b**2) * sum((-1) ** k * x**k / k for k in range(12, 1, -1))
    z0 = (g * (1.0 + depth) - rise, w0, 0.0, 0.0)
    exact = rc.solve(plant, [rc.Hold(0.0, tau, 0.0, 0.0)], [0.0, 2 * t_peak], z0=z0)
    if depth < 0.0:
        assert exact.switches == []
        return
    assert [s[1:] for s in exact.switches] == [(FREE, PLUS), (PLUS, FREE)]
    (t_in, _, _), (t_out, _, _) = exact.switches
    length = 2.0 * math.sqrt(2.0 * g * depth / (-tau / J))
    assert abs((t_out - t_in) - length) <= 1e-3 * length
    assert abs(0.5 * (t_in + t_out) - t_peak) <= 1e-3 * length


@pytest.mark.parametrize("model", archives.SINGLE_GAP)
def test_reference_closed_loop_matches_event_located_integrator(model):
    """The PI loop with backlash: reference_continuous against loops.run_loop integrating the
    equations of docs/model.md §1 written in Python (PythonPlant: DOP853 rtol 1e-12 with the
    switches as events): the loop integrator the FMU tests use, on a model known to be right.
    Tolerance 1e-8 relative, as for the FMU below (measured 4e-12 shaft, 9e-12 belt)."""
    params, gains = RIGS[model]
    plant = plant_of(model, params)
    exact = exact_loop(model)
    run = run_loop(PythonPlant(plant), gains["Kp"], gains["Ki"], loop_holds(), LOOP_TIMES, (0.0, 0.0, 0.0, 0.0))
    errors = [rel_err(run.z[:, j], exact.z[:, j]) for j in range(4)] + [rel_err(run.xi, exact.xi)]
    assert max(errors) <= 1e-8, errors
    assert len(exact.switches) >= 20
    assert [s[1:] for s in run.switches] == [s[1:] for s in exact.switches]


@pytest.mark.parametrize("model", GEARBOXES)
def test_gearbox_reference_without_backlash_is_the_linear_loop(model):
    """Both gaps 0: the gearbox's loop is linear, y' = A_cl y + G [tau_L, w_ref] on
    y = [z, xi], A_cl from the equations' Jacobian (Gearbox.jacobian, both meshes in contact)
    and the PI tau_m = Kp (w_ref - omega_m) + Ki xi; one augmented expm per hold, against
    reference_two_stage.run_pi_loop (DOP853 at rtol 1e-13 in u_j coordinates). Tolerance 1e-10
    relative, the reference's rtol with the margin of 4.8 s of oscillation (measured 5.6e-13)."""
    params, gains = RIGS[model]
    box = ref2.Gearbox.of(with_delta(params, 0.0))
    Kp, Ki = gains["Kp"], gains["Ki"]
    A, B, _ = box.jacobian((PLUS, PLUS))
    M = np.zeros((9, 9))
    M[:6, :6] = A
    M[:6, 1] -= Kp * B[:, 0]
    M[:6, 6] = Ki * B[:, 0]
    M[6, 1] = -1.0
    M[:6, 7], M[:6, 8], M[6, 8] = B[:, 1], Kp * B[:, 0], 1.0
    direct = held_linear_loop(M)
    ref = reference_gear_loop(model, 0.0)
    errors = [rel_err(ref.z[:, j], direct[:, j]) for j in range(6)] + [rel_err(ref.xi, direct[:, 6])]
    assert max(errors) <= 1e-10, errors
    assert ref.switches == []


@pytest.mark.parametrize("model", GEARBOXES)
def test_gearbox_loop_integrator_matches_the_reference(model):
    """run_loop, the integrator that closes the loop around a gearbox's FMU, around the
    equations written in Python instead (loops.PythonGearbox: reference_two_stage's
    Gearbox.field and its 18 indicators) against reference_two_stage.run_pi_loop: the loop integrator on a model known
    to be right. Tolerance LOOP_TOL relative as for the FMU below, the same switch sequence
    (measured: 1.1e-11, on omega_i; the FMU's 1.4e-11)."""
    params, gains = RIGS[model]
    model_py = PythonGearbox(ref2.Gearbox.of(params))
    run = run_loop(model_py, gains["Kp"], gains["Ki"], loop_holds(), LOOP_TIMES, np.zeros(6), meshes=2)
    ref = reference_gear_loop(model)
    errors = [rel_err(run.z[:, j], ref.z[:, j]) for j in range(6)] + [rel_err(run.xi, ref.xi)]
    assert max(errors) <= LOOP_TOL, errors
    assert len(ref.switches) >= 20
    assert [s[1:] for s in run.switches] == [s[1:] for s in ref.switches]


# --- the model description --------------------------------------------------------------------


def test_model_description_declares_model_exchange(fmu):
    md = fmu.md
    me = md.modelExchange
    assert me is not None and md.coSimulation is not None, "both interfaces in one archive"
    assert me.modelIdentifier == fmu.path.stem  # the model it was asked for (fmu_path)
    assert me.providesDirectionalDerivative and me.canGetAndSetFMUstate and me.canSerializeFMUstate
    derivatives = [d.variable for d in md.derivatives]  # <ModelStructure><Derivatives>, in order
    if fmu.model == "BacklashTwoStage":
        # docs/model.md §10: six states, the intermediate shaft's between the motor's and the
        # load's; each mesh's six contact surfaces and each body's two friction surfaces.
        assert md.numberOfEventIndicators == 18
        states = ("theta_m", "omega_m", "theta_i", "omega_i", "theta_L", "omega_L")
        derivative_vrs, state_vrs = tuple(range(38, 44)), list(range(3, 9))
    else:
        assert md.numberOfEventIndicators == EVENT_INDICATORS == 10
        # The web line's span tension T is its fifth state (docs/model.md §8).
        web = fmu.model == "BacklashWeb"
        states = (*STATES, "T") if web else STATES
        derivative_vrs, state_vrs = (24, 25, 26, 27, 33), [3, 4, 5, 6, 32][: len(states)]
    assert [d.name for d in derivatives] == [f"der({s})" for s in states]
    for der, state, vr in zip(derivatives, states, derivative_vrs, strict=False):
        assert der.valueReference == vr and der.causality == "local" and der.type == "Real"
        assert der.derivative is fmu.variables[state]
    assert [fmu.vr[s] for s in states] == state_vrs


def test_fmpy_validation_finds_no_problem(fmu):
    """fmpy's validator reads the ModelExchange element, the derivatives and the model
    structure; test_validation.py runs the same call for Co-Simulation."""
    assert validate_fmu(str(fmu.path)) == []


# --- the right-hand side at given states ----------------------------------------------------------


def test_initialisation_asks_for_no_events(fmu):
    """No time events and no discrete states (interface): after initialisation
    fmi2NewDiscreteStates asks for nothing, and fmi2CompletedIntegratorStep never asks for
    Event Mode; the continuous states are the start values."""
    params = RIGS[fmu.model][0]
    z0 = {"theta_m": 0.3, "omega_m": -1.2, "theta_L": 0.25, "omega_L": 0.7}
    if fmu.model in GEARBOXES:
        # Every state of a gearbox takes a start value, the intermediate shaft's too (§10).
        z0 = {"theta_m": 0.3, "omega_m": -1.2, "theta_i": 0.28, "omega_i": -0.4, "theta_L": 0.25, "omega_L": 0.7}
        assert tuple(z0) == state_names(fmu)
    inst = fmu.model_exchange("init", {**params, **z0})
    try:
        needed, terminate, _, _, time_defined, _ = inst.initial_event
        assert not needed and not terminate and not time_defined
        states = inst.continuous_states()
        assert list(states) == list(z0.values())
        assert inst.completed_step() == (False, False)
        needed, terminate, _, _, time_defined, _ = inst.event_iteration()
        assert not needed and not terminate and not time_defined
    finally:
        inst.free()


@pytest.mark.parametrize("delta", ["rig", 0.0])
def test_nominals_of_the_continuous_states(fmu, delta):
    """theta: g/r (1e-4 rad when g = 0), omega: omega_0 times that, with
    omega_0 = sqrt(K (r_m^2/J_m + r_L^2/J_L)) (docs/model.md §2). To 4 ulps (measured: exact).
    A gearbox: each body's angle at the finest gap beside it, Delta_j of the mesh it drives,
    Delta_j / n_j of the one driving it, omega_0 over both meshes (docs/model.md §6, §10;
    Gearbox.state_nominals), on the rig and the geared rig (ratios 2.5, 1.6, unequal gaps); at
    0.0 with both gaps closed and with each alone. To 4 ulps (measured: exact)."""
    if fmu.model in GEARBOXES:
        geared = TWO_STAGE_GEARED
        sets = [RIGS[fmu.model][0], geared] if delta == "rig" else [
            with_delta(geared, 0.0), {**geared, "Delta_1": 0.0}, {**geared, "Delta_2": 0.0}]
        for k, params in enumerate(sets):
            expected = ref2.Gearbox.of(params).state_nominals()
            inst = fmu.model_exchange(f"nominals-{k}", params)
            try:
                nominals = inst.nominals()
            finally:
                inst.free()
            assert np.all(np.abs(nominals - expected) <= 4 * EPS * expected), (params, nominals, expected)
        return
    params = RIGS[fmu.model][0] if delta == "rig" else with_delta(RIGS[fmu.model][0], 0.0)
    p = plant_of(fmu.model, params)
    w0 = math.sqrt(p.K * (p.r_m**2 / p.J_m + p.r_L**2 / p.J_L))
    th_m, th_L = (p.g / p.r_m, p.g / p.r_L) if p.g > 0.0 else (1e-4, 1e-4)
    expected = np.array([th_m, w0 * th_m, th_L, w0 * th_L])
    inst = fmu.model_exchange("nominals", params)
    try:
        nominals = inst.nominals()
    finally:
        inst.free()
    assert np.all(np.abs(nominals - expected) <= 4 * EPS * expected), (nominals, expected)


def test_indicators_psi_contact_and_derivatives_follow_the_state(fmu):
    """At 200 random states (u within +-3 g, angles up to 10 rad, seeded): event indicators
    [u - g, u + g], psi = K dz(u, g), contact = side of the gap, derivatives of docs/model.md §1
    (PythonPlant). Round-off allowance: 8 eps (|r_m theta_m| + |r_L theta_L| + g) on u, and 8 eps
    of the largest term on each derivative. A gearbox: _gearbox_follows_the_state."""
    if fmu.model in GEARBOXES:
        for k, params in enumerate([RIGS[fmu.model][0], TWO_STAGE_GEARED]):
            _gearbox_follows_the_state(fmu, params, seed=7 + k)
        return
    params = RIGS[fmu.model][0]
    p = plant_of(fmu.model, params)
    rng = np.random.default_rng(7)
    inst = fmu.model_exchange("follow", params)
    seen = set()
    try:
        for _ in range(200):
            u = rng.uniform(-3.0, 3.0) * p.g
            z = state_with_u(p, u, rng.uniform(-10, 10), rng.uniform(-5, 5), rng.uniform(-5, 5))
            tau = rng.uniform(-3, 3, 2)
            u_scale = abs(p.r_m * z[0]) + abs(p.r_L * z[2]) + p.g
            slack = 8 * EPS * u_scale
            u_f = p.r_m * z[0] - p.r_L * z[2]
            ind = inst.indicators(0.5, z)
            assert abs(ind[0] - (u_f - p.g)) <= slack and abs(ind[1] - (u_f + p.g)) <= slack
            (psi,) = inst.get("psi")
            assert abs(psi - p.K * p.dead_zone(u_f)) <= p.K * slack
            if abs(abs(u_f) - p.g) > slack:
                expected = PLUS if u_f > p.g else MINUS if u_f < -p.g else FREE
                assert inst.contact() == expected, (u_f, p.g)
                seen.add(expected)
            dz = inst.derivatives(0.5, z, *tau)
            want = PythonPlant(p).derivatives(0.5, z, *tau)
            terms = np.array([abs(z[1]), (abs(tau[0]) + abs(p.b_m * z[1]) + p.r_m * p.K * u_scale) / p.J_m,
                              abs(z[3]), (abs(tau[1]) + abs(p.b_L * z[3]) + p.r_L * p.K * u_scale) / p.J_L])
            assert np.all(np.abs(dz - want) <= 8 * EPS * terms), (dz, want)
    finally:
        inst.free()
    assert seen == {PLUS, MINUS, FREE}


def _gearbox_follows_the_state(fmu, params, seed):
    """At 200 random states of the gearbox (each u_j within +-3 Delta_j, angles up to 10 rad,
    seeded), on the rig and on the geared rig: its 18 event indicators, each mesh's
    [u_j - Delta_j, u_j + Delta_j] then the damper's four of each mesh and friction's six, which
    this plant has not, at 1 (docs/model.md §6, §10); psi_j = k_j dz(u_j, Delta_j); contact_j the
    side of mesh j's gap; the derivatives those of the equations (Gearbox.field, the reference's
    rhs in the meshes' modes). The FMU recomputes u_j from the angles: allowance 8 eps
    (|theta| + |n_j theta'| + Delta_j) on u_j, and 8 eps of the largest term on each derivative
    (J_i's row: b_i omega_i and both meshes' forces). Measured: indicators and psi_j exact, the
    derivatives within 0.014 eps of their terms."""
    box = ref2.Gearbox.of(params)
    rng = np.random.default_rng(seed)
    inst = fmu.model_exchange(f"follow-{seed}", params)
    gaps, ratios, stiff = (box.Delta_1, box.Delta_2), (box.n_1, box.n_2), (box.k_1, box.k_2)
    seen = [set(), set()]
    try:
        for _ in range(200):
            u = [rng.uniform(-3.0, 3.0) * g for g in gaps]
            z = box.state_with_u(*u, rng.uniform(-10, 10), *rng.uniform(-5, 5, 3))
            tau = rng.uniform(-3, 3, 2)
            angles = (z[0], z[2], z[4])
            scales = [abs(angles[j]) + abs(ratios[j] * angles[j + 1]) + gaps[j] for j in range(2)]
            slack = [8 * EPS * x for x in scales]
            u_f = box.u(z)
            ind = inst.indicators(0.5, z)
            expected = box.indicators(z)
            allowed = np.zeros(inst.nz)
            allowed[[0, 1, 6, 7]] = slack[0], slack[0], slack[1], slack[1]
            assert np.all(np.abs(ind - expected) <= allowed), (ind, expected)
            psi = inst.get("psi_1", "psi_2")
            contact = inst.integers("contact_1", "contact_2")
            for j in range(2):
                assert abs(psi[j] - stiff[j] * box.dead_zone(j, u_f[j])) <= stiff[j] * slack[j], (j, psi, u_f)
                if abs(abs(u_f[j]) - gaps[j]) > slack[j]:
                    side = PLUS if u_f[j] > gaps[j] else MINUS if u_f[j] < -gaps[j] else FREE
                    assert contact[j] == side, (j, u_f, gaps)
                    seen[j].add(side)
            dz = inst.derivatives(0.5, z, *tau)
            want = box.field(z, *tau)
            force = [stiff[j] * scales[j] for j in range(2)]
            terms = np.array([
                abs(z[1]), (abs(tau[0]) + abs(box.b_m * z[1]) + force[0]) / box.J_m,
                abs(z[3]), (abs(box.b_i * z[3]) + box.n_1 * force[0] + force[1]) / box.J_i,
                abs(z[5]), (abs(tau[1]) + abs(box.b_L * z[5]) + box.n_2 * force[1]) / box.J_L,
            ])
            assert np.all(np.abs(dz - want) <= 8 * EPS * terms), (dz, want)
    finally:
        inst.free()
    assert seen == [{PLUS, MINUS, FREE}] * 2


@pytest.mark.parametrize("mode", [FREE, PLUS, MINUS])
def test_directional_derivatives(fmu, mode):
    """fmi2GetDirectionalDerivative of der(x), x and psi with respect to the four states and the
    two inputs, column by column, against (a) the exact Jacobian of the mode (A_p of
    docs/model.md §3, with K = 0 in the gap; B_p, C_p), to 1e-13 of the largest entry, and (b)
    central differences of fmi2GetDerivatives and psi, exact for an affine map up to round-off:
    steps of 0.1 g / r on the angles (staying inside the mode) and 0.1 on speeds and torques
    give a round-off of ~eps |f| / step, far below the 1e-9 of the largest entry allowed.
    Also one seed on all six knowns at once equals J v (linearity). Measured: 6e-18 and 2e-15
    of the largest entry. A gearbox: _gearbox_directional_derivatives."""
    if fmu.model in GEARBOXES:
        for params in (RIGS[fmu.model][0], TWO_STAGE_GEARED):
            for mode_2 in (FREE, PLUS, MINUS):
                _gearbox_directional_derivatives(fmu, params, (mode, mode_2))
        return
    params = RIGS[fmu.model][0]
    p = plant_of(fmu.model, params)
    u = {FREE: 0.3 * p.g, PLUS: 1.7 * p.g, MINUS: -1.7 * p.g}[mode]
    z, tau = state_with_u(p, u), np.array([0.4, -0.3])
    knowns = [*STATES, "tau_m", "tau_L"]
    unknowns = [*DERIVATIVES, *STATES, "psi"]
    vr = fmu.vr
    # exact: rows der(x) (4), x (4), psi (1); columns z (4), tau (2)
    A, B = p.linear_matrices()
    if mode == FREE:
        A = _free_jacobian(p)
    c = 0.0 if mode == FREE else 1.0
    exact = np.zeros((9, 6))
    exact[:4, :4], exact[:4, 4:] = A, B
    exact[4:8, :4] = np.eye(4)
    exact[8, :4] = c * p.K * np.array([p.r_m, 0.0, -p.r_L, 0.0])

    inst = fmu.model_exchange(f"dirder-{mode}", params)
    try:
        inst.set_state(0.5, z)
        inst.set_torques(*tau)
        jac = np.column_stack(
            [inst.fmu.getDirectionalDerivative([vr[n] for n in unknowns], [vr[k]], [1.0]) for k in knowns]
        )
        seed = np.array([0.3, -1.1, 0.7, 2.0, -0.5, 1.3])
        combined = np.array(inst.fmu.getDirectionalDerivative([vr[n] for n in unknowns], [vr[k] for k in knowns], list(seed)))

        def evaluate(x, t_in):
            d = inst.derivatives(0.5, x, *t_in)
            return np.concatenate([d, inst.get(*STATES, "psi")])  # states as the FMU reads them

        steps = np.array([0.1 * p.g / p.r_m, 0.1, 0.1 * p.g / p.r_L, 0.1, 0.1, 0.1])
        fd = np.zeros((9, 6))
        for j in range(6):
            plus, minus = np.concatenate([z, tau]), np.concatenate([z, tau])
            plus[j] += steps[j]
            minus[j] -= steps[j]
            fd[:, j] = (evaluate(plus[:4], plus[4:]) - evaluate(minus[:4], minus[4:])) / (plus[j] - minus[j])
    finally:
        inst.free()
    scale = np.max(np.abs(exact))
    assert np.max(np.abs(jac - exact)) <= 1e-13 * scale, (jac, exact)
    assert np.max(np.abs(jac - fd)) <= 1e-9 * scale, (jac, fd)
    assert np.max(np.abs(combined - exact @ seed)) <= 1e-13 * scale * np.max(np.abs(seed))


def _gearbox_directional_derivatives(fmu, params, modes):
    """fmi2GetDirectionalDerivative of a gearbox, its meshes in `modes` (the first mesh's the
    test's parameter, the second's each in turn; the rig and the geared rig): der(z) (6), z (6),
    psi_1, psi_2 and the 18 event indicators with respect to the six states and the two inputs,
    column by column, against (a) the exact Jacobian of the equations in that mode
    (Gearbox.jacobian; an indicator's row is that of its u_j, 0 for one that reads 1,
    docs/model.md §6), to 1e-13 of its largest entry; (b) central differences of the equations'
    own field (Gearbox.field) and of the FMU's getDerivatives, psi_j and indicators, both exact
    for an affine map up to round-off: steps of 0.1 of each angle's nominal (the finest gap
    beside it, so every u_j moves by at most 0.1 Delta_j and stays in its mode, 0.7 Delta_j from
    a flank) and 0.1 on speeds and torques, round-off ~eps |f| / step, far below the 1e-9 of the
    largest entry allowed. One seed on all eight knowns at once equals J v. Measured, of the
    largest entry: 0 (the exact Jacobian), 4e-18 (the combined seed), 5e-14 (either difference,
    on the geared rig's smaller angle steps)."""
    box = ref2.Gearbox.of(params)
    gaps = (box.Delta_1, box.Delta_2)
    where = {FREE: 0.3, PLUS: 1.7, MINUS: -1.7}
    z = box.state_with_u(where[modes[0]] * gaps[0], where[modes[1]] * gaps[1], 0.2, 0.5, 0.1, -0.4)
    tau = np.array([0.4, -0.3])
    states, indicators = state_names(fmu), gear_indicators(fmu)
    knowns = [*states, "tau_m", "tau_L"]
    unknowns = [f"der({n})" for n in states] + [*states, "psi_1", "psi_2", *indicators]
    A, B, dpsi = box.jacobian(modes)
    exact = np.zeros((len(unknowns), 8))
    exact[:6, :6], exact[:6, 6:] = A, B
    exact[6:12, :6] = np.eye(6)
    exact[12:14, :6] = dpsi
    # u_minus_g_j and u_plus_g_j of mesh j: the row of u_j (indicators 0, 1 and 6, 7)
    for j, row in ((0, [1.0, 0.0, -box.n_1, 0.0, 0.0, 0.0]), (1, [0.0, 0.0, 1.0, 0.0, -box.n_2, 0.0])):
        exact[14 + 6 * j, :6] = exact[15 + 6 * j, :6] = row
    vr = fmu.vr
    inst = fmu.model_exchange(f"dirder-{modes}", params)
    try:
        inst.set_state(0.5, z)
        inst.set_torques(*tau)
        assert inst.integers("contact_1", "contact_2") == list(modes)
        jac = np.column_stack(
            [inst.fmu.getDirectionalDerivative([vr[n] for n in unknowns], [vr[k]], [1.0]) for k in knowns]
        )
        seed = np.array([0.3, -1.1, 0.7, 2.0, -0.5, 1.3, 0.9, -0.6])
        rows, columns = [vr[n] for n in unknowns], [vr[k] for k in knowns]
        combined = np.array(inst.fmu.getDirectionalDerivative(rows, columns, list(seed)))

        def evaluate(x, t_in):
            d = inst.derivatives(0.5, x, *t_in)
            return np.concatenate([d, inst.get(*states, "psi_1", "psi_2"), inst.indicators(0.5, x)])

        nominals = box.state_nominals()
        steps = np.array([0.1 * nominals[0], 0.1, 0.1 * nominals[2], 0.1, 0.1 * nominals[4], 0.1, 0.1, 0.1])
        fd, fd_ref = np.zeros(exact.shape), np.zeros((6, 8))
        for j in range(8):
            plus, minus = np.concatenate([z, tau]), np.concatenate([z, tau])
            plus[j] += steps[j]
            minus[j] -= steps[j]
            fd[:, j] = (evaluate(plus[:6], plus[6:]) - evaluate(minus[:6], minus[6:])) / (plus[j] - minus[j])
            fd_ref[:, j] = (box.field(plus[:6], *plus[6:]) - box.field(minus[:6], *minus[6:])) / (plus[j] - minus[j])
    finally:
        inst.free()
    scale = np.max(np.abs(exact))
    assert np.max(np.abs(fd_ref - exact[:6])) <= 1e-9 * scale, (fd_ref, exact[:6])
    assert np.max(np.abs(jac - exact)) <= 1e-13 * scale, (modes, jac, exact)
    assert np.max(np.abs(jac - fd)) <= 1e-9 * scale, (modes, jac, fd)
    assert np.max(np.abs(combined - exact @ seed)) <= 1e-13 * scale * np.max(np.abs(seed))


def _free_jacobian(p) -> np.ndarray:
    """A_p of docs/model.md §3 with the compliant member carrying nothing (psi = 0 in the gap)."""
    A = np.zeros((4, 4))
    A[0, 1], A[2, 3] = 1.0, 1.0
    A[1, 1], A[3, 3] = -p.b_m / p.J_m, -p.b_L / p.J_L
    return A


# --- integration through fmpy's own Model Exchange simulator --------------------------------------



# The two-stage gearbox's: test_two_stage.py::test_model_exchange_with_cvode_converges_to_the_reference.
@pytest.mark.parametrize("fmu", archives.SINGLE_GAP, indirect=True)
def test_simulate_fmu_with_cvode_matches_the_exact_solution(fmu):
    """fmpy.simulate_fmu(fmi_type='ModelExchange', solver='CVode') under reversing torques held
    for 0.1 s each, from a moving start, against the exact solution at the output points.

    Held torques reach fmpy as a table with every switching time written twice (value before,
    value after): fmpy's Input takes a repeated time as an input event, stops CVode there,
    applies the new value in Event Mode and restarts the solver; between the rows it
    interpolates linearly between equal values, i.e. holds them. The contact switches are
    located by CVode's root finding on the FMU's event indicators; fmpy records each event
    (input or state) as a repeated time in the result.

    CVode (BDF, rtol 1e-9, atol = rtol * nominal) controls the local error only. Over 4 s of
    lightly damped oscillation and ~70 restarts its global error is measured at 560 rtol
    (5.6e-7 relative for both models; 8e-8 at rtol 1e-10, up to 1.3e-6 at 1e-8); allowed:
    2000 rtol = 2e-6 on the states, u and psi. Every switch must be reported as a state event,
    its time within the shift that error makes at the crossing speed, 2e-6 max|u| / |u'|
    (measured: within 0.28 of that, 5e-8 s)."""
    params = RIGS[fmu.model][0]
    check_cvode_against_exact(str(fmu.path), params, plant_of(fmu.model, params))


# --- the continuous-time PI loop closed by the test -----------------------------------------------

LOOP_TOL = 1e-8


@pytest.mark.parametrize("model", MODELS)
def test_pi_loop_matches_the_exact_solution(model):
    """The loop of docs/model.md §3 closed around the FMU (FMU2Model in Continuous-Time Mode:
    setTime, setContinuousStates, setReal of the inputs, getDerivatives; getEventIndicators as
    solve_ivp's terminal events; at each event Event Mode, newDiscreteStates, back; after each
    integration completedIntegratorStep), DOP853 with rtol 1e-12 and atol 1e-15 (the angles'
    errors decide u, a difference ~1e-3 of their size, so atol must stay below rtol |u|).

    Against reference_continuous: every state, the PI integral, u = r_m theta_m - r_L theta_L and
    the FMU's psi within 1e-8 relative (normalised per signal as in the module docstring; the
    same integrator on the Python right-hand side reaches 4e-12 and 9e-12, above). Every switch
    found, in the same order; each time within the shift that an error of 1e-8 max|u| in u
    makes at the crossing speed, |dt| <= 1e-8 max|u| / |u'|. The FMU never asks for an event
    iteration or Event Mode, and `contact` is the side of the gap the exact u is on.
    Measured: 4e-12 (shaft), 1e-11 (belt); switch times within 2e-13 s and 1.4e-12 s, at most
    5e-4 of their allowance. A gearbox: _gearbox_pi_loop."""
    if model in GEARBOXES:
        _gearbox_pi_loop(model)
        return
    params, gains = RIGS[model]
    plant = plant_of(model, params)
    run, out = fmu_loop(model)
    exact = exact_loop(model)
    u = plant.r_m * run.z[:, 0] - plant.r_L * run.z[:, 2]
    errors = {name: rel_err(run.z[:, j], exact.z[:, j]) for j, name in enumerate(STATES)}
    errors["xi"] = rel_err(run.xi, exact.xi)
    errors["u"] = rel_err(u, exact.u)
    errors["psi"] = rel_err(out["psi"], [plant.K * plant.dead_zone(x) for x in exact.u])
    assert max(errors.values()) <= LOOP_TOL, errors

    assert len(exact.switches) >= 20, "the loop must cross the gap again and again"
    assert [s[1:] for s in run.switches] == [s[1:] for s in exact.switches]
    u_max = np.max(np.abs(exact.u))
    for (t_fmu, _, _), (t_ref, _, _), rate in zip(run.switches, exact.switches, exact.switch_rates):
        assert abs(t_fmu - t_ref) <= LOOP_TOL * u_max / abs(rate), (t_fmu, t_ref, rate)

    assert all(not info[0] and not info[1] and not info[4] for info in run.event_infos)
    assert run.step_answers and all(a == (False, False) for a in run.step_answers)
    clear = np.abs(np.abs(exact.u) - plant.g) > LOOP_TOL * u_max
    side = np.where(exact.u > plant.g, PLUS, np.where(exact.u < -plant.g, MINUS, FREE))
    assert np.array_equal(out["contact"][clear], side[clear])


def _gearbox_pi_loop(model):
    """The same loop closed around a gearbox's FMU (run_loop, its 18 indicators as
    events) against the loop around its equations (reference_two_stage.run_pi_loop, DOP853 at
    rtol 1e-13 inside each tuple of modes, u_j integrated directly): every state, the PI
    integral, u_1, u_2 and the FMU's psi_1, psi_2 (against k_j dz(u_j, Delta_j) of the
    reference's u_j) within LOOP_TOL relative. The reference is good to far better: its runs at
    rtol 1e-12 and 1e-13 differ by 4e-12 (on omega_i, the light shaft's speed), test_two_stage's
    open loops hold it to 1e-9. Every switch of either mesh found, in the same order, each time
    within LOOP_TOL max|u_j| / |u_j'|; the FMU never asks for an event iteration or Event Mode;
    contact_j is the side of the reference's u_j. Measured: 1.4e-11 (omega_i), the other states
    below 6e-13; 46 switches (both meshes), times within 6e-13 s."""
    box = ref2.Gearbox.of(RIGS[model][0])
    run, out = gear_loop(model)
    ref = reference_gear_loop(model)
    errors = {name: rel_err(run.z[:, j], ref.z[:, j]) for j, name in enumerate(state_names(archives.require(model)))}
    errors["xi"] = rel_err(run.xi, ref.xi)
    u = np.array([box.u(z) for z in run.z])
    for j in range(2):
        k = (box.k_1, box.k_2)[j]
        errors[f"u_{j + 1}"] = rel_err(u[:, j], ref.u[:, j])
        errors[f"psi_{j + 1}"] = rel_err(out["psi"][:, j], [k * box.dead_zone(j, x) for x in ref.u[:, j]])
    assert max(errors.values()) <= LOOP_TOL, errors

    assert len(ref.switches) >= 20 and {s[1] for s in ref.switches} == {0, 1}, ref.switches
    assert [s[1:] for s in run.switches] == [s[1:] for s in ref.switches]
    u_max = np.max(np.abs(ref.u), axis=0)
    for (t_fmu, *_), (t_ref, mesh, _, _), rate in zip(run.switches, ref.switches, ref.switch_rates):
        assert abs(t_fmu - t_ref) <= LOOP_TOL * u_max[mesh] / abs(rate), (t_fmu, t_ref, mesh, rate)

    assert all(not info[0] and not info[1] and not info[4] for info in run.event_infos)
    assert run.step_answers and all(a == (False, False) for a in run.step_answers)
    for j, g in enumerate((box.Delta_1, box.Delta_2)):
        clear = np.abs(np.abs(ref.u[:, j]) - g) > LOOP_TOL * u_max[j]
        side = np.where(ref.u[:, j] > g, PLUS, np.where(ref.u[:, j] < -g, MINUS, FREE))
        assert np.array_equal(out["contact"][clear, j], side[clear]), j


def _gearbox_twins(model):
    """test_twin_deviation_never_exceeds_bound for a gearbox: the loop with the rig's gaps and
    with both gaps 0 (docs/model.md §10: one disturbance k_j sat(u_j, Delta_j) per mesh, the
    bound their sum) around the FMU, |omega_L^b - omega_L^0| against the FMU's `bound`. Each FMU
    run is within LOOP_TOL of the reference loop (the twin's checked here, _gearbox_pi_loop the
    other's), hence the slack 2 LOOP_TOL max|omega_L|. The reference twins are held to the bound
    too, with their own resolution as slack (2e-9 max|omega_L|: test_two_stage's 1e-9 per run).
    The bound must be nearly reached: max |dw_L| / bound measured 0.902."""
    run_b, out_b = gear_loop(model)
    run_0, out_0 = gear_loop(model, 0.0)
    ref_b, ref_0 = reference_gear_loop(model), reference_gear_loop(model, 0.0)
    assert max(rel_err(run_0.z[:, j], ref_0.z[:, j]) for j in range(6)) <= LOOP_TOL
    w_max = np.max(np.abs(run_b.z[:, 5]))
    bound = out_b["bound"]
    diff = np.abs(run_b.z[:, 5] - run_0.z[:, 5])
    assert np.all(diff <= bound + 2 * LOOP_TOL * w_max), np.max(diff - bound)
    ref_diff = np.abs(ref_b.z[:, 5] - ref_0.z[:, 5])
    assert np.all(ref_diff <= bound + 2e-9 * w_max), np.max(ref_diff - bound)
    assert np.all(out_0["bound"] == 0.0), "no gap carries no disturbance"
    assert np.max(diff[1:] / bound[1:]) > 0.9


@pytest.mark.parametrize("model", MODELS)
def test_twin_deviation_never_exceeds_bound(model):
    """The same loop with the rig's Delta and with Delta = 0 (docs/model.md §3): |omega_L^b -
    omega_L^0| against the FMU's `bound` read along the backlash run (Kp, Ki = the loop's gains).
    Each run is within LOOP_TOL of its exact solution (the Delta = 0 one is checked here), so the
    deviation may exceed the exact one by 2 LOOP_TOL max|omega_L|: that is the only slack. The
    exact twin is held to the FMU's bound too, and the bound must be nearly reached, else the
    comparison would prove little: max |dw_L| / bound measured 0.997 (shaft), 0.974 (belt). A
    gearbox: _gearbox_twins."""
    if model in GEARBOXES:
        _gearbox_twins(model)
        return
    run_b, out_b = fmu_loop(model)
    run_0, out_0 = fmu_loop(model, 0.0)
    exact_0 = exact_loop(model, 0.0)
    assert max(rel_err(run_0.z[:, j], exact_0.z[:, j]) for j in range(4)) <= LOOP_TOL
    w_max = np.max(np.abs(run_b.z[:, 3]))
    bound = out_b["bound"]
    diff = np.abs(run_b.z[:, 3] - run_0.z[:, 3])
    assert np.all(diff <= bound + 2 * LOOP_TOL * w_max), np.max(diff - bound)
    exact_diff = np.abs(exact_loop(model).z[:, 3] - exact_0.z[:, 3])
    # No tie to round off: both are exactly 0 at t = 0, and the largest ratio after it is 0.997
    # (shaft), 0.974 (belt, web line).
    assert np.all(exact_diff <= bound)
    assert np.all(out_0["bound"] == 0.0), "Delta = 0 carries no disturbance"
    assert np.max(diff[1:] / bound[1:]) > 0.9


# --- bounds: exact functions of time, as in Co-Simulation -----------------------------------------


@pytest.mark.parametrize("case", ["closed-loop", "open-late-start"])
def test_bounds_equal_cosimulation(fmu, case):
    """`bound` and `bound_paper` of an ME instance after fmi2SetTime(t0 + s), s going forwards
    and backwards, equal those of a Co-Simulation instance stepped from t0 to t0 + s (both
    measure time from the start time t0), to 1e-12 relative: both are the same exact function
    of s, computed along different step sequences (one step per listed time here). Measured:
    4e-14 at most (the two-stage: 3.9e-15). `bound_sup` is the same number in both. A gearbox
    has `bound` alone, its sum over both meshes (docs/model.md §10: the paper printed no
    bound_paper for it)."""
    params, gains = RIGS[fmu.model]
    gains, t0 = (gains, 0.0) if case == "closed-loop" else ({"Kp": 0.0, "Ki": 0.0}, 1.5)
    names = [n for n in ("bound", "bound_paper") if n in fmu.vr]
    offsets = [0.0, 0.37, 1.25, 0.8, 2.9, 0.05, 2.9, 1.25, 0.0]
    inst = fmu.model_exchange("bounds-me", {**params, **gains}, start_time=t0)
    try:
        (sup_me,) = inst.get("bound_sup")
        me = {}
        for s in offsets:
            inst.fmu.setTime(t0 + s)
            me.setdefault(s, []).append(inst.get(*names))
    finally:
        inst.free()
    cs_inst = fmu.co_simulation("bounds-cs", {**params, **gains}, start_time=t0)
    try:
        (sup_cs,) = cs_inst.get("bound_sup")
        cs, now = {0.0: cs_inst.get(*names)}, 0.0
        for s in sorted(set(offsets) - {0.0}):
            cs_inst.do_step(t0 + now, s - now)
            cs[s], now = cs_inst.get(*names), s
    finally:
        cs_inst.free()
    assert cs[0.0] == [0.0] * len(names) and sup_me == sup_cs and math.isfinite(sup_cs)
    for s, readings in me.items():
        for values in readings:
            for v_me, v_cs in zip(values, cs[s]):
                assert abs(v_me - v_cs) <= 1e-12 * abs(v_cs), (s, values, cs[s])
    assert all(cs[s][0] > 0.0 for s in cs if s > 0.0)


# --- misuse ------------------------------------------------------------------------------------


def _outputs_are_not_nan(inst: ModelExchange):
    names = [n for n, v in inst.archive.variables.items() if v.type == "Real" and v.causality == "output"]
    values = inst.get(*names)
    assert not any(math.isnan(v) for v in values), dict(zip(names, values))
    return dict(zip(names, values))


def test_bad_states_times_and_inputs_are_refused(fmu):
    """NaN or infinite states, times and inputs, and vectors of the wrong length, are refused
    with fmi2Error and a reason under logErrors; a refused call stores nothing (the outputs
    keep their values and none is NaN); parameters cannot change after initialisation; inputs
    can be set in Event Mode."""
    params = RIGS[fmu.model][0]
    if fmu.model in GEARBOXES:
        # both meshes in contact, on opposite flanks
        box = ref2.Gearbox.of(params)
        z = box.state_with_u(1.5 * box.Delta_1, -1.5 * box.Delta_2)
    else:
        plant = plant_of(fmu.model, params)
        z = state_with_u(plant, 1.5 * plant.g)

    def fresh():
        inst = fmu.model_exchange("misuse", params)
        inst.set_state(0.5, z)
        return inst, _outputs_are_not_nan(inst)

    # name: (call, words the logged reason must contain)
    cases = {}
    nx = len(fmu.md.derivatives)
    names = [u.variable.derivative.name for u in fmu.md.derivatives]
    for j in range(nx):
        for bad in (math.nan, math.inf, -math.inf):
            x = np.zeros(nx)
            x[: len(z)] = z
            x[j] = bad
            cases[f"state {j} = {bad}"] = (
                lambda inst, x=x: inst.fmu.fmi2SetContinuousStates(inst.c, (ctypes.c_double * nx)(*x), nx),
                (names[j],),
            )
    for bad in (math.nan, math.inf, -math.inf):
        cases[f"time {bad}"] = (lambda inst, bad=bad: inst.fmu.setTime(bad), ("time",))
        cases[f"tau_m {bad}"] = (lambda inst, bad=bad: inst.set_torques(bad, 0.0), ("tau_m",))
        cases[f"tau_L {bad}"] = (lambda inst, bad=bad: inst.set_torques(0.0, bad), ("tau_L",))
    buffer = (ctypes.c_double * 16)(*([0.1] * 16))
    for n in (nx - 1, nx + 1, 0):
        lengths = (str(n), str(nx))
        cases[f"set states n={n}"] = (lambda inst, n=n: inst.fmu.fmi2SetContinuousStates(inst.c, buffer, n), lengths)
        cases[f"get states n={n}"] = (lambda inst, n=n: inst.fmu.fmi2GetContinuousStates(inst.c, buffer, n), lengths)
        cases[f"derivatives n={n}"] = (lambda inst, n=n: inst.fmu.fmi2GetDerivatives(inst.c, buffer, n), lengths)
        cases[f"nominals n={n}"] = (
            lambda inst, n=n: inst.fmu.fmi2GetNominalsOfContinuousStates(inst.c, buffer, n),
            lengths,
        )
    nz = fmu.md.numberOfEventIndicators  # a gearbox's 18
    assert fmu.model in GEARBOXES or nz == EVENT_INDICATORS
    room = (ctypes.c_double * (nz + 1))()
    for n in (2, nz + 1, 0):
        cases[f"indicators n={n}"] = (
            lambda inst, n=n: inst.fmu.fmi2GetEventIndicators(inst.c, room, n),
            (str(n), str(nz)),
        )
    cases["parameter after initialisation"] = (lambda inst: inst.set({"J_m": 1.0}), ("J_m",))

    for name, (call, mentions) in cases.items():
        inst, before = fresh()
        try:
            inst.refused(lambda: call(inst), *mentions)
            assert _outputs_are_not_nan(inst) == before, name
        finally:
            inst.free()

    inst, _ = fresh()
    try:
        inst.fmu.enterEventMode()
        inst.set_torques(1.0, -1.0)
        assert inst.get("tau_m", "tau_L") == [1.0, -1.0]
        inst.fmu.enterContinuousTimeMode()
        model = inst
        assert np.all(np.isfinite(model.derivatives(0.5, z, 1.0, -1.0)))
    finally:
        inst.free()

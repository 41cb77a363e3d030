"""FMI 2.0 Model Exchange of every FMU (the web line's web decoupled): the right-hand side of
docs/model.md §1 as an importer's integrator sees it, against independent references.

References (none takes a number from the FMU):
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
from scipy.linalg import expm

import archives
import reference
import reference_continuous as rc
from cvode_check import check_cvode_against_exact
from loops import DERIVATIVES, NX, PythonPlant, outputs_along, run_loop, state_with_u
from reference import FREE, MINUS, PLUS
from reference_bound import loop_matrices
from rigs import RIGS, plant_of, with_delta
from signals import rel_err, reversing_torques

MODELS = archives.MODELS
EPS = np.finfo(float).eps

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
    holds, y = loop_holds(), np.zeros(7)
    direct = np.zeros((len(LOOP_TIMES), 5))
    for k, hold in enumerate(holds):
        end = holds[k + 1].t if k + 1 < len(holds) else LOOP_TIMES[-1]
        y[5:] = hold.tau_L, hold.w_ref
        inside = (LOOP_TIMES >= hold.t) & (LOOP_TIMES <= end)
        direct[inside] = (expm((LOOP_TIMES[inside] - hold.t)[:, None, None] * M) @ y)[:, :5]
        y = expm(M * (end - hold.t)) @ y
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
    inst = fmu.model_exchange("init", {**params, **z0})
    try:
        needed, terminate, _, _, time_defined, _ = inst.initial_event
        assert not needed and not terminate and not time_defined
        assert list(inst.continuous_states()) == list(z0.values())
        assert inst.completed_step() == (False, False)
        needed, terminate, _, _, time_defined, _ = inst.event_iteration()
        assert not needed and not terminate and not time_defined
    finally:
        inst.free()


@pytest.mark.parametrize("delta", ["rig", 0.0])
def test_nominals_of_the_continuous_states(fmu, delta):
    """theta: g/r (1e-4 rad when g = 0), omega: omega_0 times that, with
    omega_0 = sqrt(K (r_m^2/J_m + r_L^2/J_L)) (docs/model.md §2). To 4 ulps (measured: exact)."""
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
    of the largest term on each derivative."""
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


@pytest.mark.parametrize("mode", [FREE, PLUS, MINUS])
def test_directional_derivatives(fmu, mode):
    """fmi2GetDirectionalDerivative of der(x), x and psi with respect to the four states and the
    two inputs, column by column, against (a) the exact Jacobian of the mode (A_p of
    docs/model.md §3, with K = 0 in the gap; B_p, C_p), to 1e-13 of the largest entry, and (b)
    central differences of fmi2GetDerivatives and psi, exact for an affine map up to round-off:
    steps of 0.1 g / r on the angles (staying inside the mode) and 0.1 on speeds and torques
    give a round-off of ~eps |f| / step, far below the 1e-9 of the largest entry allowed.
    Also one seed on all six knowns at once equals J v (linearity). Measured: 6e-18 and 2e-15
    of the largest entry."""
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
    5e-4 of their allowance."""
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


@pytest.mark.parametrize("model", MODELS)
def test_twin_deviation_never_exceeds_bound(model):
    """The same loop with the rig's Delta and with Delta = 0 (docs/model.md §3): |omega_L^b -
    omega_L^0| against the FMU's `bound` read along the backlash run (Kp, Ki = the loop's gains).
    Each run is within LOOP_TOL of its exact solution (the Delta = 0 one is checked here), so the
    deviation may exceed the exact one by 2 LOOP_TOL max|omega_L|: that is the only slack. The
    exact twin is held to the FMU's bound too, and the bound must be nearly reached, else the
    comparison would prove little: max |dw_L| / bound measured 0.997 (shaft), 0.974 (belt)."""
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
    4e-14 at most. `bound_sup` is the same number in both."""
    params, gains = RIGS[fmu.model]
    gains, t0 = (gains, 0.0) if case == "closed-loop" else ({"Kp": 0.0, "Ki": 0.0}, 1.5)
    offsets = [0.0, 0.37, 1.25, 0.8, 2.9, 0.05, 2.9, 1.25, 0.0]
    inst = fmu.model_exchange("bounds-me", {**params, **gains}, start_time=t0)
    try:
        (sup_me,) = inst.get("bound_sup")
        me = {}
        for s in offsets:
            inst.fmu.setTime(t0 + s)
            me.setdefault(s, []).append(inst.get("bound", "bound_paper"))
    finally:
        inst.free()
    cs_inst = fmu.co_simulation("bounds-cs", {**params, **gains}, start_time=t0)
    try:
        (sup_cs,) = cs_inst.get("bound_sup")
        cs, now = {0.0: cs_inst.get("bound", "bound_paper")}, 0.0
        for s in sorted(set(offsets) - {0.0}):
            cs_inst.do_step(t0 + now, s - now)
            cs[s], now = cs_inst.get("bound", "bound_paper"), s
    finally:
        cs_inst.free()
    assert cs[0.0] == [0.0, 0.0] and sup_me == sup_cs and math.isfinite(sup_cs)
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
            x[:NX] = z
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
    for n in (2, EVENT_INDICATORS + 1, 0):
        cases[f"indicators n={n}"] = (
            lambda inst, n=n: inst.fmu.fmi2GetEventIndicators(inst.c, buffer, n),
            (str(n), str(EVENT_INDICATORS)),
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
        assert np.all(np.isfinite(inst.derivatives(0.5, z, 1.0, -1.0)))
    finally:
        inst.free()

"""fmpy's CVode on a Model Exchange archive (FMI 2.0 or 3.0) against the exact solution: the
check test_model_exchange.py and test_fmi3.py share."""

from __future__ import annotations

import numpy as np
from backlash_fmu.fmu import STATES
from fmpy import simulate_fmu

import reference_continuous as rc
from loops import state_with_u
from reference import FREE, MINUS, PLUS, Plant
from signals import held_table, rel_err, reversing_torques

CVODE_RTOL = 1e-9
# Relative to each signal's largest value: CVode controls only its local error, and over 4 s of
# lightly damped oscillation and ~70 restarts its global error was measured at 560 rtol.
CVODE_TOL = 2000 * CVODE_RTOL


def check_cvode_against_exact(path: str, params: dict, plant: Plant):
    """fmpy.simulate_fmu(ModelExchange, CVode, rtol CVODE_RTOL) of the archive at `path` under
    torques reversing every 0.1 s for 4 s, from a moving start inside the gap, against the exact
    solution (reference_continuous.py) at the output points: states, u and psi within CVODE_TOL;
    every switch a state event (a repeated output time off the input edges) within the shift that
    error makes at the crossing speed; `contact` the side of the gap wherever that is clear."""
    h, n = 0.1, 40
    tau_m, tau_L = reversing_torques(n, h, 1.5, 0.6)
    edges = np.arange(n + 1) * h
    z0 = state_with_u(plant, 0.5 * plant.g, 0.01, 1.0, -0.5)
    result = simulate_fmu(
        path,
        fmi_type="ModelExchange",
        solver="CVode",
        relative_tolerance=CVODE_RTOL,
        start_time=0.0,
        stop_time=n * h,
        output_interval=0.01,
        input=held_table(tau_m, tau_L, h),
        start_values={**params, **dict(zip(STATES, z0))},
        output=[*STATES, "psi", "contact"],
    )
    t = result["time"]  # the 401 output points and, twice each, the events (record_events)
    # Exact: the start and stop times are the ones passed in, and fmpy records times in order.
    assert t[0] == 0.0 and t[-1] == n * h and np.all(np.diff(t) >= 0.0)
    assert np.all(np.min(np.abs(t[None, :] - np.linspace(0.0, n * h, 401)[:, None]), axis=1) <= 1e-12)
    exact = rc.solve(plant, rc.open_loop_holds(tau_m, tau_L, h), t, z0=z0)
    errors = {name: rel_err(result[name], exact.z[:, j]) for j, name in enumerate(STATES)}
    errors["u"] = rel_err(plant.r_m * result["theta_m"] - plant.r_L * result["theta_L"], exact.u)
    errors["psi"] = rel_err(result["psi"], [plant.K * plant.dead_zone(x) for x in exact.u])
    assert max(errors.values()) <= CVODE_TOL, errors

    repeated = t[1:][np.diff(t) == 0.0]
    state_events = [x for x in repeated if np.min(np.abs(x - edges)) > 1e-12]
    assert len(exact.switches) >= 20 and len(state_events) == len(exact.switches)
    u_max = np.max(np.abs(exact.u))
    for t_cv, (t_ref, _, _), rate in zip(state_events, exact.switches, exact.switch_rates):
        assert abs(t_cv - t_ref) <= CVODE_TOL * u_max / abs(rate), (t_cv, t_ref, rate)
    clear = np.abs(np.abs(exact.u) - plant.g) > CVODE_TOL * u_max
    side = np.where(exact.u > plant.g, PLUS, np.where(exact.u < -plant.g, MINUS, FREE))
    assert np.array_equal(result["contact"][clear], side[clear])

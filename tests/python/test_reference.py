"""The reference solver and the reference bounds against closed forms (no FMU needed).

These tests justify using reference.py / reference_bound.py as the yardstick for the FMU."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.linalg import expm

from reference import FREE, MINUS, PLUS, Plant, ReferencePlant, run_open_loop
from reference_bound import BoundReference
from rigs import BELT, SHAFT, SHAFT_GAINS, plant_of, with_delta
from signals import rel_err, reversing_torques

GEOMETRIES = {"shaft": ("BacklashShaft", SHAFT), "belt": ("BacklashBelt", BELT)}


def _plant(name: str, **changes) -> Plant:
    model, params = GEOMETRIES[name]
    return plant_of(model, {**params, **changes})


@pytest.mark.parametrize("name", GEOMETRIES)
def test_no_contact_each_inertia_obeys_its_own_ode(name):
    """With a gap that is never closed, J w' = tau - b w for each inertia alone: per held step
    w(t+s) = tau/b + (w - tau/b) e^{-b s/J}, theta(t+s) = theta + tau s/b + (w - tau/b) J/b (1 - e^{-b s/J})."""
    plant = _plant(name, Delta=1.0e3)
    h, n = 0.1, 60
    tau_m, tau_L = reversing_torques(n, h, 1.5, 0.6)
    z0 = np.array([0.3, 2.0, -0.1, -1.0])
    zs, us, ref = run_open_loop(plant, tau_m, tau_L, h, z0=z0)
    assert ref.switches == []

    def advance(theta, w, tau, J, b):
        e = math.exp(-b * h / J)
        return theta + tau * h / b + (w - tau / b) * J / b * (1.0 - e), tau / b + (w - tau / b) * e

    exact = [z0.copy()]
    for tm, tl in zip(tau_m, tau_L):
        th_m, w_m, th_L, w_L = exact[-1]
        th_m, w_m = advance(th_m, w_m, tm, plant.J_m, plant.b_m)
        th_L, w_L = advance(th_L, w_L, tl, plant.J_L, plant.b_L)
        exact.append(np.array([th_m, w_m, th_L, w_L]))
    exact = np.array(exact)
    for j in range(4):
        assert rel_err(zs[:, j], exact[:, j]) <= 1e-10


@pytest.mark.parametrize("name", GEOMETRIES)
def test_zero_gap_matches_matrix_exponential(name):
    """Delta = 0 is the linear plant z' = A_p z + B w: one augmented expm per held step (docs/model.md §2)."""
    plant = _plant(name, Delta=0.0)
    h, n = 0.05, 200
    tau_m, tau_L = reversing_torques(n, h, 1.5, 0.6)
    zs, us, _ = run_open_loop(plant, tau_m, tau_L, h)
    A, B = plant.linear_matrices()
    M = np.zeros((6, 6))
    M[:4, :4], M[:4, 4:] = A, B
    E = expm(M * h)
    exact = [np.zeros(4)]
    for w in zip(tau_m, tau_L):
        exact.append(E[:4, :4] @ exact[-1] + E[:4, 4:] @ np.array(w))
    exact = np.array(exact)
    for j in range(4):
        assert rel_err(zs[:, j], exact[:, j]) <= 1e-10
    u_exact = plant.r_m * exact[:, 0] - plant.r_L * exact[:, 2]
    assert rel_err(us, u_exact) <= 1e-10


@pytest.mark.parametrize("name", GEOMETRIES)
def test_energy_is_conserved_across_contact_switches(name):
    """With b = 0 and no torque the contact is elastic (docs/model.md §5): the kinetic energy plus the
    spring energy K dz(u, g)^2 / 2 stays constant through every switch."""
    plant = _plant(name, b_m=0.0, b_L=0.0)
    ref = ReferencePlant(plant, [0.0, 0.5, 0.0, 0.0])

    def energy(z):
        return 0.5 * (plant.J_m * z[1] ** 2 + plant.J_L * z[3] ** 2 + plant.K * plant.dead_zone(plant.u(z)) ** 2)

    e0 = energy(ref.z)
    energies = [energy(ref.step(0.0, 0.0, 0.05)) for _ in range(100)]
    assert len(ref.switches) >= 10
    assert max(abs(e - e0) for e in energies) <= 1e-10 * e0


def test_switches_alternate_between_free_and_contact():
    """Every switch leaves or enters FREE (no direct + to - jump) and the modes chain up."""
    plant = _plant("shaft")
    tau_m, tau_L = reversing_torques(300, 0.02, 1.5, 0.6)
    _, _, ref = run_open_loop(plant, tau_m, tau_L, 0.02)
    assert len(ref.switches) >= 10
    for (t0, a0, b0), (t1, a1, _) in zip(ref.switches, ref.switches[1:]):
        # Exact: each event search starts at the previous event's time.
        assert t1 >= t0 and b0 == a1 and FREE in (a0, b0)
    assert {PLUS, MINUS} <= {b for _, _, b in ref.switches}


@pytest.mark.parametrize("name", GEOMETRIES)
def test_event_located_solution_is_method_independent(name):
    """An explicit (DOP853) and an implicit (Radau) integrator, each with event location,
    agree on a reversing run with many contact switches."""
    plant = _plant(name)
    h, n = 0.1, 30
    tau_m, tau_L = reversing_torques(n, h, 1.5, 0.6)
    z1, u1, r1 = run_open_loop(plant, tau_m, tau_L, h)
    z2, u2, r2 = run_open_loop(plant, tau_m, tau_L, h, method="Radau", rtol=1e-12, atol=1e-16)
    assert len(r1.switches) >= 3 and len(r1.switches) == len(r2.switches)
    for j in range(4):
        assert rel_err(z2[:, j], z1[:, j]) <= 1e-9
    assert rel_err(u2, u1) <= 1e-9


def test_paper_bound_quadrature_matches_augmented_exponential():
    br = BoundReference(plant_of("BacklashShaft", SHAFT), **SHAFT_GAINS)
    _, vec = br.integrals(0.25, 40)
    for j in (1, 7, 40):
        exact = br.paper_closed_form(0.25 * j)
        assert np.max(np.abs(vec[j] - exact)) <= 1e-13 * np.max(np.abs(exact))


def test_bound_integral_is_consistent():
    """int_0^t |h|: equals |int_0^t h| until h first changes sign, never less, non-decreasing,
    independent of the output spacing, and close to a plain trapezoid rule of |h|."""
    br = BoundReference(plant_of("BacklashShaft", SHAFT), **SHAFT_GAINS)
    dt, n = 0.01, 300
    abs_int, vec = br.integrals(dt, n)
    signed = np.abs(vec @ br.L_c)
    grid = np.linspace(0.0, n * dt, 10 * n + 1)
    hv = br.h(grid)
    first_root = grid[np.nonzero(hv[:-1] * hv[1:] < 0.0)[0][0]]
    before = np.arange(n + 1) * dt < first_root
    assert np.all(np.abs(abs_int[before] - signed[before]) <= 1e-13 * abs_int[-1])
    # int |h| >= |int h| holds exactly, but just after a root the two meet within round-off: each
    # is a recursive sum of the k cells up to its point (m per output step), off by at most
    # k eps of its value. The cumulative sum of non-negative cells never drops (same arithmetic).
    cells = np.arange(n + 1) * max(1, math.ceil(dt / br.max_cell))
    assert np.all(abs_int >= signed - 2 * cells * np.finfo(float).eps * abs_int)
    assert np.all(np.diff(abs_int) >= 0.0)
    coarse, _ = br.integrals(3 * dt, n // 3)
    assert np.max(np.abs(coarse - abs_int[::3])) <= 1e-12 * abs_int[-1]
    trapezoid = np.concatenate(([0.0], np.cumsum(0.5 * (np.abs(hv[1:]) + np.abs(hv[:-1])) * np.diff(grid))))
    assert np.max(np.abs(trapezoid[::10] - abs_int)) <= 1e-4 * abs_int[-1]


def test_bound_holds_for_the_open_loop_twin():
    """Without a controller there is no sampling: under the same held torques the load speeds of
    the plant with and without backlash differ by at most K g int_0^t |h| with A_p (docs/model.md §3)."""
    plant = plant_of("BacklashShaft", SHAFT)
    linear = plant_of("BacklashShaft", with_delta(SHAFT, 0.0))
    h, n = 0.01, 600
    tau_m, tau_L = reversing_torques(n, h, 1.5, 0.6)
    zb, _, ref = run_open_loop(plant, tau_m, tau_L, h)
    z0, _, _ = run_open_loop(linear, tau_m, tau_L, h)
    bound, _ = BoundReference(plant).bounds(h, n)
    diff = np.abs(zb[:, 3] - z0[:, 3])
    assert len(ref.switches) >= 6
    # No tie to round off: both are exactly 0 at t = 0, and after it the largest ratio is 0.72.
    assert np.all(diff <= bound)
    assert np.max(diff) > 0.05 * np.max(bound)  # the comparison is not vacuous


def test_sup_of_the_bound():
    """bound_sup is the limit of bound for a stable loop and +inf for the undamped open plant.

    sup() and bounds() are two quadratures of |h| on different grids (sup() stops at 40 decay
    times, 9.9 s here), so they are compared within what separates them in exact arithmetic, the
    tail of int |h| beyond the shorter horizon, plus the round-off of each: every cell's start
    vector is propagated through up to 512 products with expm(A delta) (an error growing by at
    most cond(V), A = V diag V^-1, per the whole run of products), and the cells are summed
    (n - 1 roundings of positive terms). Which of the two comes out larger is round-off, and it
    differs between BLAS kernels."""
    br = BoundReference(plant_of("BacklashShaft", SHAFT), **SHAFT_GAINS)
    sup = br.sup()
    dt, n = 0.1, 100
    bound, _ = br.bounds(dt, n)
    assert math.isfinite(sup)
    # Well before the horizon the tail is far above round-off: the limit is not yet reached.
    assert bound[10] < sup
    lam, V = np.linalg.eig(br.A)
    residue = (br.L_c @ V) * np.linalg.solve(V, br.D_1)
    excited = np.abs(residue) > 1e-12 * np.max(np.abs(residue))
    # |h(s)| <= sum |r_i| e^{Re lam_i s}: the tail beyond the shorter horizon t_min.
    t_min = min(40.0 / -br.decay_rate(), dt * n)
    tail = br.scale * float(np.sum(np.abs(residue[excited]) * np.exp(lam.real[excited] * t_min) / -lam.real[excited]))
    cells = 64 * math.ceil(t_min / 64 / br.max_cell) + n * math.ceil(dt / br.max_cell)
    round_off = (2 * 512 * np.linalg.cond(V) + cells) * np.finfo(float).eps * sup
    assert abs(sup - bound[-1]) <= tail + round_off, (sup, bound[-1], tail, round_off)
    undamped = plant_of("BacklashShaft", {**SHAFT, "b_m": 0.0, "b_L": 0.0})
    # sup() is +inf when the slowest excited mode has Re lambda >= -1e-12: here its modes lie on
    # the imaginary axis (LAPACK gives Re lambda = 0 or 2e-16, within eps |A| = 2e-14 of it).
    assert BoundReference(undamped).sup() == math.inf

"""Independent computation of the speed-error bounds of docs/model.md §3.

    h(s)           = L_c expm(A s) D_1                       impulse response phi -> omega_L
    bound(t)       = K g  int_0^t |h(s)| ds
    bound_paper(t) = K g || int_0^t expm(A s) D_1 ds ||_2     eq. (37)/(41) as printed
    bound_sup      = K g  int_0^inf |h(s)| ds

A is the 5-state closed loop A_cl (PI on the motor speed) when Kp or Ki is non-zero, else the
4-state plant A_p (docs/model.md §4). The integrals are computed by Gauss-Legendre quadrature of
scipy.linalg.expm on cells cut at the sign changes of h (located with brentq), so that
|h| is smooth on every piece. (The FMU is expected to use closed forms instead.)
"""

from __future__ import annotations

import math

import numpy as np
from numpy.polynomial.legendre import leggauss
from scipy.linalg import expm
from scipy.optimize import brentq

from reference import Plant

_NODES, _WEIGHTS = leggauss(20)


def loop_matrices(plant: Plant, Kp: float, Ki: float):
    """(A, D_1, L_c) of docs/model.md §3: closed loop if any gain is non-zero, else the open plant."""
    A_p, B = plant.linear_matrices()
    B_p = B[:, :1]
    D = np.array([0.0, plant.r_m / plant.J_m, 0.0, -plant.r_L / plant.J_L])
    if Kp == 0.0 and Ki == 0.0:
        return A_p, D, np.array([0.0, 0.0, 0.0, 1.0])
    L_1 = np.array([[0.0, 1.0, 0.0, 0.0]])
    A = np.zeros((5, 5))
    A[:4, :4] = A_p - Kp * B_p @ L_1
    A[:4, 4:] = Ki * B_p
    A[4:, :4] = -L_1
    return A, np.append(D, 0.0), np.array([0.0, 0.0, 0.0, 1.0, 0.0])


def _flow(A: np.ndarray, D_1: np.ndarray, s: np.ndarray) -> np.ndarray:
    """expm(A s) D_1 for every s (batched expm), shape (len(s), n)."""
    s = np.atleast_1d(np.asarray(s, dtype=float))
    return expm(s[:, None, None] * A[None, :, :]) @ D_1


class BoundReference:
    """bound, bound_paper and bound_sup for one plant and one pair of PI gains."""

    def __init__(self, plant: Plant, Kp: float = 0.0, Ki: float = 0.0):
        self.plant = plant
        self._set_loop(*loop_matrices(plant, Kp, Ki), plant.K * plant.g)

    @classmethod
    def of_loop(cls, A: np.ndarray, D_1: np.ndarray, L_c: np.ndarray, scale: float) -> "BoundReference":
        """The bounds of any loop x' = A x + D_1 phi, |phi| <= scale, on the output L_c x (a
        stage of a chain, docs/model.md §10)."""
        ref = cls.__new__(cls)
        ref.plant = None
        ref._set_loop(A, D_1, L_c, scale)
        return ref

    def _set_loop(self, A, D_1, L_c, scale):
        self.A, self.D_1, self.L_c = A, D_1, L_c
        self.scale = scale
        # A cell of 0.5 / |lambda|_max is a sixth of the shortest half-period among the modes
        # of h, short enough to hold at most one sign change (a missed pair would show in the
        # trapezoid cross-check of test_reference.py), and |lambda| * width <= 0.5 keeps the
        # 20-point Gauss rule at round-off.
        self.rate = max(float(np.max(np.abs(np.linalg.eigvals(self.A)))), 1e-3)
        self.max_cell = 0.5 / self.rate

    def h(self, s) -> np.ndarray:
        return _flow(self.A, self.D_1, s) @ self.L_c

    def _gauss(self, v0: np.ndarray, width: float) -> np.ndarray:
        """int_0^width expm(A x) v0 dx by the 20-point Gauss-Legendre rule."""
        x = 0.5 * width * (_NODES + 1.0)
        return 0.5 * width * np.einsum("q,qn->n", _WEIGHTS, _flow(self.A, v0, x))

    def integrals(self, dt: float, n: int) -> tuple[np.ndarray, np.ndarray]:
        """(int_0^t |h|, int_0^t expm(A s) D_1 ds) at t_j = j dt, j = 0..n.

        Each [t_j, t_j+1] is cut into m equal cells no wider than max_cell. On a cell
        starting at s, expm(A (s + x)) D_1 = expm(A x) v(s), so one matrix W (the Gauss
        rule of expm(A x) over the cell) integrates every cell; a cell where h changes sign
        is split at the root (brentq) and each side integrated on its own."""
        m = max(1, int(math.ceil(dt / self.max_cell)))
        delta = dt / m
        x = 0.5 * delta * (_NODES + 1.0)
        W = 0.5 * delta * np.einsum("q,qij->ij", _WEIGHTS, expm(x[:, None, None] * self.A[None]))
        step = expm(self.A * delta)
        cells = n * m
        v = np.empty((cells + 1, len(self.D_1)))
        v[0] = self.D_1
        for i in range(cells):
            # Re-anchor on a direct expm now and then so that round-off cannot build up.
            v[i + 1] = expm(self.A * ((i + 1) * delta)) @ self.D_1 if (i + 1) % 512 == 0 else step @ v[i]
        cell_vec = v[:-1] @ W.T
        cell_abs = np.abs(cell_vec @ self.L_c)
        hv = v @ self.L_c
        for i in np.nonzero(hv[:-1] * hv[1:] < 0.0)[0]:
            r = brentq(lambda y: self.L_c @ expm(self.A * y) @ v[i], 0.0, delta, xtol=1e-16, rtol=1e-15)
            left = self._gauss(v[i], r) @ self.L_c
            right = self._gauss(expm(self.A * r) @ v[i], delta - r) @ self.L_c
            cell_abs[i] = abs(left) + abs(right)
        cum_abs = np.concatenate(([0.0], np.cumsum(cell_abs)))[::m]
        cum_vec = np.vstack((np.zeros(len(self.D_1)), np.cumsum(cell_vec, axis=0)))[::m]
        return cum_abs, cum_vec

    def bounds(self, dt: float, n: int) -> tuple[np.ndarray, np.ndarray]:
        """(bound(t), bound_paper(t)) at t_j = j dt, j = 0..n, in rad/s."""
        abs_int, vec_int = self.integrals(dt, n)
        return self.scale * abs_int, self.scale * np.linalg.norm(vec_int, axis=1)

    def decay_rate(self) -> float:
        """Largest real part among the modes that h excites (non-zero residue in h)."""
        lam, V = np.linalg.eig(self.A)
        residue = (self.L_c @ V) * np.linalg.solve(V, self.D_1)
        excited = np.abs(residue) > 1e-12 * np.max(np.abs(residue))
        return float(np.max(lam.real[excited]))

    def sup(self) -> float:
        """bound_sup = K g int_0^inf |h|: +inf unless h decays; else integrated until the
        slowest excited mode has decayed below 1e-17 of its start."""
        sigma = self.decay_rate()
        if sigma >= -1e-12:
            return math.inf
        t_end = 40.0 / -sigma
        abs_int, _ = self.integrals(t_end / 64, 64)
        return self.scale * float(abs_int[-1])

    def paper_closed_form(self, t: float) -> np.ndarray:
        """int_0^t expm(A s) D_1 ds from one augmented matrix exponential (a cross-check of
        the quadrature; not used for the comparison with the FMU)."""
        n = len(self.D_1)
        M = np.zeros((n + 1, n + 1))
        M[:n, :n], M[:n, n] = self.A, self.D_1
        return expm(M * t)[:n, n]

"""Frequency response of a state-space system and its derivative, by the Hessenberg method.

    G(s) = C (s I - A)^-1 B + D,      dG/ds = -C (s I - A)^-2 B,
    s = j w (continuous) or z = exp(j w T) (sampled with period T); dG/dw = j dG/ds, or j T z dG/dz.

A is reduced once to upper Hessenberg form, ``A = Q H Q^T`` (orthogonal Q, ``scipy.linalg.hessenberg``), so
that each frequency costs one LU factorization of the Hessenberg matrix ``s I - H`` in O(n^2) instead of O(n^3):
``G(s) = (C Q) (s I - H)^-1 (Q^T B) + D`` (Laub 1981, "Efficient multivariable frequency response
computations", IEEE TAC 26(2); the method of SLICOT TB05AD). Gaussian elimination with partial pivoting on a
Hessenberg matrix swaps at most adjacent rows and is as backward-stable as a dense LU. A frequency on a pole
(an exactly singular ``s I - H``) gives an infinite response.

Frequencies are in rad/s, as python-control's ``frequency_response`` takes them.
"""

from __future__ import annotations

import numpy as np
from numba import njit
from scipy.linalg import hessenberg

from shell.linear.system import LinearSystem


@njit(cache=True)
def _factor(H, shift, lu, swapped):
    """LU with partial pivoting of ``shift I - H`` (H upper Hessenberg) into ``lu``: U on and above the
    diagonal, the multiplier of step k at ``lu[k + 1, k]``, ``swapped[k]`` when rows k and k + 1 were exchanged.
    False when a pivot is exactly zero (the shift is an eigenvalue of H)."""
    n = H.shape[0]
    for i in range(n):
        for j in range(n):
            lu[i, j] = -H[i, j]
        lu[i, i] += shift
    for k in range(n - 1):
        swapped[k] = abs(lu[k + 1, k]) > abs(lu[k, k])
        if swapped[k]:
            for j in range(k, n):
                lu[k, j], lu[k + 1, j] = lu[k + 1, j], lu[k, j]
        if lu[k, k] == 0.0:
            return False
        multiplier = lu[k + 1, k] / lu[k, k]
        lu[k + 1, k] = multiplier
        for j in range(k + 1, n):
            lu[k + 1, j] -= multiplier * lu[k, j]
    return n == 0 or lu[n - 1, n - 1] != 0.0


@njit(cache=True)
def _solve(lu, swapped, rhs):
    """Overwrite ``rhs`` (n x r) with ``(shift I - H)^-1 rhs`` from :func:`_factor`'s factors."""
    n, r = rhs.shape
    for k in range(n - 1):
        for c in range(r):
            if swapped[k]:
                rhs[k, c], rhs[k + 1, c] = rhs[k + 1, c], rhs[k, c]
            rhs[k + 1, c] -= lu[k + 1, k] * rhs[k, c]
    for i in range(n - 1, -1, -1):
        for c in range(r):
            acc = rhs[i, c]
            for j in range(i + 1, n):
                acc -= lu[i, j] * rhs[j, c]
            rhs[i, c] = acc / lu[i, i]


@njit(cache=True)
def _project(CQ, X, scale, D, out):
    """``out = scale (C Q) X + D``."""
    p, m = out.shape
    for i in range(p):
        for c in range(m):
            acc = 0.0j
            for j in range(X.shape[0]):
                acc += CQ[i, j] * X[j, c]
            out[i, c] = scale * acc + D[i, c]


@njit(cache=True)
def hessenberg_responses(H, QtB, CQ, D, shifts, out):
    """``out[k] = C Q (shifts[k] I - H)^-1 Q^T B + D`` for every shift; infinite on a pole."""
    n, m = QtB.shape
    lu = np.empty((n, n), dtype=np.complex128)
    swapped = np.zeros(n, dtype=np.bool_)
    X = np.empty((n, m), dtype=np.complex128)
    for k in range(shifts.shape[0]):
        if not _factor(H, shifts[k], lu, swapped):
            out[k, :, :] = np.inf
            continue
        X[:, :] = QtB
        _solve(lu, swapped, X)
        _project(CQ, X, 1.0, D, out[k])


@njit(cache=True)
def hessenberg_response_derivative(H, QtB, CQ, D, shift, G, dG):
    """``G = C Q (s I - H)^-1 Q^T B + D`` and ``dG = dG/ds = -C Q (s I - H)^-2 Q^T B`` at ``s = shift``;
    False on a pole."""
    n, m = QtB.shape
    lu = np.empty((n, n), dtype=np.complex128)
    swapped = np.zeros(n, dtype=np.bool_)
    X = np.empty((n, m), dtype=np.complex128)
    if not _factor(H, shift, lu, swapped):
        return False
    X[:, :] = QtB
    _solve(lu, swapped, X)
    _project(CQ, X, 1.0, D, G)
    _solve(lu, swapped, X)
    _project(CQ, X, -1.0, np.zeros_like(D), dG)
    return True


class TransferEvaluator:
    """G(j w) (or G(exp(j w T))) of a :class:`LinearSystem` at any frequency, and dG/dw, from one Hessenberg
    reduction of A."""

    def __init__(self, system: LinearSystem):
        self.system = system
        A, B, C = system.A, system.B, system.C
        if A.shape[0]:
            H, Q = hessenberg(A, calc_q=True)
            self.H, self.QtB, self.CQ = np.ascontiguousarray(H), Q.T @ B, C @ Q
        else:
            self.H, self.QtB, self.CQ = A, B, C
        self.QtB = np.ascontiguousarray(self.QtB, dtype=np.complex128)
        self.CQ = np.ascontiguousarray(self.CQ, dtype=np.complex128)
        self.D = np.ascontiguousarray(system.D)

    def shifts(self, omega) -> np.ndarray:
        """s = j w, or z = exp(j w T) for a sampled system."""
        omega = np.asarray(omega, dtype=float)
        T = self.system.sample_time
        return np.exp(1j * omega * T) if T is not None else 1j * omega

    def response(self, omega) -> np.ndarray:
        """Complex G, shape (outputs, inputs, frequencies), at the frequencies ``omega`` (rad/s)."""
        omega = np.atleast_1d(np.asarray(omega, dtype=float))
        p, m = self.D.shape
        out = np.empty((omega.size, p, m), dtype=np.complex128)
        hessenberg_responses(self.H, self.QtB, self.CQ, self.D, self.shifts(omega), out)
        return np.moveaxis(out, 0, -1)

    def response_and_derivative(self, omega: float) -> tuple[np.ndarray, np.ndarray]:
        """(G, dG/dw) at one frequency (rad/s), each (outputs, inputs); infinite on a pole."""
        shift = complex(self.shifts(float(omega)))
        p, m = self.D.shape
        G = np.empty((p, m), dtype=np.complex128)
        dG = np.empty((p, m), dtype=np.complex128)
        if not hessenberg_response_derivative(self.H, self.QtB, self.CQ, self.D, shift, G, dG):
            return np.full((p, m), np.inf + 0j), np.full((p, m), np.inf + 0j)
        T = self.system.sample_time
        return G, (1j * T * shift if T is not None else 1j) * dG


def frequency_response(system: LinearSystem, omega) -> np.ndarray:
    """Complex G(j w) (or G(exp(j w T))) of ``system``, shape (outputs, inputs, frequencies); w in rad/s."""
    return TransferEvaluator(system).response(omega)

"""Small dense linear algebra for the engine's recursions (numba): the few-by-few systems of one body.

* :func:`spd_inverse` - inverse of a symmetric positive definite block by Cholesky (the hinge's
  ``D = S' IA S`` of the articulated-body algorithm, RBDA Table 7.1);
* :func:`lu_factor`, :func:`lu_solve_column` - LU with partial pivoting kept for later right-hand sides (the
  Woodbury capacitance system of :mod:`dynamics.kernels.modal_condensation`, solved again by each refinement);
* :func:`psd_factor` - pivoted Cholesky of a symmetric positive semidefinite 6 x 6 (an articulated inertia
  that may be rank deficient);
* :func:`symmetric_eigen` - cyclic Jacobi eigen-decomposition (Golub and Van Loan, *Matrix Computations*,
  sec. 8.5) of a small symmetric indefinite matrix.

They allocate nothing and take their scratch as arguments.
"""

from __future__ import annotations

import numpy as np
from numba import njit


@njit(cache=True, inline="always")
def spd_inverse(D, n, tol, L, out):
    """Inverse of the leading n x n block of a symmetric positive definite matrix, into ``out``.

    Cholesky ``D = L L^T`` (``L`` a scratch matrix, its diagonal holding the reciprocals of L's: n divisions instead
    of n^2 + n, 0.63x of the time at n = 6, 208 against 330 ns, 2026-12-07), then one forward and one back
    substitution per column. Returns False when a pivot is not above ``tol`` (a numerically singular articulated
    inertia: D is assembled from the entries of IA, so a pivot below ~eps * trace(IA) is round-off)."""
    if n == 1:
        if not D[0, 0] > tol:
            return False
        out[0, 0] = 1.0 / D[0, 0]
        return True
    for j in range(n):
        s = D[j, j]
        for k in range(j):
            s -= L[j, k] * L[j, k]
        if not s > tol:
            return False
        r = 1.0 / np.sqrt(s)
        L[j, j] = r
        for i in range(j + 1, n):
            s = D[i, j]
            for k in range(j):
                s -= L[i, k] * L[j, k]
            L[i, j] = s * r
    for j in range(n):
        for i in range(n):
            s = 1.0 if i == j else 0.0
            for k in range(i):
                s -= L[i, k] * out[k, j]
            out[i, j] = s * L[i, i]
        for i in range(n - 1, -1, -1):
            s = out[i, j]
            for k in range(i + 1, n):
                s -= L[k, i] * out[k, j]
            out[i, j] = s * L[i, i]
    return True


@njit(cache=True)
def lu_factor(A, r, piv):
    """LU factorization with partial pivoting of ``A[:r, :r]`` in place (``P A = L U``: the unit lower
    triangle's multipliers below the diagonal, U on and above it; ``piv[k]`` the row exchanged with row k at
    step k, as a float). The other columns of ``A`` are left alone. False when a pivot is negligible against
    the matrix."""
    scale = 0.0
    for a in range(r):
        for b in range(r):
            scale = max(scale, abs(A[a, b]))
    for col in range(r):
        p = col
        big = abs(A[col, col])
        for row in range(col + 1, r):
            if abs(A[row, col]) > big:
                big = abs(A[row, col])
                p = row
        if not big > 1e-14 * scale:
            return False
        piv[col] = p
        if p != col:
            for b in range(r):
                t = A[col, b]
                A[col, b] = A[p, b]
                A[p, b] = t
        for row in range(col + 1, r):
            f = A[row, col] / A[col, col]
            A[row, col] = f
            if f != 0.0:
                for b in range(col + 1, r):
                    A[row, b] -= f * A[col, b]
    return True


@njit(cache=True)
def lu_solve_column(A, r, piv, col):
    """Solve ``A[:r, :r] x = A[:r, col]`` in place, with ``A[:r, :r]`` and ``piv`` from :func:`lu_factor`."""
    for k in range(r):
        p = int(piv[k])
        if p != k:
            t = A[k, col]
            A[k, col] = A[p, col]
            A[p, col] = t
    for row in range(r):
        t = A[row, col]
        for k in range(row):
            t -= A[row, k] * A[k, col]
        A[row, col] = t
    for row in range(r - 1, -1, -1):
        t = A[row, col]
        for k in range(row + 1, r):
            t -= A[row, k] * A[k, col]
        A[row, col] = t / A[row, row]


@njit(cache=True)
def psd_factor(Y, L, piv):
    """Pivoted Cholesky of a symmetric positive semidefinite 6 x 6 ``Y`` (read-only here):
    ``Y[piv[a], piv[b]] = (L L')[a, b]`` with ``L`` lower triangular; columns past the numerical rank
    (pivot below 1e-14 of the largest diagonal entry, round-off for an articulated inertia) are zero.
    ``L`` is used as the working copy; ``piv`` receives the permutation (as floats)."""
    for a in range(6):
        piv[a] = a
        for b in range(6):
            L[a, b] = Y[a, b]
    biggest = 0.0
    for a in range(6):
        biggest = max(biggest, L[a, a])
    for k in range(6):
        j = k
        for a in range(k + 1, 6):
            if L[a, a] > L[j, j]:
                j = a
        if j != k:
            for b in range(6):
                t = L[k, b]
                L[k, b] = L[j, b]
                L[j, b] = t
            for a in range(6):
                t = L[a, k]
                L[a, k] = L[a, j]
                L[a, j] = t
            t = piv[k]
            piv[k] = piv[j]
            piv[j] = t
        if not L[k, k] > 1e-14 * biggest:
            for a in range(k, 6):
                for b in range(k, 6):
                    L[a, b] = 0.0
            break
        d = np.sqrt(L[k, k])
        L[k, k] = d
        for a in range(k + 1, 6):
            L[a, k] /= d
        for a in range(k + 1, 6):  # the whole trailing block, so that later swaps see it symmetric
            for b in range(k + 1, 6):
                L[a, b] -= L[a, k] * L[b, k]
    for a in range(6):
        for b in range(a + 1, 6):
            L[a, b] = 0.0


@njit(cache=True)
def symmetric_eigen(A, r, V):
    """Cyclic Jacobi eigen-decomposition of the symmetric ``A`` (r x r): on return ``A`` is diagonal with
    the eigenvalues and ``A_in = V diag(A) V'`` (accurate to round-off relative to the largest entry)."""
    for a in range(r):
        for b in range(r):
            V[a, b] = 1.0 if a == b else 0.0
    for sweep in range(60):
        off = 0.0
        scale = 0.0
        for a in range(r):
            scale += A[a, a] * A[a, a]
            for b in range(a + 1, r):
                off += A[a, b] * A[a, b]
        if off <= 1e-32 * (scale + off):
            return
        for p in range(r - 1):
            for q in range(p + 1, r):
                apq = A[p, q]
                if apq == 0.0:
                    continue
                theta = (A[q, q] - A[p, p]) / (2.0 * apq)
                if abs(theta) > 1e150:
                    t = 0.5 / theta
                else:
                    t = (1.0 if theta >= 0.0 else -1.0) / (abs(theta) + np.sqrt(theta * theta + 1.0))
                c = 1.0 / np.sqrt(t * t + 1.0)
                s = t * c
                for k in range(r):
                    akp = A[k, p]
                    akq = A[k, q]
                    A[k, p] = c * akp - s * akq
                    A[k, q] = s * akp + c * akq
                for k in range(r):
                    apk = A[p, k]
                    aqk = A[q, k]
                    A[p, k] = c * apk - s * aqk
                    A[q, k] = s * apk + c * aqk
                for k in range(r):
                    vkp = V[k, p]
                    vkq = V[k, q]
                    V[k, p] = c * vkp - s * vkq
                    V[k, q] = s * vkp + c * vkq

"""Exponential Runge-Kutta integrator of order 4 (Krogstad's ETDRK4): flexible modes propagated exactly.

A flexible scene ``y' = f(t, y)`` is split as ``y' = L y + N(t, y)`` with ``L`` the linear modal part
(:func:`dynamics.modal_linear_part.modal_linear_part`: stiffness and damping through the mass matrix at a
configuration, all the high frequencies) and ``N = f - L y`` the rest (rigid-body motion, gyroscopic terms,
actuators; slow). The method integrates ``L`` exactly through the matrix functions

    phi_0(z) = e^z,   phi_{k+1}(z) = (phi_k(z) - 1/k!) / z,   i.e.  phi_k(hL) = int_0^1 e^{(1-s)hL} s^{k-1}/(k-1)! ds,

and treats ``N`` explicitly; its step is limited by how fast ``N`` varies, not by the top mode
(Hochbruck & Ostermann, "Exponential integrators", Acta Numerica 19:209-286, 2010, Sec. 2.3).

Method: Krogstad's four-stage scheme (S. Krogstad, "Generalized integrating factor methods for stiff
PDEs", J. Comput. Phys. 203:72-88, 2005; Hochbruck & Ostermann 2010 eq. 2.39), with ``phi_{k,c} =
phi_k(c h L)``, ``N_i = N(t + c_i h, Y_i)``, c = (0, 1/2, 1/2, 1):

    Y2 = phi_{0,1/2} y + h/2 phi_{1,1/2} N1
    Y3 = Y2 + h phi_{2,1/2} (N2 - N1)
    Y4 = phi_0 y + h phi_1 N1 + 2h phi_2 (N3 - N1)
    y1 = Y4 + h phi_2 (-N1 + 2 N2 - N4) + 4h phi_3 (N1 - N2 - N3 + N4)

(the last line is Krogstad's ``y1 = phi_0 y + h [b1 N1 + b2 N2 + b3 N3 + b4 N4]``, ``b1 = phi_1 - 3 phi_2 +
4 phi_3``, ``b2 = b3 = 2 phi_2 - 4 phi_3``, ``b4 = 4 phi_3 - phi_2``, written from Y4; the cost of these lines
is in "Cost" below). It is exact for ``y' = L y + c``
(constant forcing: a static deflection under a held actuator command comes out exact), of classical order 4,
and of stiff order 3 for any ``L`` generating a bounded semigroup (Hochbruck & Ostermann, SIAM J. Numer.
Anal. 43:1069-1090, 2005). With ``L = 0`` it is the classical RK4, which is what the components outside the
linear part (attitude quaternions, positions, hinge angles) see.

Choice by measurement (a numpy prototype of four schemes, not kept, on the 190-mode observatory of
benchmarks/linearize_speed.py: modes to 1943 Hz, open loop with smooth wheel and thruster loads, 50 ms, against
RK4 at 25 us): Lawson's integrating-factor RK4 (``e^{-tL}`` transformation, Lawson 1967), Cox & Matthews'
ETDRK4 (J. Comput. Phys. 176:430-455, 2002), Krogstad's scheme and the five-stage stiff-order-4 method of
Hochbruck & Ostermann (2005) at h = 2, 1, 0.5 ms. Lawson's error in the IMU node's rate was 1.4e-4, 1.8e-5 and
4.3e-6 rad/s, the three ETD schemes' 1.7e-8 at every step, which is the reference's own error: Lawson's
method is not exact for constant forcing, so every quasi-static modal response carries an O(h omega) error.
The ETD schemes could not be told apart (attitude within 2.6e-13 of each other); Hochbruck & Ostermann's costs
a fifth stage, and of the two four-stage schemes Krogstad's has the better stiff order in theory (3 against
2, Hochbruck & Ostermann 2005) at the same cost, hence this one. A Rosenbrock (linearly implicit) method with
the modal Jacobian was not measured: its stability function damps or phase-shifts the modes with
h omega >> 1 (L-stable: the top mode disappears; A-stable: it is aliased) that the exponential propagates
exactly, for the same O(m^2) work per stage.

Matrix functions: ``L`` is balanced (``D^-1 L D``, Parlett & Reinsch 1969, scipy.linalg.matrix_balance) and
diagonalized, ``L = (D V) diag(lambda) (D V)^-1``; the phi_k of each eigenvalue come from their Taylor series
for |z| < 1 and from the recurrence above otherwise. The exponential obtained this way is checked against
scipy.linalg.expm (Pade with scaling and squaring, an independent algorithm) at every (re)computation; a
linear part that is not diagonalizable to working accuracy (a critically damped or zero-frequency mode with
a free rate) is refused with that message. For the nominal step the real matrices ``phi_k(c h L)`` are
formed once (the stage products below, one BLAS gemv per stage); a shortened step (the last one before
``t_bound``, after an event) works in the eigenbasis instead (O(m) functions, one complex m x m product per term
and one back).

Cost: at a few hundred modes the step is bound by reading the matrices (m = 418 on the 196-mode observatory of
benchmarks/flexible_observatory.py: 196 modal coordinates, 206 free velocities, 16 driven rows; 1.4 MB per m x m
matrix), so the nominal step reads as few as the method allows.

* ``phi_0(z) = 1 + z phi_1(z)`` and ``F = f(t, y) = L y + N1`` give ``phi_{0,c} y + c h phi_{1,c} N1 = y + c h
  phi_{1,c} F``: stages 2 and 4 start from y with one phi_1 product of the slope, and ``phi_0`` is never formed
  (:data:`STAGES`: 5 products with phi_1, phi_2, phi_3 instead of 8 with phi_0 .. phi_3). Same scheme, same
  exactness for ``y' = L y + c``; for ``L = 0`` still RK4.
* A row of L that copies one component (``d eta/dt = eta_dot``: a single entry, exactly 1) has ``N = f - L y =
  f_a - y_b``, exactly zero when the model's rate is that component (the engine's is: a copy); the remainder
  computes it as that difference (no product) and multiplies only the other rows of L (``L_other``); the
  products of the N-differences take only the columns of the other rows (``other_rows``: u and driven rows, half
  of m), and a term whose vector is not exactly zero on the copy rows (F, or N of a model whose rate is not a
  copy) adds the product with those columns (``Phi_copies``): the same result, nothing assumed.
* A zero column of L (a rigid-body or rotor rate that no row of L reads, a driven row: 26 of the observatory's 418)
  has ``L e_j = 0``, hence ``phi_k(c h L) e_j = e_j / k!`` exactly: the products and the remainder skip these
  columns (``zero_columns``) and add ``W_j / k!`` on row j.

Per step the observatory reads 5.7 m^2 matrix entries (2 phi_1 matrices over their 392 non-zero columns, 4 phi_2/phi_3
blocks over the 196 columns of the other rows, 4 times L's 222 other rows over its 392 non-zero columns), against
6.2 m^2 before the zero columns were skipped and 12 m^2 with the published form (8 phi products and 4 full L y
products): 382 -> 243 us of linear algebra per step for the first two changes (1.57x, 2026-12-07, load 4.3), and
1.08-1.14x more for the zero columns (1.19-1.28x on the 50-mode tube, m = 126; the four remainders and stages in
sequence inside one compiled loop, before and after in one process, interleaved, medians, load 3.8-4.0). The result
equals the published form to round-off (tests/integrators/test_exponential.py, phi functions from a block
exponential).

Dense output: the continuous extension of the same quadrature, exact for the linear part,
``y(t + theta h) = phi_0(theta h L) y + theta h [phi_1 n0 + theta phi_2 n1 + 2 theta^2 phi_3 n2](theta h L)``
with ``n0 + n1 s + n2 s^2`` the quadratic through N1, (N2 + N3)/2 and N4 at s = 0, 1/2, 1 (third order;
equal to the step at theta = 1; for ``L = 0`` it is RK4's standard cubic continuous extension), evaluated
in the eigenbasis.

Driven components: states outside the linear part whose derivative depends on it (an IMU integrating its
node's rate and acceleration, a wheel angle measured against the structure, the attitude quaternion) would see
the fast modes only through RK4's quadrature nodes, which alias a mode with h omega >> 1 (measured on the
observatory: 23 % error in the IMU rate at 1 ms). When the linear part is set, the columns ``df/dy`` over its
m components are taken by forward differences (m evaluations of ``fun``); the rows outside it that depend on
them join the linear part with their coupling ``C P`` to its oscillating modes (``P`` the spectral projector
on the non-zero eigenvalues; the rigid-body directions are not stiff and would make the extended matrix
defective) and zero columns, so their integrals of the modal motion are exact too (IMU rate error 9e-5). The
extended matrix's eigen-decomposition follows from L's (:meth:`LinearPart.extended`: its eigenvalues are L's and
zeros), checked against expm like any other.

Changing configuration: ``L`` is built at the configuration where the integrator starts. If hinged parts
then rotate far enough to change the mass matrix, the difference ``(L(q) - L(q0)) y`` is a stiff term inside
``N`` that the explicit part integrates badly. With a callable ``linear_part(t, y)`` (what the shell passes)
the integrator re-evaluates it after 2, 8, 32, ... steps while it does not move (the build is the first step's
check: a check at that same state would find no drift; the interval grows 4x after a check that found a drift
below 1/64 of DRIFT_TOLERANCE, 2x below a quarter of it: :func:`check_growth`), up to MAX_CHECK_INTERVAL steps
or MAX_CHECK_TIME of simulated time, whichever is longer (the configuration moves on the time scale of the
scene, not of the step; a mass matrix and a Cholesky solve: ~0.7 ms for the 60-mode observatory, a fifth of one
derivative, but 5-21 ms for the 196-mode general-mass one at order 1, about 15 derivatives: every 64 steps of
1 ms that was 5-10 % of its run, every 250 steps it is 1-3 %; of one check ~6.3 ms are the callable's and
0.04-0.05 ms the drift, :func:`frobenius_distance`, against 0.13-0.16 ms for numpy's norm of the m x m difference,
0.56 ms when that difference lands on fresh pages; since modal_linear_part solves for only the columns of the
inverse mass matrix it needs and keeps its spin-averaged copy, one check is 3.4-3.9 ms, 2-3 % of an order-1 run
over its first 2 s) and rebuilds
the matrix functions and the driven rows when ``||L(y) - L||_F / ||L||_F > DRIFT_TOLERANCE``; the check starts
again every step after a rebuild. Independently, each step estimates the stiffness of ``N`` from its two stages
at c = 1/2 (``rho = ||N3 - N2|| / ||Y3 - Y2||``, the Rayleigh-quotient estimate of HNW I Sec. IV.2, skipped
when ``||Y3 - Y2||`` is within round-off of ``L Y``); when ``h rho > 1`` (a third of RK4's explicit stability
radius 2.83) a callable is checked at once (and the step retaken after a rebuild), a fixed ``(indices, L)``
gives a :class:`StiffRemainderWarning`.
"""
import math
import warnings

import numpy as np
from numba import njit

from . import kernels
from .base import EPS, DenseOutput, Integrator

#: h * rho(N) above which the remainder is treated as stiff (module docstring)
STIFF_REMAINDER_BOUND = 1.0
#: relative change ||L(y) - L||_F / ||L||_F of a callable linear part that triggers its recomputation
DRIFT_TOLERANCE = 1e-3
#: longest interval, in steps, between two evaluations of a callable linear part that has not moved
MAX_CHECK_INTERVAL = 64
#: simulated time (s) that the interval between two such evaluations may grow to when that is more than
#: MAX_CHECK_INTERVAL steps (the longest interval is max(MAX_CHECK_INTERVAL, floor(MAX_CHECK_TIME / h)) steps)
MAX_CHECK_TIME = 0.25
#: largest difference between the eigen-decomposition's exponential and scipy's expm (balanced coordinates,
#: where the exponential's entries are O(1)) accepted as working accuracy
EXPM_AGREEMENT = 1e-9
#: phi functions: (c, k) of the real matrices formed for the nominal step, in the order of the stage terms
FUNCTIONS = ((0.5, 0), (0.5, 1), (0.5, 2), (1.0, 0), (1.0, 1), (1.0, 2), (1.0, 3))
PHI_AT_ZERO = np.array([1.0 / math.factorial(k) for _, k in FUNCTIONS])

# Stage table. Each stage is (base, terms): Y = base + sum_t Phi[function_t] @ (h sum_j C_t[j] X_j) with base -1
# (the step's start y) or an earlier stage state (0: Y2, 2: Y4) and X = F, N1, N2, N3, N4 (F = f(t, y), the slope at
# the step's start). phi_0(c h L) y + c h phi_1(c h L) N1 = y + c h phi_1(c h L) F (phi_0(z) = 1 + z phi_1(z) and
# F = L y + N1): the exponential of each stage folds into its phi_1 term (module docstring, "Cost").
_STAGE2 = (-1, ((1, (0.5, 0.0, 0.0, 0.0, 0.0)),))
_STAGE3 = (0, ((2, (0.0, -1.0, 1.0, 0.0, 0.0)),))
_STAGE4 = (-1, ((4, (1.0, 0.0, 0.0, 0.0, 0.0)), (5, (0.0, -2.0, 0.0, 2.0, 0.0))))
_FINAL = (2, ((5, (0.0, -1.0, 2.0, 0.0, -1.0)), (6, (0.0, 4.0, -4.0, -4.0, 4.0))))
#: most terms of a stage
MAX_TERMS = 2


def _table(stage):
    base, terms = stage
    return (base, np.array([t[0] for t in terms], dtype=np.int64),
            np.array([t[1] for t in terms], dtype=np.float64))


STAGES = tuple(_table(s) for s in (_STAGE2, _STAGE3, _STAGE4, _FINAL))
C_NODES = (0.5, 0.5, 1.0)  # times of stages 2, 3, 4


def check_growth(drift):
    """The factor the interval between two checks of a callable linear part grows by after a check that found it
    within DRIFT_TOLERANCE (module docstring, "Changing configuration"): 4 below 1/64 of the tolerance, 2 below a
    quarter of it, else 1. The intervals grow geometrically, so the time since the build grows by about the same
    factor: a drift growing as the square of that time stays within the tolerance over the next interval in both
    cases (4 / 64 and 4 / 4 of it), and one growing as its cube too after a factor of 4 (4^3 / 64). Measured on the
    196-mode observatory of benchmarks/flexible_observatory.py at order 1: a drift of 9e-10 after the first 2 steps
    and at most 6e-8 over 2 s with balanced wheels (the checks go 2, 8, 32, 128, 250 steps apart instead of 2, 4,
    ..., 128, 250: 7 instead of 9 in the first second), 4e-6 after 2 steps and at most 3.3e-4 with an unbalanced
    wheel (intervals 2, 4, 8, ...: as before; never rebuilt)."""
    if drift <= DRIFT_TOLERANCE / 64.0:
        return 4
    return 2 if drift <= 0.25 * DRIFT_TOLERANCE else 1


class StiffRemainderWarning(UserWarning):
    """The part of the dynamics outside the linear part has become stiff (the configuration moved away from
    the one the linear part was built at)."""


def phi_functions(z, k_max):
    """``phi_0(z) .. phi_{k_max}(z)`` of a complex array z, shape (k_max + 1, z.size).

    Taylor series ``phi_k(z) = sum_j z^j / (j + k)!`` for |z| < 1 (30 terms: truncation below 1e-32), the
    recurrence ``phi_{k+1} = (phi_k - 1/k!) / z`` from ``e^z`` otherwise (cancellation bounded by 1/|z|^k <= 1).
    Compiled (:func:`phi_into`): the dense output evaluates it at every event-search sample.
    """
    z = np.asarray(z, dtype=np.complex128).ravel()
    out = np.empty((k_max + 1, z.size), dtype=np.complex128)
    phi_into(z, int(k_max), out)
    return out


#: 1 / j! for the Taylor series of the phi functions
_INVERSE_FACTORIALS = np.array([1.0 / math.factorial(j) for j in range(40)])


@njit(cache=True)
def phi_into(z, k_max, out):
    """``phi_0(z) .. phi_{k_max}(z)`` into ``out`` (shape (k_max + 1, z.size)), as :func:`phi_functions` says; the
    exponential stepper's dense output calls it at each event-search sample (no allocation)."""
    inverse_factorials = _INVERSE_FACTORIALS
    for i in range(z.size):
        zi = z[i]
        if abs(zi) < 1.0:
            for k in range(k_max + 1):
                acc = 0j
                for j in range(29, -1, -1):  # Horner in z
                    acc = acc * zi + inverse_factorials[j + k]
                out[k, i] = acc
        else:
            value = np.exp(zi)
            out[0, i] = value
            for k in range(k_max):
                value = (value - inverse_factorials[k]) / zi
                out[k + 1, i] = value


class LinearPart:
    """The linear part over ``indices`` of an n-state system and its eigen-decomposition (module docstring)."""

    def __init__(self, indices, L, n, name, decomposition=None):
        """``decomposition``: ``(lam, V, Vinv)`` of L in its own axes, known (:meth:`extended`), instead of numpy's
        eigen-decomposition of the balanced L (:meth:`check_exponential` checks either)."""
        indices = np.asarray(indices)
        if indices.ndim != 1 or (indices.size and not np.issubdtype(indices.dtype, np.integer)):
            raise ValueError(f"{name}: linear_part indices must be a 1-D integer array, got {indices!r}")
        indices = indices.astype(np.int64)
        if indices.size and (indices.min() < 0 or indices.max() >= n):
            raise ValueError(f"{name}: linear_part indices must lie in [0, {n}), got range "
                             f"[{indices.min()}, {indices.max()}]")
        if np.unique(indices).size != indices.size:
            raise ValueError(f"{name}: linear_part indices repeat a state component")
        L = np.array(L, dtype=np.float64)
        m = indices.size
        if L.shape != (m, m):
            raise ValueError(f"{name}: linear_part L must be square over its {m} indices, got shape {L.shape}")
        if not np.all(np.isfinite(L)):
            raise ValueError(f"{name}: linear_part L has non-finite entries")
        self.name = name
        self.indices = indices
        self.L = np.ascontiguousarray(L)
        self.m = m
        self.L_norm = float(np.abs(L).sum(axis=1).max()) if m else 0.0
        self.is_linear = np.zeros(n, dtype=np.bool_)
        self.is_linear[indices] = True
        # rows of L that copy one linear component (d eta/dt = eta_dot: a single entry, exactly 1): there
        # N = f - L y is f_a - y_b, zero when the model's f copies the same rate (module docstring, "Cost")
        nonzero = L != 0.0
        single = nonzero.sum(axis=1) == 1
        copies = single & (L[np.arange(m), np.argmax(nonzero, axis=1) if m else np.zeros(0, np.int64)] == 1.0)
        self.copy_rows = np.flatnonzero(copies).astype(np.int64)
        self.other_rows = np.flatnonzero(~copies).astype(np.int64)
        self.copied = np.argmax(nonzero[self.copy_rows], axis=1).astype(np.int64) if m else np.zeros(0, np.int64)
        #: state components of the two kinds of rows and the components the copy rows copy
        self.copy_components = indices[self.copy_rows]
        self.other_components = indices[self.other_rows]
        self.copied_components = indices[self.copied]
        # zero columns of L (rigid-body and rotor rates, driven rows): L e_j = 0 gives phi_k(c h L) e_j = e_j / k!
        # exactly, so the products skip them (module docstring, "Cost")
        zero = ~nonzero.any(axis=0)
        self.zero_columns = np.flatnonzero(zero).astype(np.int64)
        self.nonzero_columns = np.flatnonzero(~zero).astype(np.int64)
        self.zero_components = indices[self.zero_columns]
        self.nonzero_components = indices[self.nonzero_columns]
        #: the columns the stage products read: copy rows and other rows whose column of L is not zero
        self.dense_copy_rows = self.copy_rows[~zero[self.copy_rows]]
        self.dense_other_rows = self.other_rows[~zero[self.other_rows]]
        self.dense_copy_components = indices[self.dense_copy_rows]
        self.dense_other_components = indices[self.dense_other_rows]
        #: the other rows of L over its non-zero columns (the remainder's product)
        self.L_other = np.ascontiguousarray(self.L[np.ix_(self.other_rows, self.nonzero_columns)])
        if m:
            import scipy.linalg  # here, not at module level: scipy.linalg costs ~0.3 s at every start

            balanced, (scale, _) = scipy.linalg.matrix_balance(L, permute=False, separate=True)
            if decomposition is None:
                lam, V = np.linalg.eig(balanced)
                Vinv = np.linalg.inv(V)
            else:
                lam, V, Vinv = decomposition
                V, Vinv = V / scale[:, None], Vinv * scale[None, :]
            self.lam = lam
            self.scale = scale
            self.V_balanced = V
            self.Vinv_balanced = Vinv
            self.balanced = balanced
            self.V = np.ascontiguousarray(scale[:, None] * V)
            self.Vinv = np.ascontiguousarray(self.Vinv_balanced / scale[None, :])
        else:
            self.lam = np.zeros(0, dtype=np.complex128)
            self.V = self.Vinv = np.zeros((0, 0), dtype=np.complex128)

    def moving(self):
        """The eigenvalues that are not zero to working accuracy (the oscillating modes; the zero ones are the
        rigid-body velocities)."""
        return np.abs(self.lam) > 1e3 * EPS * np.abs(self.lam).max()

    def extended(self, rows, coupling, n):
        """The linear part over ``indices`` and the driven ``rows``, ``[[L, 0], [C, 0]]`` with ``C = J P`` (``P`` the
        spectral projector on :meth:`moving`), with its eigen-decomposition from L's: ``C`` annihilates L's
        eigenvectors of eigenvalue zero, so ``V' = [[V, 0], [C V diag(1/lambda), I]]`` (``1/lambda`` zero where
        lambda is) holds eigenvectors of the extended matrix for ``(lambda, 0, ..., 0)``, and ``V'^-1 = [[V^-1, 0],
        [-C V diag(1/lambda) V^-1, I]]``: no second eigen-decomposition (at m = 402 + 16, 0.16 s of a 0.69 s build),
        the same check against expm."""
        m, r = self.m, rows.size
        L_ext = np.zeros((m + r, m + r))
        L_ext[:m, :m] = self.L
        L_ext[m:, :m] = coupling
        moving = self.moving()
        inverse = np.zeros(m, dtype=np.complex128)
        inverse[moving] = 1.0 / self.lam[moving]
        W = (coupling @ self.V) * inverse
        V = np.zeros((m + r, m + r), dtype=np.complex128)
        V[:m, :m] = self.V
        V[m:, :m] = W
        V[m:, m:] = np.eye(r)
        Vinv = np.zeros_like(V)
        Vinv[:m, :m] = self.Vinv
        Vinv[m:, :m] = -W @ self.Vinv
        Vinv[m:, m:] = np.eye(r)
        lam = np.concatenate([self.lam, np.zeros(r, dtype=self.lam.dtype)])
        return LinearPart(np.concatenate([self.indices, rows]), L_ext, n, self.name, (lam, V, Vinv))

    def check_exponential(self, h):
        """Refuse a decomposition whose exponential e^{hL} disagrees with scipy's expm (module docstring)."""
        if not self.m:
            return
        E_eig = (self.V_balanced * np.exp(h * self.lam)) @ self.Vinv_balanced
        import scipy.linalg

        E_ref = scipy.linalg.expm(h * self.balanced)
        diff = float(np.abs(E_eig - E_ref).max())
        if not diff <= EXPM_AGREEMENT * max(1.0, float(np.abs(E_ref).max())):
            raise ValueError(
                f"{self.name}: the linear part is not diagonalizable to working accuracy (its exponential over "
                f"h = {h:.6g} s from the eigen-decomposition differs from scipy.linalg.expm by {diff:.3g}; "
                f"condition number of the eigenvectors {np.linalg.cond(self.V_balanced):.3g}). A critically damped "
                f"mode or a zero-frequency mode makes L defective; remove that mode (modes:/max_frequency:) or use "
                f"rk4 with a step below the stability limit, or radau5")

    def real_functions(self, h):
        """The real matrices phi_k(c h L) of :data:`FUNCTIONS`, stacked (len(FUNCTIONS), m, m), original axes: the
        real part of ``(V diag(phi_k(c h lambda))) V^-1`` as two real products (a complex one is four: at m = 418 the
        seven functions took 0.15 s of a 0.69 s build)."""
        out = np.empty((len(FUNCTIONS), self.m, self.m))
        Vinv_real, Vinv_imag = np.ascontiguousarray(self.Vinv.real), np.ascontiguousarray(self.Vinv.imag)
        for f, (c, k) in enumerate(FUNCTIONS):
            scaled = self.V * phi_functions(c * h * self.lam, k)[k]
            np.matmul(scaled.real, Vinv_real, out=out[f])
            out[f] -= scaled.imag @ Vinv_imag
        return out

    def stage_matrices(self, h):
        """The nominal step's matrices: for each stage of :data:`STAGES` the columns of the other rows
        (``dense_other_rows``: not copies, column of L not zero) of its phi matrices side by side (m x n_terms
        n_other, C order: one BLAS gemv), and the columns of the copy rows (``dense_copy_rows``) of every function of
        :data:`FUNCTIONS` ((len(FUNCTIONS), m, n_copy): a term whose vector is not zero on the copy rows, F's, adds
        that product). The zero columns of L are not stored: there phi_k(c h L) is the unit column over k!."""
        m = self.m
        phi = self.real_functions(h) if m else np.zeros((len(FUNCTIONS), 0, 0))
        other = tuple(np.ascontiguousarray(np.hstack([phi[f][:, self.dense_other_rows] for f in functions]))
                      if m else np.zeros((0, 0)) for _, functions, _ in STAGES)
        copies = np.ascontiguousarray(phi[:, :, self.dense_copy_rows]) if m else np.zeros((len(FUNCTIONS), 0, 0))
        return other, copies

    def diagonal_functions(self, h):
        """phi_k(c h lambda) of :data:`FUNCTIONS`, (len(FUNCTIONS), m) complex (eigenbasis steps)."""
        out = np.empty((len(FUNCTIONS), self.m), dtype=np.complex128)
        for f, (c, k) in enumerate(FUNCTIONS):
            out[f] = phi_functions(c * h * self.lam, k)[k]
        return out


@njit(cache=True)
def remainder(f, y, nonzero_components, L_other, other_components, copy_components, copied_components, y_lin,
              product, out):
    """out = f - L y on the linear components, f elsewhere (N = f - L y): on the rows of L that copy a component
    (``copy_components`` <- ``copied_components``) ``f - y`` directly, on the others one BLAS gemv with their rows
    over the non-zero columns of L (``L_other``, ``nonzero_components``); y_lin (m,), product (m,) scratch."""
    for i in range(f.shape[0]):
        out[i] = f[i]
    n_columns = nonzero_components.shape[0]
    if n_columns == 0 and copy_components.shape[0] == 0:
        return
    for a in range(n_columns):
        y_lin[a] = y[nonzero_components[a]]
    n_other = other_components.shape[0]
    if n_columns:
        np.dot(L_other, y_lin[:n_columns], product[:n_other])  # BLAS gemv
    else:
        product[:n_other] = 0.0
    for a in range(n_other):
        out[other_components[a]] -= product[a]
    for a in range(copy_components.shape[0]):
        out[copy_components[a]] = f[copy_components[a]] - y[copied_components[a]]


@njit(cache=True, fastmath={"reassoc", "contract"})
def frobenius_distance(A, B):
    """||A - B||_F of two matrices of the same shape without forming A - B (one pass over both, vectorized: the
    sum's order is the compiler's, the same in every run)."""
    total = 0.0
    for i in range(A.shape[0]):
        for j in range(A.shape[1]):
            d = A[i, j] - B[i, j]
            total += d * d
    return np.sqrt(total)


@njit(cache=True)
def remainder_stiffness(N2, N3, Y2, Y3, indices, L_norm):
    """(rho, noise): rho = ||N3 - N2|| / ||Y3 - Y2|| (HNW I Sec. IV.2) and the same quotient for a difference
    N3 - N2 made of round-off alone, 64 eps (||N3|| + ||L|| ||Y3_lin||) / ||Y3 - Y2|| (inf when Y3 = Y2)."""
    dn = 0.0
    dy = 0.0
    n3 = 0.0
    for i in range(N2.shape[0]):
        dn += (N3[i] - N2[i]) ** 2
        dy += (Y3[i] - Y2[i]) ** 2
        n3 += N3[i] ** 2
    y3 = 0.0
    for a in range(indices.shape[0]):
        y3 += Y3[indices[a]] ** 2
    if dy == 0.0:
        return 0.0, np.inf
    dy = np.sqrt(dy)
    return np.sqrt(dn) / dy, 64.0 * 2.220446049250313e-16 * (np.sqrt(n3) + L_norm * np.sqrt(y3)) / dy


@njit(cache=True)
def _term_vectors(coefficients, F, N, h, W):
    """W[t] = h (C[t, 0] F + sum_j C[t, j + 1] N[j]), reading only the rows with a non-zero coefficient (the
    stages not yet computed in this step hold the previous step's values)."""
    n = F.shape[0]
    for t in range(coefficients.shape[0]):
        for i in range(n):
            W[t, i] = 0.0
        for j in range(N.shape[0] + 1):
            c = h * coefficients[t, j]
            if c != 0.0:
                X = F if j == 0 else N[j - 1]
                for i in range(n):
                    W[t, i] += c * X[i]


@njit(cache=True, inline="always")
def _outside_linear_part(phi_at_zero, functions, coefficients, F, N, h, base, is_linear, out, W):
    """The stage's term vectors into ``W`` and ``out = base + sum_t phi_{f_t}(0) W_t`` on the components outside
    the linear part (``base`` on the linear ones, which the caller completes)."""
    n = F.shape[0]
    n_terms = functions.shape[0]
    _term_vectors(coefficients, F, N, h, W)
    for i in range(n):
        acc = base[i]
        if not is_linear[i]:
            for t in range(n_terms):
                acc += phi_at_zero[functions[t]] * W[t, i]
        out[i] = acc


@njit(cache=True)
def stage_real(Phi_other, Phi_copies, phi_at_zero, functions, coefficients, F, N, h, base, indices,
               other_components, copy_components, zero_components, is_linear, out, W, w_stack, w_copies, product):
    """One stage with the real matrices: out = base + sum_t Phi[f_t] W_t on the linear components and
    base + sum_t phi_{f_t}(0) W_t elsewhere. ``Phi_other`` holds the columns of the stage's matrices for the rows
    of L that are not copies side by side (m x n_terms n_other: one BLAS gemv); the columns of the copy rows
    (``Phi_copies[f_t]``, m x n_copy) are multiplied only for a term whose vector is not zero there (F's: on the
    copy rows N is f - y = 0 when the model's rate is the copied component); the columns of L that are zero
    (``zero_components``, in neither) add phi_{f_t}(0) W_t on their own row. Returns True if out is finite."""
    n_terms = functions.shape[0]
    _outside_linear_part(phi_at_zero, functions, coefficients, F, N, h, base, is_linear, out, W)
    m = indices.shape[0]
    if m == 0:
        return kernels.all_finite(out)
    for a in range(zero_components.shape[0]):
        j = zero_components[a]
        for t in range(n_terms):
            out[j] += phi_at_zero[functions[t]] * W[t, j]
    n_other = other_components.shape[0]
    n_copy = copy_components.shape[0]
    if n_other:
        for t in range(n_terms):
            for b in range(n_other):
                w_stack[t * n_other + b] = W[t, other_components[b]]
        np.dot(Phi_other, w_stack[:n_terms * n_other], product)
        for a in range(m):
            out[indices[a]] += product[a]
    for t in range(n_terms):
        zero = True
        for b in range(n_copy):
            w_copies[b] = W[t, copy_components[b]]
            if w_copies[b] != 0.0:
                zero = False
        if not zero:
            np.dot(Phi_copies[functions[t]], w_copies[:n_copy], product)
            for a in range(m):
                out[indices[a]] += product[a]
    return kernels.all_finite(out)


@njit(cache=True)
def stage_eigen(V, Vinv, phi_diag, phi_at_zero, functions, coefficients, F, N, h, base, indices, is_linear, out,
                W, z_acc, z_in, z_out):
    """As :func:`stage_real` with the linear components in the eigenbasis:
    out_lin = base_lin + Re(V sum_t phi_{f_t} (Vinv W_t,lin)) (complex BLAS gemv; z_* are (m,) scratch)."""
    n_terms = functions.shape[0]
    _outside_linear_part(phi_at_zero, functions, coefficients, F, N, h, base, is_linear, out, W)
    m = indices.shape[0]
    if m == 0:
        return kernels.all_finite(out)
    for a in range(m):
        z_acc[a] = 0.0
    for t in range(n_terms):
        for b in range(m):
            z_in[b] = W[t, indices[b]]
        np.dot(Vinv, z_in, z_out)
        d = phi_diag[functions[t]]
        for a in range(m):
            z_acc[a] += d[a] * z_out[a]
    np.dot(V, z_acc, z_out)
    for a in range(m):
        out[indices[a]] += z_out[a].real
    return kernels.all_finite(out)


@njit(cache=True)
def dense_coefficients(y_old, N, Vinv, indices, n, z, z_in):
    """The dense output's quadratic ``n0 + n1 s + n2 s^2`` through N1, (N2 + N3)/2, N4 into ``n`` (3, n) and the
    eigenbasis coordinates ``Vinv [y_old, n0, n1, n2]`` of its linear components into ``z`` (4, m) complex."""
    for i in range(y_old.shape[0]):
        mid = 0.5 * (N[1, i] + N[2, i])
        n[0, i] = N[0, i]
        n[1, i] = -3.0 * N[0, i] + 4.0 * mid - N[3, i]
        n[2, i] = 2.0 * N[0, i] - 4.0 * mid + 2.0 * N[3, i]
    m = indices.shape[0]
    for r in range(4):
        for a in range(m):
            z_in[a] = y_old[indices[a]] if r == 0 else n[r - 1, indices[a]]
        np.dot(Vinv, z_in[:m], z[r])


@njit(cache=True)
def dense_state(theta, h, y_old, n, z, lam, V, indices, z_work, phi, modal, z_out, out):
    """The state at ``t_old + theta h`` (module docstring, "Dense output") into ``out``; z_work, modal, z_out
    (m,) and phi (4, m) complex scratch."""
    th = theta * h
    for i in range(y_old.shape[0]):
        out[i] = y_old[i] + th * (n[0, i] + theta * n[1, i] / 2.0 + theta * theta * n[2, i] / 3.0)
    m = indices.shape[0]
    if m == 0:
        return
    for a in range(m):
        z_work[a] = th * lam[a]
    phi_into(z_work[:m], 3, phi)
    for a in range(m):
        modal[a] = phi[0, a] * z[0, a] + th * (phi[1, a] * z[1, a] + theta * phi[2, a] * z[2, a]
                                               + 2.0 * theta * theta * phi[3, a] * z[3, a])
    np.dot(V, modal, z_out)
    for a in range(m):
        out[indices[a]] = z_out[a].real


class ExponentialDenseOutput(DenseOutput):
    """Continuous extension of one ETDRK4 step (module docstring), exact for the linear part; evaluated by the
    compiled :func:`dense_state`, the function the compiled loop samples for its event search."""

    def __init__(self, t_old, t, y_old, N, part):
        super().__init__(t_old, t)
        self.h = t - t_old
        self.y_old = np.array(y_old, dtype=np.float64)
        self.part = part
        m = part.m
        self.n = np.empty((3, self.y_old.size))
        self.z = np.empty((4, m), dtype=np.complex128)
        self.V = np.ascontiguousarray(part.V, dtype=np.complex128)
        self.lam = np.ascontiguousarray(part.lam, dtype=np.complex128)
        self._scratch = [np.empty(m, dtype=np.complex128) for _ in range(3)]
        self._phi = np.empty((4, m), dtype=np.complex128)
        dense_coefficients(self.y_old, np.ascontiguousarray(N, dtype=np.float64),
                           np.ascontiguousarray(part.Vinv, dtype=np.complex128), part.indices, self.n, self.z,
                           self._scratch[0])

    def _one(self, theta):
        out = np.empty_like(self.y_old)
        z_work, modal, z_out = self._scratch
        dense_state(theta, self.h, self.y_old, self.n, self.z, self.lam, self.V, self.part.indices, z_work,
                    self._phi, modal, z_out, out)
        return out

    def _evaluate(self, t):
        theta = (t - self.t_min) / self.h
        if t.ndim == 0:
            return self._one(float(theta))
        return np.stack([self._one(float(th)) for th in theta], axis=1)


class ExponentialRK4(Integrator):
    """Krogstad's exponential RK4 with a fixed step; the linear part is propagated exactly (module docstring).

    Options: ``step`` (required), ``linear_part`` (required): ``(indices, L)`` over the state vector, or a
    callable ``linear_part(t, y) -> (indices, L)`` re-evaluated when the remainder becomes stiff.
    Counters: ``njev`` evaluations of the linear part, ``nlu`` eigen-decompositions (that of the part with its
    driven rows derived from the part's, :meth:`LinearPart.extended`).
    """

    name = "etdrk4"
    order = 4
    fixed_step = True
    options = {"max_step": ("s", "largest step: the step taken is min(step, max_step)")}
    #: the simulation passes ``linear_part`` (from the models' ``stiff_linear_part``)
    uses_linear_part = True

    def __init__(self, fun, t0, y0, t_bound, *, linear_part=None, **options):
        if linear_part is None:
            raise ValueError(f"{self.name} needs linear_part=(indices, L) or a callable linear_part(t, y) -> "
                             f"(indices, L): the stiff linear dynamics it propagates exactly (a flexible scene's "
                             f"shell.simulation.Simulation supplies it from dynamics.modal_linear_part)")
        if not callable(linear_part):
            if not isinstance(linear_part, (tuple, list)) or len(linear_part) != 2:
                raise ValueError(f"{self.name}: linear_part must be (indices, L) or a callable, got "
                                 f"{type(linear_part).__name__}")
        self.linear_part_option = linear_part
        self._f = None
        super().__init__(fun, t0, y0, t_bound, **options)

    # the derivative at (t, y) is needed only when a step starts without a reset in between (a reset
    # computes it anyway); evaluating it lazily saves one evaluation per step of a sampled closed loop
    @property
    def f(self):
        if self._f is None:
            self._f = self._initial_derivative(self.t, self.y)
        return self._f

    @f.setter
    def f(self, value):
        self._f = value

    def _setup(self):
        self.h = min(self.step_option, self.max_step)
        n = self.n
        self.N = np.empty((4, n))
        self.Y = np.empty((4, n))  # stage states Y2, Y3, Y4 and the new state
        self.W = np.empty((MAX_TERMS, n))
        self.warned_stiff = False
        self.last_rho = 0.0
        # the build is the first step's check (at its start, drift 0): the next after 2 steps, as after any such check
        self.check_interval = 2
        self.steps_since_check = -1
        self.max_check_interval = max(MAX_CHECK_INTERVAL, int(MAX_CHECK_TIME / self.h))
        self._set_linear_part(self.t, self.y)

    def _set_linear_part(self, t, y):
        option = self.linear_part_option
        indices, L = option(t, y.copy()) if callable(option) else option
        self.njev += 1
        part = LinearPart(indices, L, self.n, self.name)
        self.base_indices, self.base_L = part.indices, part.L
        self.base_L_norm = float(np.linalg.norm(part.L))  # the drift's scale, once per build
        self.nlu += 1
        if part.m == 0:
            warnings.warn(f"{self.name}: the linear part is empty (no flexible modes); the method is the classical "
                          f"rk4 at a higher cost per step", stacklevel=4)
        else:
            rows, coupling = self._driven_coupling(t, y, part)
            if rows.size:
                part = part.extended(rows, coupling, self.n)
                self.nlu += 1
        part.check_exponential(self.h)
        self.part = part
        self.y_lin = np.empty(part.m)
        self.product = np.empty(part.m)
        self.w_stack = np.empty(MAX_TERMS * part.other_rows.size)
        self.w_copies = np.empty(part.copy_rows.size)
        self.z_acc = np.empty(part.m, dtype=np.complex128)
        self.z_in = np.empty(part.m, dtype=np.complex128)
        self.z_out = np.empty(part.m, dtype=np.complex128)
        self.Phi_other, self.Phi_copies = part.stage_matrices(self.h)
        self.phi_diag_h = None
        self.phi_diag = None

    def _check_drift(self, t, y, force):
        """Re-evaluate a callable linear part (every ``check_interval`` steps, growing up to
        MAX_CHECK_INTERVAL while it does not move: :func:`check_growth`, or now when ``force``) and rebuild the matrix functions when
        it moved by more than DRIFT_TOLERANCE. Returns True if it was rebuilt."""
        self.steps_since_check += 1
        if not force and self.steps_since_check < self.check_interval:
            return False
        self.steps_since_check = 0
        return self.check_linear_part(t, y)

    def check_linear_part(self, t, y):
        """The check itself (what :meth:`_check_drift` does when one is due; the compiled loop, which keeps the
        step counters, calls it directly): evaluate the callable linear part at (t, y), lengthen the check
        interval while it does not move, rebuild when it moved. Returns True if it was rebuilt."""
        indices, L = self.linear_part_option(t, y.copy())
        self.njev += 1
        L = np.ascontiguousarray(L, dtype=np.float64)
        scale = self.base_L_norm
        same_shape = L.shape == self.base_L.shape and np.array_equal(np.asarray(indices), self.base_indices)
        drift = frobenius_distance(L, self.base_L) / scale if same_shape and scale > 0.0 else np.inf
        if drift <= DRIFT_TOLERANCE:
            self.check_interval = min(check_growth(drift) * self.check_interval, self.max_check_interval)
            return False
        self.check_interval = 1
        self._set_linear_part(t, y)
        return True

    def _driven_coupling(self, t, y, part):
        """(rows, C): the components outside the linear part whose derivative depends on it (an IMU integrating
        a node's rate and acceleration, a wheel angle measured against the structure), and their coupling
        ``C = (df/dy)[rows, linear] P`` to its oscillating modes (module docstring); forward differences over the
        m linear components (m evaluations of fun, exact up to round-off for a linear dependence)."""
        f = np.asarray(self.fun(t, y), dtype=np.float64)
        J = np.empty((self.n, part.m))
        y_pert = y.copy()
        for k, i in enumerate(part.indices):
            delta = np.sqrt(EPS) * max(1.0, abs(y[i]))
            y_pert[i] = y[i] + delta
            J[:, k] = (np.asarray(self.fun(t, y_pert), dtype=np.float64) - f) / delta
            y_pert[i] = y[i]
        self.nfev += part.m + 1
        rows = np.flatnonzero(~part.is_linear & np.any(J != 0.0, axis=1))
        # spectral projector on the non-zero eigenvalues: the zero ones (rigid-body velocities) are not stiff,
        # and coupling a driven row to them would make the extended matrix defective (a Jordan block)
        P = ((part.V * part.moving()) @ part.Vinv).real
        return rows, J[rows] @ P

    def _stage(self, k, h, nominal, out):
        base_index, functions, coefficients = STAGES[k]
        base = self.y if base_index < 0 else self.Y[base_index]
        part = self.part
        W = self.W[:functions.shape[0]]
        if nominal:
            return stage_real(self.Phi_other[k], self.Phi_copies, PHI_AT_ZERO, functions, coefficients, self.f,
                              self.N, h, base, part.indices, part.dense_other_components,
                              part.dense_copy_components, part.zero_components, part.is_linear, out, W, self.w_stack,
                              self.w_copies, self.product)
        if self.phi_diag_h != h:
            self.phi_diag = part.diagonal_functions(h)
            self.phi_diag_h = h
        return stage_eigen(part.V, part.Vinv, self.phi_diag, PHI_AT_ZERO, functions, coefficients, self.f, self.N,
                           h, base, part.indices, part.is_linear, out, W, self.z_acc, self.z_in, self.z_out)

    def _evaluate_remainder(self, j, t, y):
        f = np.asarray(self.fun(t, y), dtype=np.float64)
        self.nfev += 1
        if not kernels.all_finite(f):
            return f
        self._remainder(f, y, self.N[j])
        return None

    def _remainder(self, f, y, out):
        part = self.part
        remainder(f, y, part.nonzero_components, part.L_other, part.other_components, part.copy_components,
                  part.copied_components, self.y_lin, self.product, out)

    def _step_impl(self):
        t = self.t
        remaining = self.t_bound - t
        last = remaining <= self.h * (1.0 + 1e-9)
        h = remaining if last else self.h
        nominal = abs(h - self.h) <= 1e-12 * self.h
        t_new = self.t_bound if last else t + h
        if callable(self.linear_part_option):
            self._check_drift(t, self.y, force=False)
        refreshed = False
        while True:
            self._remainder(self.f, self.y, self.N[0])
            for k in range(3):
                if not self._stage(k, h, nominal, self.Y[k]):
                    return self._fail(self._nonfinite_reason(f"stage {k + 2}", t + C_NODES[k] * h, self.Y[k]),
                                      t + C_NODES[k] * h, self.Y[k], self._suggestion(h))
                bad = self._evaluate_remainder(k + 1, t + C_NODES[k] * h, self.Y[k])
                if bad is not None:
                    return self._fail(self._nonfinite_reason("the derivative fun(t, y)", t + C_NODES[k] * h, bad),
                                      t + C_NODES[k] * h, self.Y[k], "Check the model at that state; "
                                      + self._suggestion(h))
                if k == 1 and not refreshed and self._remainder_is_stiff(h):
                    if not callable(self.linear_part_option):
                        self._warn_stiff(h)
                    elif self._check_drift(t, self.y, force=True):
                        refreshed = True
                        self.nrejected += 1
                        break
            else:
                break
        if not self._stage(3, h, nominal, self.Y[3]):
            return self._fail(self._nonfinite_reason("the new state", t_new, self.Y[3]), t_new, self.Y[3],
                              self._suggestion(h))
        y_new = self.Y[3].copy()
        if self.normalize is not None:
            self.normalize(y_new)
        self.t_old = t
        self.y_old = self.y
        self.f_old = self._f
        self.t = t_new
        self.y = y_new
        self._f = None
        return True

    def _remainder_is_stiff(self, h):
        """h rho(N) > STIFF_REMAINDER_BOUND from the two stages at c = 1/2, when they differ beyond round-off."""
        rho, noise = remainder_stiffness(self.N[1], self.N[2], self.Y[0], self.Y[1], self.part.indices,
                                         self.part.L_norm)
        # N3 - N2 carries the round-off of f and L Y: a quotient at that level measures nothing
        if h * noise > 0.1 * STIFF_REMAINDER_BOUND:
            return False
        self.last_rho = rho
        return h * rho > STIFF_REMAINDER_BOUND

    def _warn_stiff(self, h):
        if self.warned_stiff:
            return
        self.warned_stiff = True
        warnings.warn(f"{self.name}: the dynamics outside the linear part became stiff near t={self.t:.6g} s "
                      f"(h rho = {h * self.last_rho:.3g} > {STIFF_REMAINDER_BOUND}); the linear part no longer "
                      f"describes the fast modes (the configuration moved away from the one L was built at). "
                      f"Pass linear_part as a callable (t, y) -> (indices, L) so that it is re-evaluated, or "
                      f"reduce the step", StiffRemainderWarning, stacklevel=4)

    def _suggestion(self, h):
        return (f"The linear part is propagated exactly, so a blow-up comes from the remainder N = f - L y "
                f"(last stiffness estimate h rho = {h * self.last_rho:.3g}): reduce the step, or make sure the "
                f"linear part describes the scene's fast modes at this configuration")

    def _dense_output_impl(self):
        return ExponentialDenseOutput(self.t_old, self.t, self.y_old, self.N, self.part)

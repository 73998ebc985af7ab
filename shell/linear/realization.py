"""Realizations and discretizations of the linear blocks: transfer functions, second-order filters, zero-order
hold, series connection. Design-time Python; the blocks step the result with :mod:`shell.linear.kernels`.

Transfer function to a minimal realization. ``G = num / den``, coefficients highest power first (numpy's and
python-control's order), in s or, with a sample time, in z. With ``den`` made monic and ``D = b_n`` (the
numerator's coefficient of ``s^n``), the strictly proper rest ``r(s) = num(s) - D den(s)`` is realized in the
controller canonical form (Kailath, Linear Systems, 1980, Sec. 2.1; MATLAB's and scipy's ``tf2ss``)::

    A = [[-a_1, -a_2, ..., -a_n], [1, 0, ..., 0], ..., [0, ..., 1, 0]],  B = e_1,  C = [r_(n-1), ..., r_0]

which is controllable; it is observable, so minimal, exactly when num and den have no common root. Common roots
are removed by the Kalman decomposition (:func:`minimal_realization`: orthogonal staircase bases of the
reachable subspace of (A, B) and of the observable subspace of (A, C), Varga 1981, "Numerically stable
algorithm for standard controllability form determination", Electronics Letters 17(2)), with a warning that
says how many states went. The realization is then balanced by a diagonal similarity of powers of two
(``scipy.linalg.matrix_balance``: exact in floating point) so that companion forms of stiff filters keep their
accuracy.

Second-order filters, ``H(s) = N(s) / D(s)`` with normalized quadratics ``q(s) = s^2 / w^2 + 2 zeta s / w + 1``
(unit gain at zero frequency)::

    low-pass  N = 1,                          D = q(w, zeta)
    notch     N = q(w, g zeta),               D = q(w, zeta)     |H(j w)| = g, the gain at the notch
    bending   N = q(w_n, zeta_n),             D = q(w_d, zeta_d) (gain or phase stabilization of a bending mode)

Sampled filters: Tustin's (bilinear) transform with prewarping, each quadratic at its own frequency::

    s -> k (z - 1) / (z + 1),   k = w / tan(w T / 2)
    q_d(z) = (z + 1)^2 q(k (z - 1)/(z + 1)) = (c^2 + 2 zeta c + 1) z^2 + 2 (1 - c^2) z + (c^2 - 2 zeta c + 1),  c = k / w

so that the sampled filter's response is ``H_d(exp(j W T)) = N(j k_n tan(W T / 2)) / D(j k_d tan(W T / 2))``:
the numerator's and the denominator's natural frequencies land exactly where the continuous filter has them
(a notch's null stays on the mode it was designed for, at any sample rate), the gain at zero frequency stays 1,
and the gain at the notch frequency stays ``g`` (Franklin, Powell, Workman, Digital Control of Dynamic Systems,
3rd ed., Sec. 6.3.2, prewarping; applied per factor). Frequencies must lie below the Nyquist frequency 1/(2T).

Zero-order hold of a continuous system: ``[[Ad, Bd], [0, I]] = expm([[A, B], [0, 0]] T)`` (Van Loan 1978,
"Computing integrals involving the matrix exponential", IEEE TAC 23(3)); C and D unchanged.
"""

from __future__ import annotations

import math
import warnings
from dataclasses import dataclass

import numpy as np
from scipy.linalg import expm, matrix_balance

from shell.linear.system import LinearSystem, LinearSystemError

#: relative size below which a staircase step's singular value counts as zero (a removed state)
MINIMAL_TOLERANCE = 1e-10


def _coefficients(where: str, key: str, values) -> np.ndarray:
    try:
        array = np.atleast_1d(np.asarray(values, dtype=float))
    except (TypeError, ValueError):
        raise LinearSystemError(f"{where}: {key}: expected a list of numbers (highest power first), "
                                f"given {values!r}") from None
    if array.ndim != 1 or not array.size or not np.all(np.isfinite(array)):
        raise LinearSystemError(f"{where}: {key}: expected a non-empty list of finite numbers (highest power "
                                f"first), given {values!r}")
    nonzero = np.flatnonzero(array)
    return array[nonzero[0]:] if nonzero.size else np.zeros(1)


def _orthonormal_staircase(A, B, tolerance) -> np.ndarray:
    """Orthonormal basis of the reachable subspace span[B, A B, A^2 B, ...] (columns), built block by block."""
    n = A.shape[0]
    basis = np.zeros((n, 0))
    block = B
    scale = max(1.0, np.linalg.norm(A, 2), np.linalg.norm(B, 2)) * tolerance
    while basis.shape[1] < n and block.size:
        for _ in range(2):  # twice: classical Gram-Schmidt loses orthogonality once
            block = block - basis @ (basis.T @ block)
        U, s, _ = np.linalg.svd(block, full_matrices=False)
        rank = int(np.sum(s > scale))
        if rank == 0:
            break
        basis = np.hstack([basis, U[:, :rank]])
        block = A @ U[:, :rank]
    return basis


def minimal_realization(system: LinearSystem, tolerance: float = MINIMAL_TOLERANCE) -> LinearSystem:
    """The reachable and observable part of ``system`` (the Kalman decomposition; module docstring). The
    input-output behaviour is unchanged; states are in new coordinates (named x[k])."""
    A, B, C = system.A, system.B, system.C
    reachable = _orthonormal_staircase(A, B, tolerance)
    A, B, C = reachable.T @ A @ reachable, reachable.T @ B, C @ reachable
    observable = _orthonormal_staircase(A.T, C.T, tolerance)
    A, B, C = observable.T @ A @ observable, observable.T @ B, C @ observable
    return LinearSystem(A, B, C, system.D, system.sample_time, system.input_names, system.output_names, (),
                        system.input_units, system.output_units, system.where)


def balanced(system: LinearSystem) -> LinearSystem:
    """The same system after a diagonal similarity of powers of two that equalizes A's row and column norms."""
    if not system.A.size:
        return system
    _, (scale, _) = matrix_balance(system.A, permute=False, separate=True)
    A = system.A * scale[None, :] / scale[:, None]
    return LinearSystem(A, system.B / scale[:, None], system.C * scale[None, :], system.D, system.sample_time,
                        system.input_names, system.output_names, (), system.input_units, system.output_units,
                        system.where)


def transfer_function(numerator, denominator, sample_time=None, where: str = "transfer function",
                      tolerance: float = MINIMAL_TOLERANCE) -> LinearSystem:
    """Minimal, balanced realization of ``numerator / denominator`` (module docstring), continuous or sampled.
    Refuses an improper function (a numerator of higher degree: a derivative, which no block can realize);
    warns when numerator and denominator share roots (the realization then has fewer states than the degree)."""
    num, den = _coefficients(where, "numerator", numerator), _coefficients(where, "denominator", denominator)
    if not np.any(den):
        raise LinearSystemError(f"{where}: denominator: every coefficient is zero")
    n = den.size - 1
    if num.size - 1 > n:
        raise LinearSystemError(f"{where}: numerator: degree {num.size - 1} above the denominator's {n}: an "
                                "improper transfer function (a derivative) cannot be realized; add poles")
    b = np.concatenate([np.zeros(n + 1 - num.size), num]) / den[0]
    a = den / den[0]
    D = b[0]
    A = np.zeros((n, n))
    if n:
        A[0, :] = -a[1:]
        A[np.arange(1, n), np.arange(n - 1)] = 1.0
    B = np.zeros((n, 1))
    if n:
        B[0, 0] = 1.0
    C = (b[1:] - D * a[1:]).reshape(1, n)
    full = balanced(LinearSystem(A, B, C, [[D]], sample_time, where=where))
    reduced = minimal_realization(full, tolerance)
    if reduced.A.shape[0] < n:
        zeros, poles = np.roots(num) if num.size > 1 else np.zeros(0), np.roots(den)
        shared = [p for p in poles if zeros.size and np.min(np.abs(zeros - p)) <= 1e-6 * max(1.0, abs(p))]
        shown = ", ".join(f"{p:.6g}" for p in shared) or "close roots"
        warnings.warn(f"{where}: numerator and denominator share {n - reduced.A.shape[0]} root(s) ({shown}); "
                      f"they cancel: the realization has {reduced.A.shape[0]} states, not {n}")
    return balanced(reduced)


def series(first: LinearSystem, second: LinearSystem) -> LinearSystem:
    """``second`` after ``first`` (y = G2 G1 u): x = [x1; x2]."""
    if first.sample_time != second.sample_time:
        raise LinearSystemError(f"{second.where}: cannot follow {first.where}: sample times {second.sample_time} "
                                f"and {first.sample_time} s differ")
    if second.B.shape[1] != first.C.shape[0]:
        raise LinearSystemError(f"{second.where}: has {second.B.shape[1]} inputs, {first.where} gives "
                                f"{first.C.shape[0]} outputs")
    n1, n2 = first.A.shape[0], second.A.shape[0]
    A = np.block([[first.A, np.zeros((n1, n2))], [second.B @ first.C, second.A]])
    B = np.vstack([first.B, second.B @ first.D])
    C = np.hstack([second.D @ first.C, second.C])
    return LinearSystem(A, B, C, second.D @ first.D, first.sample_time, first.input_names, second.output_names,
                        (), first.input_units, second.output_units, f"{first.where} then {second.where}")


def zero_order_hold(system: LinearSystem, sample_time: float) -> LinearSystem:
    """The sampled system seen through a zero-order hold of period ``sample_time`` (module docstring)."""
    if system.discrete:
        raise LinearSystemError(f"{system.where}: is sampled already (period {system.sample_time} s)")
    n, m = system.B.shape
    augmented = np.zeros((n + m, n + m))
    augmented[:n, :n], augmented[:n, n:] = system.A, system.B
    E = expm(augmented * float(sample_time))
    return LinearSystem(E[:n, :n], E[:n, n:], system.C, system.D, sample_time, system.input_names,
                        system.output_names, system.state_names, system.input_units, system.output_units,
                        system.where)


@dataclass(frozen=True)
class Quadratic:
    """``q(s) = s^2 / w^2 + 2 zeta s / w + 1``, ``w = 2 pi frequency_hz``."""

    frequency_hz: float
    damping: float

    @property
    def omega(self) -> float:
        return 2.0 * math.pi * self.frequency_hz

    def continuous(self) -> np.ndarray:
        """Coefficients in s, highest power first."""
        return np.array([1.0 / self.omega ** 2, 2.0 * self.damping / self.omega, 1.0])

    def tustin(self, sample_time: float) -> np.ndarray:
        """Coefficients in z of (z + 1)^2 q(k (z - 1)/(z + 1)), prewarped at this quadratic's frequency."""
        c = 1.0 / math.tan(self.omega * sample_time / 2.0)  # k / w
        zeta = self.damping
        return np.array([c * c + 2.0 * zeta * c + 1.0, 2.0 * (1.0 - c * c), c * c - 2.0 * zeta * c + 1.0])


@dataclass(frozen=True)
class SecondOrderFilter:
    """``H = N / D`` of normalized quadratics (N = 1 for a low-pass); see the module docstring."""

    kind: str
    denominator: Quadratic
    numerator: Quadratic | None = None
    where: str = "filter"

    def __post_init__(self):
        for role, quadratic, least in (("denominator", self.denominator, "> 0"),
                                       ("numerator", self.numerator, ">= 0")):
            if quadratic is None:
                continue
            f, zeta = quadratic.frequency_hz, quadratic.damping
            if not (math.isfinite(f) and f > 0.0):
                raise LinearSystemError(f"{self.where}: {role} frequency: expected a finite frequency > 0 Hz, "
                                        f"given {f}")
            if not math.isfinite(zeta) or zeta < 0.0 or (least == "> 0" and zeta == 0.0):
                raise LinearSystemError(f"{self.where}: {role} damping: expected a finite damping ratio {least}"
                                        f"{' (a stable filter)' if role == 'denominator' else ''}, given {zeta}")

    def continuous(self) -> LinearSystem:
        """The continuous filter as a minimal state-space system (2 states)."""
        numerator = self.numerator.continuous() if self.numerator else [1.0]
        return transfer_function(numerator, self.denominator.continuous(), where=self.where)

    def tustin(self, sample_time: float) -> LinearSystem:
        """The sampled filter (Tustin with prewarping per quadratic; module docstring)."""
        nyquist = 0.5 / sample_time
        for role, quadratic in (("numerator", self.numerator), ("denominator", self.denominator)):
            if quadratic is not None and quadratic.frequency_hz >= nyquist:
                raise LinearSystemError(f"{self.where}: {role} frequency {quadratic.frequency_hz:g} Hz is not below "
                                        f"the Nyquist frequency {nyquist:g} Hz of the sample period {sample_time:g} "
                                        "s; sample faster or run the filter continuous")
        numerator = self.numerator.tustin(sample_time) if self.numerator else np.array([1.0, 2.0, 1.0])
        return transfer_function(numerator, self.denominator.tustin(sample_time), sample_time, where=self.where)


def low_pass(frequency_hz: float, damping: float, where: str = "low-pass filter") -> SecondOrderFilter:
    """``w^2 / (s^2 + 2 zeta w s + w^2)``."""
    return SecondOrderFilter("low_pass", Quadratic(frequency_hz, damping), None, where)


def notch(frequency_hz: float, damping: float, notch_gain: float, where: str = "notch filter") -> SecondOrderFilter:
    """``(s^2 + 2 g zeta w s + w^2) / (s^2 + 2 zeta w s + w^2)``: gain ``g = notch_gain`` (0 <= g < 1) at the
    notch frequency, width set by ``damping`` (the -3 dB width of a deep notch is about 2 zeta f)."""
    if not (math.isfinite(notch_gain) and 0.0 <= notch_gain < 1.0):
        raise LinearSystemError(f"{where}: notch gain: expected 0 <= gain < 1 (the gain at the notch frequency; "
                                f"0.1 is -20 dB), given {notch_gain}")
    return SecondOrderFilter("notch", Quadratic(frequency_hz, damping),
                             Quadratic(frequency_hz, notch_gain * damping), where)


def bending(numerator_frequency_hz: float, numerator_damping: float, denominator_frequency_hz: float,
            denominator_damping: float, where: str = "bending filter") -> SecondOrderFilter:
    """``q(w_n, zeta_n) / q(w_d, zeta_d)``: the general second-order bending filter, unit gain at zero frequency."""
    return SecondOrderFilter("bending", Quadratic(denominator_frequency_hz, denominator_damping),
                             Quadratic(numerator_frequency_hz, numerator_damping), where)

"""A linear time-invariant system in state-space form, continuous or sampled, with named signals.

    continuous (sample_time None):  x' = A x + B u,            y = C x + D u
    sampled (period sample_time s): x[k+1] = A x[k] + B u[k],  y[k] = C x[k] + D u[k]

The record that the linear blocks, the frequency-domain tools (:mod:`shell.analysis.margins`, ``flexshell
bode``) and the Kalman design (:mod:`shell.analysis.kalman`) share: python-control's ``StateSpace`` with its
``dt``, without the dependency. Every system is checked when it is made (:func:`check_state_space`): square A,
shapes that agree, finite entries, a positive finite sample time; a refusal names where the matrices came from
(``where``: a file, a file and a group, a model) and the matrix (``A``, ``B``, ``C``, ``D``).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

KEYS = ("A", "B", "C", "D")


class LinearSystemError(ValueError):
    """Matrices that do not make the system asked for; the message names where they came from and the key."""


def _finite_matrix(where: str, key: str, value) -> np.ndarray:
    try:
        matrix = np.asarray(value, dtype=float)
    except (TypeError, ValueError):
        raise LinearSystemError(f"{where}: {key}: expected a matrix of numbers, given {type(value).__name__}") \
            from None
    if matrix.ndim != 2:
        raise LinearSystemError(f"{where}: {key}: expected a 2-D matrix, given an array of shape {matrix.shape}")
    bad = np.argwhere(~np.isfinite(matrix))
    if bad.size:
        row, column = (int(i) for i in bad[0])
        raise LinearSystemError(f"{where}: {key}: entry [{row}, {column}] is {matrix[row, column]} ({len(bad)} "
                                "entries are not finite); expected finite numbers")
    return matrix


def check_state_space(A, B, C, D, where: str = "state-space system"):
    """(A, B, C, D) as finite float matrices of agreeing shapes: A (n, n), B (n, m), C (p, n), D (p, m)."""
    A, B, C, D = (_finite_matrix(where, key, value) for key, value in zip(KEYS, (A, B, C, D)))
    n = A.shape[0]
    if A.shape != (n, n):
        raise LinearSystemError(f"{where}: A: expected a square matrix, given shape {A.shape}")
    if B.shape[0] != n:
        raise LinearSystemError(f"{where}: B: expected {n} rows (the states of A), given shape {B.shape}")
    if C.shape[1] != n:
        raise LinearSystemError(f"{where}: C: expected {n} columns (the states of A), given shape {C.shape}")
    if D.shape != (C.shape[0], B.shape[1]):
        raise LinearSystemError(f"{where}: D: expected shape {(C.shape[0], B.shape[1])} (outputs of C x inputs of "
                                f"B), given {D.shape}")
    return A, B, C, D


def check_sample_time(sample_time, where: str = "state-space system") -> float | None:
    """None (continuous) or a finite period > 0 in seconds."""
    if sample_time is None:
        return None
    try:
        value = None if isinstance(sample_time, bool) else float(sample_time)
    except (TypeError, ValueError):
        value = None
    if value is None or not np.isfinite(value) or value <= 0.0:
        raise LinearSystemError(f"{where}: sample_time: expected a period > 0 s (or none for a continuous system), "
                                f"given {sample_time!r}")
    return value


def _names(where: str, what: str, given, count: int, default: str) -> tuple:
    names = tuple(str(name) for name in given) if given is not None and len(given) else \
        tuple(f"{default}[{k}]" for k in range(count))
    if len(names) != count:
        raise LinearSystemError(f"{where}: {what}: expected {count} names, given {len(names)}")
    return names


@dataclass(frozen=True)
class LinearSystem:
    """``(A, B, C, D)``, ``sample_time`` (None: continuous), names and units of the signals (see module)."""

    A: np.ndarray
    B: np.ndarray
    C: np.ndarray
    D: np.ndarray
    sample_time: float | None = None
    input_names: tuple = ()
    output_names: tuple = ()
    state_names: tuple = ()
    input_units: tuple = ()
    output_units: tuple = ()
    #: where the matrices came from, for messages (a file, a file and a group, a model)
    where: str = field(default="state-space system", compare=False)

    def __post_init__(self):
        A, B, C, D = check_state_space(self.A, self.B, self.C, self.D, self.where)
        n, m, p = A.shape[0], B.shape[1], C.shape[0]
        values = {"A": A, "B": B, "C": C, "D": D,
                  "sample_time": check_sample_time(self.sample_time, self.where),
                  "input_names": _names(self.where, "input names", self.input_names, m, "u"),
                  "output_names": _names(self.where, "output names", self.output_names, p, "y"),
                  "state_names": _names(self.where, "state names", self.state_names, n, "x"),
                  "input_units": _names(self.where, "input units", self.input_units or ("",) * m, m, ""),
                  "output_units": _names(self.where, "output units", self.output_units or ("",) * p, p, "")}
        for key, value in values.items():
            object.__setattr__(self, key, value)

    @property
    def discrete(self) -> bool:
        return self.sample_time is not None

    @property
    def shape(self) -> tuple[int, int, int]:
        """(states, inputs, outputs)."""
        return self.A.shape[0], self.B.shape[1], self.C.shape[0]

    def poles(self) -> np.ndarray:
        return np.linalg.eigvals(self.A) if self.A.size else np.zeros(0, dtype=complex)

    def is_stable(self) -> bool:
        """Every pole strictly inside the stability region (left half-plane; unit disc when sampled)."""
        poles = self.poles()
        if not poles.size:
            return True
        return bool(np.max(np.abs(poles)) < 1.0) if self.discrete else bool(np.max(poles.real) < 0.0)

    def require_stable(self, what: str = "the system") -> None:
        """Refuse a system that is not asymptotically stable (where the use requires it: an estimator's error
        dynamics, a filter), naming the unstable poles."""
        if self.is_stable():
            return
        poles = self.poles()
        bad = poles[np.abs(poles) >= 1.0] if self.discrete else poles[poles.real >= 0.0]
        region = "on or outside the unit circle" if self.discrete else "in the closed right half-plane"
        shown = ", ".join(f"{p:.6g}" for p in bad[:6]) + (", ..." if bad.size > 6 else "")
        raise LinearSystemError(f"{self.where}: A: {what} must be stable; {bad.size} eigenvalue(s) {region}: "
                                f"{shown}")

    def select(self, inputs=None, outputs=None) -> LinearSystem:
        """The system from the inputs to the outputs given by index (all when None), states unchanged."""
        ins = list(range(self.B.shape[1])) if inputs is None else list(inputs)
        outs = list(range(self.C.shape[0])) if outputs is None else list(outputs)
        return LinearSystem(self.A, self.B[:, ins], self.C[outs], self.D[np.ix_(outs, ins)], self.sample_time,
                            tuple(self.input_names[i] for i in ins), tuple(self.output_names[i] for i in outs),
                            self.state_names, tuple(self.input_units[i] for i in ins),
                            tuple(self.output_units[i] for i in outs), self.where)

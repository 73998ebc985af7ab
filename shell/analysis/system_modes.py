"""System modes from a linear model: frequencies, damping ratios and shapes from the eigenvalues of A,
and their comparison with finite-element (or any reference) frequencies.

For ``x' = A x`` every complex pair ``lambda = -zeta w_n +- i w_n sqrt(1 - zeta^2)`` is one mode with
undamped natural frequency ``w_n = |lambda|`` (reported in Hz) and damping ratio
``zeta = -Re(lambda) / |lambda|``; its shape is the eigenvector (state space). Eigenvalues with
``|lambda| / 2 pi`` below ``rigid_threshold_hz`` are rigid-body (or mechanism) modes; the finite
differences leave them at about sqrt(truncation) instead of exactly zero, hence the threshold
(TM-2020-5008164 App. G.4, Fig. G.4.1 compares such frequencies with NASTRAN's).
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

DEFAULT_RIGID_THRESHOLD_HZ = 1e-4


class StateSpaceModes(NamedTuple):
    frequencies_hz: np.ndarray   # (k,) undamped natural frequencies of the oscillatory modes, ascending
    damping_ratios: np.ndarray   # (k,)
    eigenvalues: np.ndarray      # (k,) the eigenvalue with positive imaginary part of each pair
    shapes: np.ndarray           # (n, k) complex state-space eigenvectors, unit norm
    real_eigenvalues: np.ndarray  # non-oscillatory eigenvalues above the rigid threshold (overdamped, unstable)
    n_rigid: int                 # eigenvalues below the rigid threshold


def state_space_modes(A, rigid_threshold_hz: float = DEFAULT_RIGID_THRESHOLD_HZ) -> StateSpaceModes:
    """Modes of ``x' = A x`` (see the module docstring)."""
    A = np.asarray(A, dtype=float)
    values, vectors = np.linalg.eig(A)
    magnitude = np.abs(values)
    rigid = magnitude < 2.0 * np.pi * rigid_threshold_hz
    # a pair is oscillatory if its imaginary part is clearly above the round-off of A
    tiny = 1e3 * np.finfo(float).eps * max(1.0, float(np.max(magnitude, initial=0.0)))
    oscillatory = ~rigid & (values.imag > tiny)
    real = ~rigid & (np.abs(values.imag) <= tiny)
    order = np.flatnonzero(oscillatory)[np.argsort(magnitude[oscillatory])]
    lam = values[order]
    return StateSpaceModes(np.abs(lam) / (2.0 * np.pi), -lam.real / np.abs(lam), lam,
                           vectors[:, order] / np.linalg.norm(vectors[:, order], axis=0),
                           np.sort(values[real].real), int(np.count_nonzero(rigid)))


def compare_frequencies(frequencies_hz, reference_hz, n: int | None = None) -> np.ndarray:
    """``frequencies_hz[:n] - reference_hz[:n]`` in Hz (both ascending), refusing too few modes."""
    a, b = np.asarray(frequencies_hz, dtype=float), np.asarray(reference_hz, dtype=float)
    n = min(a.size, b.size) if n is None else int(n)
    if a.size < n or b.size < n:
        raise ValueError(f"comparing {n} modes: the model has {a.size} oscillatory modes, the reference {b.size}")
    return a[:n] - b[:n]

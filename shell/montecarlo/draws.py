"""Dispersion draws of a Monte Carlo campaign: distributions, per-run random streams, correlation.

Every dispersed value is a transform of independent standard normals ``z`` (one per scalar
component), so one mechanism serves every distribution and correlation is imposed on the normals
before the transform (the Gaussian copula, "NORTA": Cario & Nelson, "Modeling and generating random
vectors with arbitrary marginal distributions and correlation matrix", 1997):

==================  ===========================================  ===================================
distribution        value                                        parameters
==================  ===========================================  ===================================
normal              ``mean + sigma z``                           mean, sigma
uniform             ``low + (high - low) Phi(z)``                low, high
truncated_normal    ``mean + sigma F^-1(Phi(z))``, F the         mean, sigma, low, high
                    standard normal truncated to
                    ``[(low-mean)/sigma, (high-mean)/sigma]``
lognormal           ``median exp(log_sigma z)``                  median, log_sigma
choice              ``choices[k]``, k the first index with       choices, probabilities
                    ``Phi(z) < cumsum(probabilities)[k]``
==================  ===========================================  ===================================

``Phi`` is the standard normal CDF. Correlated dispersions share one group: the concatenated normals
of its members are multiplied by the Cholesky factor ``L`` of the requested correlation matrix
(``z' = L z``); for normal marginals the matrix is the correlation of the values themselves, for the
others it is that of the underlying normals.

Streams: the normals of dispersion ``name`` in run ``i`` of a campaign with master seed ``s`` come from
``PCG64(SeedSequence(entropy=s, spawn_key=(i, *words(sha256(name)))))``, i.e. the ``i``-th child of
``SeedSequence(s)`` spawned once more by the dispersion's name. They depend on (s, i, name) only:
adding a dispersion, changing the number of runs or the executor changes no other draw. The
scenario of run ``i`` is seeded with ``[s, i]`` (docs/shell.md), so its models' noise streams also
depend on (s, i) only, and differ from the dispersion streams (different entropy).
"""

from __future__ import annotations

import functools
import hashlib
from dataclasses import dataclass, field

import numpy as np
from scipy import special, stats

DISTRIBUTIONS = {
    "normal": ("mean", "sigma"),
    "uniform": ("low", "high"),
    "truncated_normal": ("mean", "sigma", "low", "high"),
    "lognormal": ("median", "log_sigma"),
    "choice": ("choices",),
}


@functools.lru_cache(maxsize=1024)
def stream_key(name: str) -> tuple[int, ...]:
    """Four 32-bit words of sha256(name): the spawn key that makes a dispersion's stream its own."""
    digest = hashlib.sha256(name.encode()).digest()
    return tuple(int.from_bytes(digest[k:k + 4], "little") for k in range(0, 16, 4))


def standard_normals(master_seed: int, run: int, name: str, size: int) -> np.ndarray:
    """The ``size`` independent standard normals of dispersion ``name`` in run ``run``."""
    sequence = np.random.SeedSequence(entropy=master_seed, spawn_key=(int(run), *stream_key(name)))
    return np.random.Generator(np.random.PCG64(sequence)).standard_normal(size)


@dataclass
class Dispersion:
    """One dispersed scenario value: ``path`` as in ``--set``, SI-free magnitudes in ``unit``."""

    path: str
    distribution: str
    shape: tuple
    unit: str
    parameters: dict          # name -> float64 array broadcast to shape (choice: probabilities)
    choices: list = field(default_factory=list)  # choice: the YAML values

    @property
    def size(self) -> int:
        return int(np.prod(self.shape, dtype=int)) if self.shape else 1

    def transform(self, z: np.ndarray) -> np.ndarray:
        """Values (flattened, in ``unit``; choice: indices as floats) for standard normals ``z``."""
        p = self.parameters
        if self.distribution == "normal":
            return p["mean"].ravel() + p["sigma"].ravel() * z
        if self.distribution == "uniform":
            low, high = p["low"].ravel(), p["high"].ravel()
            return low + (high - low) * special.ndtr(z)
        if self.distribution == "truncated_normal":
            mean, sigma = p["mean"].ravel(), p["sigma"].ravel()
            a, b = (p["low"].ravel() - mean) / sigma, (p["high"].ravel() - mean) / sigma
            # ndtr(z) saturates at 1 for z > 8.3; use the upper tail there so ppf keeps its precision
            upper = z > 0
            q = np.where(upper, special.ndtr(-z), special.ndtr(z))
            standard = np.where(upper, -truncated_normal_ppf(q, -b, -a), truncated_normal_ppf(q, a, b))
            return mean + sigma * np.clip(standard, a, b)
        if self.distribution == "lognormal":
            return p["median"].ravel() * np.exp(p["log_sigma"].ravel() * z)
        if self.distribution == "choice":
            cumulative = np.cumsum(p["probabilities"])
            cumulative[-1] = 1.0
            index = np.searchsorted(cumulative, special.ndtr(z), side="right")
            return np.minimum(index, len(self.choices) - 1).astype(np.float64)
        raise ValueError(f"unknown distribution {self.distribution!r}")

    def value(self, flat: np.ndarray):
        """The drawn value shaped like the dispersion (choice: the chosen YAML value)."""
        if self.distribution == "choice":
            return self.choices[int(flat[0])]
        return flat.reshape(self.shape) if self.shape else float(flat[0])

    def columns(self) -> list[str]:
        """Table column names of the flattened components: ``path`` or ``path[k]`` / ``path[j,k]``."""
        if not self.shape:
            return [self.path]
        return [f"{self.path}[{','.join(str(k) for k in index)}]" for index in np.ndindex(*self.shape)]


def truncated_normal_ppf(q, a, b):
    """``scipy.stats.truncnorm.ppf(q, a, b)`` for ``a < b`` (checked when a campaign is read) and ``q`` in [0, 1],
    element for element the same numbers: the distribution's own quantile kernel inside the support and its bounds
    at q = 0 and 1, without the public method's argument handling, which costs more than the quantiles of a run's
    few components (tests/montecarlo/test_draws.py compares the two bit for bit)."""
    with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
        inside = stats.truncnorm._ppf(q, a, b) * 1.0 + 0.0
    return np.where(q == 0.0, a * 1.0 + 0.0, np.where(q == 1.0, b * 1.0 + 0.0, inside))


@dataclass
class CorrelationGroup:
    """Dispersions drawn jointly: their normals are mixed by ``cholesky`` (lower triangular)."""

    members: list[str]
    cholesky: np.ndarray


def draw_run(dispersions: list[Dispersion], groups: list[CorrelationGroup], master_seed: int,
             run: int) -> dict[str, np.ndarray]:
    """Flattened draws of every dispersion in run ``run``: {path: values in the dispersion's unit}."""
    normals = {d.path: standard_normals(master_seed, run, d.path, d.size) for d in dispersions}
    for group in groups:
        sizes = [normals[m].size for m in group.members]
        mixed = group.cholesky @ np.concatenate([normals[m] for m in group.members])
        for member, piece in zip(group.members, np.split(mixed, np.cumsum(sizes)[:-1])):
            normals[member] = piece
    return {d.path: d.transform(normals[d.path]) for d in dispersions}

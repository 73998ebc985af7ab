"""Per-run metrics of a Monte Carlo campaign, computed from a run's logged samples.

A metric reduces one logged signal y(t_k), k = 0..N-1 (the log's instants), optionally first mapped
sample by sample (``of``):

* ``value``: the signal itself (a vector signal gives one column per component, or pick ``component``),
* ``norm``: the Euclidean norm of each sample,
* ``quaternion_angle``: the rotation angle ``2 atan2(|v_e|, |w_e|)`` of the error quaternion
  ``e = r^* (x) q`` between each scalar-first sample ``q`` and a ``reference`` quaternion ``r`` (default
  identity): the attitude error to a command, the short way round. With ``r = [r_w, r_v]``:
  ``w_e = r_w q_w + r_v . q_v``, ``v_e = r_w q_v - q_w r_v - r_v x q_v`` (Hamilton product),

then over time (``statistic``):

* ``final``: y(t_{N-1}); ``max``, ``min``, ``max_abs``, ``mean`` over the samples;
* ``rms``: ``sqrt(mean(y_k^2))`` over the samples (equally spaced log instants);
* ``settling_time``: the first log instant t_k such that ``|y_j - target| <= tolerance`` for every
  j >= k; ``inf`` if the last sample is outside the band (not settled). Its resolution is the log period.

A metric may carry a ``requirement`` (``"<= 0.5 deg"``, ``">= 10 s"``, or a bare number in the metric's
unit after an operator): the report draws it as a line on the metric's histogram and scatter plots and
counts the runs that meet it (:func:`parse_requirement`, :func:`meets`).

Values are converted from the log's unit to the metric's ``unit`` (angles of ``quaternion_angle``
are in rad). Only numpy, after the run: nothing here runs inside the integration loop.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

REQUIREMENT_OPERATORS = ("<=", ">=", "<", ">")
STATISTICS = ("final", "max", "min", "max_abs", "mean", "rms", "settling_time")
MAPPINGS = ("value", "norm", "quaternion_angle")


@dataclass
class Metric:
    name: str
    signal: str
    statistic: str
    of: str = "value"
    component: int | None = None
    unit: str | None = None        # output unit (None: the log's unit; rad for quaternion_angle)
    tolerance: float | None = None  # settling_time band, in ``unit``
    target: float = 0.0             # settling_time target, in ``unit``
    reference: tuple = (1.0, 0.0, 0.0, 0.0)  # quaternion_angle: attitude the error is measured from
    size: int = 1                   # number of columns (set from the signal's logged shape)
    requirement: tuple | None = None  # (operator, bound in the result unit): drawn and counted by the report

    def columns(self) -> list[str]:
        return [self.name] if self.size == 1 else [f"{self.name}[{k}]" for k in range(self.size)]


def mapped_samples(metric: Metric, values: np.ndarray) -> np.ndarray:
    """(N, columns) samples after ``of`` and ``component`` (in the log's unit; rad for angles)."""
    samples = values.reshape(values.shape[0], -1)
    if metric.of == "norm":
        return np.sqrt(np.sum(samples ** 2, axis=1))[:, None]
    if metric.of == "quaternion_angle":
        if samples.shape[1] != 4:
            raise ValueError(f"metric {metric.name}: quaternion_angle needs a 4-component signal, "
                             f"{metric.signal} has {samples.shape[1]}")
        r = np.asarray(metric.reference, dtype=np.float64)
        qw, qv = samples[:, 0], samples[:, 1:]
        w_e = r[0] * qw + qv @ r[1:]
        v_e = r[0] * qv - qw[:, None] * r[1:] - np.cross(r[1:], qv)
        vector = np.sqrt(np.sum(v_e ** 2, axis=1))
        return (2.0 * np.arctan2(vector, np.abs(w_e)))[:, None]
    if metric.component is not None:
        if not 0 <= metric.component < samples.shape[1]:
            raise ValueError(f"metric {metric.name}: component {metric.component} of {metric.signal}, which has "
                             f"{samples.shape[1]} components")
        return samples[:, metric.component:metric.component + 1]
    return samples


def evaluate(metric: Metric, time: np.ndarray, samples: np.ndarray) -> np.ndarray:
    """The metric's columns for mapped, unit-converted ``samples`` (N, columns) at ``time`` (N,)."""
    if samples.shape[0] == 0:
        raise ValueError(f"metric {metric.name}: {metric.signal} has no logged samples")
    s = metric.statistic
    if s == "final":
        return samples[-1].copy()
    if s == "max":
        return samples.max(axis=0)
    if s == "min":
        return samples.min(axis=0)
    if s == "max_abs":
        return np.abs(samples).max(axis=0)
    if s == "mean":
        return samples.mean(axis=0)
    if s == "rms":
        return np.sqrt(np.mean(samples ** 2, axis=0))
    if s == "settling_time":
        outside = np.abs(samples - metric.target) > metric.tolerance
        result = np.empty(samples.shape[1])
        for c in range(samples.shape[1]):
            out = np.flatnonzero(outside[:, c])
            if out.size == 0:
                result[c] = time[0]
            elif out[-1] == samples.shape[0] - 1:
                result[c] = np.inf
            else:
                result[c] = time[out[-1] + 1]
        return result
    raise ValueError(f"unknown statistic {s!r}")


def parse_requirement(text, unit: str) -> tuple[str, float]:
    """(operator, bound in ``unit``) of a requirement such as ``"<= 0.5 deg"``; ValueError if malformed."""
    from shell.units import UnitError, to_magnitude

    if not isinstance(text, str):
        raise ValueError(f"expected a requirement such as '<= 0.5 deg' or '>= 10 s', given {text!r}")
    stripped = text.strip()
    operator = next((op for op in REQUIREMENT_OPERATORS if stripped.startswith(op)), None)
    if operator is None:
        raise ValueError(f"expected a requirement starting with one of {list(REQUIREMENT_OPERATORS)} "
                         f"(e.g. '<= 0.5 deg'), given {text!r}")
    bound_text = stripped[len(operator):].strip()
    try:
        bound = float(to_magnitude(bound_text, unit or "", (), "requirement"))
    except (UnitError, ValueError) as exc:
        raise ValueError(f"requirement {text!r}: the bound must be a number in {unit or 'the metric unit'} "
                         f"or carry a unit convertible to it ({exc})") from None
    if not np.isfinite(bound):
        raise ValueError(f"requirement {text!r}: the bound must be finite")
    return operator, bound


def meets(values: np.ndarray, requirement: tuple[str, float]) -> np.ndarray:
    """Per value, True where it meets ``requirement`` (NaN never does; +inf meets only a '>' bound)."""
    operator, bound = requirement
    values = np.asarray(values, float)
    with np.errstate(invalid="ignore"):
        return {"<=": values <= bound, ">=": values >= bound, "<": values < bound, ">": values > bound}[operator]

"""Monte Carlo campaigns: the campaign YAML schema, and one run of a campaign.

A campaign file names a scenario, what is dispersed and how, how many runs, the master seed, the
metrics computed per run and the signals kept (schema and example: docs/montecarlo.md)::

    scenario: demo_attitude_hold.yaml       # relative to the campaign file
    set: {stop.time: 60 s}                  # overrides applied to every run (as --set)
    runs: 200
    seed: 2026
    timeout: 60 s                           # wall time per run
    dispersions:
      controller.kp: {distribution: lognormal, median: "[10, 7.5, 6.25] N*m/rad", log_sigma: 0.1}
    correlations: [{between: [controller.kp, controller.kd], coefficient: 0.8}]
    metrics:
      settling: {signal: multibody.acs.attitude, of: quaternion_angle, statistic: settling_time,
                 tolerance: 1 deg}
    keep: [multibody.acs.attitude]

Run ``i`` is the scenario with the campaign's ``set:`` overrides, then one ``--set PATH=VALUE`` per
dispersion (the value drawn for run i, see :mod:`shell.montecarlo.draws`), then ``seed=[master, i]``.
Everything a run does depends only on (campaign, i): the same run alone (``flexshell montecarlo
CAMPAIGN --rerun i``, or ``flexshell run SCENARIO`` with :meth:`Campaign.overrides`) reproduces it
bit for bit. Every refusal names the campaign file, the line and the key path, like shell/scenario.py.
"""

from __future__ import annotations

import difflib
import hashlib
import os
import re
import socket
import tempfile
import time
from dataclasses import dataclass, field
from pathlib import Path

import h5py
import numpy as np

from shell.montecarlo.draws import DISTRIBUTIONS, CorrelationGroup, Dispersion, draw_run
from shell.montecarlo.metrics import MAPPINGS, STATISTICS, Metric, evaluate, mapped_samples, parse_requirement
from shell.scenario import ScenarioError, build_simulation, decode_scenario, load_yaml, parse_scenario, show
from shell.schema import Where, expect_mapping
from shell.schema.document import plain
from shell.units import UnitError, conversion_factor, parse_unit, to_magnitude, ureg

class CampaignError(ScenarioError):
    """An invalid campaign; the message starts with ``file:line: key.path:``."""


class RunTimeout(Exception):
    """Raised from the progress callback when a run exceeds the campaign's wall-time limit."""


class _Where(Where):
    """A location in the campaign file (file, line, dotted key path); errors are CampaignErrors."""

    def error(self, message: str) -> CampaignError:
        return CampaignError(f"{self.file}:{self.line}: {self.key}: {message}" if self.key
                             else f"{self.file}:{self.line}: {message}")


_mapping = expect_mapping  # the scenario's key check; the _Where decides the error type


def yaml_text(value, top: bool = True) -> str:
    """YAML flow text that reads back exactly: floats keep every bit (a '.' in the mantissa, so that
    YAML 1.1 reads ``1.0e-05`` as a float, not as text)."""
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, (int, np.integer)):
        return str(int(value))
    if isinstance(value, (float, np.floating)):
        text = repr(float(value))
        mantissa, e, exponent = text.partition("e")
        if e and "." not in mantissa:
            text = f"{mantissa}.0e{exponent}"
        return text
    if isinstance(value, str):
        return value if top else "'" + value.replace("'", "''") + "'"
    if isinstance(value, (list, tuple, np.ndarray)):
        return "[" + ", ".join(yaml_text(v, False) for v in value) + "]"
    if isinstance(value, dict):
        return "{" + ", ".join(f"{k}: {yaml_text(v, False)}" for k, v in value.items()) + "}"
    if value is None:
        return "null"
    raise TypeError(f"cannot write {value!r} as YAML")


#: most runs of one campaign (its results table is allocated when the campaign starts)
MAX_RUNS = 10**6
#: most components of one dispersed value
MAX_DRAWN = 10**4


def _one_of(value, options) -> bool:
    """``value in options`` for values of any YAML kind (a list is never an option: unhashable)."""
    return isinstance(value, str) and value in options

CAMPAIGN_KEYS = {
    "name": "campaign name", "description": "free text", "scenario": "scenario file, relative to the campaign",
    "set": "overrides applied to every run: {key.path: value}", "runs": "number of runs",
    "seed": "master seed (non-negative integer)",
    "timeout": "wall-time limit per run, e.g. 60 s (numba compilation not counted)",
    "dispersions": "dispersed values by --set path", "correlations": "correlated dispersions",
    "metrics": "per-run metrics by name", "keep": "signals kept per run (list)",
    "log_rate": "rate of the signals the campaign adds to the scenario's log (default: its log rate)",
}
DISPERSION_KEYS = {
    "distribution": f"one of {sorted(DISTRIBUTIONS)}", "unit": "unit of the drawn value",
    "shape": "shape of a per-axis value, e.g. [3]", "mean": "mean", "sigma": "standard deviation",
    "low": "lower bound", "high": "upper bound", "median": "median of a log-normal value",
    "log_sigma": "standard deviation of ln(value)", "choices": "list of values",
    "probabilities": "probability of each choice (default: equal)",
}
METRIC_KEYS = {
    "signal": "logged model.port or model.state", "statistic": f"one of {list(STATISTICS)}",
    "of": f"one of {list(MAPPINGS)} (default value)", "component": "component index of a vector signal",
    "unit": "unit of the result", "tolerance": "settling_time band", "target": "settling_time target (default 0)",
    "reference": "quaternion_angle: unit quaternion [w, x, y, z] the error is measured from (default identity)",
    "requirement": "pass bound drawn and counted by the report, e.g. '<= 0.5 deg' (in the metric's unit)",
}


def _unit_of(value) -> str:
    """The unit as written in a value ("3 deg/s", "[1, 2] N*m", {value, unit}); "" for bare numbers."""
    if isinstance(value, dict) and "unit" in value:
        return str(value["unit"])
    if isinstance(value, list) and value and isinstance(value[0], (str, list, dict)):
        return _unit_of(value[0])
    if isinstance(value, str):
        text = value.strip()
        if text.startswith("["):
            return text[text.rfind("]") + 1:].strip()
        match = _NUMBER_THEN_UNIT.match(text)
        return match.group(1).strip() if match else ""
    return ""


_NUMBER_THEN_UNIT = re.compile(r"^[-+]?(?:\d+\.?\d*|\.\d+)(?:[eE][-+]?\d+)?\s*(.*)$")


def _parse_dispersion(path: str, spec, where: _Where) -> Dispersion:
    _mapping(spec, where, DISPERSION_KEYS, required=("distribution",))
    kind = spec["distribution"]
    if not _one_of(kind, DISTRIBUTIONS):
        close = difflib.get_close_matches(str(kind), list(DISTRIBUTIONS), n=1) if isinstance(kind, str) else []
        hint = f" (did you mean {close[0]!r}?)" if close else ""
        raise where.child(spec, "distribution").error(f"expected one of {sorted(DISTRIBUTIONS)}, given "
                                                      f"{show(kind)}{hint}")
    needed = DISTRIBUTIONS[kind]
    for key in needed:
        if key not in spec:
            raise where.error(f"a {kind} dispersion needs {list(needed)}; {key!r} is missing")
    extra = [k for k in spec if k not in needed and k not in ("distribution", "unit", "shape")
             and not (kind == "choice" and k == "probabilities")]
    if extra:
        raise where.child(spec, extra[0]).error(f"{extra[0]!r} does not belong to a {kind} dispersion "
                                                f"(it takes {list(needed)})")
    if kind == "choice":
        choices = spec["choices"]
        if not isinstance(choices, list) or not choices:
            raise where.child(spec, "choices").error(f"expected a non-empty list of values, given {show(choices)}")
        probabilities = spec.get("probabilities", [1.0 / len(choices)] * len(choices))
        try:
            probabilities = np.asarray(probabilities, dtype=np.float64)
        except (TypeError, ValueError):
            raise where.child(spec, "probabilities").error(f"expected numbers, given {probabilities!r}") from None
        if probabilities.shape != (len(choices),) or not np.all(np.isfinite(probabilities)) \
                or np.any(probabilities < 0) or not abs(probabilities.sum() - 1.0) <= 1e-9:
            raise where.child(spec, "probabilities").error(
                f"expected {len(choices)} non-negative numbers summing to 1, given {show(spec.get('probabilities'))}")
        return Dispersion(path, kind, (), "", {"probabilities": probabilities}, plain(choices))
    location = {"normal": "mean", "truncated_normal": "mean", "uniform": "low", "lognormal": "median"}[kind]
    unit = spec["unit"] if "unit" in spec else _unit_of(spec[location])
    try:
        unit = "" if parse_unit(unit, "unit") == ureg.dimensionless else unit
    except UnitError as exc:
        raise where.child(spec, "unit" if "unit" in spec else location).error(str(exc)) from None
    parameters = {}
    for key in needed:
        try:
            parameters[key] = to_magnitude(spec[key], "" if key == "log_sigma" else unit, None, key)
        except UnitError as exc:
            raise where.child(spec, key).error(str(exc)) from None
        if not np.all(np.isfinite(parameters[key])):
            raise where.child(spec, key).error(f"expected finite numbers, given {show(spec[key])}")
    try:
        shape = tuple(int(n) for n in spec["shape"]) if "shape" in spec else \
            np.broadcast_shapes(*(a.shape for a in parameters.values()))
        if any(n < 0 for n in shape) or int(np.prod(shape, dtype=np.float64)) > MAX_DRAWN:
            raise ValueError(f"at most {MAX_DRAWN} components")
        parameters = {k: np.array(np.broadcast_to(a, shape), dtype=np.float64) for k, a in parameters.items()}
    except (ValueError, TypeError, OverflowError) as exc:
        raise where.child(spec, "shape" if "shape" in spec else location).error(
            f"parameter shapes {[a.shape for a in parameters.values()]} do not fit one value shape ({exc})") from None
    p = parameters

    def refuse(key, message):
        raise where.child(spec, key).error(message)

    if "sigma" in p and np.any(p["sigma"] < 0) or kind == "truncated_normal" and np.any(p["sigma"] <= 0):
        refuse("sigma", f"expected a {'positive' if kind == 'truncated_normal' else 'non-negative'} standard "
                        f"deviation, given {spec['sigma']!r}")
    if "low" in p and np.any(p["low"] >= p["high"]):
        refuse("high", f"expected high > low, given low {spec['low']!r}, high {spec['high']!r}")
    if kind == "truncated_normal" and np.any((p["mean"] < p["low"]) | (p["mean"] > p["high"])):
        refuse("mean", f"expected low <= mean <= high, given mean {spec['mean']!r}")
    if kind == "lognormal":
        if np.any(p["median"] <= 0):
            refuse("median", f"expected a positive median, given {spec['median']!r}")
        if np.any(p["log_sigma"] < 0):
            refuse("log_sigma", f"expected a non-negative number, given {spec['log_sigma']!r}")
    return Dispersion(path, kind, shape, unit, parameters)


def _parse_correlations(section, where: _Where, dispersions: dict[str, Dispersion]) -> list[CorrelationGroup]:
    if not isinstance(section, list):
        raise where.error(f"expected a list of {{between: [...], coefficient: r}} or {{between: [...], "
                          f"matrix: [[...]]}}, given {section!r}")
    groups, used = [], {}
    for k, entry in enumerate(section):
        here = where.child(section, k)
        _mapping(entry, here, {"between": "dispersion paths", "coefficient": "correlation of equal-size members, "
                               "component by component", "matrix": "correlation matrix of all components"},
                 required=("between",))
        members = entry["between"]
        if not isinstance(members, list) or len(members) < 2:
            raise here.child(entry, "between").error(f"expected a list of at least two dispersion paths, given {members!r}")
        for m in members:
            if not _one_of(m, dispersions):
                raise here.child(entry, "between").error(f"{m!r} is not a dispersion; dispersions: {sorted(dispersions)}")
            if dispersions[m].distribution == "choice":
                raise here.child(entry, "between").error(f"{m!r} is a discrete choice; correlate continuous dispersions")
            if m in used:
                raise here.child(entry, "between").error(f"{m!r} is already correlated by correlations[{used[m]}]; "
                                                         "put all its partners in one entry with a matrix")
            used[m] = k
        sizes = [dispersions[m].size for m in members]
        n = sum(sizes)
        if ("coefficient" in entry) == ("matrix" in entry):
            raise here.error("give either coefficient or matrix")
        if "coefficient" in entry:
            if len(set(sizes)) != 1:
                raise here.child(entry, "coefficient").error(
                    f"a coefficient correlates members component by component; their sizes differ: {sizes} "
                    "(give a matrix instead)")
            rho = entry["coefficient"]
            if not isinstance(rho, (int, float)) or isinstance(rho, bool) or not -1 < rho < 1:
                raise here.child(entry, "coefficient").error(f"expected a number in (-1, 1), given {rho!r}")
            matrix = np.kron(np.full((len(members), len(members)), float(rho)) +
                             (1 - float(rho)) * np.eye(len(members)), np.eye(sizes[0]))
            key = "coefficient"
        else:
            key = "matrix"
            try:
                matrix = np.asarray(entry["matrix"], dtype=np.float64)
            except (TypeError, ValueError):
                raise here.child(entry, "matrix").error("expected a square list of lists of numbers") from None
            if matrix.shape != (n, n) or not np.allclose(matrix, matrix.T, rtol=0, atol=1e-12) \
                    or not np.allclose(np.diag(matrix), 1.0, rtol=0, atol=1e-12):
                raise here.child(entry, "matrix").error(
                    f"expected a symmetric {n} x {n} matrix with unit diagonal (components of {members}: {sizes}), "
                    f"given shape {matrix.shape}")
        try:
            cholesky = np.linalg.cholesky(matrix)
        except np.linalg.LinAlgError:
            raise here.child(entry, key).error("the correlation matrix is not positive definite") from None
        groups.append(CorrelationGroup(list(members), cholesky))
    return groups


def _parse_metric(name: str, spec, where: _Where) -> Metric:
    _mapping(spec, where, METRIC_KEYS, required=("signal", "statistic"))
    if not _one_of(spec["statistic"], STATISTICS):
        raise where.child(spec, "statistic").error(f"expected one of {list(STATISTICS)}, given {show(spec['statistic'])}")
    of = spec.get("of", "value")
    if not _one_of(of, MAPPINGS):
        raise where.child(spec, "of").error(f"expected one of {list(MAPPINGS)}, given {show(of)}")
    if not isinstance(spec["signal"], str) or not spec["signal"]:
        raise where.child(spec, "signal").error(f"expected a signal name (model.port), given {show(spec['signal'])}")
    component = spec.get("component")
    if component is not None and (not isinstance(component, int) or of != "value"):
        raise where.child(spec, "component").error(f"expected an integer index with of: value, given {component!r}")
    unit = spec.get("unit")
    if unit is not None:
        try:
            parse_unit(str(unit), "unit")
        except UnitError as exc:
            raise where.child(spec, "unit").error(str(exc)) from None
    metric = Metric(name, spec["signal"], spec["statistic"], of, component, None if unit is None else str(unit))
    if "reference" in spec:
        reference = spec["reference"]
        try:
            r = np.asarray(reference, dtype=np.float64)
        except (TypeError, ValueError):
            r = np.zeros(0)
        if of != "quaternion_angle" or r.shape != (4,) or abs(np.linalg.norm(r) - 1.0) > 1e-9:
            raise where.child(spec, "reference").error(
                f"expected a unit quaternion [w, x, y, z] with of: quaternion_angle, given {reference!r}")
        metric.reference = tuple(float(v) for v in r)
    if metric.statistic == "settling_time":
        if "tolerance" not in spec:
            raise where.error("settling_time needs a tolerance (the band around target)")
        band_unit = metric.unit or _unit_of(spec["tolerance"])
        metric.unit = band_unit if metric.unit or band_unit else None
        for key in ("tolerance", "target"):
            if key in spec:
                try:
                    setattr(metric, key, float(to_magnitude(spec[key], band_unit, (), key)))
                except UnitError as exc:
                    raise where.child(spec, key).error(str(exc)) from None
        if not metric.tolerance > 0:
            raise where.child(spec, "tolerance").error(f"expected a positive band, given {spec['tolerance']!r}")
    elif "tolerance" in spec or "target" in spec:
        raise where.child(spec, "tolerance" if "tolerance" in spec else "target").error(
            "tolerance and target belong to statistic: settling_time")
    if "requirement" in spec:
        result_unit = "s" if metric.statistic == "settling_time" else (metric.unit or "")  # as the results file
        try:
            metric.requirement = parse_requirement(spec["requirement"], result_unit)
        except ValueError as exc:
            raise where.child(spec, "requirement").error(str(exc)) from None
    return metric


@dataclass
class RunRecord:
    """Everything one run produced: its row of the campaign table and its kept signals."""

    run: int
    status: str
    message: str
    t_end: float
    draws: np.ndarray
    metrics: np.ndarray
    wall_time: float = 0.0          # the whole run: build, simulate, metrics
    simulation_time: float = 0.0    # Simulation.run alone
    cpu_time: float = 0.0           # CPU time of the worker process during the whole run
    worker: str = ""
    compiled_kernels: int = 0       # numba compilations in the worker during this run (0: cache used)
    kept: dict = field(default_factory=dict)  # signal -> (time, values, unit)


class _CompileCounter:
    """Counts numba compilations of flexshell's kernels in this process, and the seconds spent compiling anything
    (:class:`dynamics.compile_cache.CompileClock`: compiled, not loaded from the on-disk cache; nested compilations
    of callees counted once in the seconds); installed on first use, so a run pays nothing to ask."""

    def __init__(self) -> None:
        from dynamics.compile_cache import CompileClock

        self.count = 0
        self.clock = CompileClock(on_start=self._count).start()

    def _count(self, dispatcher) -> None:
        module = getattr(getattr(dispatcher, "py_func", None), "__module__", "") or ""
        if module.startswith(("shell", "dynamics")):
            self.count += 1


_COUNTER: list = []


def _compile_counter() -> _CompileCounter:
    if not _COUNTER:
        _COUNTER.append(_CompileCounter())
    return _COUNTER[0]


def _numba_compilations() -> int:
    """Kernels of flexshell compiled (not loaded from numba's on-disk cache) in this process since the first
    call (the first call installs the counter)."""
    return _compile_counter().count


def _compile_seconds() -> float:
    """Seconds this process spent in numba compilations since the first call (which installs the counter)."""
    return _compile_counter().clock.seconds


@dataclass
class Campaign:
    """A validated campaign. Picklable: executors ship it to worker processes and Dask workers."""

    file: str
    text: str
    name: str
    description: str
    scenario_file: str
    scenario_text: str
    runs: int
    seed: int
    timeout: float | None
    base_overrides: list
    dispersions: list
    groups: list
    metrics: list
    keep: list
    log_rate: object = None
    #: run each run as a new context of the scene built once per process (shell.montecarlo.reuse); False:
    #: rebuild the scene from the overrides for every run (the reference)
    reuse_scene: bool = True
    #: why the last run rebuilt its scene (None: it reused the process's scene)
    rebuild_reason: object = None

    @property
    def fingerprint(self) -> str:
        """sha256 of the campaign and scenario texts: a results file belongs to exactly one campaign."""
        return hashlib.sha256((self.text + "\0" + self.scenario_text).encode()).hexdigest()

    @property
    def draw_columns(self) -> list[str]:
        return [c for d in self.dispersions for c in d.columns()]

    @property
    def metric_columns(self) -> list[str]:
        return [c for m in self.metrics for c in m.columns()]

    @property
    def signals(self) -> list[str]:
        """Signals each run must log: metric signals and kept signals."""
        return list(dict.fromkeys([m.signal for m in self.metrics] + list(self.keep)))

    def draws(self, run: int) -> dict[str, np.ndarray]:
        return draw_run(self.dispersions, self.groups, self.seed, run)

    def overrides(self, run: int, draws: dict | None = None) -> list[str]:
        """The ``--set`` list that turns the scenario into run ``run``."""
        draws = self.draws(run) if draws is None else draws
        items = list(self.base_overrides)
        for d in self.dispersions:
            value = d.value(draws[d.path])
            if d.distribution == "choice":
                items.append(f"{d.path}={yaml_text(value)}")
            else:
                magnitude = value.tolist() if isinstance(value, np.ndarray) else value
                items.append(f"{d.path}={yaml_text({'value': magnitude, 'unit': d.unit or ''})}")
        items.append(f"seed=[{self.seed}, {int(run)}]")
        return items

    def dispersed_values(self, run: int, draws: dict | None = None) -> list[tuple[str, object]]:
        """(path, value) of each dispersion of run ``run``, as the scene's values take them by name
        (:meth:`shell.diagram.Context.assign`): ``{value, unit}`` with the drawn magnitudes, or the chosen value;
        the numbers :meth:`overrides` writes as text, without the text."""
        draws = self.draws(run) if draws is None else draws
        values = []
        for d in self.dispersions:
            value = d.value(draws[d.path])
            values.append((d.path, value if d.distribution == "choice" else {"value": value, "unit": d.unit or ""}))
        return values

    def build(self, run: int, draws: dict | None = None):
        """(scenario, simulation) of run ``run`` built from its overrides, logging the campaign's signals."""
        scenario = parse_scenario(self.scenario_text, self.scenario_file, self.overrides(run, draws))
        simulation = build_simulation(scenario)
        self.log_signals(simulation, scenario)
        return scenario, simulation

    def log_signals(self, simulation, scenario) -> None:
        """Log the campaign's signals that the scenario does not log (at ``log_rate``, else the scenario's)."""
        logged = {name for name, _, _ in scenario.log_signals}
        rate = self.log_rate or scenario.log_rate or "10 Hz"
        for signal in self.signals:
            if signal not in logged:
                simulation.log([signal], rate)  # refuses unknown signals, naming the model's ports

    def _scene(self, run: int, draws: dict, log_path):
        """(scenario, simulation, in-memory log or None) of run ``run``: a new context of the scene built
        once per process (:mod:`shell.montecarlo.reuse`), or the scene rebuilt from the overrides when the
        dispersions change its structure."""
        from shell.log_file import MemoryLog
        from shell.montecarlo.reuse import scene_for
        from shell.names import StructuralChange

        scene = scene_for(self) if self.reuse_scene else "disabled"
        if not isinstance(scene, str):
            try:
                scenario, simulation = scene.simulation(run, draws)
                return scenario, simulation, MemoryLog(simulation.log_groups()) if log_path is None else None
            except StructuralChange as exc:
                self.rebuild_reason = str(exc)
        else:
            self.rebuild_reason = scene
        scenario, simulation = self.build(run, draws)
        return scenario, simulation, None

    def run(self, run: int, log_path=None) -> RunRecord:
        """Run ``run`` of the campaign; never raises for a failing scene (the record says why).

        ``log_path``: keep the run's full HDF5 log there (default: a temporary file, removed).
        """
        wall_start, cpu_start = time.perf_counter(), time.process_time()
        compiled_before = _numba_compilations()
        draws = self.draws(run)
        row = np.concatenate([draws[d.path] for d in self.dispersions]) if self.dispersions else np.zeros(0)
        record = RunRecord(run, "failed", "", float("nan"), row, np.full(len(self.metric_columns), np.nan),
                           worker=f"{socket.gethostname()}:{os.getpid()}")
        temporary = []
        try:
            self._simulate(run, draws, None if log_path is None else str(log_path), record, temporary)
        finally:
            for path in temporary:
                Path(path).unlink(missing_ok=True)
        record.compiled_kernels = _numba_compilations() - compiled_before
        record.wall_time = time.perf_counter() - wall_start
        record.cpu_time = time.process_time() - cpu_start
        return record

    def _simulate(self, run: int, draws: dict, log_path: str | None, record: RunRecord, temporary: list) -> None:
        from shell.model import ModelError
        from shell.simulation import SimulationError

        simulation = None
        memory = None
        try:
            scenario, simulation, memory = self._scene(run, draws, log_path)
            if memory is None and log_path is None:  # a rebuilt scene logs to a temporary file
                handle, log_path = tempfile.mkstemp(prefix=f"flexshell_run{run}_", suffix=".h5")
                os.close(handle)
                temporary.append(log_path)
            if scenario.t_final is None:
                raise CampaignError(f"{self.scenario_file}: no stop time; add stop: {{time: ...}} to the scenario "
                                    "or set: {stop.time: ...} to the campaign")
            # the timeout bounds the run's own work: a kernel the run is first to need is compiled (once per
            # installation) on the run's clock, which is not the run's fault and is not counted
            deadline = None if self.timeout is None else time.perf_counter() + self.timeout
            compiling = _compile_seconds()

            def check_deadline(t):
                if deadline is not None and time.perf_counter() - (_compile_seconds() - compiling) > deadline:
                    compiled = _compile_seconds() - compiling
                    also = f", not counting {compiled:.3g} s of numba compilation" if compiled else ""
                    raise RunTimeout(f"run {run} exceeded the campaign timeout of {self.timeout:g} s "
                                     f"(wall time{also}) at t = {t:.6g} s")

            summary = simulation.run(scenario.t_final, log_path=memory if memory is not None else log_path,
                                     progress=check_deadline, log_attributes={"campaign": self.name, "run": run})
            record.simulation_time = summary.wall_time
            record.status, record.message, record.t_end = summary.status, summary.reason, summary.t_end
        except SimulationError as exc:
            timeout = isinstance(exc.__cause__, RunTimeout)
            record.status = "timeout" if timeout else ("nonfinite" if "non-finite" in str(exc) else "failed")
            record.message = str(exc.__cause__) if timeout else str(exc)
            record.t_end = simulation.t if simulation is not None else float("nan")
        except (ScenarioError, ModelError, UnitError, ValueError, KeyError, TypeError) as exc:
            record.status, record.message = "failed", f"the run does not build: {exc}"
            return
        try:
            logged = memory.signals() if memory is not None else _read_log(log_path, self.signals)
        except (OSError, KeyError, TypeError) as exc:
            record.status, record.message = "failed", f"cannot read the run's log: {exc}"
            return
        record.kept = {s: logged[s] for s in self.keep if s in logged}
        if record.status not in ("completed", "stopped"):
            return
        columns = []
        for metric in self.metrics:
            time_s, values, unit = logged[metric.signal]
            samples = mapped_samples(metric, values)
            source_unit = "rad" if metric.of == "quaternion_angle" else unit
            if metric.unit is not None:
                samples = samples * conversion_factor(source_unit, metric.unit, f"metric {metric.name}")
            columns.append(evaluate(metric, time_s, samples))
        record.metrics = np.concatenate(columns) if columns else np.zeros(0)
        bad = [c for c, v in zip(self.metric_columns, record.metrics) if np.isnan(v)]
        if bad:
            record.status, record.message = "nonfinite", f"metric(s) {bad} are NaN"


def _read_log(path: str, signals: list[str]) -> dict:
    """{signal: (time, values, unit)} for the first log group that holds each signal."""
    found = {}
    with h5py.File(path, "r") as f:
        for group in f.values():
            if not isinstance(group, h5py.Group) or "time" not in group:
                continue
            time_s = None
            for signal in signals:
                if signal in found or signal not in group:
                    continue
                time_s = group["time"][:] if time_s is None else time_s
                dataset = group[signal]
                found[signal] = (time_s, dataset[:], str(dataset.attrs.get("unit", "")))
    return found


def load_campaign(path, validate: bool = True) -> Campaign:
    """Read and validate a campaign file; ``validate`` also builds the scenario with the median draws
    (every dispersion path, metric signal and kept signal must exist)."""
    path = str(path)
    try:
        with open(path, "rb") as f:
            data = f.read()
        text = decode_scenario(data, path)
    except OSError as exc:
        raise CampaignError(f"{path}: cannot read the campaign ({exc.strerror})") from None
    except ScenarioError as exc:
        raise CampaignError(str(exc)) from None
    return parse_campaign(text, path, validate)


def parse_campaign(text: str, filename: str = "<string>", validate: bool = True) -> Campaign:
    document = load_yaml(text, filename)
    root = _Where(filename, 1, "")
    if not isinstance(document, dict):
        raise root.error(f"expected a mapping at the top level (keys {sorted(CAMPAIGN_KEYS)})")
    _mapping(document, root, CAMPAIGN_KEYS, required=("scenario", "runs"))
    here = root.child(document, "scenario")
    if not isinstance(document["scenario"], str) or not document["scenario"].strip() or "\0" in document["scenario"]:
        raise here.error(f"expected the scenario's file name, given {show(document['scenario'])}")
    scenario_file = Path(filename).parent / document["scenario"]
    try:
        with open(scenario_file, "rb") as f:
            scenario_text = decode_scenario(f.read(), str(scenario_file))
    except OSError as exc:
        raise here.error(f"cannot read the scenario {str(scenario_file)!r} ({exc.strerror})") from None
    except ScenarioError as exc:
        raise here.error(str(exc)) from None
    runs = document["runs"]
    if not isinstance(runs, int) or isinstance(runs, bool) or runs < 1:
        raise root.child(document, "runs").error(f"expected a positive integer, given {show(runs)}")
    if runs > MAX_RUNS:
        raise root.child(document, "runs").error(f"{runs} runs: a campaign file holds at most {MAX_RUNS} (its "
                                                 "table is allocated whole); split the campaign into several")
    seed = document.get("seed", 0)
    if not isinstance(seed, int) or isinstance(seed, bool) or seed < 0:
        raise root.child(document, "seed").error(f"expected a non-negative integer, given {seed!r}")
    timeout = None
    if "timeout" in document:
        try:
            timeout = float(to_magnitude(document["timeout"], "s", (), "timeout"))
        except UnitError as exc:
            raise root.child(document, "timeout").error(str(exc)) from None
        if not timeout > 0:
            raise root.child(document, "timeout").error(f"expected a positive time, given {document['timeout']!r}")
    base = []
    settings = document.get("set", {}) or {}
    if not isinstance(settings, dict):
        raise root.child(document, "set").error(f"expected a mapping key.path: value, given {settings!r}")
    for key, value in settings.items():
        base.append(f"{key}={yaml_text(plain(value))}")
    dispersions = []
    section = document.get("dispersions", {}) or {}
    where = root.child(document, "dispersions")
    if not isinstance(section, dict):
        raise where.error(f"expected a mapping of --set path -> distribution, given {section!r}")
    for key, spec in section.items():
        if key in ("seed",) or str(key).startswith(("log.", "stop.events")):
            raise where.child(section, key).error(f"{key!r} cannot be dispersed (run i's seed is [seed, i])")
        dispersions.append(_parse_dispersion(str(key), spec, where.child(section, key)))
    groups = []
    if "correlations" in document:
        groups = _parse_correlations(document["correlations"], root.child(document, "correlations"),
                                     {d.path: d for d in dispersions})
    metrics = []
    section = document.get("metrics", {}) or {}
    where = root.child(document, "metrics")
    if not isinstance(section, dict):
        raise where.error(f"expected a mapping of metric name -> {{signal, statistic, ...}}, given {section!r}")
    for name, spec in section.items():
        metrics.append(_parse_metric(str(name), spec, where.child(section, name)))
    keep = document.get("keep", []) or []
    if not isinstance(keep, list) or not all(isinstance(s, str) for s in keep):
        raise root.child(document, "keep").error(f"expected a list of signal names, given {keep!r}")
    campaign = Campaign(file=filename, text=text, name=str(document.get("name", Path(filename).stem)),
                        description=str(document.get("description", "")), scenario_file=str(scenario_file),
                        scenario_text=scenario_text, runs=runs, seed=seed, timeout=timeout, base_overrides=base,
                        dispersions=dispersions, groups=groups, metrics=metrics, keep=list(keep),
                        log_rate=document.get("log_rate"))
    if validate:
        _validate_against_scenario(campaign, document, root)
    return campaign


def _validate_against_scenario(campaign: Campaign, document: dict, root: _Where) -> None:
    """Build the scenario with the median draws (z = 0): paths, signals and units must all resolve."""
    from shell.model import ModelError

    median = {d.path: d.transform(np.zeros(d.size)) for d in campaign.dispersions}
    for d in campaign.dispersions:  # one dispersion at a time, so that an error names its line
        section = document["dispersions"]
        items = [o for o in campaign.overrides(0, median) if not o.startswith(("seed=",))]
        own = [o for o in items if o.startswith(f"{d.path}=")]
        try:
            parse_scenario(campaign.scenario_text, campaign.scenario_file, campaign.base_overrides + own)
        except ScenarioError as exc:
            raise root.child(document, "dispersions").child(section, d.path).error(str(exc)) from None
    handle, log_path = tempfile.mkstemp(prefix="flexshell_campaign_check_", suffix=".h5")
    os.close(handle)
    try:
        scenario, simulation = campaign.build(0, median)
        if scenario.t_final is None:
            raise ScenarioError(f"{campaign.scenario_file}: no stop time; add stop: {{time: ...}} to the scenario "
                                "or set: {stop.time: ...} to the campaign")
        # a few steps: compiles (or loads) every kernel the runs need into numba's on-disk cache before
        # any worker starts, and gives the logged signals' shapes and units
        simulation.run(min(scenario.t_final, 2 * (scenario.step or 0.01)), log_path=log_path)
        logged = _read_log(log_path, campaign.signals)
    except (ScenarioError, ModelError, UnitError, ValueError) as exc:
        raise root.error(f"the scenario with the median draws does not run: {exc}") from None
    finally:
        Path(log_path).unlink(missing_ok=True)
    section = document.get("metrics", {}) or {}
    for metric in campaign.metrics:
        here = root.child(document, "metrics").child(section, metric.name)
        _, values, unit = logged[metric.signal]
        shape = values.shape[1:]
        size = int(np.prod(shape, dtype=int))
        if metric.of == "quaternion_angle" and size != 4:
            raise here.error(f"quaternion_angle needs a 4-component signal; {metric.signal} has shape {shape}")
        if metric.component is not None and not 0 <= metric.component < size:
            raise here.error(f"component {metric.component} of {metric.signal}, which has shape {shape}")
        if metric.of == "value":
            metric.size = 1 if metric.component is not None else size
        source = "rad" if metric.of == "quaternion_angle" else unit
        if metric.unit is not None:
            try:
                conversion_factor(source, metric.unit, f"metric {metric.name}")
            except UnitError as exc:
                raise here.child(section[metric.name], "unit").error(str(exc)) from None

"""The log of one run: which signals are logged at which rates, when each group samples next, and its rows.

One group per log rate, named after its period (``every_0.1s``, the HDF5 layout of :mod:`shell.log_file`),
holds its signals (name, shape, unit, description, and where each lives: the signal buffer, ``x`` or ``z``) and
the exact time of its next sample, a Fraction on the grid ``k * period`` (the first at or after the time the run
starts from). The Python loop samples the due groups at an instant (:meth:`LogSession.sample`, one evaluation of
the output stages the logged signals need); the compiled loop takes the same groups as arrays
(:mod:`shell.compiled_run`) and hands back the rows it filled.
"""

from __future__ import annotations

import json
import weakref
from fractions import Fraction

from shell.log_file import LoggedSignal, LogWriter, MemoryLog
from shell.model import ModelError, parse_period
from shell.units import format_unit

#: per diagram, the logged signals already described: {name: (LoggedSignal, kind, slice)} (formatting a unit
#: costs ~0.1 ms, and every Monte Carlo run of a diagram logs the same signals)
_DESCRIBED: weakref.WeakKeyDictionary = weakref.WeakKeyDictionary()


class LogSession:
    """The log groups of a run of ``diagram``; see the module docstring."""

    def __init__(self, diagram):
        self.diagram = diagram
        #: {group name: {"period": Fraction, "signals": [(LoggedSignal, kind, slice)], "next": Fraction or None}}
        self.groups: dict[str, dict] = {}
        self._stages_key, self._stages = None, ()

    def add(self, signals, rate) -> None:
        """Log ``signals`` (dotted port/state names) every ``rate`` ("10 Hz", "0.1 s", seconds)."""
        period = parse_period(rate, "log rate")
        group = f"every_{float(period):g}s"
        entries = self.groups.setdefault(group, {"period": period, "signals": [], "next": None})
        known = _DESCRIBED.setdefault(self.diagram, {})
        for name in signals:
            if name not in known:
                kind, sl, decl = self.diagram.locate(name)
                known[name] = (LoggedSignal(name, tuple(decl.shape), format_unit(decl.unit), decl.description), kind,
                               sl)
            if any(s.name == name for s, _, _ in entries["signals"]):
                continue
            entries["signals"].append(known[name])

    def layout(self) -> dict:
        """{group name: [LoggedSignal, ...]} (a writer's layout)."""
        return {g: [s for s, _, _ in e["signals"]] for g, e in self.groups.items()}

    def open(self, log_path, seed, attributes: dict | None):
        """The writer of a run logging to ``log_path`` (an HDF5 file, or a :class:`MemoryLog`), or None."""
        if log_path is None:
            return None
        if not self.groups:
            raise ModelError("nothing to log: call Simulation.log(signals, rate) (or list log: signals in the "
                             "scenario) before running with a log file")
        if isinstance(log_path, MemoryLog):
            return log_path
        return LogWriter(log_path, self.layout(), {"seed": json.dumps(seed)} | dict(attributes or {}))

    def next_time(self, group: dict, t: float) -> Fraction:
        """The group's next sample instant (on first use: the first on its grid at or after ``t``)."""
        if group["next"] is None:
            start = Fraction(t).limit_denominator(10**9)
            group["next"] = -(-start // group["period"]) * group["period"]
        return group["next"]

    def stages(self) -> tuple:
        """The output stages the logged signals need (computed once per set of logged signals)."""
        names = tuple(s.name for group in self.groups.values() for s, _, _ in group["signals"])
        if self._stages_key != names:
            self._stages_key = names
            self._stages = self.diagram.stages_of_signals(names)
        return self._stages

    def sample(self, writer, t: float, sources: dict, evaluate, instant: Fraction | None = None,
               force: bool = False) -> None:
        """Log the groups due at ``instant`` (every group, off its grid, with ``force``: a stop event) from
        ``sources`` ({"signal": buffer, "x": ..., "z": ...}) after ``evaluate(t, stages)``; without a writer only
        the schedule moves on."""
        if writer is None:
            for group in self.groups.values():
                if not force and self.next_time(group, t) == instant:
                    group["next"] += group["period"]
            return
        evaluated = False
        for name, group in self.groups.items():
            if not (force or self.next_time(group, t) == instant):
                continue
            if not evaluated:
                evaluate(t, self.stages())
                evaluated = True
            writer.append(name, t, [sources[kind][sl].reshape(s.shape) for s, kind, sl in group["signals"]])
            if not force:
                group["next"] += group["period"]

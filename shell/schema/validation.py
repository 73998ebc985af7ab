"""The scenario schema's validation vocabulary: where a value is, and checks that name it when they refuse.

:class:`Where` is a location in a scenario (file, line, dotted key path such as
``models.controller.parameters.kp``); ``where.child(container, key)`` descends into a mapping or list
keeping the line of the key, and ``where.error(message)`` makes the :class:`ScenarioError` a user reads as
``file:line: key.path: message``. The ``expect_*`` checks refuse a value of the wrong kind with what was
expected and what was given (a did-you-mean for a misspelt key). Every section reader of the schema
(:mod:`shell.schema.sections`, :mod:`shell.schema.multibody`) and the Monte Carlo campaign file use them.
"""

from __future__ import annotations

import difflib
import math
from dataclasses import dataclass

from shell.model import ModelError, parse_period
from shell.schema.document import LineDict, LineList, ScenarioError, show, type_name
from shell.units import UnitError, to_magnitude


@dataclass
class Where:
    """A location in the scenario: file, line and dotted key path."""

    file: str
    line: int
    key: str

    def __str__(self) -> str:
        if self.key.startswith("--set"):  # a command-line override: no line in the file
            return f"{self.file}: {self.key}"
        return f"{self.file}:{self.line}: {self.key}"

    def child(self, container, key, path_part=None) -> "Where":
        """The location of ``container[key]`` (``path_part``: how the key is written in the path, e.g.
        ``[2](bus)`` for the body named bus)."""
        line = self.line
        lines = getattr(container, "lines", None) or {}
        if isinstance(container, LineDict) and key in lines:
            line = lines[key]
        elif isinstance(container, LineList) and isinstance(key, int) and key < len(lines):
            line = lines[key]
        part = path_part if path_part is not None else (f"[{key}]" if isinstance(key, int) else str(key))
        joined = f"{self.key}{part}" if part.startswith("[") or not self.key else f"{self.key}.{part}"
        return type(self)(self.file, line, joined)

    def named(self, name) -> "Where":
        """The same place with the key path naming the item, ``bodies[2]`` -> ``bodies[2](bus)``."""
        return type(self)(self.file, self.line, f"{self.key}({name})")

    def error(self, message: str) -> ScenarioError:
        return ScenarioError(f"{self}: {message}")


def find(document, file: str, keys: tuple) -> Where:
    """The location of ``document[keys[0]][keys[1]]...`` (as deep as it exists)."""
    where = Where(file, 1, "")
    container = document
    for key in keys:
        if not isinstance(container, dict) or key not in container:
            break
        where = where.child(container, key)
        container = container[key]
    return where


def expect_mapping(value, where: Where, allowed: dict[str, str], required=()) -> dict:
    """Check a mapping's keys; ``allowed`` maps key -> short description used in messages."""
    if not isinstance(value, dict):
        raise where.error(f"expected a mapping with keys {sorted(allowed)}, given {type_name(value)} {show(value)}")
    for key in value:
        if key not in allowed:
            close = difflib.get_close_matches(str(key), list(allowed), n=1)
            hint = f" (did you mean {close[0]!r}?)" if close else ""
            raise where.child(value, key).error(f"unknown key {key!r}{hint}; expected one of {sorted(allowed)}")
    for key in required:
        if key not in value:
            raise where.error(f"missing required key {key!r} ({allowed[key]})")
    return value


def expect_list(value, where: Where, what: str) -> list:
    if not isinstance(value, list):
        raise where.error(f"expected a list of {what}, given {type_name(value)} {show(value)}")
    return value


def expect_name(value, where: Where, what: str) -> str:
    if not isinstance(value, str) or not value:
        raise where.error(f"expected {what} (text), given {type_name(value)} {show(value)}")
    return value


def refuse_nan(value, where: Where) -> None:
    """NaN is never a meaningful input (a value, a limit, a state): refused wherever it appears."""
    if isinstance(value, float) and value != value:
        raise where.error("expected a number, given NaN (.nan)")
    if isinstance(value, dict):
        for key, item in value.items():
            refuse_nan(item, where.child(value, key))
    elif isinstance(value, list):
        for k, item in enumerate(value):
            refuse_nan(item, where.child(value, k))


def check_time(seconds: float, where: str, given) -> float:
    """``seconds`` if it is a finite positive time; else ScenarioError naming ``where``."""
    if not math.isfinite(seconds) or seconds <= 0:
        raise ScenarioError(f"{where}: expected a positive time (a finite number of seconds), given {show(given)}")
    return seconds


def seconds(value, where: Where) -> float:
    """A time value in seconds (any unit of time; a bare number is in seconds)."""
    try:
        return float(to_magnitude(value, "s", (), "time"))
    except UnitError as exc:
        raise where.error(f"expected a time, given {show(value)} ({exc})") from None


def period_seconds(value) -> float | None:
    """The sample period of a rate or period value in seconds, None if it is not one."""
    try:
        return float(parse_period(value, "rate"))
    except (ModelError, UnitError, ZeroDivisionError, OverflowError, ValueError):
        return None


def check_rate(value, where: Where, key: str = "rate", expected: str = "a rate such as 10 Hz") -> None:
    """A sample rate (``rate:``, "10 Hz") or period (``period:``, "0.1 s"): with a unit under ``rate:``
    (a bare number there was once read as a period in seconds), finite, positive."""
    if key == "rate" and is_bare_number(value) and not math.isfinite(float(value)):
        raise where.error(f"expected a finite rate such as 10 Hz, given {show(value)}")
    if key == "rate" and is_bare_number(value):
        raise where.error(f"a rate needs a unit: write `{show(value)} Hz` (or a period such as `0.1 s`), "
                          f"given the bare number {show(value)}")
    try:
        period = parse_period(value, key)
    except (ModelError, UnitError) as exc:
        raise where.error(f"expected {expected}, given {show(value)} ({exc})") from None
    except (ZeroDivisionError, OverflowError, ValueError):
        raise where.error(f"expected {expected}, given {show(value)}") from None
    if not math.isfinite(float(period)) or float(period) < 1e-9:
        raise where.error(f"expected {expected} with a period of at least 1 ns, given {show(value)}")


def is_bare_number(value) -> bool:
    """A number without a unit: an int or float, or text that reads as one."""
    if isinstance(value, bool):
        return False
    if isinstance(value, (int, float)):
        return True
    if isinstance(value, str):
        try:
            float(value)
        except ValueError:
            return False
        return True
    return False

"""Physical units at the boundary of the framework: one pint registry for the whole package.

Values enter flexshell with units (YAML strings such as ``"5 deg/s"``, ``"20 kg*m^2"``, Python
``Quantity`` objects, or bare numbers meaning "in the declared unit"). They are converted once, at
build time, into the unit a parameter or port declares; kernels only ever see float64 magnitudes
(docs/conventions.md: SI inside every kernel). Wiring two ports computes one multiplicative conversion
factor here; nothing in this module is called inside the integration loop.
"""

from __future__ import annotations

import functools
import re
import reprlib
import sys

import numpy as np


def _import_pint():
    """pint without its optional dask support. pint imports ``dask.base`` whenever dask is installed (it is, for
    Monte Carlo campaigns), which cost 0.1-0.3 s of every start; flexshell never hands pint a dask array. A
    ``None`` entry in ``sys.modules`` makes pint's ``find_spec("dask")`` answer "not installed" during pint's
    own import only; the entry is removed at once, so a later ``import dask`` is unaffected. Left alone when
    either package is already imported."""
    if "dask" in sys.modules or "pint" in sys.modules:
        import pint
        return pint
    sys.modules["dask"] = None
    try:
        import pint
    finally:
        del sys.modules["dask"]
    return pint


pint = _import_pint()


def _registry() -> pint.UnitRegistry:
    """pint's default registry, its parsed definitions cached on disk (pint's own ``cache_folder``,
    under ``$XDG_CACHE_HOME/flexshell/pint``): parsing the definitions file costs ~0.4-0.8 s at every
    start, loading the cache ~0.04 s. Any failure of the cache (unwritable home, a cache pint cannot
    read) falls back to parsing, the same registry."""
    import os
    from pathlib import Path

    folder = Path(os.environ.get("XDG_CACHE_HOME") or Path.home() / ".cache") / "flexshell" / "pint"
    try:
        folder.mkdir(parents=True, exist_ok=True)
        return pint.UnitRegistry(cache_folder=folder)
    except Exception:  # noqa: BLE001 - any cache problem: the uncached registry is the same registry
        return pint.UnitRegistry()


#: The package's single unit registry (pint recommends one per application).
ureg = _registry()
Quantity = ureg.Quantity

_VECTOR_WITH_UNIT = re.compile(r"^\s*(\[.*\])\s*(.*?)\s*$", re.DOTALL)


class UnitError(ValueError):
    """A value or a connection whose units cannot be reconciled; the message names both sides."""


def parse_unit(unit: str | pint.Unit, where: str = "") -> pint.Unit:
    """The pint unit for ``unit`` ("" or "1" is dimensionless); refuses unknown unit names."""
    if isinstance(unit, pint.Unit):
        return unit
    if unit is None:
        unit = ""
    if isinstance(unit, (int, float)) and not isinstance(unit, bool) and unit == 1:
        unit = "1"  # YAML reads `unit: 1` as a number
    if not isinstance(unit, str):
        raise UnitError(f"{where}: expected a unit name such as m/s, given {short_repr(unit)}")
    text = unit.strip()
    if text in ("", "1", "-", "dimensionless"):
        return ureg.dimensionless
    try:
        return _unit(text)
    except Exception as exc:  # pint's parser raises lookup, syntax, tokenize and assertion errors
        raise UnitError(f"{where}: unknown unit {short_repr(text)} ({type(exc).__name__}: "
                        f"{short_repr(str(exc))})") from None


@functools.lru_cache(maxsize=4096)
def _unit(text: str) -> pint.Unit:
    """``ureg.Unit(text)``, memoized (pint units are immutable; parsing one costs ~0.1 ms, and a scene
    build or a Monte Carlo run parses the same few unit names hundreds of times). Failures are not
    cached: they raise each time."""
    return ureg.Unit(text)


@functools.lru_cache(maxsize=4096)
def _scale(src: pint.Unit, dst: pint.Unit) -> float:
    """``1 src`` in ``dst`` for units of equal dimensions, memoized."""
    return float(ureg.Quantity(1.0, src).to(dst).magnitude)


@functools.lru_cache(maxsize=4096)
def is_offset_unit(unit: pint.Unit) -> bool:
    """True for units whose conversion is not a pure scale (degC, degF): refused on ports."""
    return not ureg.Quantity(1.0, unit)._is_multiplicative


def conversion_factor(from_unit: str | pint.Unit, to_unit: str | pint.Unit, where: str = "") -> float:
    """Scale such that ``value_in_to_unit = factor * value_in_from_unit``.

    Raises :class:`UnitError` naming ``where`` and both units if their dimensions differ.
    """
    src = parse_unit(from_unit, where)
    dst = parse_unit(to_unit, where)
    if src.dimensionality != dst.dimensionality:
        raise UnitError(
            f"{where}: unit dimensions differ: {format_unit(src)} [{src.dimensionality}] cannot become "
            f"{format_unit(dst)} [{dst.dimensionality}]"
        )
    if is_offset_unit(src) or is_offset_unit(dst):
        raise UnitError(f"{where}: offset units ({format_unit(src)} -> {format_unit(dst)}) are not allowed "
                        "on ports or parameters; use kelvin")
    return _scale(src, dst)


def format_unit(unit: str | pint.Unit) -> str:
    """Compact human-readable unit string ("" for dimensionless)."""
    u = parse_unit(unit)
    if u == ureg.dimensionless:
        return "1"
    return f"{u:~C}"


def _split_string_value(text: str) -> tuple[object, str]:
    """Split "3.5 deg", "[1, 2, 3] deg/s" or "1e-3" into (number or nested list, unit text)."""
    match = _VECTOR_WITH_UNIT.match(text)
    if match:
        import json

        import yaml  # the bracketed part is a JSON (or else YAML) flow sequence

        try:  # JSON first: PyYAML (YAML 1.1) reads 1e5 or 1e-6 as strings, JSON as numbers
            return json.loads(match.group(1)), match.group(2)
        except ValueError:
            pass
        except RecursionError:
            raise ValueError(f"the list {_short(match.group(1))} is nested too deeply") from None
        try:
            numbers = yaml.safe_load(match.group(1))
        except (yaml.YAMLError, RecursionError) as exc:
            raise ValueError(f"cannot read the list {_short(match.group(1))}: {_short(str(exc))}") from None
        return numbers, match.group(2)
    try:
        return float(text), ""  # a bare number is in the declared unit
    except ValueError:
        pass
    try:
        quantity = ureg.Quantity(text)
    except Exception as exc:  # pint's parser raises tokenize, syntax, assertion and lookup errors: the caller
        raise ValueError(f"not a number with a unit: {type(exc).__name__}: {_short(str(exc))}") from None  # says where
    if isinstance(quantity, (int, float)):
        return float(quantity), ""
    return quantity.magnitude, f"{quantity.units}"


_SHORT = reprlib.Repr()
_SHORT.maxstring, _SHORT.maxother, _SHORT.maxlist, _SHORT.maxdict, _SHORT.maxlevel = 60, 60, 6, 6, 3


def short_repr(value) -> str:
    """``repr(value)`` cut to a line: error messages never print a huge (or alias-expanded) value whole."""
    return _SHORT.repr(value)


_short = short_repr


def written_numbers(value) -> np.ndarray:
    """The numbers of a user value as written, whatever its unit ("[1e999, 0] deg/s" -> [inf, 0]), for
    checks that do not depend on the unit (finiteness); raises UnitError when ``value`` holds no numbers."""
    try:
        if isinstance(value, str):
            numbers, _ = _split_string_value(value)
            return np.asarray(_plain_numbers(numbers, ""), dtype=np.float64)
        if isinstance(value, dict) and "value" in value:
            return written_numbers(value["value"])
        if isinstance(value, (list, tuple)) and any(isinstance(v, (str, list, tuple, dict)) for v in value):
            return np.concatenate([written_numbers(v).reshape(-1) for v in value]) if value else np.zeros(0)
        return np.asarray(_plain_numbers(value, ""), dtype=np.float64)
    except (ValueError, TypeError, AttributeError) as exc:
        raise UnitError(f"{short_repr(value)} holds no numbers ({exc})") from None


def to_magnitude(value, unit: str | pint.Unit, shape: tuple[int, ...] | None = None,
                 where: str = "") -> np.ndarray:
    """Convert a user value to a float64 array expressed in ``unit``.

    Accepted forms: a number or nested list of numbers (already in ``unit``); a string with a unit
    ("5 deg/s", "[1, 2, 3] deg/s"); a list of such strings; a mapping ``{value: ..., unit: ...}``;
    a pint Quantity. ``shape`` (if given) is enforced; a scalar is never broadcast silently.
    """
    target = parse_unit(unit, where)
    try:
        magnitude = _magnitude_in(value, target, where)
    except pint.errors.DimensionalityError as exc:
        raise UnitError(f"{where}: expected a value in {format_unit(target)} "
                        f"[{target.dimensionality}], given {_short(value)} ({exc})") from None
    except (pint.UndefinedUnitError, pint.errors.DefinitionSyntaxError, TypeError, ValueError,
            AttributeError, AssertionError) as exc:
        if isinstance(exc, UnitError):
            raise
        raise UnitError(f"{where}: expected a value in {format_unit(target)}, given {_short(value)} ({exc})") from None
    array = np.asarray(magnitude, dtype=np.float64)
    if shape is not None and tuple(array.shape) != tuple(shape):
        raise UnitError(f"{where}: expected shape {tuple(shape)}, given shape {tuple(array.shape)} ({_short(value)})")
    return array


def _magnitude_in(value, target: pint.Unit, where: str):
    if isinstance(value, pint.Quantity):
        return np.asarray(value.to(target).magnitude, dtype=np.float64)
    if isinstance(value, dict):
        if set(value) != {"value", "unit"}:
            raise UnitError(f"{where}: a value mapping needs exactly the keys 'value' and 'unit', given {sorted(value)}")
        factor = conversion_factor(value["unit"], target, where)
        return np.asarray(_plain_numbers(value["value"], where), dtype=np.float64) * factor
    if isinstance(value, str):
        numbers, unit_text = _split_string_value(value)
        if isinstance(numbers, str):
            raise UnitError(f"{where}: {_short(value)} is not a number with a unit")
        factor = conversion_factor(unit_text, target, where) if unit_text else 1.0
        return np.asarray(_plain_numbers(numbers, where), dtype=np.float64) * factor
    if isinstance(value, (list, tuple)) and any(isinstance(v, (str, list, tuple, dict)) for v in value):
        return np.array([_magnitude_in(v, target, where) for v in value], dtype=np.float64)
    if isinstance(value, bool):
        raise UnitError(f"{where}: expected a number, given the boolean {value}")
    return np.asarray(_plain_numbers(value, where), dtype=np.float64)


def _plain_numbers(value, where: str):
    array = np.asarray(value)
    if array.dtype.kind not in "iuf":
        raise UnitError(f"{where}: expected numbers, given {_short(value)}")
    return array

"""Charts of logged signals: their labels, units and lookup, shared by everything that draws them.

``flexshell plot`` (:mod:`shell.commands.plot`), the Monte Carlo campaign report
(:mod:`shell.montecarlo.report`) and the 3-D view's signal panels (:mod:`shell.view.scene`) show logged
signals the same way:

* a signal is named in full or by a unique suffix (``acs.attitude`` for ``multibody.acs.attitude``):
  :func:`resolve_signal`;
* legends name components (:func:`component_labels`): ``w, x, y, z`` for a quaternion, ``x, y, z`` for a
  3-vector, ``R11 .. R33`` for a rotation matrix, ``eta1 .. etan`` for modal coordinates;
* units print as an engineer writes them (:func:`pretty_unit`: ``N m``, ``kg m²``, ``rad/s²``), and
  dimensionless signals carry none;
* figures keep a readable size: ``PER_PAGE`` panels of ``PANEL_HEIGHT`` inches in a ``FIGURE_WIDTH``-inch page.
"""

from __future__ import annotations

import numpy as np

from shell.units import UnitError, parse_unit, ureg

PER_PAGE = 6

PANEL_HEIGHT = 1.9   # inches per panel

FIGURE_WIDTH = 9.0   # inches

SUPERSCRIPTS = str.maketrans("0123456789-", "⁰¹²³⁴⁵⁶⁷⁸⁹⁻")

#: symbols listed first in a product, in this order (an engineer writes N m, kg m², N m s/rad)
UNIT_ORDER = ("N", "kg", "m", "rad", "deg", "s")


def pretty_unit(unit) -> str:
    """``N m`` for ``m*N``, ``kg m²`` for ``kg*m^2``, ``N m s/rad``; "" for a dimensionless unit."""
    try:
        u = parse_unit(unit if unit is not None else "")
    except UnitError:
        return str(unit)  # a label that is not a unit (a choice draw's "index") prints as written
    if u == ureg.dimensionless:
        return ""
    symbols = {ureg.get_symbol(name): power for name, power in u._units.items()}
    if all(p < 0 for p in symbols.values()) and len(symbols) == 1:
        (name, power), = symbols.items()
        return f"1/{name}{_power(-power)}"

    def ordered(items):
        return sorted(items, key=lambda kv: (UNIT_ORDER.index(kv[0]) if kv[0] in UNIT_ORDER else len(UNIT_ORDER),
                                             kv[0]))

    top = " ".join(f"{n}{_power(p)}" for n, p in ordered((n, p) for n, p in symbols.items() if p > 0))
    bottom = [f"{n}{_power(-p)}" for n, p in ordered((n, p) for n, p in symbols.items() if p < 0)]
    if not bottom:
        return top
    return f"{top}/{bottom[0]}" if len(bottom) == 1 else f"{top}/({' '.join(bottom)})"


def _power(p) -> str:
    if p == 1:
        return ""
    if float(p).is_integer():
        return str(int(p)).translate(SUPERSCRIPTS)
    return f"^{p:g}"


def unit_label(unit) -> str:
    """`` [N m]`` or "" (dimensionless) to append to an axis label."""
    text = pretty_unit(unit)
    return f" [{text}]" if text else ""


def is_quaternion(name: str, shape: tuple, description: str = "") -> bool:
    """A logged attitude quaternion: shape (4,), named ``...attitude`` or described as a quaternion."""
    return tuple(shape) == (4,) and (name.endswith("attitude") or "quaternion" in description.lower())


def component_labels(name: str, shape: tuple, description: str = "") -> list[str]:
    """Legend texts of the components of a logged signal (one per element, row-major)."""
    shape = tuple(int(n) for n in shape)
    size = int(np.prod(shape, dtype=int))
    leaf = name.rsplit(".", 1)[-1]
    if size == 1:
        return [leaf]
    if is_quaternion(name, shape, description):
        return ["w", "x", "y", "z"]
    if leaf.startswith("modal_"):
        return [f"η{k + 1}" + {"modal_u": "'", "modal_u_dot": "''"}.get(leaf, "") for k in range(size)]
    if shape == (3,):
        return ["x", "y", "z"]
    if shape == (3, 3):
        return [f"R{i}{j}" for i in range(1, 4) for j in range(1, 4)]
    return [f"{leaf}[{k}]" for k in range(size)]


def resolve_signal(requested: str, available: list[str], error: type[Exception] = KeyError) -> str:
    """The logged signal ``requested`` names, in full or by a unique suffix; ``error`` (the caller's
    exception type) names what is missing or ambiguous."""
    if requested in available:
        return requested
    matches = [name for name in available if name.endswith("." + requested)]
    if len(matches) == 1:
        return matches[0]
    if not matches:
        raise error(f"no signal {requested!r} in the log; signals: {available}")
    raise error(f"{requested!r} is ambiguous: {matches}")

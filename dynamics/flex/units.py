"""Deck units: the unit system a NASTRAN deck is written in, and its factors to SI.

NASTRAN has no units: a deck is consistent in some system of length, force (or mass) and time, and
PARAM WTMASS scales every mass term into the consistent mass unit (MSC Nastran QRG, PARAM WTMASS:
a deck in inch, pound-force, second with densities in pound-mass per cubic inch uses WTMASS =
1/386.0886, the pound-mass in lbf s^2/in). fem2modal assembles and solves in the deck's units and
expresses the body in SI at the end (:mod:`dynamics.flex.transform`); this module reads the
system the user names and gives the factors.

A system is written ``LENGTH,FORCE,TIME`` (``in,lbf,s``; ``mm,N,s``) or ``LENGTH,MASS,TIME``
(``mm,kg,s``; ``m,kg,s``). The unit of the fourth quantity follows from Newton's law with a unit
coefficient: mass = force time^2 / length (in,lbf,s: 1 lbf s^2/in = 175.1268 kg), or
force = mass length / time^2 (mm,kg,s: 1 kg mm/s^2 = 1e-3 N). Exact definitions: 1 in = 0.0254 m,
1 ft = 0.3048 m, 1 lbm = 0.45359237 kg, 1 lbf = 1 lbm x 9.80665 m/s^2 (NIST SP 811, App. B).
"""

from __future__ import annotations

from dataclasses import dataclass

STANDARD_GRAVITY = 9.80665          # m/s^2, exact (NIST SP 811)
POUND_MASS = 0.45359237             # kg, exact
POUND_FORCE = POUND_MASS * STANDARD_GRAVITY   # N

LENGTH_UNITS = {"m": 1.0, "cm": 0.01, "mm": 1e-3, "km": 1e3, "in": 0.0254, "ft": 0.3048}
FORCE_UNITS = {"N": 1.0, "kN": 1e3, "MN": 1e6, "mN": 1e-3, "lbf": POUND_FORCE, "kip": 1e3 * POUND_FORCE}
MASS_UNITS = {"kg": 1.0, "g": 1e-3, "t": 1e3, "tonne": 1e3, "Mg": 1e3, "lbm": POUND_MASS,
              "slug": POUND_FORCE / 0.3048}
TIME_UNITS = {"s": 1.0, "ms": 1e-3}


class UnitsError(ValueError):
    """A unit system fem2modal cannot use; the message names what was given and what is known."""


@dataclass(frozen=True)
class DeckUnits:
    """A consistent unit system: SI value = deck value x factor.

    ``spec``: the system as the user wrote it (``in,lbf,s``); ``length``, ``mass``, ``time``,
    ``force``: metres, kilograms, seconds, newtons per deck unit; ``mass_name`` / ``force_name``:
    how the derived unit reads (``lbf*s^2/in``)."""

    spec: str
    length: float
    mass: float
    time: float
    force: float
    mass_name: str
    force_name: str

    @property
    def is_si(self) -> bool:
        return self.length == 1.0 and self.mass == 1.0 and self.time == 1.0

    def density(self, value: float) -> float:
        """A deck density (consistent mass unit per length^3) in kg/m^3."""
        return value * self.mass / self.length ** 3

    def describe(self) -> str:
        return (f"{self.spec}: 1 length unit = {self.length:.10g} m, 1 mass unit ({self.mass_name}) = "
                f"{self.mass:.10g} kg, 1 force unit ({self.force_name}) = {self.force:.10g} N, 1 time unit = "
                f"{self.time:.10g} s")


SI = DeckUnits("m,N,s", 1.0, 1.0, 1.0, 1.0, "kg", "N")


def parse_units(text: str) -> DeckUnits:
    """``LENGTH,FORCE,TIME`` or ``LENGTH,MASS,TIME`` (e.g. ``in,lbf,s``, ``mm,N,s``, ``mm,kg,s``) ->
    :class:`DeckUnits`; :class:`UnitsError` for an unknown unit or a list that is not one length,
    one force or mass, one time (in that order)."""
    known = (f"lengths {', '.join(LENGTH_UNITS)}; forces {', '.join(FORCE_UNITS)}; masses "
             f"{', '.join(MASS_UNITS)}; times {', '.join(TIME_UNITS)}")
    tokens = [t.strip() for t in str(text).split(",")]
    if len(tokens) != 3 or not all(tokens):
        raise UnitsError(f"--units {text!r}: expected LENGTH,FORCE,TIME or LENGTH,MASS,TIME (e.g. in,lbf,s, "
                         f"mm,N,s, mm,kg,s): three units, the fourth follows from F = m a; a system naming both "
                         f"a force and a mass unit would fix g's value by units and is refused. Known: {known}")
    length, middle, time = tokens
    kinds = {name: kind for kind, table in (("length", LENGTH_UNITS), ("force", FORCE_UNITS),
                                            ("mass", MASS_UNITS), ("time", TIME_UNITS)) for name in table}
    for position, token, wanted in ((1, length, ("length",)), (2, middle, ("force", "mass")),
                                    (3, time, ("time",))):
        kind = kinds.get(token)
        if kind is None:
            raise UnitsError(f"--units {text!r}: unknown unit {token!r} (unit {position}); known: {known}")
        if kind not in wanted:
            raise UnitsError(f"--units {text!r}: unit {position} ({token!r}) is a {kind}, expected a "
                             f"{' or '.join(wanted)}: the order is LENGTH,FORCE,TIME or LENGTH,MASS,TIME")
    L, T = LENGTH_UNITS[length], TIME_UNITS[time]
    if middle in FORCE_UNITS:
        F = FORCE_UNITS[middle]
        return DeckUnits(text.replace(" ", ""), L, F * T * T / L, T, F, f"{middle}*{time}^2/{length}", middle)
    m = MASS_UNITS[middle]
    return DeckUnits(text.replace(" ", ""), L, m, T, m * L / (T * T), middle, f"{middle}*{length}/{time}^2")

"""Cross sections of PBARL and PBEAML (beam properties given by shape and dimensions).

NASTRAN turns a PBARL/PBEAML into an equivalent PBAR/PBEAM (MSC Nastran QRG, PBARL remarks 3-4: area,
moments of inertia, torsion constant, shear flexibility factors and stress recovery points C, D, E, F from
TYPE and DIMi) and prints it in the f06 (USER INFORMATION MESSAGE 4379). The QRG gives the shapes as
figures; the dimensions are read as there: the section's y axis (plane 1, I1 = int y^2 dA) along DIM2 for
BAR and BOX and along DIM1 (the height) for I, z along DIM1 (BAR, BOX) or the flange width (I).

Verified against NASTRAN's own equivalent entries (pyNastran's models/aero/fmondsp.f06, MSC Nastran 2005;
models/aero/aerobeam.f06, NX Nastran; models/beam_modes/beam_modes.f06, MSC: tests/flex/test_interop_cards.py):

* ROD (DIM1 = r): A = pi r^2, I1 = I2 = pi r^4 / 4, J = pi r^4 / 2, K1 = K2 = 0.9 (MSC's value; it
  reproduces MSC's eigenvalues of beam_modes to 7 digits, tests/flex/test_nastran_reference.py).
* TUBE (DIM1 = outer radius, DIM2 = inner) and TUBE2 (DIM1 = outer radius, DIM2 = wall thickness):
  the annulus, J = I1 + I2, K1 = K2 = 0.5 (MSC prints 0.5 for tubes of t/r = 0.003 - 0.025).
* BOX (DIM1 = width along z, DIM2 = height along y, DIM3 = thickness of the walls parallel to z, DIM4 =
  of the walls parallel to y): A and I of the hollow rectangle; J by Bredt's formula on the wall midlines,
  J = 4 A_m^2 / (sum of wall length / thickness); K1 = area of the walls parallel to y between the others
  over A, K2 likewise for z (MSC's and NX's printed values to their 5 digits).

And against closed forms and published tables only (NASTRAN's values for these shapes are not available
to us; the card report says so):

* BAR (DIM1 = width along z, DIM2 = height along y): A = b h, I1 = b h^3 / 12, I2 = h b^3 / 12; J by the
  exact series of St-Venant torsion of a rectangle, a b^3 [1/3 - (64 / pi^5)(b/a) sum_n odd
  tanh(n pi a / 2b) / n^5], a >= b (Timoshenko and Goodier, Theory of Elasticity, 3rd ed., sec. 109; the
  table there: beta = 0.141, 0.229, 0.281, 0.312 for a/b = 1, 2, 4, 10); K1 = K2 = 5/6.
* I with equal flanges (DIM1 = height h along y, DIM2 = DIM3 = flange width b, DIM4 = web thickness tw,
  DIM5 = DIM6 = flange thickness tf): A, I1, I2 of the three rectangles; J = (2 b tf^3 + hw tw^3) / 3 (the
  thin-walled open-section value, hw = h - 2 tf; fillets and corners not counted, as in section tables'
  idealized shapes); K1 = hw tw / A, K2 = 2 b tf / A (the walls parallel to the shear, as for BOX).

Refused: the other shapes, and I sections with unequal flanges: their shear centre is not the centroid,
which CBAR and this CBEAM do not model.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from dynamics.flex.bulk_data import BulkDataError

SHAPES = ("ROD", "TUBE", "TUBE2", "BAR", "BOX", "I")


@dataclass(frozen=True)
class Section:
    """Equivalent PBAR values of a shape: area, moments of inertia, torsion constant, shear factors, the
    stress recovery points C, D, E, F as (4, 2) (y, z), and a note for the card report (empty when the
    values were checked against NASTRAN's own)."""

    A: float
    I1: float
    I2: float
    J: float
    k1: float
    k2: float
    stress_points: np.ndarray
    note: str = ""


def rectangle_torsion_constant(a: float, b: float, terms: int = 50) -> float:
    """St-Venant torsion constant of an a x b rectangle by its exact series (Timoshenko & Goodier sec. 109)."""
    a, b = max(a, b), min(a, b)
    n = np.arange(1, 2 * terms, 2, dtype=float)
    series = np.sum(np.tanh(n * np.pi * a / (2.0 * b)) / n ** 5)
    return float(a * b ** 3 * (1.0 / 3.0 - 64.0 / np.pi ** 5 * (b / a) * series))


def _positive(dims, names, shape, context):
    for value, name in zip(dims, names):
        if not value > 0.0:
            raise BulkDataError(f"{context}: {shape} {name} = {value} must be > 0")


def section_properties(shape: str, dims, context: str) -> Section:
    """:class:`Section` of a PBARL/PBEAML ``shape`` with dimensions ``dims`` (module docstring)."""
    shape = str(shape).strip().upper()
    d = [float(v) for v in dims]
    need = {"ROD": 1, "TUBE": 2, "TUBE2": 2, "BAR": 2, "BOX": 4, "I": 6}
    if shape not in need:
        raise BulkDataError(f"{context}: section {shape} is not supported (supported: {', '.join(SHAPES)}); "
                            "give the section as PBAR/PBEAM values")
    if len(d) < need[shape]:
        raise BulkDataError(f"{context}: section {shape} needs {need[shape]} dimensions, got {len(d)}")
    d = d[:need[shape]]
    if shape == "ROD":
        _positive(d, ["DIM1 (radius)"], shape, context)
        r = d[0]
        I = np.pi * r ** 4 / 4.0
        return Section(np.pi * r * r, I, I, 2.0 * I, 0.9, 0.9, _round_points(r))
    if shape in ("TUBE", "TUBE2"):
        ro = d[0]
        ri = d[1] if shape == "TUBE" else d[0] - d[1]
        _positive([ro, d[1]], ["DIM1 (outer radius)", "DIM2"], shape, context)
        if not 0.0 <= ri < ro:
            raise BulkDataError(f"{context}: {shape} inner radius {ri} must be in [0, outer radius {ro})")
        I = np.pi * (ro ** 4 - ri ** 4) / 4.0
        return Section(np.pi * (ro * ro - ri * ri), I, I, 2.0 * I, 0.5, 0.5, _round_points(ro))
    if shape == "BAR":
        _positive(d, ["DIM1 (width)", "DIM2 (height)"], shape, context)
        b, h = d
        return Section(b * h, b * h ** 3 / 12.0, h * b ** 3 / 12.0, rectangle_torsion_constant(b, h), 5.0 / 6.0,
                       5.0 / 6.0, _box_points(b, h),
                       note="BAR: J by the exact rectangle series, shear factors 5/6 (NASTRAN's own values for "
                            "BAR were not available to check)")
    if shape == "BOX":
        _positive(d, ["DIM1 (width)", "DIM2 (height)", "DIM3", "DIM4"], shape, context)
        b, h, t3, t4 = d
        bi, hi = b - 2.0 * t4, h - 2.0 * t3
        if bi <= 0.0 or hi <= 0.0:
            raise BulkDataError(f"{context}: BOX walls fill the section (DIM1 > 2 DIM4 and DIM2 > 2 DIM3 needed)")
        A = b * h - bi * hi
        midline = 2.0 * (b - t4) / t3 + 2.0 * (h - t3) / t4
        J = 4.0 * ((b - t4) * (h - t3)) ** 2 / midline
        return Section(A, (b * h ** 3 - bi * hi ** 3) / 12.0, (h * b ** 3 - hi * bi ** 3) / 12.0, J,
                       2.0 * t4 * hi / A, 2.0 * t3 * bi / A, _box_points(b, h))
    _positive(d, ["DIM1 (height)", "DIM2", "DIM3", "DIM4 (web)", "DIM5", "DIM6"], shape, context)
    h, b_bottom, b_top, tw, t_bottom, t_top = d
    if b_bottom != b_top or t_bottom != t_top:
        raise BulkDataError(f"{context}: I section with unequal flanges (DIM2 {b_bottom} / DIM3 {b_top}, DIM5 "
                            f"{t_bottom} / DIM6 {t_top}): its shear centre is not its centroid, which is not "
                            "modelled; give equal flanges or PBAR/PBEAM values")
    b, tf = b_top, t_top
    hw = h - 2.0 * tf
    if hw <= 0.0 or tw >= b:
        raise BulkDataError(f"{context}: I section flanges fill the height (DIM1 > DIM5 + DIM6) or the web is "
                            "wider than the flanges")
    A = 2.0 * b * tf + hw * tw
    return Section(A, (b * h ** 3 - (b - tw) * hw ** 3) / 12.0, (2.0 * tf * b ** 3 + hw * tw ** 3) / 12.0,
                   (2.0 * b * tf ** 3 + hw * tw ** 3) / 3.0, hw * tw / A, 2.0 * b * tf / A, _box_points(b, h),
                   note="I: J of the thin-walled open section, shear factors from the wall areas (NASTRAN's own "
                        "values for I were not available to check)")


def _round_points(r):
    return np.array([[r, 0.0], [0.0, r], [-r, 0.0], [0.0, -r]])


def _box_points(width_z, height_y):
    y, z = 0.5 * height_y, 0.5 * width_z
    return np.array([[y, z], [-y, z], [-y, -z], [y, -z]])

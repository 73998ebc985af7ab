"""Rotating uniform cantilever: an independent reference and the deck and scene of the user workflow
(issue 15, geometric stiffening).

Reference: the rotating Euler-Bernoulli beam in dimensionless form (x = s / L, lambda = Omega
sqrt(rho A L^4 / EI), hub radius delta = R / L, frequency omega sqrt(rho A L^4 / EI)),

    w'''' - lambda^2 (T(x) w')' - c lambda^2 w = omega^2 w,   T(x) = (1 - x^2) / 2 + delta (1 - x),

clamped at x = 0 (w = w' = 0), free at x = 1 (w'' = 0, w''' - lambda^2 T(1) w' = w''' = 0); c = 0 for
flapwise (out of the plane of rotation), c = 1 for chordwise (in-plane: the centrifugal force of the
lateral displacement; axial motion inextensible). Solved by its power series w = sum a_k x^k (the
coefficients are polynomials, so the series is entire): a_0 = a_1 = 0, two solutions from (a_2, a_3), a
four-term recursion for a_{k+4}, and the frequencies are the roots of the 2 x 2 determinant of the free-end
conditions (converged: 160 and 240 terms agree to < 1e-12, checked in the tests). Published values: Wright, Smith, Thresher and Wang, J. Appl. Mech. 49
(1982), Table 1 (flapwise, no hub).
"""

from __future__ import annotations

import numpy as np

# Wright, Smith, Thresher & Wang 1982, uniform cantilever, flapwise, no hub: first frequency for
# lambda = 0..12
WRIGHT_1982_FLAP_1 = (3.5160, 3.6816, 4.1373, 4.7973, 5.5850, 6.4495, 7.3604, 8.2996, 9.2568, 10.2257,
                      11.2023, 12.1843, 13.1702)


def _tip_determinant(omega, lam, hub, c, terms):
    """det [w''(1), w'''(1)] of the two power-series solutions with w(0) = w'(0) = 0 (module docstring),
    for a frequency or an array of them."""
    l2 = lam * lam
    w2 = np.asarray(omega, dtype=float) ** 2
    out = []
    for start in ((1.0, 0.0), (0.0, 1.0)):
        a = np.zeros((terms + 4,) + w2.shape)
        a[2], a[3] = start
        for k in range(terms):
            a[k + 4] = (l2 * ((0.5 + hub) * (k + 2) * (k + 1) * a[k + 2] - hub * (k + 1) ** 2 * a[k + 1]
                              - 0.5 * k * (k + 1) * a[k]) + (c * l2 + w2) * a[k]) \
                / ((k + 4) * (k + 3) * (k + 2) * (k + 1))
        k = np.arange(terms + 4, dtype=float).reshape((-1,) + (1,) * w2.ndim)
        out.append((np.sum(k * (k - 1) * a, axis=0), np.sum(k * (k - 1) * (k - 2) * a, axis=0)))
    return out[0][0] * out[1][1] - out[1][0] * out[0][1]


def rotating_beam_frequencies(lam, hub=0.0, chordwise=False, count=3, terms=160):
    """First ``count`` dimensionless frequencies omega sqrt(rho A L^4 / EI) (module docstring): roots of
    the free-end determinant of the power series (Frobenius) solution, bracketed on a fine grid and
    refined by Brent's method to 1e-14."""
    from scipy.optimize import brentq

    c = 1.0 if chordwise else 0.0
    found = []
    grid = np.linspace(1e-3, 4.0 * (count + 1) ** 2 + 2.0 * lam * (count + 1) + 40.0, 4000)
    values = _tip_determinant(grid, lam, hub, c, terms)
    for w0, w1, f0, f1 in zip(grid[:-1], grid[1:], values[:-1], values[1:]):
        if np.sign(f0) != np.sign(f1):
            found.append(brentq(lambda w: float(_tip_determinant(w, lam, hub, c, terms)), w0, w1, xtol=1e-14, rtol=1e-15))
            if len(found) == count:
                break
    if len(found) < count:
        raise RuntimeError(f"found only {len(found)} frequencies for lambda = {lam}")
    return np.array(found)


# the FE beam of the workflow: L = 1 m, rho A = 1 kg/m, EI = 1 N m^2 (dimensionless frequencies in rad/s),
# EA = 1e8 N: axially stiff like the inextensible beam of the tables, and its axial (15,700 rad/s) and
# torsion (~9,800 rad/s) modes stay out of the mode set (a CBAR's lumped mass has no torsional inertia, so a
# torsion mode in the set would be nearly massless in the engine's modal integrals)
LENGTH, E_MOD, AREA, INERTIA, RHO = 1.0, 1.0e8, 1.0, 1.0e-8, 1.0


def rotating_beam_deck(n_elements=80, coupled=True) -> str:
    """Uniform CBAR cantilever along basic x, grids 1 (root) .. n + 1 (tip), elements 101..."""
    lines = ["$ uniform CBAR beam, L = 1 m, rho A = 1 kg/m, EI = 1 N m^2, EA = 1e8 N (issue 15)"]
    if coupled:
        lines.append("PARAM,COUPMASS,1")
    for i, xi in enumerate(np.linspace(0.0, LENGTH, n_elements + 1)):
        lines.append(f"GRID,{i + 1},,{float(xi)!r},0.0,0.0")
    lines.append(f"MAT1,1,{E_MOD!r},,0.3,{RHO!r}")
    lines.append(f"PBAR,10,1,{AREA!r},{INERTIA!r},{INERTIA!r},{2 * INERTIA!r}")
    for i in range(n_elements):
        lines.append(f"CBAR,{101 + i},10,{i + 1},{i + 2},0.0,1.0,0.0")
    lines.append("ENDDATA")
    return "\n".join(lines) + "\n"


def spinning_scene(body_file, omega, hub_radius=0.0, stiffening=True, tip_grid=41) -> str:
    """YAML scene: a hub prescribed to spin about z at ``omega`` rad/s (prescribed acceleration input
    left at zero), the beam clamped to it at ``hub_radius`` by a locked hinge holding grid 1."""
    return f"""name: spinning_beam
description: uniform cantilever on a hub spinning at a constant rate (issue 15)
multibody:
  bodies:
    - name: hub
      parent: world
      hinge: revolute
      axis: [0, 0, 1]
      prescribed: true
      mass: 10 kg
      inertia: "[1, 1, 1] kg*m^2"
      initial: {{angle: 0 deg, angle_rate: "{omega!r} rad/s"}}
    - name: beam
      parent: hub
      hinge: locked
      inboard_position: "[{hub_radius!r}, 0, 0] m"
      body_file: {body_file}
      child_grid: 1
      geometric_stiffening: {'true' if stiffening else 'false'}
  nodes:
    - {{name: tip, body: beam, grid: {tip_grid}}}
integrator:
  method: rk4
  step: 1 ms
stop:
  time: 0.01 s
"""


def _axial_determinant(omega, tau, terms):
    """Free-end determinant of w'''' - tau w'' = omega^2 w (constant axial force tau = P L^2 / EI, tension
    positive, a dead load at the tip): w''(1) = 0, w'''(1) - tau w'(1) = 0, for one frequency or an array."""
    w2 = np.asarray(omega, dtype=float) ** 2
    cols = []
    for start in ((1.0, 0.0), (0.0, 1.0)):
        a = np.zeros((terms + 4,) + w2.shape)
        a[2], a[3] = start
        for k in range(terms):
            a[k + 4] = (tau * (k + 2) * (k + 1) * a[k + 2] + w2 * a[k]) / ((k + 4) * (k + 3) * (k + 2) * (k + 1))
        k = np.arange(terms + 4, dtype=float).reshape((-1,) + (1,) * w2.ndim)
        d1 = np.sum(k * a, axis=0)
        d2 = np.sum(k * (k - 1) * a, axis=0)
        d3 = np.sum(k * (k - 1) * (k - 2) * a, axis=0)
        cols.append((d2, d3 - tau * d1))
    return cols[0][0] * cols[1][1] - cols[1][0] * cols[0][1]


def axially_loaded_cantilever_frequencies(tau, count=3, terms=160):
    """First ``count`` dimensionless bending frequencies of a cantilever under a constant axial tip load
    (power series as :func:`rotating_beam_frequencies`; buckling at tau = -pi^2 / 4)."""
    from scipy.optimize import brentq

    grid = np.linspace(1e-3, 4.0 * (count + 1) ** 2 + 2.0 * abs(tau) + 40.0, 4000)
    values = _axial_determinant(grid, tau, terms)
    found = []
    for w0, w1, f0, f1 in zip(grid[:-1], grid[1:], values[:-1], values[1:]):
        if np.sign(f0) != np.sign(f1):
            found.append(brentq(lambda w: float(_axial_determinant(w, tau, terms)), w0, w1, xtol=1e-14, rtol=1e-15))
            if len(found) == count:
                break
    return np.array(found)

"""CQUAD4 (MITC4 + QM6 membrane) and CTRIA3 (MITC3 + CST) shells: patch tests, plate frequencies
against closed forms and published tables, convergence rates, locking.

References:
* Patch test geometry: MacNeal & Harder, "A proposed standard set of problems to test finite
  element accuracy", Finite Elements in Analysis and Design 1 (1985) 3-20, fig. 2 (0.24 x 0.12
  rectangle, interior grids at (0.04, 0.02), (0.18, 0.03), (0.16, 0.08), (0.08, 0.08)).
* Simply supported rectangular Mindlin plate: the Navier solution is exact (w = W sin sin,
  psi_x = X cos sin, psi_y = Y sin cos solve Mindlin's equations with the hard simply supported
  edges); each (m, n) gives a 3 x 3 eigen-problem (Mindlin, J. Appl. Mech. 18, 1951; Hashemi &
  Arsanjani, IJSS 42, 2005, eq. 25). For thin plates it tends to Leissa's Kirchhoff formula
  omega = pi^2 (m^2/a^2 + n^2/b^2) sqrt(D / (rho t)) (Leissa, Vibration of Plates, NASA SP-160,
  1969, eq. 4.5).
* Square cantilever plate (CFFF), nu = 0.3: lambda = omega a^2 sqrt(rho t / D) = 3.4917, 8.5246,
  21.429, 27.331, 31.111 (Leissa, NASA SP-160, Table 4.48, from Young 1950 / Barton 1951 Ritz
  solutions; quoted to 5 digits, about 1e-3 of the Kirchhoff answer).
"""

import numpy as np
import pytest
from numpy.testing import assert_allclose

import decks
from dynamics.flex.pipeline import Fem2ModalOptions, fem2modal
from dynamics.flex.shells import shell_batch

E, NU, RHO = decks.E, decks.NU, decks.RHO
G = E / (2 * (1 + NU))

PATCH = np.array([[0.0, 0.0], [0.24, 0.0], [0.24, 0.12], [0.0, 0.12],
                  [0.04, 0.02], [0.18, 0.03], [0.16, 0.08], [0.08, 0.08]])
PATCH_QUADS = [(0, 1, 5, 4), (1, 2, 6, 5), (2, 3, 7, 6), (3, 0, 4, 7), (4, 5, 6, 7)]


def _patch_matrices(triangles: bool, t: float):
    elems = [(q[0], q[1], q[2]) for q in PATCH_QUADS] + [(q[0], q[2], q[3]) for q in PATCH_QUADS] \
        if triangles else PATCH_QUADS
    xyz = np.zeros((len(elems), len(elems[0]), 3))
    for e, conn in enumerate(elems):
        xyz[e, :, :2] = PATCH[list(conn)]
    props = np.tile([E, NU, G, RHO, t, 0.0, 1.0, 5.0 / 6.0, 0.0], (len(elems), 1))
    Ke, _, _ = shell_batch(xyz, props, True)
    K = np.zeros((48, 48))
    for e, conn in enumerate(elems):
        dofs = (6 * np.asarray(conn)[:, None] + np.arange(6)).ravel()
        K[np.ix_(dofs, dofs)] += Ke[e]
    return K


def _exact_patch_field(kind):
    x, y = PATCH[:, 0], PATCH[:, 1]
    u = np.zeros((8, 6))
    if kind == "membrane":
        u[:, 0] = 1e-3 * (x + 0.5 * y)
        u[:, 1] = 1e-3 * (y + 0.5 * x)
        u[:, 5] = 0.5 * (0.5e-3 - 0.5e-3)      # in-plane rotation of this field: zero
    else:                                      # constant curvature, no transverse shear
        u[:, 2] = 1e-3 * 0.5 * (x**2 + x * y + y**2)
        u[:, 3] = 1e-3 * (0.5 * x + y)         # theta_x = w,y
        u[:, 4] = -1e-3 * (x + 0.5 * y)        # theta_y = -w,x
    return u.ravel()


@pytest.mark.parametrize("triangles", [False, True], ids=["CQUAD4", "CTRIA3"])
@pytest.mark.parametrize("kind", ["membrane", "bending"])
@pytest.mark.parametrize("t", [1e-3, 1e-1])
def test_patch_test(triangles, kind, t):
    """Boundary grids given the exact constant-strain (or constant-curvature) field, the four
    interior grids are solved for: they must take the exact values (MacNeal & Harder patch).
    Round-off only: 1e-8 relative to the field (theta_z, held only by the 1e-4 G t drilling
    penalty, carries round-off ~1e4 x eps x the condition of the membrane stiffness: 3e-13)."""
    K = _patch_matrices(triangles, t)
    exact = _exact_patch_field(kind)
    b = np.arange(24)
    i = np.arange(24, 48)
    ui = np.linalg.solve(K[np.ix_(i, i)], -K[np.ix_(i, b)] @ exact[b])
    assert_allclose(ui, exact[i], rtol=0, atol=1e-8 * np.abs(exact).max())
    # and the exact field is in equilibrium: no force on the interior grids
    assert np.abs(K[i] @ exact).max() <= 1e-9 * np.abs(K).max() * np.abs(exact).max()


def mindlin_ss_frequency(m, n, a, b, t, shear_factor=5.0 / 6.0):
    """Exact lowest (flexural) frequency [Hz] of mode (m, n) of a hard simply supported plate."""
    al, be = m * np.pi / a, n * np.pi / b
    D = E * t**3 / (12 * (1 - NU**2))
    S = shear_factor * G * t
    K = np.array([[S * (al**2 + be**2), S * al, S * be],
                  [S * al, D * (al**2 + 0.5 * (1 - NU) * be**2) + S, 0.5 * D * (1 + NU) * al * be],
                  [S * be, 0.5 * D * (1 + NU) * al * be, D * (be**2 + 0.5 * (1 - NU) * al**2) + S]])
    Mm = np.diag([RHO * t, RHO * t**3 / 12, RHO * t**3 / 12])
    lam = np.linalg.eigvals(np.linalg.solve(Mm, K)).real.min()
    return np.sqrt(lam) / (2 * np.pi)


def _plate_frequencies(write_deck, n, count, **kw):
    import warnings
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        body = fem2modal(write_deck(decks.plate_deck(n, **kw), f"plate{n}.dat"),
                         Fem2ModalOptions(n_modes=count))
    return body.frequencies_hz


SS_MODES = [(1, 1), (1, 2), (2, 1), (2, 2)]


# measured errors (4, 8, 16, 32 elements per side), modes (1,1) (1,2) (2,1) (2,2):
#   CQUAD4 (MITC4): 7.2e-2 3.2e-1 3.2e-1 3.4e-1 / 1.7e-2 6.6e-2 ... / 4.3e-3 1.6e-2 1.6e-2 1.7e-2 /
#                   1.07e-3 3.9e-3 3.9e-3 4.3e-3; rates 2.00-2.02 over the last halving
#   CTRIA3 (MITC3): 1.28 ... / 1.9e-1 ... / 2.0e-2 2.8e-2 5.4e-2 7.6e-2 /
#                   3.0e-3 5.7e-3 8.4e-3 1.2e-2; rates 2.3-2.7 (still pre-asymptotic)
@pytest.mark.parametrize("triangles,first16,all32,rate", [(False, 5e-3, 5e-3, 1.95),
                                                          (True, 2.5e-2, 1.5e-2, 2.0)],
                         ids=["CQUAD4", "CTRIA3"])
def test_simply_supported_plate_converges_at_second_order(write_deck, triangles, first16, all32,
                                                          rate):
    a, t = 1.0, 0.01
    exact = np.sort([mindlin_ss_frequency(m, n, a, a, t) for m, n in SS_MODES])
    # Kirchhoff (Leissa eq. 4.5) differs from Mindlin by shear and rotary inertia: 3e-4 here
    D = E * t**3 / (12 * (1 - NU**2))
    leissa = 2 * np.pi**2 * np.sqrt(D / (RHO * t)) / (2 * np.pi)    # m = n = 1, a = b
    assert abs(exact[0] / leissa - 1) < 1e-3
    errs = []
    for n in (4, 8, 16, 32):
        f = _plate_frequencies(write_deck, n, 4, t=t, triangles=triangles)
        errs.append(np.abs(f - exact) / exact)
    errs = np.array(errs)
    print("SS plate", "tria" if triangles else "quad", "errors", errs, "exact", exact)
    rates = np.log2(errs[:-1] / errs[1:])
    print("rates", rates)
    assert errs[2, 0] < first16                       # (1,1) at 16 x 16
    assert np.all(errs[-1] < all32)                   # the four lowest at 32 x 32
    assert np.all(rates[-1] > rate)                   # at least O(h^2): error / 4 per halving


@pytest.mark.parametrize("t", [1e-2, 1e-3, 1e-4])
def test_cantilever_plate_bending_and_twist_without_locking(write_deck, t):
    """Leissa's CFFF square plate; the same mesh for t/a = 1e-2 .. 1e-4 (shear locking would
    stiffen the thin ones by orders of magnitude)."""
    a = 1.0
    D = E * t**3 / (12 * (1 - NU**2))
    lam = np.array([3.4917, 8.5246, 21.429, 27.331, 31.111])
    leissa = lam / a**2 * np.sqrt(D / (RHO * t)) / (2 * np.pi)
    f = _plate_frequencies(write_deck, 16, 5, t=t, edges="CFFF")
    assert_allclose(f, leissa, rtol=1e-2)

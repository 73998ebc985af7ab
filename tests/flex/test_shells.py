"""CQUAD4 (MITC4 + QM6 membrane) and CTRIA3 (MITC3+ + CST) shells: patch tests, plate frequencies
against closed forms and published tables, convergence rates, locking (the CTRIA3 on other mesh
patterns: test_tria_meshes.py).

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
from dynamics.flex.shells import isotropic_props, shell_batch

E, NU, RHO = decks.E, decks.NU, decks.RHO
G = E / (2 * (1 + NU))

PATCH = np.array([[0.0, 0.0], [0.24, 0.0], [0.24, 0.12], [0.0, 0.12],
                  [0.04, 0.02], [0.18, 0.03], [0.16, 0.08], [0.08, 0.08]])
PATCH_QUADS = [(0, 1, 5, 4), (1, 2, 6, 5), (2, 3, 7, 6), (3, 0, 4, 7), (4, 5, 6, 7)]


PATCH_MESHES = {"CQUAD4": PATCH_QUADS,
                 "CTRIA3": [(q[0], q[1], q[2]) for q in PATCH_QUADS]
                 + [(q[0], q[2], q[3]) for q in PATCH_QUADS],
                 "CTRIA3, other diagonal": [(q[0], q[1], q[3]) for q in PATCH_QUADS]
                 + [(q[1], q[2], q[3]) for q in PATCH_QUADS]}


def _patch_matrices(mesh: str, t: float):
    elems = PATCH_MESHES[mesh]
    xyz = np.zeros((len(elems), len(elems[0]), 3))
    for e, conn in enumerate(elems):
        xyz[e, :, :2] = PATCH[list(conn)]
    props = np.tile(isotropic_props(E, NU, RHO, t), (len(elems), 1))
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


@pytest.mark.parametrize("mesh", list(PATCH_MESHES))
@pytest.mark.parametrize("kind", ["membrane", "bending"])
@pytest.mark.parametrize("t", [1e-3, 1e-1])
def test_patch_test(mesh, kind, t):
    """Boundary grids given the exact constant-strain (or constant-curvature) field, the four
    interior grids are solved for: they must take the exact values (MacNeal & Harder patch).
    Round-off only: 1e-8 relative to the field (theta_z, held only by the drilling penalty,
    1e-4 ... 0.1 G t, carries round-off ~ eps G t / gamma_d x the condition of the membrane
    stiffness: 3e-13 when it was 1e-4 G t everywhere)."""
    K = _patch_matrices(mesh, t)
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
#   CTRIA3 (MITC3+): 1.7e-1 3.6e-1 5.5e-1 6.8e-1 / 3.8e-2 8.1e-2 1.1e-1 1.5e-1 /
#                   9.0e-3 1.9e-2 2.6e-2 3.6e-2 / 2.20e-3 4.7e-3 6.2e-3 8.8e-3; rates 2.02-2.04
#                   (the MITC3 it replaced: 3.0e-3 5.7e-3 8.4e-3 1.2e-2 at 32, rates 2.3-2.7)
# bounds: the measured values with a margin of 10 % (1.1 x 8.8e-3 = 9.7e-3 keeps the 1 %)
@pytest.mark.parametrize("triangles,first16,all32,rate", [(False, 5e-3, 5e-3, 1.95),
                                                          (True, 1.0e-2, 9.7e-3, 1.95)],
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


@pytest.mark.parametrize("triangles", [False, True], ids=["CQUAD4", "CTRIA3"])
@pytest.mark.parametrize("t", [1e-2, 1e-3, 1e-4])
def test_cantilever_plate_bending_and_twist_without_locking(write_deck, t, triangles):
    """Leissa's CFFF square plate; the same mesh for t/a = 1e-2 .. 1e-4 (shear locking would
    stiffen the thin ones by orders of magnitude). CTRIA3 (MITC3+) measured within -5.2e-3 ..
    +4.7e-3 at every thickness; the MITC3 it replaced was 2 % off at 1e-2 and locked below
    (modes 2, 4, 5: +26 .. +74 % at 1e-3, +103 .. +130 % at 1e-4)."""
    a = 1.0
    D = E * t**3 / (12 * (1 - NU**2))
    lam = np.array([3.4917, 8.5246, 21.429, 27.331, 31.111])
    leissa = lam / a**2 * np.sqrt(D / (RHO * t)) / (2 * np.pi)
    f = _plate_frequencies(write_deck, 16, 5, t=t, edges="CFFF", triangles=triangles)
    print("cantilever", "tria" if triangles else "quad", t, f / leissa - 1)
    assert_allclose(f, leissa, rtol=1e-2)


def _orthotropic_moduli(E1, E2, nu12, G12):
    nu21 = nu12 * E2 / E1
    d = 1.0 - nu12 * nu21
    return E1 / d, nu12 * E2 / d, E2 / d, G12


def mindlin_ss_orthotropic(m, n, a, b, t, Q, Gs, rho, kappa=5.0 / 6.0):
    """Exact lowest frequency [Hz] of mode (m, n) of a specially orthotropic hard simply
    supported Mindlin plate (the Navier solution of the isotropic case with D11, D22, D12, D66
    and the two transverse shear moduli; Reddy, Mechanics of Laminated Composite Plates and
    Shells, 2004, sec. 7.3)."""
    al, be = m * np.pi / a, n * np.pi / b
    D11, D12, D22, D66 = (q * t**3 / 12 for q in Q)
    S1, S2 = kappa * Gs[0] * t, kappa * Gs[1] * t
    K = np.array([[S1 * al**2 + S2 * be**2, S1 * al, S2 * be],
                  [S1 * al, D11 * al**2 + D66 * be**2 + S1, (D12 + D66) * al * be],
                  [S2 * be, (D12 + D66) * al * be, D66 * al**2 + D22 * be**2 + S2]])
    Mm = np.diag([rho * t, rho * t**3 / 12, rho * t**3 / 12])
    return np.sqrt(np.linalg.eigvals(np.linalg.solve(Mm, K)).real.min()) / (2 * np.pi)


def _mat2_deck(n, a, b, t, theta=None, swap=False, mcid=False):
    Q11, Q12, Q22, Q66 = _orthotropic_moduli(1.4e11, 1.0e10, 0.3, 5.0e9)
    Gs = (5.0e9, 3.0e9)
    if swap:
        Q11, Q22 = Q22, Q11
        Gs = Gs[::-1]
    text = decks.plate_deck(n, a=a, b=b, t=t)
    text = text.replace(f"MAT1,1,{E!r},,{NU!r},{RHO!r}",
                        f"MAT2,1,{Q11!r},{Q12!r},0.0,{Q22!r},0.0,{Q66!r},1600.0\n"
                        f"MAT2,3,{Gs[0]!r},0.0,0.0,{Gs[1]!r},0.0,1.0,1600.0")
    text = text.replace("PSHELL,1,1,", "PSHELL,1,1,").replace(f"PSHELL,1,1,{t!r},1,,1",
                                                              f"PSHELL,1,1,{t!r},1,,3")
    if theta is not None or mcid:
        lines = []
        for ln in text.splitlines():
            if ln.startswith("CQUAD4"):
                ln += ",8" if mcid else f",{theta!r}"
            lines.append(ln)
        text = "\n".join(lines) + "\n"
        if mcid:      # material x along basic y
            text = text.replace("ENDDATA", "CORD2R,8,,0.0,0.0,0.0,0.0,0.0,1.0\n,0.0,1.0,0.0\nENDDATA")
    return text, (Q11, Q12, Q22, Q66), Gs


def test_mat2_orthotropic_plate_against_the_navier_solution(write_deck):
    a, b, t = 1.0, 0.6, 0.01
    errs = []
    for n in (8, 16, 32):
        text, Q, Gs = _mat2_deck(n, a, b, t)
        f = _quiet_modes(write_deck, text, 3, f"ortho{n}.dat")
        exact = np.sort([mindlin_ss_orthotropic(m, k, a, b, t, Q, Gs, 1600.0)
                         for m, k in ((1, 1), (2, 1), (1, 2), (3, 1), (2, 2))])[:3]
        errs.append(np.abs(f / exact - 1))
    errs = np.array(errs)
    print("orthotropic SS plate errors", errs)
    assert np.all(errs[-1] < 1e-2)
    assert np.all(np.log2(errs[-2] / errs[-1]) > 1.9)


def test_mat2_axes_by_theta_and_mcid(write_deck):
    """Material axes turned by THETA = 90 deg (or an MCID whose x axis is basic y) equal the
    same plate with E1 and E2 (and the shear moduli) swapped."""
    a, b, t = 1.0, 0.6, 0.01
    swapped = _quiet_modes(write_deck, _mat2_deck(8, a, b, t, swap=True)[0], 4, "s.dat")
    turned = _quiet_modes(write_deck, _mat2_deck(8, a, b, t, theta=90.0)[0], 4, "t.dat")
    mcid = _quiet_modes(write_deck, _mat2_deck(8, a, b, t, mcid=True)[0], 4, "m.dat")
    assert_allclose(turned, swapped, rtol=1e-10)
    assert_allclose(mcid, swapped, rtol=1e-10)


def test_mat2_with_isotropic_moduli_equals_mat1(write_deck):
    c = E / (1 - NU**2)
    text = decks.plate_deck(8, t=0.01).replace(
        f"MAT1,1,{E!r},,{NU!r},{RHO!r}",
        f"MAT2,1,{c!r},{NU * c!r},0.0,{c!r},0.0,{G!r},{RHO!r}\nMAT2,3,{G!r},0.0,0.0,{G!r},0.0,1.0")
    text = text.replace("PSHELL,1,1,0.01,1,,1", "PSHELL,1,1,0.01,1,,3")
    ref = _quiet_modes(write_deck, decks.plate_deck(8, t=0.01), 4, "i.dat")
    assert_allclose(_quiet_modes(write_deck, text, 4, "o.dat"), ref, rtol=1e-12)


def _quiet_modes(write_deck, text, count, name):
    import warnings
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return fem2modal(write_deck(text, name), Fem2ModalOptions(n_modes=count)).frequencies_hz


def _ring_deck(n, radius=1.0, length=0.05, t=0.01, triangles=False):
    """Cylinder slice, n CQUAD4 (or 2 n CTRIA3) around, one along z, nu = 0, axial translation
    held: the in-plane modes of a thin ring."""
    lines = ["PARAM,COUPMASS,1"]
    for k in range(n):
        phi = 2 * np.pi * k / n
        x, y = float(radius * np.cos(phi)), float(radius * np.sin(phi))
        lines.append(f"GRID,{k + 1},,{x!r},{y!r},0.0,,3")
        lines.append(f"GRID,{n + k + 1},,{x!r},{y!r},{length!r},,3")
    lines.append(f"MAT1,1,{E!r},,0.0,{RHO!r}")
    lines.append(f"PSHELL,1,1,{t!r},1,,1")
    for k in range(n):
        k2 = (k + 1) % n
        g = (k + 1, k2 + 1, n + k2 + 1, n + k + 1)
        if triangles:
            lines.append(f"CTRIA3,{2 * k + 1},1,{g[0]},{g[1]},{g[2]}")
            lines.append(f"CTRIA3,{2 * k + 2},1,{g[0]},{g[2]},{g[3]}")
        else:
            lines.append(f"CQUAD4,{k + 1},1,{g[0]},{g[1]},{g[2]},{g[3]}")
    return "\n".join(lines + ["ENDDATA"]) + "\n"


@pytest.mark.parametrize("triangles", [False, True], ids=["CQUAD4", "CTRIA3"])
def test_cylindrical_shell_ring_modes_converge(write_deck, triangles):
    """Flat facets on a curved surface (drilling DOFs at every fold): the inextensional modes of
    a thin ring, omega_n^2 = E I n^2 (n^2 - 1)^2 / (rho A R^4 (n^2 + 1)) (Soedel, Vibrations of
    Shells and Plates, 3rd ed., 2004, eq. 5.3.12; Love), n = 2, 3, 4. Each n is a pair; the
    three rigid motions in the plane come out as rigid-body modes. Measured at 128 around:
    CQUAD4 1.1e-3 - 4.5e-3, rates 2.06-2.07; CTRIA3 9.8e-4 - 3.9e-3, rates 2.18-2.19."""
    R, Lz, t = 1.0, 0.05, 0.01
    I, A = Lz * t**3 / 12, Lz * t
    n = np.array([2.0, 3.0, 4.0])
    exact = np.sqrt(E * I * n**2 * (n**2 - 1) ** 2 / (RHO * A * R**4 * (n**2 + 1))) / (2 * np.pi)
    errs = []
    for count in (32, 64, 128):
        import warnings
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            body = fem2modal(write_deck(_ring_deck(count, R, Lz, t, triangles), f"ring{count}.dat"),
                             Fem2ModalOptions(n_modes=6))
        assert body.n_rigid_modes_removed == 3
        f = body.frequencies_hz
        assert_allclose(f[0::2], f[1::2], rtol=1e-8)          # cos / sin pairs
        errs.append(np.abs(f[0::2] / exact - 1))
    errs = np.array(errs)
    print("ring errors", errs)
    assert np.all(errs[-1] < 1e-2)
    assert np.all(np.log2(errs[-2] / errs[-1]) > 1.8)


def test_zoffs_equals_rigid_links_to_offset_grids(write_deck):
    """A stiffened cantilever plate (CBAR stiffener on the grids along its centre line) whose
    CQUAD4s carry ZOFFS = 0.02 equals the plate meshed on grids moved 0.02 along z and joined to
    the original grids by RBE2s; the offset makes a T-section, so it changes the frequencies
    (a uniform offset alone would only translate the whole plate)."""
    n, z = 4, 0.02
    base = decks.plate_deck(n, t=0.01, edges="CFFF", in_plane_held=False)
    row = [1 + i + (n + 1) * (n // 2) for i in range(n + 1)]
    stiffener = ["PBAR,7,1,4e-4,2e-8,2e-8,4e-8"] + [
        f"CBAR,{900 + i},7,{a},{b},0.0,1.0,0.0" for i, (a, b) in enumerate(zip(row, row[1:]))]
    base = base.replace("ENDDATA", "\n".join(stiffener) + "\nENDDATA")
    offset = "\n".join(ln + f",,{z!r}" if ln.startswith("CQUAD4") else ln
                       for ln in base.splitlines()) + "\n"
    linked = []
    for ln in base.splitlines():
        if ln.startswith("GRID"):
            f = ln.split(",")
            gid = int(f[1])
            linked.append(ln)
            linked.append(f"GRID,{gid + 1000},,{f[3]},{f[4]},{z!r}")
            linked.append(f"RBE2,{gid + 5000},{gid},123456,{gid + 1000}")
        elif ln.startswith("CQUAD4") and not ln.startswith("CBAR"):
            f = ln.split(",")
            linked.append(",".join(f[:3] + [str(int(g) + 1000) for g in f[3:7]]))
        else:
            linked.append(ln)
    a = _quiet_modes(write_deck, offset, 8, "zoffs.dat")
    b = _quiet_modes(write_deck, "\n".join(linked) + "\n", 8, "linked.dat")
    assert_allclose(a, b, rtol=1e-10)
    plain = _quiet_modes(write_deck, base, 8, "plain.dat")
    assert np.max(np.abs(a / plain - 1)) > 1e-3          # the offset does change the plate

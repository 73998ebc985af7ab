"""Slosh equivalents from the fill level of an upright cylindrical tank (dynamics/slosh_tank.py) against
an independent numerical potential-flow solution, and in the engine.

Reference: Chebyshev collocation of Laplace's equation for the lateral (m = 1) potential F(r, z) cos(theta)
in the liquid (F_rr + F_r / r - F / r^2 + F_zz = 0; F = 0 on the axis, F_r = 0 at the wall, F_z = 0 on the
bottom), the free-surface condition F_z = (omega^2 / a) F as a generalized eigenproblem, and
Clenshaw-Curtis quadrature of the slosh mass Gamma^2 / mu (Gamma = rho pi int r^2 F_z dr,
mu = rho pi int r F F_z dr on the surface) and of the height of the mode's pressure resultant (wall and
bottom moments over the wall force) -- no Bessel functions, no closed forms. 28 x 28 points resolve the
first three modes to 1e-9 relative (measured <= 1.5e-9 on the shallow tank, 4e-12 on the others):
tolerance 1e-8. This reference found a spurious factor xi_n in the first version of the slosh mass."""

import numpy as np
import pytest
import scipy.linalg as sla

from dynamics.slosh_tank import cylindrical_tank_slosh


def _chebyshev(n, a, b):
    """Chebyshev points on [a, b] ascending, their differentiation matrix and Clenshaw-Curtis weights."""
    x = np.cos(np.pi * np.arange(n + 1) / n)
    c = np.hstack([2.0, np.ones(n - 1), 2.0]) * (-1.0) ** np.arange(n + 1)
    X = np.tile(x, (n + 1, 1)).T
    D = np.outer(c, 1.0 / c) / (X - X.T + np.eye(n + 1))
    D -= np.diag(D.sum(axis=1))
    theta = np.pi * np.arange(n + 1) / n
    w, v = np.zeros(n + 1), np.ones(n - 1)
    assert n % 2 == 0
    w[0] = w[n] = 1.0 / (n**2 - 1)
    for k in range(1, n // 2):
        v -= 2.0 * np.cos(2 * k * theta[1:-1]) / (4 * k * k - 1)
    v -= np.cos(n * theta[1:-1]) / (n**2 - 1)
    w[1:-1] = 2.0 * v / n
    half = 0.5 * (b - a)
    return a + half * (x[::-1] + 1.0), D[::-1, ::-1] / half, w[::-1] * half


def potential_flow_slosh(R, h, density, acceleration, n_modes=3, nr=28, nz=28):
    """(omega, slosh mass, pressure-resultant height) of the lowest lateral modes, numerically."""
    r, Dr, wr = _chebyshev(nr, 0.0, R)
    z, Dz, wz = _chebyshev(nz, 0.0, h)
    Ir, Iz = np.eye(nr + 1), np.eye(nz + 1)
    inv_r = np.divide(1.0, r, out=np.zeros_like(r), where=r > 0)
    A = np.kron(Dr @ Dr + np.diag(inv_r) @ Dr - np.diag(inv_r**2), Iz) + np.kron(Ir, Dz @ Dz)
    B = np.zeros_like(A)
    index = np.arange(A.shape[0]).reshape(nr + 1, nz + 1)
    for i in range(nr + 1):
        for j in range(nz + 1):
            row = index[i, j]
            if i == 0:
                A[row] = 0.0
                A[row, row] = 1.0
            elif i == nr:
                A[row] = np.kron(Dr[nr], Iz[j])
            elif j == 0:
                A[row] = np.kron(Ir[i], Dz[0])
            elif j == nz:
                A[row] = np.kron(Ir[i], Dz[nz])
                B[row, row] = 1.0
    lam, V = sla.eig(A, B)
    ok = np.isfinite(lam) & (np.abs(lam.imag) < 1e-8) & (lam.real > 1e-9)
    order = np.argsort(lam.real[ok])
    lam, V = lam.real[ok][order], V[:, ok].real[:, order]
    out = []
    for m in range(n_modes):
        F = V[:, m].reshape(nr + 1, nz + 1)
        eta = (F @ Dz.T)[:, nz]
        gamma = density * np.pi * np.sum(wr * r**2 * eta)
        mu = density * np.pi * np.sum(wr * r * F[:, nz] * eta)
        force = R * np.sum(wz * F[nr, :])
        moment = R * np.sum(wz * z * F[nr, :]) + np.sum(wr * r**2 * F[:, 0])
        out.append((np.sqrt(acceleration * lam[m]), gamma**2 / mu, moment / force))
    return np.array(out)


@pytest.mark.parametrize("radius,depth", [(1.5, 2.0), (1.0, 0.3), (2.0, 6.0)])
def test_closed_forms_match_numerical_potential_flow(radius, depth):
    density, acceleration = 1140.0, 30.0   # LOX, 3 g of thrust
    tank = cylindrical_tank_slosh(radius, depth, density, acceleration, n_modes=3)
    reference = potential_flow_slosh(radius, depth, density, acceleration)
    np.testing.assert_allclose(tank.frequencies, reference[:, 0], rtol=1e-8)
    np.testing.assert_allclose(tank.slosh_masses, reference[:, 1], rtol=1e-8)
    np.testing.assert_allclose(tank.hinge_heights, reference[:, 2], rtol=0, atol=1e-8 * depth)
    # the pendulum hangs from the pressure resultant with the length a / omega^2; the spring-mass sits
    # at the bob's height; the rigid remainder keeps the liquid's mass and centre of mass
    np.testing.assert_allclose(tank.pendulum_lengths, acceleration / tank.frequencies**2, rtol=1e-14)
    np.testing.assert_allclose(tank.spring_stiffnesses, tank.slosh_masses * tank.frequencies**2, rtol=1e-14)
    assert tank.liquid_mass == pytest.approx(density * np.pi * radius**2 * depth, rel=1e-15)
    total = tank.fixed_mass + tank.slosh_masses.sum()
    first_moment = tank.fixed_mass * tank.fixed_height + np.sum(tank.slosh_masses * tank.mass_heights)
    assert total == pytest.approx(tank.liquid_mass, rel=1e-14)
    assert first_moment == pytest.approx(tank.liquid_mass * depth / 2, rel=1e-12)


def test_shallow_liquid_sloshes_entirely_and_deep_liquid_mostly_not():
    """sum 2 / (xi_n^2 - 1) = 1: as h / R -> 0 the modes carry the whole liquid; with N modes the
    rigid remainder is the tail of the series, 2 / (pi^2 N) asymptotically (xi_n ~ (n + 1/4) pi):
    measured 0.9975 and 0.9994 of it at N = 100 and 400. A deep tank's first mode carries
    2 R / (xi_1 (xi_1^2 - 1) h) of the liquid."""
    for n in (100, 400):
        shallow = cylindrical_tank_slosh(1.0, 1e-6, 1000.0, 9.81, n_modes=n)
        remainder = shallow.fixed_mass / shallow.liquid_mass
        assert remainder == pytest.approx(2.0 / (np.pi**2 * n), rel=3e-3)
    deep = cylindrical_tank_slosh(1.0, 20.0, 1000.0, 9.81, n_modes=1)
    xi = 1.8411837813406593
    assert deep.slosh_masses[0] / deep.liquid_mass == pytest.approx(2.0 / (xi * (xi**2 - 1.0) * 20.0), rel=1e-12)
    assert deep.frequencies[0] == pytest.approx(np.sqrt(9.81 * xi), rel=1e-12)   # tanh -> 1


def test_refuses_nonphysical_input():
    with pytest.raises(ValueError, match="fill_height must be a positive number"):
        cylindrical_tank_slosh(1.0, 0.0, 1000.0, 9.81)
    with pytest.raises(ValueError, match="acceleration must be a positive number"):
        cylindrical_tank_slosh(1.0, 1.0, 1000.0, -9.81)


def test_pendulum_from_fill_level_swings_at_the_liquid_frequency_in_the_engine():
    """The first-mode pendulum as an engine body (U-joint at the hinge height, bob at L below) on a tank
    held in a uniform field a: its small swing has the potential-flow slosh frequency (0.05 deg amplitude:
    the finite-amplitude shift theta0^2 / 16 = 5e-8 is inside the 1e-6 tolerance)."""
    from dynamics import Multibody

    a = 30.0
    tank = cylindrical_tank_slosh(1.5, 2.0, 1140.0, a)
    mb = Multibody(gravity=(0.0, 0.0, -a))
    mb.add_body("tank", None, mass=1.0, inertia=np.eye(3), hinge="locked")
    mb.add_body("slosh", "tank", mass=tank.slosh_masses[0], com=(0.0, 0.0, -tank.pendulum_lengths[0]),
                inertia=1e-9 * np.eye(3), hinge="ujoint", axes=[(1.0, 0.0, 0.0), (0.0, 1.0, 0.0)],
                inboard_position=(0.0, 0.0, tank.hinge_heights[0]))
    system = mb.compile()
    q, u = system.neutral_configuration(), np.zeros(system.nu)
    q[0] = np.radians(0.05)
    period = 2 * np.pi / tank.frequencies[0]
    h = period / 2000
    crossings, t, previous = [], 0.0, q[0]

    def rate(q, u):
        return np.concatenate([system.q_dot(q, u), system.forward_dynamics(q, u, np.zeros(system.nu))])

    y = np.concatenate([q, u])
    n = system.nq
    for _ in range(6000):                      # RK4 over three periods
        k1 = rate(y[:n], y[n:])
        k2 = rate(y[:n] + 0.5 * h * k1[:n], y[n:] + 0.5 * h * k1[n:])
        k3 = rate(y[:n] + 0.5 * h * k2[:n], y[n:] + 0.5 * h * k2[n:])
        k4 = rate(y[:n] + h * k3[:n], y[n:] + h * k3[n:])
        y_next = y + h / 6 * (k1 + 2 * k2 + 2 * k3 + k4)
        if previous > 0.0 >= y_next[0]:        # downward zero crossing of the swing angle
            crossings.append(t + h * previous / (previous - y_next[0]))
        previous, y, t = y_next[0], y_next, t + h
    measured = np.mean(np.diff(crossings))
    assert measured == pytest.approx(period, rel=1e-6)


def test_flexshell_slosh_prints_a_scenario_that_builds(capsys, tmp_path):
    """`flexshell slosh` output pasted under a stage body is a valid scenario whose pendulum bodies and
    dampers carry the fill-level values (9 significant digits printed)."""
    import yaml

    from shell.cli import main
    from shell.scenario import build_simulation, parse_scenario

    assert main(["slosh", "--radius", "1.5 m", "--fill", "200 cm", "--density", "1140 kg/m^3",
                 "--acceleration", "30 m/s^2", "--modes", "2", "--damping-ratio", "0.02",
                 "--bottom", "[0, 0, 1] m"]) == 0
    text = capsys.readouterr().out
    generated = yaml.safe_load(text)
    tank = cylindrical_tank_slosh(1.5, 2.0, 1140.0, 30.0, n_modes=2)
    stage = {"name": "stage", "hinge": "free", "mass": "20000 kg", "inertia": "[1e5, 1e5, 2e4] kg*m^2"}
    scenario = {"multibody": {"gravity": "[0, 0, -30] m/s^2", "bodies": [stage] + generated["multibody"]["bodies"]},
                "models": generated["models"]}
    sim = build_simulation(parse_scenario(yaml.safe_dump(scenario), "slosh.yaml", None))
    system = sim.models[sim.model_index["multibody"]].system
    for n, name in enumerate(("slosh1", "slosh2")):
        b = system.body_index(name)
        assert system.masses[b] == pytest.approx(tank.slosh_masses[n], rel=1e-8)
        assert system.definitions[0][b].com[2] == pytest.approx(-tank.pendulum_lengths[n], rel=1e-8)
        damper = sim.models[sim.model_index[f"{name}_damper"]]
        expected = 2 * 0.02 * tank.slosh_masses[n] * tank.pendulum_lengths[n] ** 2 * tank.frequencies[n]
        np.testing.assert_allclose(damper.parameter("damping"), expected, rtol=1e-8)
    assert f"{tank.fixed_mass:.6g} kg" in text
    assert main(["slosh", "--radius", "1.5 m", "--fill", "2 kg", "--density", "1 kg/m^3",
                 "--acceleration", "1 m/s^2"]) == 1
    assert "--fill" in capsys.readouterr().err

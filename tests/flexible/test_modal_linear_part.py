"""dynamics.modal_linear_part against the engine it linearizes, and the exponential integrator on a free
flexible body (energy and angular momentum), and dynamics.mode_selection.

References: the Jacobian of the engine's forward dynamics at rest by central differences (exact for the
velocity columns, whose terms are at most quadratic; O(delta^2) for the modal coordinates); the system modes
of dynamics.modal_analysis (generalized eigenproblem K phi = omega^2 M phi); conservation of energy and
angular momentum of a torque-free undamped body.
"""

from __future__ import annotations

import warnings
from pathlib import Path

import numpy as np
import pytest

from dynamics import Multibody, SingularConfigurationError
from dynamics.flex.body_file import read_body_file
from dynamics.modal_analysis import system_modes
from dynamics.modal_linear_part import (_rotors_averaged, _times, modal_indices, modal_linear_part,
                                        rotor_gyroscopic_factors, spin_averaged_inertia)
from dynamics.mode_selection import select_modes
from dynamics.system import MODAL_DIAGONAL_TOLERANCE, _offdiagonal_ratio
from shell.integrators import make_integrator

STRUCTURE = Path(__file__).resolve().parents[2] / "configs" / "observatory" / "structure.h5"


@pytest.fixture(scope="module")
def structure():
    return read_body_file(STRUCTURE)


def articulated(structure, modes=range(12), prescribed=True):
    """The observatory structure (order-2 modal integrals) on a free hinge, a rigid arm on a revolute hinge at
    grid 101 and a rigid rotor with a prescribed (or free) rate on the arm: every kind of DOF the linear part
    sorts."""
    mb = Multibody()
    mb.add_flexible_body("structure", None, modal=structure, hinge="free", modes=list(modes), order=2)
    mb.add_node("tip", "structure", grid=101)
    mb.add_body("arm", "structure", mass=20.0, com=(0.3, 0.0, 0.0), inertia=np.diag([0.2, 1.0, 1.1]),
                hinge="revolute", axis=(0.0, 0.0, 1.0), parent_node="tip")
    mb.add_body("rotor", "arm", mass=5.0, inertia=np.diag([0.3, 0.2, 0.2]), hinge="revolute", axis=(1.0, 0.0, 0.0),
                inboard_position=(0.6, 0.0, 0.0), prescribed=prescribed)
    return mb.compile()


def engine_jacobian(system, q, indices):
    """d(u_dot)/d[x over indices] at (q, u = 0) by central differences (free rows)."""
    nq = system.nq
    free = np.flatnonzero(~system.prescribed_dofs)
    x0 = np.concatenate([q, np.zeros(system.nu)])
    J = np.empty((free.size, indices.size))
    for k, i in enumerate(indices):
        delta = 1e-6 if i < nq else 1e-2  # velocity terms are quadratic: central differences are exact
        plus, minus = x0.copy(), x0.copy()
        plus[i] += delta
        minus[i] -= delta
        f_plus = system.forward_dynamics(plus[:nq], plus[nq:])
        f_minus = system.forward_dynamics(minus[:nq], minus[nq:])
        J[:, k] = (f_plus - f_minus)[free] / (2 * delta)
    return J


def test_linear_part_is_the_engine_jacobian_at_rest(structure):
    system = articulated(structure)
    q0 = system.neutral_configuration()
    q0[system.q_slices[1]] = 0.7  # the arm turned: M(q0) is not the neutral one
    indices, L = modal_linear_part(system, q0)
    eta_q, eta_u = modal_indices(system)
    free = np.flatnonzero(~system.prescribed_dofs)
    assert np.array_equal(indices, np.concatenate([eta_q, system.nq + free]))
    assert system.prescribed_dofs.sum() == 1 and free.size == system.nu - 1
    n_eta = eta_q.size
    # eta rows: d(eta)/dt = eta_dot exactly
    expected_top = np.zeros((n_eta, indices.size))
    expected_top[np.arange(n_eta), n_eta + np.searchsorted(free, eta_u)] = 1.0
    np.testing.assert_array_equal(L[:n_eta], expected_top)
    J = engine_jacobian(system, q0, indices)
    scale = np.abs(L[n_eta:]).max()
    # eta columns: O(delta^2 |d3 f|) of the order-2 modal integrals (delta = 1e-6) and round-off; measured 9.5e-16
    assert np.abs(J - L[n_eta:]).max() <= 1e-11 * scale, np.abs(J - L[n_eta:]).max() / scale


def test_an_unbalanced_rotor_does_not_move_the_linear_part(structure):
    """A wheel with products of inertia and its centre of mass 2 cm off its axis (a real imbalance) on the
    structure: L is the same at every wheel angle (the wheel enters with its spin-averaged inertia, so the
    exponential integrator never rebuilds for it), and it is the engine Jacobian of the same scene with that
    averaged wheel (the definition: round-off between the two L, central differences against the engine)."""
    def scene(com, inertia):
        mb = Multibody()
        mb.add_flexible_body("structure", None, modal=structure, hinge="free", modes=range(12), order=2)
        mb.add_node("tip", "structure", grid=101)
        mb.add_body("wheel", "structure", mass=5.0, com=com, inertia=inertia, hinge="revolute", axis=(1.0, 0.0, 0.0),
                    inboard_position=(0.2, 0.1, 0.0), parent_node="tip")
        return mb.compile()

    com, inertia = np.array([0.01, 0.02, 0.0]), np.array([[0.3, 0.01, 0.02], [0.01, 0.2, 0.015], [0.02, 0.015, 0.25]])
    unbalanced = scene(com, inertia)
    q = unbalanced.neutral_configuration()
    indices, L = modal_linear_part(unbalanced, q)
    wheel = unbalanced.q_slices[1].start
    for angle in (0.9, 2.5, -1.7):
        q[wheel] = angle
        np.testing.assert_allclose(modal_linear_part(unbalanced, q)[1], L, rtol=0, atol=1e-13 * np.abs(L).max())
    mass, com_mean, inertia_mean = spin_averaged_inertia(5.0, com, inertia, np.zeros(3), np.array([1.0, 0.0, 0.0]))
    np.testing.assert_allclose(com_mean, [0.01, 0.0, 0.0], atol=1e-16)
    averaged = scene(com_mean, inertia_mean)
    n_eta = modal_indices(averaged)[0].size
    J = engine_jacobian(averaged, averaged.neutral_configuration(), indices)
    assert np.abs(J - L[n_eta:]).max() <= 1e-11 * np.abs(L[n_eta:]).max()
    assert np.abs(modal_linear_part(averaged, q)[1] - L).max() <= 1e-13 * np.abs(L).max()


def test_a_spinning_rotor_on_a_deforming_node_is_in_the_linear_part(structure):
    """With the wheel spinning (u = its spin rate only), L's columns for the modal rates are the engine's
    Jacobian there: the wheel's gyroscopic coupling with the node's rotation rates (central differences are
    exact for the quadratic velocity terms; the coupling with the structure's rigid rates stays in N)."""
    mb = Multibody()
    mb.add_flexible_body("structure", None, modal=structure, hinge="free", modes=range(12), order=2)
    mb.add_node("tip", "structure", grid=101, rotation=[np.cos(0.3), 0.0, 0.0, np.sin(0.3)])
    mb.add_body("wheel", "structure", mass=5.0, inertia=np.diag([0.3, 0.2, 0.2]), com=(0.05, 0.0, 0.0),
                hinge="revolute", axis=(1.0, 0.0, 0.0), inboard_position=(0.2, 0.1, 0.0), parent_node="tip",
                inboard_rotation=[np.cos(0.2), np.sin(0.2), 0.0, 0.0])
    system = mb.compile()
    q, u = system.neutral_configuration(), np.zeros(system.nu)
    u[system.u_slices[1].start] = 300.0
    indices, L = modal_linear_part(system, q, u)
    _, rest = modal_linear_part(system, q)
    eta_q, eta_u = modal_indices(system)
    n_eta, free = eta_q.size, np.flatnonzero(~system.prescribed_dofs)
    columns = n_eta + np.searchsorted(free, eta_u)
    J = _rate_jacobian(system, q, u, eta_u, free)
    assert np.abs(L[n_eta:, columns] - rest[n_eta:, columns]).max() > 1e-3 * np.abs(L[n_eta:, columns]).max()
    np.testing.assert_allclose(L[n_eta:, columns], J, rtol=0, atol=1e-9 * np.abs(J).max())


def three_wheels(structure, inertia=np.diag([0.3, 0.2, 0.2])):
    """The structure (file damping 1 %) on a free hinge, an arm on a revolute hinge at grid 101 (the tip), two wheels
    spinning on the tip node (one with a product of inertia and its centre of mass off its axis) and one on grid 51,
    with the first wheel's inertia ``inertia``."""
    mb = Multibody()
    mb.add_flexible_body("structure", None, modal=structure, hinge="free", modes=range(16), order=2)
    mb.add_node("tip", "structure", grid=101, rotation=[np.cos(0.3), 0.0, 0.0, np.sin(0.3)])
    mb.add_node("middle", "structure", grid=51)
    mb.add_body("arm", "structure", mass=20.0, com=(0.3, 0.0, 0.0), inertia=np.diag([0.2, 1.0, 1.1]),
                hinge="revolute", axis=(0.0, 0.0, 1.0), parent_node="tip")
    mb.add_body("w1", "structure", mass=5.0, inertia=inertia, com=(0.05, 0.01, 0.0), hinge="revolute",
                axis=(1.0, 0.0, 0.0), inboard_position=(0.2, 0.1, 0.0), parent_node="tip",
                inboard_rotation=[np.cos(0.2), np.sin(0.2), 0.0, 0.0])
    mb.add_body("w2", "structure", mass=4.0, inertia=np.diag([0.1, 0.25, 0.25]), hinge="revolute",
                axis=(0.0, 1.0, 0.0), parent_node="tip")
    mb.add_body("w3", "structure", mass=4.0, inertia=np.diag([0.2, 0.2, 0.12]), hinge="revolute",
                axis=(0.0, 0.0, 1.0), parent_node="middle")
    return mb.compile()


def test_the_columns_of_the_inverse_mass_matrix_are_the_solve_of_every_column(structure):
    """modal_linear_part solves M_ff only for the columns its right-hand sides need (the modal rows of the stiffness
    and damping blocks, three per node carrying rotors: module docstring, "Cost"): L equals the definition
    -M_ff^-1 [K_aug[f, modal] | D_aug[f, f] + C] solved for all its columns (numpy's LU here, an independent
    factorization), C assembled densely, to round-off in each block (measured 1.6e-16 and 2.1e-16 of the stiffness
    and damping blocks' largest entries; the bound 1e-13: M_ff's condition number is 1.5e4), with damping, an arm,
    a deformed structure, two rotors on one node and one on another; the modal-rate columns are the engine's
    Jacobian there (as in the one-wheel test)."""
    system = three_wheels(structure)
    q, u = system.neutral_configuration(), np.zeros(system.nu)
    q[system.q_slices[1]] = 0.4  # the arm turned
    q[7:7 + 16] = 1e-3 * np.sin(np.arange(16.0))  # deformed (order-2 modal integrals: M depends on eta)
    for body, spin in (("w1", 300.0), ("w2", -200.0), ("w3", 150.0)):
        u[system.u_slices[system.body_index(body)].start] = spin
    indices, L = modal_linear_part(system, q, u)
    averaged = _rotors_averaged(system)
    eta_q, eta_u = modal_indices(system)
    free = np.flatnonzero(~system.prescribed_dofs)
    n_eta = eta_q.size
    M = averaged.mass_matrix(q)
    C = np.zeros((system.nu, system.nu))
    factors = rotor_gyroscopic_factors(averaged, u)
    assert len(factors) == 2  # the tip's two wheels share one factor
    for rows, columns, J, h in factors:
        skew = np.array([[0.0, -h[2], h[1]], [h[2], 0.0, -h[0]], [-h[1], h[0], 0.0]])
        C[np.ix_(rows, columns)] -= J.T @ skew @ J[:, J.shape[1] - columns.size:]
    D = system.damping_matrix() + C
    assert np.count_nonzero(system.damping_matrix())  # the file's 1 % damping: the damping columns are exercised
    rhs = np.concatenate([system.stiffness_matrix()[np.ix_(free, eta_u)], D[np.ix_(free, free)]], axis=1)
    solved = np.linalg.solve(M[np.ix_(free, free)], rhs)
    for block in (np.s_[:, :n_eta], np.s_[:, n_eta:]):
        assert np.abs(L[n_eta:][block] + solved[block]).max() <= 1e-13 * np.abs(solved[block]).max()
    # the wheels' coupling against the engine, undeformed (where L is its Jacobian: velocity terms of order u eta
    # stay in N): central differences in the modal rates, exact for the quadratic velocity terms
    q[7:7 + 16] = 0.0
    _, L = modal_linear_part(system, q, u)
    _, still = modal_linear_part(system, q)
    columns = n_eta + np.searchsorted(free, eta_u)
    J = _rate_jacobian(averaged, q, u, eta_u, free)
    np.testing.assert_allclose(L[n_eta:, columns], J, rtol=0, atol=1e-9 * np.abs(J).max())
    assert np.abs(L[n_eta:, columns] - still[n_eta:, columns]).max() > 1e-3 * np.abs(L[n_eta:, columns]).max()


def test_a_change_of_mass_properties_reaches_the_linear_part(structure):
    """The spin-averaged copy of the system is kept between evaluations; set_mass_properties (mass depletion, a
    dispersed wheel) must reach L: after a change of a wheel's inertia L is that of a system built with it (to
    round-off), not the one before."""
    system = three_wheels(structure)
    q = system.neutral_configuration()
    _, before = modal_linear_part(system, q)
    inertia = np.array([[0.5, 0.02, 0.0], [0.02, 0.3, 0.0], [0.0, 0.0, 0.35]])
    body = system.definitions[0][system.body_index("w1")]
    system.set_mass_properties("w1", 7.0, body.com, inertia)
    _, after = modal_linear_part(system, q)
    built = three_wheels(structure, inertia)
    built.set_mass_properties("w1", 7.0, body.com, inertia)
    _, expected = modal_linear_part(built, q)
    scale = np.abs(expected).max()
    assert np.abs(after - before).max() > 1e-3 * scale
    assert np.abs(after - expected).max() <= 1e-14 * scale


def test_a_diagonal_block_scales_the_columns_bit_for_bit():
    """_times' shortcut for a diagonal block gives the product's numbers exactly (its other terms are exact
    zeros): the linear part is the same whichever way a body's modal stiffness is stored."""
    rng = np.random.default_rng(4)
    X = rng.standard_normal((30, 12))
    B = np.diag(rng.uniform(1.0, 1e6, 12))
    np.testing.assert_array_equal(_times(X, B), X @ B)
    B[3, 5] = 1e-9  # not diagonal: the product
    np.testing.assert_array_equal(_times(X, B), X @ B)


def test_eigenvalues_are_the_system_modes(structure):
    system = articulated(structure, modes=range(20), prescribed=False)  # system_modes has no prescribed DOFs
    q0 = system.neutral_configuration()
    free = ~system.prescribed_dofs
    _, L = modal_linear_part(system, q0)
    lam = np.linalg.eigvals(L)
    oscillating = np.sort(np.abs(lam[np.abs(lam) > 1e-6]))[::2] / (2 * np.pi)  # conjugate pairs
    # undamped system modes of the free DOFs from the symmetric generalized eigenproblem (file damping 1 %:
    # |lambda| = omega exactly for modal damping zeta, lambda = omega (-zeta +- i sqrt(1 - zeta^2)))
    M = system.mass_matrix(q0)[np.ix_(free, free)]
    K = system.stiffness_matrix()[np.ix_(free, free)]
    import scipy.linalg
    w2 = scipy.linalg.eigh(K, M, eigvals_only=True)
    reference = np.sqrt(w2[w2 > 1e-6]) / (2 * np.pi)
    assert oscillating.size == reference.size == 20
    # |lambda| equals omega only if the damping is modal in the system modes; it is not exactly (the 1 %
    # is per body mode), so compare with the damped shift bound: |lambda|/omega - 1 = O(zeta^2 coupling)
    np.testing.assert_allclose(oscillating, reference, rtol=1e-4)
    # the linearization the project already validated against whole-structure FE (dynamics.modal_analysis)
    modes = system_modes(system, q0)
    np.testing.assert_allclose(np.sort(modes.frequencies_hz[modes.frequencies_hz > 1e-3])[:20], reference,
                               rtol=1e-10)


def test_rigid_system_has_no_linear_part():
    mb = Multibody()
    mb.add_body("bus", None, mass=10.0, inertia=np.eye(3), hinge="free")
    system = mb.compile()
    indices, L = modal_linear_part(system, system.neutral_configuration())
    assert indices.size == 0 and L.shape == (0, 0)
    with pytest.raises(ValueError, match=r"q must have shape \(7,\)"):
        modal_linear_part(system, np.zeros(3))


def _rate_jacobian(system, q, u, rates, free):
    """The free accelerations' derivatives in the velocities ``rates``: central differences of 1e-2 (exact for
    the quadratic velocity terms)."""
    J = np.empty((free.size, rates.size))
    for k, i in enumerate(rates):
        plus, minus = u.copy(), u.copy()
        plus[i] += 1e-2
        minus[i] -= 1e-2
        J[:, k] = (system.forward_dynamics(q, plus) - system.forward_dynamics(q, minus))[free] / 2e-2
    return J


def free_body(structure, modes):
    mb = Multibody()
    mb.add_flexible_body("s", None, modal=structure, hinge="free", damping_ratio=0.0, modes=list(modes))
    return mb.compile()


def test_energy_and_momentum_of_a_free_flexible_body(structure):
    """30 modes up to 827 Hz, every mode moving, tumbling at 2 deg/s, no damping: the exponential RK4 at
    h omega_max = 10 and 5 conserves energy and angular momentum to its accuracy (fourth order in h); RK4 at
    the same steps diverges."""
    system = free_body(structure, range(30))
    nq, nu = system.nq, system.nu
    rng = np.random.default_rng(1)
    q0 = system.neutral_configuration()
    q0[7:] = 1e-5 * rng.standard_normal(nq - 7)
    u0 = np.zeros(nu)
    u0[:3] = np.radians([1.1, -0.6, 1.7])
    u0[6:] = 1e-4 * rng.standard_normal(nu - 6)
    x0 = np.concatenate([q0, u0])

    def fun(t, x):
        return np.concatenate([system.q_dot(x[:nq], x[nq:]), system.forward_dynamics(x[:nq], x[nq:])])

    def energy(x):
        return system.kinetic_energy(x[:nq], x[nq:]) + system.potential_energy(x[:nq])

    def momentum(x):
        return system.angular_momentum(x[:nq], x[nq:])

    def normalize(x):
        system.normalize_quaternions(x[:nq])

    drift = {}
    for h in (2e-3, 1e-3):
        integ = make_integrator("etdrk4", fun, 0.0, x0, 0.4, step=h, normalize=normalize,
                                linear_part=lambda t, y: modal_linear_part(system, y[:nq]))
        while integ.status == "running":
            integ.step()
        drift[h] = (abs(energy(integ.y) / energy(x0) - 1.0),
                    np.linalg.norm(momentum(integ.y) - momentum(x0)) / np.linalg.norm(momentum(x0)))
        assert integ.nlu == 2  # the linear part and its driven rows (attitude) once: L does not move
    # measured 2026-11-23: energy 8.0e-6 / 2.6e-8, momentum 3.8e-6 / 1.9e-8 at 2 / 1 ms (ratios 310, 200)
    assert drift[1e-3][0] < 1e-7 and drift[1e-3][1] < 1e-7, drift
    assert drift[2e-3][0] / drift[1e-3][0] > 16 and drift[2e-3][1] / drift[1e-3][1] > 16, drift
    # RK4 at the same step: the 827 Hz mode (h omega = 5.2 > 2.83) grows until the deformed body's mass matrix
    # degenerates or the state overflows
    with warnings.catch_warnings(), pytest.raises(SingularConfigurationError):
        warnings.simplefilter("ignore")
        integ = make_integrator("rk4", fun, 0.0, x0, 0.4, step=1e-3, normalize=normalize)
        while integ.status == "running":
            integ.step()


# --- mode selection -------------------------------------------------------------------------------------------
def test_select_modes():
    f = np.array([1.0, 5.0, 20.0, 80.0, 320.0])
    np.testing.assert_array_equal(select_modes(f), [0, 1, 2, 3, 4])
    np.testing.assert_array_equal(select_modes(f, max_frequency=80.0), [0, 1, 2, 3])  # at or below
    np.testing.assert_array_equal(select_modes(f, max_frequency=79.999), [0, 1, 2])
    np.testing.assert_array_equal(select_modes(f, modes=[3, 0, 1]), [3, 0, 1])
    with pytest.warns(UserWarning, match=r"drops the listed modes \[4\] \(at \[320.0\] Hz\)"):
        np.testing.assert_array_equal(select_modes(f, modes=[4, 2, 0], max_frequency=100.0), [2, 0])
    with pytest.raises(ValueError, match=r"max_frequency = 0.5 Hz removes every mode \(the lowest is mode 0 at 1 Hz\)"):
        select_modes(f, max_frequency=0.5)
    with pytest.raises(ValueError, match="removes every mode of the listed modes"):
        select_modes(f, modes=[3, 4], max_frequency=50.0)
    with pytest.raises(ValueError, match="must be a positive, finite frequency"):
        select_modes(f, max_frequency=-1.0)
    with pytest.raises(ValueError, match=r"indices \[5\] are outside the body file's 5 modes"):
        select_modes(f, modes=[5])
    with pytest.raises(ValueError, match=r"indices \[1\] are listed more than once"):
        select_modes(f, modes=[1, 1])
    with pytest.raises(ValueError, match="non-empty list of mode indices"):
        select_modes(f, modes=[True])


def test_selected_modes_are_the_file_modes(structure):
    """The cutoff keeps exactly the body file's modes at or below it (the structure's 60 modes span 11.5 Hz to
    2.29 kHz): the compiled body's stiffness is their omega^2."""
    keep = select_modes(structure.frequencies_hz, max_frequency=400.0)
    assert keep.size == 21 and structure.frequencies_hz[keep].max() <= 400.0 < structure.frequencies_hz[21]
    system = free_body(structure, keep)
    K = system.stiffness_matrix()[6:, 6:]
    file_K = np.asarray(structure.modal_stiffness)[np.ix_(keep, keep)]
    # the file's Pi' K Pi is diagonal to round-off (below MODAL_DIAGONAL_TOLERANCE of the geometric mean of its
    # diagonal entries), and the engine holds that diagonal
    assert 0.0 < _offdiagonal_ratio(file_K) <= MODAL_DIAGONAL_TOLERANCE
    np.testing.assert_array_equal(K, np.diag(np.diag(file_K)))
    assert "modal stiffness applied as its diagonal" in system.summary()
    # the file's Pi' K Pi and its FREQ (from the eigenvalues) agree to the eigen-solver's accuracy (4e-10)
    np.testing.assert_allclose(np.diag(K), (2 * np.pi * structure.frequencies_hz[keep]) ** 2, rtol=1e-9)


def test_builder_max_frequency_keeps_the_same_modes(structure):
    """``Multibody.add_flexible_body(max_frequency=...)`` (Hz) compiles the same body as the indices of
    ``select_modes``: identical stiffness and mass matrices; a cutoff below the lowest mode is refused with
    the body's name."""
    from dynamics import ModelDefinitionError

    keep = select_modes(structure.frequencies_hz, max_frequency=400.0)
    mb = Multibody()
    mb.add_flexible_body("s", None, modal=structure, hinge="free", damping_ratio=0.0, max_frequency=400.0)
    by_cutoff = mb.compile()
    by_index = free_body(structure, keep)
    assert by_cutoff.nu == 6 + 21
    np.testing.assert_array_equal(by_cutoff.stiffness_matrix(), by_index.stiffness_matrix())
    q = by_index.neutral_configuration()
    np.testing.assert_array_equal(by_cutoff.mass_matrix(q), by_index.mass_matrix(q))
    mb = Multibody()
    with pytest.raises(ModelDefinitionError, match=r"body 'structure': select_modes: max_frequency = 1 Hz removes"):
        mb.add_flexible_body("structure", None, modal=structure, hinge="free", max_frequency=1.0)

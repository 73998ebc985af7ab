"""Exponential RK4 (``etdrk4``): phi functions, exactness on linear systems, order, stability, energy, refusals.

References: phi_k from their integral definition evaluated in 40-digit arithmetic (mpmath); the exponential of a
linear system from scipy.linalg.expm and from the closed-form oscillator; a stiff oscillator driven by the
solution of p' = -p^2 in closed form (sine and cosine integrals); the flexible body's energy and momentum
conservation laws.
"""

import math
import warnings

import mpmath
import numpy as np
import pytest
import scipy.linalg
from scipy.integrate import solve_ivp
from scipy.special import sici

from shell.integrators import INTEGRATORS, StiffRemainderWarning, make_integrator
from shell.integrators.exponential import FUNCTIONS, LinearPart, phi_functions


def run(method, fun, y0, t_end, step, **options):
    integ = make_integrator(method, fun, 0.0, y0, t_end, step=step, **options)
    while integ.status == "running":
        integ.step()
    assert integ.status == "finished", integ.message
    return integ


# --- phi functions -----------------------------------------------------------------------------------------
def phi_reference(z, k):
    """phi_k(z) = 1/(k-1)! int_0^1 e^{(1-s) z} s^(k-1) ds (k >= 1), e^z (k = 0), in 40 digits."""
    mpmath.mp.dps = 40
    z = mpmath.mpc(z)
    if k == 0:
        return complex(mpmath.exp(z))
    value = mpmath.quad(lambda s: mpmath.exp((1 - s) * z) * s ** (k - 1), [0, 1]) / mpmath.factorial(k - 1)
    return complex(value)


@pytest.mark.parametrize("z", [0.0, 1e-8, 0.3 + 0.2j, -0.99, 0.999j, 1.0, -1.5 + 2.0j, 12j, -40.0 + 300j, -700.0,
                               5.0 - 0.1j])
def test_phi_functions_match_their_integral_definition(z):
    values = phi_functions(np.array([z]), 3)[:, 0]
    for k in range(4):
        ref = phi_reference(z, k)
        # both branches (Taylor below |z| = 1, recurrence above) are within a few ulps of the 40-digit value
        assert abs(values[k] - ref) <= 4e-15 * abs(ref) + 1e-300, (k, values[k], ref)


# --- linear systems ----------------------------------------------------------------------------------------
def damped_chain(n=6, seed=3):
    """Mass-spring-damper chain y = [x; v]: x'' = -M^-1 (K x + C v), with an undamped and a heavily damped mode."""
    rng = np.random.default_rng(seed)
    m = rng.uniform(0.5, 2.0, n)
    k = rng.uniform(1e2, 1e6, n)
    K = np.diag(k) + np.diag(np.r_[k[1:], 0.0]) - np.diag(k[1:], 1) - np.diag(k[1:], -1)
    C = 1e-3 * K + 0.1 * np.diag(m)
    A = np.zeros((2 * n, 2 * n))
    A[:n, n:] = np.eye(n)
    A[n:, :n] = -K / m[:, None]
    A[n:, n:] = -C / m[:, None]
    return A


@pytest.mark.parametrize("step", [1e-5, 1e-3, 0.1, 2.0])
def test_linear_system_is_propagated_exactly_for_any_step(step):
    A = damped_chain()
    omega_max = np.abs(np.linalg.eigvals(A)).max()
    y0 = np.linspace(-1.0, 1.0, A.shape[0])
    t_end = 20 * step
    integ = run("etdrk4", lambda t, y: A @ y, y0, t_end, step, linear_part=(np.arange(A.shape[0]), A))
    exact = scipy.linalg.expm(t_end * A) @ y0
    # 20 steps of h * omega_max up to ~4000: only the rounding of e^{hL} accumulates (scipy's expm is itself
    # accurate to ~1e-13 relative here)
    assert np.abs(integ.y - exact).max() <= 1e-11 * max(1.0, np.abs(y0).max()) * max(1.0, omega_max * 1e-3), \
        (step * omega_max, np.abs(integ.y - exact).max())
    # dense output inside the last step is exact too
    sol = integ.dense_output()
    t_mid = integ.t_old + 0.37 * (integ.t - integ.t_old)
    np.testing.assert_allclose(sol(t_mid), scipy.linalg.expm(t_mid * A) @ y0, rtol=0,
                               atol=1e-11 * max(1.0, omega_max * 1e-3))


def test_undamped_oscillator_matches_closed_form_at_h_omega_1000():
    omega = 1e4
    L = np.array([[0.0, 1.0], [-omega ** 2, 0.0]])
    integ = run("etdrk4", lambda t, y: L @ y, np.array([1.0, 0.0]), 1.0, 0.1, linear_part=(np.array([0, 1]), L))
    # cos(omega t) at t = 1 is known to ~omega * eps in absolute terms; the energy norm (x, v / omega)
    assert abs(integ.y[0] - np.cos(omega)) <= 1e-11
    assert abs(integ.y[1] / omega + np.sin(omega)) <= 1e-11


def test_constant_forcing_is_exact():
    """y' = L y + c: the static deflection under a held command comes out exact at any step (Lawson's
    integrating-factor method would not)."""
    omega = 3e3
    L = np.array([[0.0, 1.0], [-omega ** 2, -2 * 0.01 * omega]])
    c = np.array([0.0, 7.0])
    y0 = np.array([2e-6, -0.3])
    integ = run("etdrk4", lambda t, y: L @ y + c, y0, 0.5, 0.05, linear_part=(np.array([0, 1]), L))
    static = -np.linalg.solve(L, c)
    exact = static + scipy.linalg.expm(0.5 * L) @ (y0 - static)
    np.testing.assert_allclose(integ.y, exact, rtol=0, atol=1e-15 * omega)


# --- order and stability with a nonlinear term --------------------------------------------------------------
def forced_oscillator(omega):
    """x'' + omega^2 x = p, p' = -p^2: x driven by the nonlinear p(t) = p0 / (1 + p0 t); closed form below."""
    L = np.array([[0.0, 1.0], [-omega ** 2, 0.0]])

    def fun(t, y):
        return np.array([y[1], -omega ** 2 * y[0] + y[2], -y[2] ** 2])

    def exact(t, x0, v0, p0):
        # x = x_h + (1/omega) int_0^t sin(omega (t - s)) / (c + s) ds, c = 1/p0: sine and cosine integrals
        c = 1.0 / p0
        big = omega * (t + c)
        si1, ci1 = sici(omega * (c + t))
        si0, ci0 = sici(omega * c)
        integral = np.sin(big) * (ci1 - ci0) - np.cos(big) * (si1 - si0)
        d_integral = omega * (np.cos(big) * (ci1 - ci0) + np.sin(big) * (si1 - si0))
        x = x0 * np.cos(omega * t) + v0 / omega * np.sin(omega * t) + integral / omega
        v = -x0 * omega * np.sin(omega * t) + v0 * np.cos(omega * t) + d_integral / omega
        return np.array([x, v, p0 / (1 + p0 * t)])

    return L, fun, exact


def energy_norm_error(y, ref, omega):
    e = np.abs(y - ref)
    e[1] /= omega
    return e


def test_closed_form_of_the_forced_oscillator_satisfies_its_equation():
    L, fun, exact = forced_oscillator(50.0)
    y0 = (1e-3, 0.5, 2.0)
    t, d = 0.7, 1e-5
    dy = (exact(t + d, *y0) - exact(t - d, *y0)) / (2 * d)
    np.testing.assert_allclose(dy, fun(t, exact(t, *y0)), rtol=1e-7, atol=1e-7)  # central difference O(d^2)
    np.testing.assert_allclose(exact(0.0, *y0), y0, rtol=0, atol=1e-15)


def test_observed_order_is_four_when_the_step_resolves_the_mode():
    omega = 10.0
    L, fun, exact = forced_oscillator(omega)
    y0 = np.array([1e-3, 0.5, 2.0])
    steps = [0.05, 0.025, 0.0125, 0.00625]
    errors = [energy_norm_error(run("etdrk4", fun, y0, 1.0, h, linear_part=(np.array([0, 1]), L)).y,
                                exact(1.0, *y0), omega).max() for h in steps]
    slopes = np.log2(np.array(errors[:-1]) / np.array(errors[1:]))
    np.testing.assert_allclose(slopes, 4.0, atol=0.1)  # measured 3.98-4.00


def test_stiff_regime_error_is_small_and_converges():
    """h omega from 100 down to 12.5: error at least second order in h (stiff order reduction, Hochbruck &
    Ostermann 2005) and far below the response; RK4 is unstable at all these steps."""
    omega = 1000.0
    L, fun, exact = forced_oscillator(omega)
    y0 = np.array([1e-3, 0.5, 2.0])
    steps = [0.1, 0.05, 0.025, 0.0125]
    errors = np.array([energy_norm_error(run("etdrk4", fun, y0, 1.0, h, linear_part=(np.array([0, 1]), L)).y,
                                         exact(1.0, *y0), omega)[:2].max() for h in steps])
    assert errors[0] < 1e-8  # measured 6.3e-9, against an amplitude of 5e-4 (x and v / omega)
    assert np.all(np.log2(errors[:-1] / errors[1:]) > 1.8)  # measured 2.2, 2.1, 1.9
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        integ = make_integrator("rk4", fun, 0.0, y0, 1.0, step=0.0125)
        while integ.status == "running":
            integ.step()
    # |R_rk4(12.5 i)| = 990: 80 steps multiply the mode by ~1e240
    assert integ.status == "failed" or energy_norm_error(integ.y, exact(1.0, *y0), omega)[:2].max() > 1e100


def test_stability_far_beyond_the_explicit_limit():
    """h omega = 1000, 350 times RK4's limit, for 10^4 steps with the nonlinear forcing: stays on the solution."""
    omega = 1e5
    L, fun, exact = forced_oscillator(omega)
    y0 = np.array([1e-6, 0.2, 5.0])
    integ = run("etdrk4", fun, y0, 100.0, 0.01, linear_part=(np.array([0, 1]), L))
    # amplitude 2e-6 (x and v / omega); measured error 3.2e-12, mostly RK4's error in p
    assert energy_norm_error(integ.y, exact(100.0, *y0), omega).max() < 1e-11


def test_without_linear_part_it_is_rk4():
    omega = 10.0
    L, fun, exact = forced_oscillator(omega)
    y0 = np.array([1e-3, 0.5, 2.0])
    with pytest.warns(UserWarning, match="linear part is empty"):
        a = run("etdrk4", fun, y0, 1.0, 0.01, linear_part=(np.zeros(0, dtype=np.int64), np.zeros((0, 0))))
    b = run("rk4", fun, y0, 1.0, 0.01)
    # same RK4 weights, summed in another order (y1 written from Y4): equal to a few ulps
    np.testing.assert_allclose(a.y, b.y, rtol=5e-14, atol=1e-17)
    # a linear part whose L is zero: every column is a zero column (phi_k = I / k!, no product): RK4 again
    c = run("etdrk4", fun, y0, 1.0, 0.01, linear_part=(np.array([0, 1]), np.zeros((2, 2))))
    assert list(c.part.zero_columns) == [0, 1] and c.part.L_other.shape == (2, 0)
    np.testing.assert_allclose(c.y, b.y, rtol=5e-14, atol=1e-17)


# --- components driven by the linear part ------------------------------------------------------------------
def test_a_quadrature_of_a_stiff_mode_is_exact():
    """s' = v (an IMU integrating the velocity of a stiff mode) is outside the linear part given by the user;
    the integrator finds the coupling and integrates s exactly: s(t) = x(t) - x(0)."""
    omega = 2e3
    L = np.array([[0.0, 1.0], [-omega ** 2, 0.0]])
    fun = lambda t, y: np.array([y[1], -omega ** 2 * y[0], y[1]])  # noqa: E731
    y0 = np.array([1e-3, 0.4, 0.0])
    integ = run("etdrk4", fun, y0, 0.5, 0.01, linear_part=(np.array([0, 1]), L))
    assert list(integ.part.indices) == [0, 1, 2]
    assert abs(integ.y[2] - (integ.y[0] - y0[0])) < 1e-16
    x_exact = y0[0] * np.cos(omega * 0.5) + y0[1] / omega * np.sin(omega * 0.5)
    assert abs(integ.y[0] - x_exact) < 1e-15


# --- configuration-dependent linear part -------------------------------------------------------------------
def stiffening_oscillator(omega0=300.0, rate=0.3):
    """x'' = -omega0^2 (1 + s) x, s' = rate: the stiffness grows by 30 % over 1 s (a configuration that moves)."""

    def fun(t, y):
        return np.array([y[1], -omega0 ** 2 * (1.0 + y[2]) * y[0], rate])

    def linear_part(t, y):
        return np.array([0, 1]), np.array([[0.0, 1.0], [-omega0 ** 2 * (1.0 + y[2]), 0.0]])

    return fun, linear_part


def test_a_moving_configuration_refreshes_the_callable_linear_part():
    fun, linear_part = stiffening_oscillator()
    y0 = np.array([1e-3, 0.0, 0.0])
    ref = solve_ivp(fun, (0.0, 1.0), y0, method="DOP853", rtol=1e-13, atol=1e-16).y[:, -1]
    with warnings.catch_warnings():
        warnings.simplefilter("error", StiffRemainderWarning)
        integ = run("etdrk4", fun, y0, 1.0, 0.01, linear_part=linear_part)
        fixed = run("etdrk4", fun, y0, 1.0, 0.01, linear_part=linear_part(0.0, y0))
    # L moves by 0.3 % per step (h omega = 3.0 .. 3.4): re-evaluated every step from the third on (the build is the
    # first step's check), rebuilt when it moved > 0.1 %: the build, 98 checks, 98 rebuilds
    assert integ.njev == 2 * 100 - 3 and integ.nlu == 99
    assert abs(integ.y[0] - ref[0]) < 5e-6  # measured 2.9e-6 against the amplitude 1e-3
    assert abs(fixed.y[0] - ref[0]) > 1e-4  # measured 1.8e-4: the frozen linear part misses the stiffening
    # at twice the step the frozen part's remainder is stiff: the monitor says so
    with pytest.warns(StiffRemainderWarning, match="became stiff"):
        run("etdrk4", fun, y0, 1.0, 0.02, linear_part=linear_part(0.0, y0))


def test_a_linear_part_that_does_not_move_is_checked_ever_more_rarely():
    omega = 300.0
    L = np.array([[0.0, 1.0], [-omega ** 2, 0.0]])
    evaluations = []

    def linear_part(t, y):
        evaluations.append(t)
        return np.array([0, 1]), L

    integ = run("etdrk4", lambda t, y: L @ y, np.array([1e-3, 0.0]), 10.0, 0.01, linear_part=linear_part)
    # 1000 steps: one evaluation at the start (the build, which is step 1's check: the same state), checks at steps
    # 3, 11, 43 (intervals 2, 8, 32: no drift, exponential.check_growth), then every 64 steps from 107 up to step
    # 939: 1 + 3 + 14
    assert integ.njev == len(evaluations) == 18 and integ.nlu == 1
    np.testing.assert_allclose(evaluations[:4], [0.0, 0.02, 0.10, 0.42], rtol=1e-12)


@pytest.mark.parametrize("drift, intervals", [(1e-5, [2, 8, 32, 64, 64]), (1e-4, [2, 4, 8, 16, 32, 64, 64]),
                                              (5e-4, [2, 2, 2, 2])])
def test_the_checks_are_spaced_by_the_drift_they_find(drift, intervals):
    """A linear part that is ``drift`` (relative, Frobenius) away from the one the integrator was built with at every
    check: the interval between checks grows 4x below 1/64 of the tolerance 1e-3, 2x below a quarter of it, and stays
    above (exponential.check_growth; up to 64 steps at h = 0.01, MAX_CHECK_INTERVAL); no rebuild."""
    omega = 300.0
    L = np.array([[0.0, 1.0], [-omega ** 2, 0.0]])
    evaluations = []

    def linear_part(t, y):
        evaluations.append(t)
        return np.array([0, 1]), L * (1.0 + (drift if len(evaluations) > 1 else 0.0))

    integ = run("etdrk4", lambda t, y: L @ y, np.array([1e-3, 0.0]), 5.0, 0.01, linear_part=linear_part)
    steps = np.rint(np.diff(evaluations) / 0.01).astype(int)
    np.testing.assert_array_equal(steps[:len(intervals)], intervals)
    assert integ.nlu == 1


def test_at_a_short_step_the_checks_are_spaced_in_time():
    """The longest interval between checks is max(64 steps, 0.25 s): at 1 ms, 250 steps (the configuration moves
    on the scene's time scale; one check of the 196-mode observatory costs 15 derivatives)."""
    omega = 300.0
    L = np.array([[0.0, 1.0], [-omega ** 2, 0.0]])
    evaluations = []

    def linear_part(t, y):
        evaluations.append(t)
        return np.array([0, 1]), L

    integ = run("etdrk4", lambda t, y: L @ y, np.array([1e-3, 0.0]), 2.0, 1e-3, linear_part=linear_part)
    # 2000 steps: the start (step 1's check), checks at steps 3, 11, 43, 171 (intervals 2, 8, 32, 128), then every
    # 250 steps (421, 671, ..., 1921): 1 + 4 + 7
    assert integ.max_check_interval == 250
    assert integ.njev == len(evaluations) == 12 and integ.nlu == 1
    np.testing.assert_allclose(np.diff(evaluations)[-7:], 0.25, rtol=1e-9)


# --- interface ----------------------------------------------------------------------------------------------
def test_registered_and_lazy_derivative():
    assert INTEGRATORS["etdrk4"].uses_linear_part and INTEGRATORS["etdrk4"].fixed_step
    omega = 50.0
    L = np.array([[0.0, 1.0], [-omega ** 2, 0.0]])
    calls = []

    def fun(t, y):
        calls.append(t)
        return L @ y

    integ = make_integrator("etdrk4", fun, 0.0, [1.0, 0.0], 0.1, step=0.01, linear_part=(np.array([0, 1]), L))
    n0 = integ.nfev
    integ.step()
    assert integ.nfev - n0 == 3  # three stages; the end derivative is evaluated only if the next step needs it
    integ.reset(integ.t, integ.y, 0.2)  # a discrete update: the reset evaluates it
    integ.step()
    assert integ.nfev - n0 == 7
    np.testing.assert_allclose(integ.f, L @ integ.y, rtol=1e-15)  # computed on demand
    assert integ.nfev - n0 == 8 and len(calls) == integ.nfev


def test_refusals():
    L = np.array([[0.0, 1.0], [-4.0, 0.0]])
    fun = lambda t, y: L @ y  # noqa: E731
    with pytest.raises(ValueError, match="needs linear_part"):
        make_integrator("etdrk4", fun, 0.0, [1.0, 0.0], 1.0, step=0.1)
    with pytest.raises(ValueError, match="fixed-step method"):
        make_integrator("etdrk4", fun, 0.0, [1.0, 0.0], 1.0, linear_part=(np.array([0, 1]), L))
    with pytest.raises(ValueError, match=r"indices must lie in \[0, 2\)"):
        make_integrator("etdrk4", fun, 0.0, [1.0, 0.0], 1.0, step=0.1, linear_part=(np.array([0, 2]), L))
    with pytest.raises(ValueError, match="repeat a state component"):
        make_integrator("etdrk4", fun, 0.0, [1.0, 0.0], 1.0, step=0.1, linear_part=(np.array([1, 1]), L))
    with pytest.raises(ValueError, match=r"square over its 1 indices, got shape \(2, 2\)"):
        make_integrator("etdrk4", fun, 0.0, [1.0, 0.0], 1.0, step=0.1, linear_part=(np.array([0]), L))
    with pytest.raises(ValueError, match="must be \\(indices, L\\) or a callable"):
        make_integrator("etdrk4", fun, 0.0, [1.0, 0.0], 1.0, step=0.1, linear_part=L)
    jordan = np.array([[0.0, 1.0], [0.0, 0.0]])  # a free rate with no stiffness: defective
    with pytest.raises(ValueError, match="not diagonalizable to working accuracy"):
        make_integrator("etdrk4", lambda t, y: jordan @ y, 0.0, [1.0, 1.0], 1.0, step=0.1,
                        linear_part=(np.array([0, 1]), jordan))


def test_the_driven_rows_are_decomposed_from_the_linear_part():
    """LinearPart.extended: the linear part with driven rows ``[[L, 0], [J P, 0]]`` (P the spectral projector on L's
    non-zero eigenvalues) decomposed from L's eigen-decomposition instead of numpy's of the whole matrix. The damped
    chain with two rigid rates appended (zero columns of L, eigenvalue 0, as a free body's) and three driven rows:
    its eigenvectors are eigenvectors (residual 1.2e-18 of ||L|| ||V||), V^-1 is the inverse (2.2e-13, that of L's own
    V and V^-1), and its phi matrices are those of numpy's decomposition of the whole matrix (measured 3e-15 to 2e-14
    of their largest entries at h = 1e-4 .. 1e-2) and of scipy's expm (phi_0, an independent algorithm: 1.3e-14)."""
    A = damped_chain(6, seed=7)
    m = A.shape[0] + 2
    L = np.zeros((m, m))
    L[:m - 2, :m - 2] = A
    L[m - 2:, :6] = np.random.default_rng(2).standard_normal((2, 6)) * 1e3  # rigid rates driven by the springs
    part = LinearPart(np.arange(m), L, m + 3, "test")
    assert np.count_nonzero(~part.moving()) == 2
    J = np.random.default_rng(5).standard_normal((3, m))
    coupling = J @ ((part.V * part.moving()) @ part.Vinv).real
    rows = np.array([m, m + 1, m + 2])
    derived = part.extended(rows, coupling, m + 3)
    L_ext = np.zeros((m + 3, m + 3))
    L_ext[:m, :m] = L
    L_ext[m:, :m] = coupling
    whole = LinearPart(np.arange(m + 3), L_ext, m + 3, "test")
    np.testing.assert_array_equal(derived.L, whole.L)
    scale = np.abs(L_ext).max() * np.abs(derived.V).max()
    assert np.abs(L_ext @ derived.V - derived.V * derived.lam).max() <= 1e-14 * scale
    assert np.abs(derived.V @ derived.Vinv - np.eye(m + 3)).max() <= 1e-12
    derived.check_exponential(1e-3)
    for h in (1e-4, 1e-3, 1e-2):
        ours, reference = derived.real_functions(h), whole.real_functions(h)
        for f in range(len(FUNCTIONS)):
            assert np.abs(ours[f] - reference[f]).max() <= 1e-12 * np.abs(reference[f]).max()
        np.testing.assert_allclose(ours[3], scipy.linalg.expm(h * L_ext), rtol=0, atol=1e-11 * np.abs(ours[3]).max())


def test_linear_part_decomposition_reproduces_expm():
    A = damped_chain(8, seed=11)
    part = LinearPart(np.arange(16), A, 16, "test")
    for k, (c, order) in enumerate(((0.5, 0), (1.0, 0))):
        phi = part.real_functions(0.01)[3 * k]
        np.testing.assert_allclose(phi, scipy.linalg.expm(c * 0.01 * A), rtol=0,
                                   atol=1e-12 * np.abs(phi).max())
    # phi_1(hA) = (hA)^-1 (e^{hA} - I) for this invertible A
    phi1 = part.real_functions(0.01)[4]
    np.testing.assert_allclose(phi1, np.linalg.solve(0.01 * A, scipy.linalg.expm(0.01 * A) - np.eye(16)), rtol=0,
                               atol=1e-9 * np.abs(phi1).max())
    assert math.isclose(part.L_norm, np.abs(A).sum(axis=1).max())


# --- the nominal step's products: copy rows and the phi_1 form of the stages -----------------------------------
def phi_blocks(A):
    """phi_0..phi_3 of A from one exponential of a block matrix (Van Loan 1978; Saad 1992): expm of
    [[A, I, 0, 0], [0, 0, I, 0], [0, 0, 0, I], [0, 0, 0, 0]] has e^A, phi_1(A), phi_2(A), phi_3(A) in its first block
    row: an algorithm independent of the integrator's eigen-decomposition."""
    m = A.shape[0]
    big = np.zeros((4 * m, 4 * m))
    big[:m, :m] = A
    for k in range(3):
        big[k * m:(k + 1) * m, (k + 1) * m:(k + 2) * m] = np.eye(m)
    E = scipy.linalg.expm(big)
    return [E[:m, k * m:(k + 1) * m] for k in range(4)]


def krogstad_step(fun, L, y, h, zero_rows=()):
    """One step of Krogstad's scheme as published (8 products with phi_0 .. phi_3; module docstring); N set to zero
    on ``zero_rows`` (what skipping those columns would compute)."""
    half, full = phi_blocks(0.5 * h * L), phi_blocks(h * L)

    def N(t, Y):
        out = fun(t, Y) - L @ Y
        out[list(zero_rows)] = 0.0
        return out

    N1 = N(0.0, y)
    Y2 = half[0] @ y + 0.5 * h * half[1] @ N1
    N2 = N(0.5 * h, Y2)
    Y3 = Y2 + h * half[2] @ (N2 - N1)
    N3 = N(0.5 * h, Y3)
    Y4 = full[0] @ y + h * full[1] @ N1 + 2 * h * full[2] @ (N3 - N1)
    N4 = N(h, Y4)
    return Y4 + h * full[2] @ (-N1 + 2 * N2 - N4) + 4 * h * full[3] @ (N1 - N2 - N3 + N4)


@pytest.mark.parametrize("rate_offset", [0.0, 1.0])
def test_one_step_equals_krogstad_as_published(rate_offset):
    """A nonlinear chain (cubic springs in N): one nominal step equals Krogstad's published 8-product formula with
    phi functions from a block exponential, to round-off (1e-12 of the state). With ``rate_offset`` 0 the model's
    x' is v itself (N is exactly zero on the copy rows, whose columns the products skip); with 1, x' = v + 1e-3
    sin(x) makes N non-zero there and those columns must be multiplied."""
    A = damped_chain(5, seed=4)
    n = 5

    def fun(t, y):
        out = A @ y
        out[n:] += 3e5 * y[:n] ** 3 + np.cos(7.0 * t)
        out[:n] = y[n:] + rate_offset * 1e-3 * np.sin(40.0 * y[:n])
        return out

    part = LinearPart(np.arange(2 * n), A, 2 * n, "test")
    assert list(part.copy_rows) == list(range(n)) and list(part.copied) == list(range(n, 2 * n))
    rng = np.random.default_rng(2)
    y0 = np.r_[rng.uniform(-0.02, 0.02, n), rng.uniform(-1.0, 1.0, n)]
    h = 2e-3
    integ = make_integrator("etdrk4", fun, 0.0, y0, 1.0, step=h, linear_part=(np.arange(2 * n), A))
    integ.step()
    reference = krogstad_step(fun, A, y0, h)
    np.testing.assert_allclose(integ.y, reference, rtol=0, atol=1e-12 * np.abs(reference).max())
    if rate_offset:  # the copy columns matter here: without them the step would be this far off
        skipped = krogstad_step(fun, A, y0, h, zero_rows=range(n))
        assert np.abs(reference - skipped).max() > 1e4 * 1e-12 * np.abs(reference).max()


def test_constant_forcing_on_the_copy_rows_is_exact():
    """y' = L y + c with c on the row x' = v as well: N is not zero on the copy row, its columns are multiplied, and
    the step stays exact (closed form through expm)."""
    omega = 3e3
    L = np.array([[0.0, 1.0], [-omega ** 2, -2 * 0.01 * omega]])
    c = np.array([4e-3, 7.0])
    y0 = np.array([2e-6, -0.3])
    integ = run("etdrk4", lambda t, y: L @ y + c, y0, 0.5, 0.05, linear_part=(np.array([0, 1]), L))
    static = -np.linalg.solve(L, c)
    exact = static + scipy.linalg.expm(0.5 * L) @ (y0 - static)
    np.testing.assert_allclose(integ.y, exact, rtol=0, atol=1e-15 * omega)


def test_copy_rows_are_single_entries_of_exactly_one():
    """Only a row with one non-zero entry, exactly 1, is a copy row (its N is computed as f_a - y_b)."""
    L = np.array([[0.0, 1.0, 0.0, 0.0],      # copy of component 1
                  [-4.0, 0.0, 0.0, 0.0],
                  [0.0, 0.0, 0.0, 2.0],      # a single entry, but 2
                  [0.0, 1.0, -9.0, 1.0]])    # entries of 1 among others
    part = LinearPart(np.array([3, 0, 2, 1]), L, 5, "test")
    assert list(part.copy_rows) == [0] and list(part.copied) == [1]
    assert list(part.copy_components) == [3] and list(part.copied_components) == [0]
    assert list(part.other_rows) == [1, 2, 3] and list(part.other_components) == [0, 2, 1]
    np.testing.assert_array_equal(part.L_other, L[1:])


def test_zero_columns_of_L_take_the_unit_columns_of_the_phi_functions():
    """A rigid-body rate w that nothing in L depends on (w' couples to the chain, x'' does not see w: the observatory's
    free-hinge and rotor rates) and a driven row s' = c v (an IMU's integral, found by the integrator) give zero
    columns of L, where phi_k(c h L) is the unit column over k!: the products skip them and add W / k! on their own row.
    One nominal step equals Krogstad's published step with phi functions from a block exponential to round-off
    (1e-12 of the state); N is large on those rows (gyroscopic-like w^2 terms, a forcing), so leaving their terms out
    would be 1e4 times the tolerance off."""
    A = damped_chain(5, seed=7)
    n = 5
    a = np.linspace(1e3, 5e3, n)
    c = np.linspace(0.5, 1.5, n)
    L_given = np.zeros((2 * n + 1, 2 * n + 1))
    L_given[:2 * n, :2 * n] = A
    L_given[2 * n, :n] = -a  # w' = -a x: a row of L, its column zero

    def fun(t, y):
        x, v, w = y[:n], y[n:2 * n], y[2 * n]
        out = np.empty(2 * n + 2)
        out[:2 * n] = A @ y[:2 * n]
        out[n:2 * n] += 3e5 * x ** 3 + 0.4 * w ** 2
        out[:n] = v
        out[2 * n] = -a @ x + np.cos(9.0 * t) + 2.0 * w * v[0]
        out[2 * n + 1] = c @ v
        return out

    rng = np.random.default_rng(5)
    y0 = np.r_[rng.uniform(-0.02, 0.02, n), rng.uniform(-1.0, 1.0, n), 0.7, 0.0]
    h = 2e-3
    integ = make_integrator("etdrk4", fun, 0.0, y0, 1.0, step=h, linear_part=(np.arange(2 * n + 1), L_given))
    part = integ.part
    assert list(part.indices) == list(range(2 * n + 2))  # the driven row s joined the linear part
    assert list(part.zero_columns) == [2 * n, 2 * n + 1]
    assert list(part.dense_other_rows) == list(range(n, 2 * n)) and list(part.dense_copy_rows) == list(range(n))
    phi = part.real_functions(h)
    for f, (_, k) in enumerate(FUNCTIONS):
        np.testing.assert_allclose(phi[f][:, part.zero_columns], np.eye(2 * n + 2)[:, part.zero_columns] /
                                   math.factorial(k), rtol=0, atol=1e-14)
    integ.step()
    reference = krogstad_step(fun, part.L, y0, h)
    np.testing.assert_allclose(integ.y, reference, rtol=0, atol=1e-12 * np.abs(reference).max())
    without = krogstad_step(fun, part.L, y0, h, zero_rows=list(range(n)) + [2 * n, 2 * n + 1])
    assert np.abs(reference - without).max() > 1e4 * 1e-12 * np.abs(reference).max()


def test_drift_of_the_linear_part_is_the_frobenius_norm_of_the_difference():
    """The check's drift ||L(y) - L|| / ||L|| sums the squared differences without forming L(y) - L: equal to numpy's
    Frobenius norm to round-off (1e-13: a sum of 1e4 squares)."""
    from shell.integrators.exponential import frobenius_distance

    rng = np.random.default_rng(9)
    A, B = rng.standard_normal((2, 97, 103)) * 1e6
    assert math.isclose(frobenius_distance(A, B), np.linalg.norm(A - B), rel_tol=1e-13)
    assert frobenius_distance(A, A) == 0.0

"""Linear stability of the explicit Runge-Kutta methods (HNW I Sec. IV.2, HW II Sec. IV.2).

For the test equation ``y' = lambda y`` one step multiplies the state by ``R(h lambda)`` with
``R(z) = 1 + z b^T (I - z A)^-1 1``; a step is stable when ``|R(h lambda)| <= 1``. A lightly damped
structural mode ``lambda = omega (-zeta +- i sqrt(1 - zeta^2))`` therefore limits an explicit method to
``h <= r(zeta) / omega`` where ``r`` is the distance to the stability boundary along that ray.
"""
import numpy as np


def stability_radius(tableau, angle, r_max=40.0, n_grid=40000):
    """Largest r such that ``abs(R(r' e^{i angle})) <= 1`` for all 0 < r' <= r (0 if unstable right away).

    ``angle`` is measured from the positive real axis: pi for a real decaying mode, pi/2 for an undamped
    oscillation, ``pi - arcsin(sqrt(1 - zeta^2))`` ... i.e. ``pi/2 + arcsin(zeta)`` for damping ratio zeta.
    The boundary is bracketed on a fine grid and refined by bisection.
    """
    direction = np.exp(1j * angle)
    r = np.linspace(r_max / n_grid, r_max, n_grid)
    amp = np.abs(tableau.stability_function(r * direction))
    unstable = np.flatnonzero(amp > 1.0 + 1e-13)
    if unstable.size == 0:
        return r_max
    k = unstable[0]
    if k == 0:
        lo, hi = 0.0, r[0]
    else:
        lo, hi = r[k - 1], r[k]
    for _ in range(60):
        mid = 0.5 * (lo + hi)
        if abs(tableau.stability_function(mid * direction)[0]) > 1.0 + 1e-13:
            hi = mid
        else:
            lo = mid
    return lo


def mode_angle(damping_ratio):
    """Angle in the complex plane of ``lambda = omega (-zeta + i sqrt(1 - zeta^2))``."""
    return np.pi / 2 + np.arcsin(damping_ratio)


def max_stable_step(tableau, omega, damping_ratio):
    """Largest stable step for a mode of natural frequency omega (rad/s) and damping ratio zeta."""
    return stability_radius(tableau, mode_angle(damping_ratio)) / omega

"""Mechanical-equivalent slosh parameters of an upright cylindrical tank from its fill level.

Linear potential flow of an inviscid, incompressible liquid of depth ``h`` in a rigid upright circular
cylinder of radius ``R`` with a flat bottom, under the axial acceleration ``a`` (gravity, or thrust
divided by mass). The lateral modes are ``phi_n = J1(k_n r) cosh(k_n z) cos(theta)`` with ``k_n = xi_n /
R`` and ``J1'(xi_n) = 0`` (xi = 1.8412, 5.3314, 8.5363, ...); the free-surface condition
``phi_z = (omega^2 / a) phi`` gives the frequencies (Abramson, NASA SP-106, 1966, ch. 2; Dodge, "The New
Dynamic Behavior of Liquids in Moving Containers", SwRI 2000, ch. 3):

    omega_n^2 = a k_n tanh(k_n h)

Kinetic energy of the flow ``x_dot x + q_dot phi_n`` (tank translation x, surface coordinate q) has the
cross term ``Gamma_n = rho * integral(x eta_n dA)`` over the free surface and the modal mass
``mu_n = rho * integral(phi_n eta_n dA)``; the mass that moves with the mode is ``m_n = Gamma_n^2 / mu_n``:

    m_n = m_L * 2 tanh(k_n h) / ((xi_n^2 - 1) k_n h)  [= m_L 2 R tanh(xi_n h / R) / (xi_n (xi_n^2 - 1) h)],
    m_L = rho pi R^2 h

and the rest, ``m_0 = m_L - sum m_n``, moves rigidly with the tank (sum over all modes is m_L:
sum 2 / (xi_n^2 - 1) = 1). The moment of the mode's wall and bottom pressure about the bottom centre,
divided by its lateral force, puts the force at the height ``H_n = h - (cosh(k_n h) - 2) / (k_n sinh(k_n h))``
above the bottom (wall integral R int z cosh(kz) dz, bottom integral int r^2 J1(kr) dr = R J1(xi) / k^2
with J2(xi) = J1(xi) / xi). The equivalents that reproduce force and moment under lateral motion:

* pendulum: hinge at ``H_n``, length ``L_n = a / omega_n^2 = 1 / (k_n tanh(k_n h))``, mass ``m_n`` at
  ``H_n - L_n = h - (2 / k_n) tanh(k_n h / 2)``;
* spring-mass: mass ``m_n`` at that same height ``h_n = h - (2 / k_n) tanh(k_n h / 2)`` (Dodge's
  ``h/2 - (2R/xi_n) tanh(xi_n h / 2R)`` from the liquid's centre of mass), stiffness ``k = m_n omega_n^2``
  (the weight of the displaced mass supplies the difference between H_n and h_n);
* the rigid part m_0 at the height that keeps the liquid's centre of mass at h / 2.

Not modelled: the liquid's reduced rotational inertia about its centre of mass (a parameter of the
rigid part left to the user), domed or spherical bottoms (Dodge gives those as charts), damping (from
the liquid's viscosity and baffles; set ``zeta`` on the hinge damper), and the change of these values as
the tank drains (they are computed once for a fill level).
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
from scipy.special import jnp_zeros


class TankSlosh(NamedTuple):
    """Equivalent-model data for ``n`` lateral slosh modes (heights from the tank bottom, SI units)."""

    liquid_mass: float
    frequencies: np.ndarray        # (n,) omega_n [rad/s]
    slosh_masses: np.ndarray       # (n,) m_n [kg]
    mass_heights: np.ndarray       # (n,) h_n: spring-mass and pendulum-bob height [m]
    pendulum_lengths: np.ndarray   # (n,) L_n [m]
    hinge_heights: np.ndarray      # (n,) H_n = h_n + L_n: pendulum hinge [m]
    spring_stiffnesses: np.ndarray  # (n,) m_n omega_n^2 [N/m]
    fixed_mass: float              # m_0 [kg]
    fixed_height: float            # h_0 [m]

    @property
    def frequencies_hz(self) -> np.ndarray:
        return self.frequencies / (2.0 * np.pi)


def cylindrical_tank_slosh(radius: float, fill_height: float, density: float, acceleration: float,
                           n_modes: int = 1) -> TankSlosh:
    """Slosh equivalents of an upright flat-bottomed cylinder (see the module docstring).

    radius [m], fill_height (liquid depth) [m], density [kg/m^3], acceleration: axial acceleration
    pressing the liquid to the bottom [m/s^2] (> 0), n_modes: lateral modes kept (in one lateral
    direction; the tank's symmetry repeats them in the other)."""
    for name, value in (("radius", radius), ("fill_height", fill_height), ("density", density),
                        ("acceleration", acceleration)):
        if not (np.isfinite(value) and value > 0.0):
            raise ValueError(f"cylindrical_tank_slosh: {name} must be a positive number, given {value!r}")
    if int(n_modes) < 1:
        raise ValueError(f"cylindrical_tank_slosh: n_modes must be >= 1, given {n_modes!r}")
    R, h = float(radius), float(fill_height)
    liquid = float(density) * np.pi * R**2 * h
    xi = jnp_zeros(1, int(n_modes))
    k = xi / R
    kh = k * h
    omega = np.sqrt(acceleration * k * np.tanh(kh))
    masses = liquid * 2.0 * np.tanh(kh) / ((xi**2 - 1.0) * kh)
    mass_heights = h - (2.0 / k) * np.tanh(0.5 * kh)
    lengths = 1.0 / (k * np.tanh(kh))
    fixed = liquid - float(np.sum(masses))
    fixed_height = (liquid * 0.5 * h - float(np.sum(masses * mass_heights))) / fixed
    return TankSlosh(liquid, omega, masses, mass_heights, lengths, mass_heights + lengths,
                     masses * omega**2, fixed, fixed_height)

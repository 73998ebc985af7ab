"""Kane-Ryan-Banerjee spin-up beam (Kane, Ryan and Banerjee, "Dynamics of a cantilever beam attached to
a moving base", JGCD 10(2), 1987): an independent geometrically nonlinear reference (issue 15).

The beam (L = 10 m, EI = 14,000 N m^2, rho A = 1.2 kg/m, clamped to a hub on the spin axis) is driven in its
plane by the prescribed hub rate

    Omega(t) = (6 / 15) (t - (15 / (2 pi)) sin(2 pi t / 15))   for t < 15 s, then 6 rad/s.

Reference model: a planar chain of rigid links joined by rotary springs (the finite-segment model), exact
in its large rotations: joints at x_i = (i - 1/2) h (h = L / N, i = 1..N), each with a spring EI / h (the
midpoint rule of the bending energy: a tip load gives the cantilever's deflection to O(h^2)); between
joints rigid links of length h (the last one h / 2 to the tip), mass rho A times their length and centroidal
inertia m l^2 / 12; the stub from the axis to the first joint turns with the hub. With absolute link angles
theta_k (theta_0 = the hub angle, prescribed) the kinetic energy is
``1/2 sum_jk c_jk cos(theta_j - theta_k) theta_j' theta_k' + 1/2 sum J_k theta_k'^2`` with
``c_jk = sum_i m_i A_ij A_ik`` (A_ij = l_j for j < i, l_i / 2 for j = i), and Lagrange's equations

    sum_k c_jk (cos(theta_j - theta_k) theta_k'' + sin(theta_j - theta_k) theta_k'^2) + J_j theta_j''
        = -dV/dtheta_j,   V = sum_i EI / (2 h) (theta_i - theta_{i-1})^2,

are integrated by scipy's DOP853 (rtol 1e-9). The tip deflection is the tip position across the hub's x
axis, in the hub frame. Nothing in it is shared with the modal engine (no modes, no geometric stiffness: the
stiffening comes out of the exact kinematics).
"""

from __future__ import annotations

import numpy as np

LENGTH, EI, RHO_A = 10.0, 14000.0, 1.2
T_SPIN, OMEGA_FINAL = 15.0, 6.0


def hub_motion(t):
    """(angle, rate, acceleration) of the hub at time t (prescribed spin-up)."""
    if t < T_SPIN:
        w = 2.0 * np.pi / T_SPIN
        c = OMEGA_FINAL / T_SPIN
        angle = c * (0.5 * t * t + (np.cos(w * t) - 1.0) / (w * w))
        rate = c * (t - np.sin(w * t) / w)
        accel = c * (1.0 - np.cos(w * t))
        return angle, rate, accel
    angle15 = OMEGA_FINAL / T_SPIN * (0.5 * T_SPIN ** 2)
    return angle15 + OMEGA_FINAL * (t - T_SPIN), OMEGA_FINAL, 0.0


def chain_reference(t_eval, n_links=20, rtol=1e-9):
    """Tip deflection (m, across the hub x axis) at the times ``t_eval`` (module docstring)."""
    from scipy.integrate import solve_ivp

    h = LENGTH / n_links
    lengths = np.array([0.5 * h] + [h] * (n_links - 1) + [0.5 * h])  # link 0: the stub on the hub
    m = RHO_A * lengths
    m[0] = 0.0  # the stub is part of the prescribed hub
    n = lengths.size
    A = np.zeros((n, n))
    for i in range(n):
        A[i, :i] = lengths[:i]
        A[i, i] = 0.5 * lengths[i]
    c = (A * m[:, None]).T @ A
    J = m * lengths ** 2 / 12.0
    k = EI / h

    def rates(t, y):
        th = np.empty(n)
        dth = np.empty(n)
        th[0], dth[0], acc0 = hub_motion(t)
        th[1:] = y[:n - 1]
        dth[1:] = y[n - 1:]
        d = th[:, None] - th[None, :]
        Mfull = c * np.cos(d) + np.diag(J)
        rhs = -(c * np.sin(d)) @ (dth * dth)
        rel = np.diff(th)
        force = np.zeros(n)
        force[1:] -= k * rel
        force[:-1] += k * rel
        rhs += force
        rhs = rhs[1:] - Mfull[1:, 0] * acc0
        return np.concatenate([dth[1:], np.linalg.solve(Mfull[1:, 1:], rhs)])

    y0 = np.zeros(2 * (n - 1))
    sol = solve_ivp(rates, (0.0, float(t_eval[-1])), y0, method="DOP853", t_eval=t_eval, rtol=rtol,
                    atol=1e-10 * LENGTH)
    if not sol.success:
        raise RuntimeError(sol.message)
    out = np.empty(len(t_eval))
    for j, t in enumerate(sol.t):
        th = np.concatenate([[hub_motion(t)[0]], sol.y[:n - 1, j]]) - hub_motion(t)[0]
        out[j] = np.sum(lengths * np.sin(th))
    return out

"""The flexible-body verification suite checks the articulated-body recursion (the modal condensation,
hinges on deforming nodes): force it, since compile() would choose the dense solve for the small bodies
used here (dynamics.system.choose_solver). The dense solver is checked against the recursion and the
nodal reference in test_modal_condensation.py, with ``compile(solver="dense")``."""

import numpy as np
import pytest

import dynamics.system


@pytest.fixture(autouse=True)
def articulated_body_solver(monkeypatch):
    monkeypatch.setattr(dynamics.system, "choose_solver",
                        lambda topology: ("aba", "articulated-body recursion (forced by tests/flexible/conftest.py)"))


def rk4_march(system, q, u, h, steps, t0=0.0, tau=None, prescribed_accel=None, normalize=True, after_step=None):
    """Classic fourth-order Runge-Kutta on ``q' = system.q_dot(q, u)``, ``u' = system.forward_dynamics(q, u,
    tau, prescribed_accel=...)`` for ``steps`` steps of ``h`` from time ``t0`` (the hand-written loop the
    flexible tests share: an integrator independent of the shell's). ``tau`` (nu,) constant generalized forces
    (zero if None); ``prescribed_accel``: None (zero), an (nu,) array or a function of t giving one;
    ``normalize``: renormalize the quaternions after every step; ``after_step(t, q, u)`` is called after every
    step and may return True to stop early. Returns (q, u, t)."""
    tau = np.zeros(system.nu) if tau is None else np.asarray(tau, dtype=float)

    def accel(t):
        if prescribed_accel is None or not callable(prescribed_accel):
            return prescribed_accel
        return prescribed_accel(t)

    def f(t, q, u):
        return system.q_dot(q, u), system.forward_dynamics(q, u, tau, prescribed_accel=accel(t))

    t = t0
    for i in range(steps):
        k1 = f(t, q, u)
        k2 = f(t + h / 2, q + h / 2 * k1[0], u + h / 2 * k1[1])
        k3 = f(t + h / 2, q + h / 2 * k2[0], u + h / 2 * k2[1])
        k4 = f(t + h, q + h * k3[0], u + h * k3[1])
        q = q + h / 6 * (k1[0] + 2 * k2[0] + 2 * k3[0] + k4[0])
        u = u + h / 6 * (k1[1] + 2 * k2[1] + 2 * k3[1] + k4[1])
        if normalize:
            system.normalize_quaternions(q)
        t = t0 + (i + 1) * h
        if after_step is not None and after_step(t, q, u):
            break
    return q, u, t

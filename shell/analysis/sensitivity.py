"""Parameter sensitivities of a built simulation: how the state rates and named outputs change with named parameters.

At an operating point (t0, x0, the scene's inputs), the Jacobians

    S_x = d(xi')/dp,   S_y = dy/dp

of the tangent state rates (the linearization's coordinates: quaternions as rotation vectors,
:mod:`shell.analysis.linearize`) and of named outputs with respect to the elements of named parameters, by the
linearization's central differences (2 or 4 points, Richardson extrapolation, step ``scale_j tol^(1/p)`` with
``scale_j`` the larger of ``abs(p_j)`` and the parameter's typical size, error estimate of every entry). The parameters are
written by name into the run's Context (:mod:`shell.names`): a model parameter's slice of ``p``, a rigid body's mass,
center of mass and inertia in the run's own engine system (:class:`shell.analysis.linearize.NamedParameters`); the
operating values are written back afterwards. This is the input of a covariance or worst-case analysis
(``dy = S_y dp``), and what a Monte Carlo campaign's scatter plots estimate statistically.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from shell.analysis.linearize import (SCHEMES, Evaluation, LinearizationError, NamedParameters, NamedSignals,
                                      TangentStates, difference_column, input_signals)


@dataclass
class Sensitivities:
    """``rates = d(xi')/dp`` (tangent states x parameter elements) and ``outputs = dy/dp`` at an operating point."""

    rates: np.ndarray
    outputs: np.ndarray
    state_names: list
    output_names: list
    output_units: list
    parameter_names: list        # one per element: "controller.kp[1]", "multibody.bus.inertia[0,1]"
    parameter_units: list
    parameter_values: np.ndarray  # the operating values of the elements
    errors: dict                  # estimated absolute error of every entry of rates and outputs
    operating_point: dict         # t, x, xdot (tangent rates), y

    def __str__(self) -> str:
        return (f"sensitivities of {len(self.state_names)} state rates and {len(self.output_names)} outputs to "
                f"{len(self.parameter_names)} parameter elements; largest estimated entry error "
                f"{max(float(np.max(e, initial=0.0)) for e in self.errors.values()):.3g}")


def parameter_sensitivities(sim, parameters, outputs=(), *, tolerance: float = 1e-10, points: int = 4,
                            richardson: bool = True, t=None, x=None, scales=None) -> Sensitivities:
    """Sensitivities of ``sim``'s state rates and ``outputs`` (port or state names or elements) to ``parameters``
    (names of the scene's name index: ``controller.kp``, ``multibody.bus.inertia``) at its current (or the given)
    time and state; ``scales``: {parameter name: typical size} where it is not ~1 in its unit."""
    if (points, bool(richardson)) not in SCHEMES:
        raise LinearizationError(f"points = {points}: expected 2 or 4 (central differences)")
    if not 0.0 < tolerance < 1.0:
        raise LinearizationError(f"tolerance = {tolerance}: expected a relative error in (0, 1)")
    t0 = sim.t if t is None else float(t)
    x_saved, signals_saved = sim.x.copy(), sim.signals.copy()
    x0 = sim.x.copy() if x is None else np.asarray(x, dtype=float).copy()
    if x0.shape != sim.x.shape:
        raise LinearizationError(f"operating state has shape {x0.shape}, the scene's state has {sim.x.shape}")
    sim.plan.normalize(x0)
    states = TangentStates(sim, x0, {})
    outs = NamedSignals(sim, list(outputs), "output")
    named = NamedParameters(sim, list(parameters))
    typical = np.ones(named.n)
    for name, value in (scales or {}).items():
        if name not in named.index:
            raise LinearizationError(f"scale given for {name!r}, which is not a listed parameter ({list(named.index)})")
        typical[named.index[name]] = np.broadcast_to(np.asarray(value, dtype=float), named.index[name].shape)
    scale = np.maximum(np.abs(named.value), typical)
    n, p = states.n, len(outs.names)
    jac, err = np.empty((n + p, named.n)), np.empty((n + p, named.n))
    try:
        sim.x[:] = x0
        sim.evaluate(t0)
        evaluate = Evaluation(sim, states, input_signals(sim, []), outs, named)
        zero_x, zero_u = np.zeros(n), np.zeros(0)
        F0 = evaluate(t0, zero_u, zero_x, zero_u, np.zeros(named.n))
        for j in range(named.n):
            def at(delta, j=j):
                w = np.zeros(named.n)
                w[j] = delta
                return evaluate(t0, zero_u, zero_x, zero_u, w)

            jac[:, j], err[:, j], _ = difference_column(at, scale[j], F0, tolerance, points, richardson,
                                                       named.names[j])
    finally:
        named.apply(None)
        sim.x[:] = x_saved
        sim.signals[:] = signals_saved
    return Sensitivities(jac[:n], jac[n:], states.names, outs.names, outs.units, named.names, named.units,
                         named.value.copy(), {"rates": err[:n], "outputs": err[n:]},
                         {"t": t0, "x": x0, "xdot": F0[:n], "y": F0[n:]})

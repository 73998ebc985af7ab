"""Trim: an operating point where chosen state derivatives vanish (or take target values).

Unknowns are the tangent coordinates (:mod:`shell.analysis.linearize`: quaternions as rotation
vectors) of the states that are not held, the input-port elements declared free, and the elements of the named
parameters declared free (written by name into the run's Context, :mod:`shell.names`: a model parameter, a rigid
body's mass properties; they keep the trim's values); equations are the
rates of the chosen states minus their targets. Solved as a nonlinear least-squares problem
(``scipy.optimize.least_squares``, trust-region reflective, finite-difference Jacobian), which also
handles more equations than unknowns; the residual of every equation is reported, so a trim that
cannot be reached (e.g. a pre-loaded flexible launch vehicle whose modal accelerations cannot all
vanish with the inputs given: TM-2020-5008164 finding F-2, recommendation R-2) is visible.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.optimize import least_squares

from shell.analysis.linearize import (Evaluation, LinearizationError, NamedParameters, NamedSignals, TangentStates,
                                      input_signals)


@dataclass
class TrimResult:
    x: np.ndarray                 # full state at the trim point (set into the simulation)
    input_values: dict            # {free or held input: value}; pass to linearize(input_values=...)
    parameter_values: dict        # {free parameter: value} (the run's Context holds them)
    residuals: dict               # {state name: rate minus target} of every trimmed derivative
    max_residual: float
    success: bool
    message: str
    evaluations: int

    def __str__(self) -> str:
        return (f"trim {'converged' if self.success else 'FAILED'}: largest residual {self.max_residual:.3g} "
                f"after {self.evaluations} evaluations ({self.message})")


def trim(sim, *, hold=(), free_inputs=(), inputs=(), input_values=None, derivatives=None, targets=None,
         free_parameters=(), tolerance: float = 1e-12, max_evaluations: int = 2000) -> TrimResult:
    """Solve for an operating point of ``sim`` starting from its current state.

    hold: state names (``model.state``) or elements (``model.state[k]``, the names of
        ``LinearModel.state_names``) kept at their current values.
    free_inputs: input ports/elements solved for (start at their current values).
    inputs, input_values: further (held) inputs opened at the given values.
    derivatives: state names whose rates must vanish (default: every state: an equilibrium).
    targets: {state name: rate} for rates that must take a value other than zero.
    free_parameters: names of parameters solved for (shell.names: ``controller.bias``, ``multibody.bus.mass``).
    On return the simulation's state is the trim state and its free parameters take their trim values.
    """
    targets = dict(targets or {})
    states = TangentStates(sim, sim.x.copy(), {})
    position = {name: k for k, name in enumerate(states.names)}

    def members(name):
        if name in states.index:
            return states.index[name]
        if name in position:
            return np.array([position[name]], dtype=np.int64)
        if states.kept is not None and name in states.full_names:
            raise LinearizationError(f"trim: {name!r} is a dependent coordinate of a closed loop (it follows from the "
                                     f"closure constraints); the minimal coordinates are {states.names}")
        raise LinearizationError(f"trim: {name!r} is neither a continuous state nor a state element; states: "
                                 f"{sorted(states.index)} (elements as in LinearModel.state_names, e.g. "
                                 f"{states.names[-1]!r})")

    held = np.zeros(states.n, dtype=bool)
    for name in hold:
        held[members(name)] = True
    equations_of = list(derivatives) if derivatives is not None else list(states.index)
    for name in targets:
        if name not in equations_of:
            equations_of.append(name)
    rows = np.concatenate([members(name) for name in equations_of]) if equations_of else np.zeros(0, int)
    target = np.zeros(states.n)
    for name, value in targets.items():
        target[members(name)] = np.asarray(value, dtype=float).reshape(-1)
    all_inputs = list(free_inputs) + [name for name in inputs if name not in free_inputs]
    ins = input_signals(sim, all_inputs)
    sim.evaluate(sim.t)
    u0 = sim.signals[ins.positions].copy()
    for name, value in (input_values or {}).items():
        if name not in ins.index:
            raise LinearizationError(f"trim: value given for {name!r}, which is not a listed input ({all_inputs})")
        u0[ins.index[name]] = np.asarray(value, dtype=float).reshape(-1)
    free_u = np.concatenate([ins.index[name] for name in free_inputs]) if free_inputs else np.zeros(0, int)
    free_x = np.flatnonzero(~held)
    if rows.size == 0:
        raise LinearizationError("trim: no derivative to drive to its target (every state is held)")
    outputs = NamedSignals(sim, [], "output")
    named = NamedParameters(sim, list(free_parameters))
    saved_signals = sim.signals.copy()
    counter = [0]

    evaluate = Evaluation(sim, states, ins, outputs, named)

    def unpack(z):
        xi, v = np.zeros(states.n), np.zeros(len(ins.names))
        xi[free_x] = z[:free_x.size]
        v[free_u] = z[free_x.size:free_x.size + free_u.size]
        return xi, v, z[free_x.size + free_u.size:]

    def residual(z):
        counter[0] += 1
        xi, v, w = unpack(z)
        rates = evaluate(sim.t, u0, xi, v, w)[:states.n]
        return rates[rows] - target[rows]

    solution = least_squares(residual, np.zeros(free_x.size + free_u.size + named.n), method="trf", xtol=tolerance,
                             ftol=tolerance, gtol=tolerance, max_nfev=max_evaluations, x_scale="jac")
    xi, v, w = unpack(solution.x)
    final = residual(solution.x)  # leaves the free parameters at the solution
    sim.signals[:] = saved_signals
    x = states.retract(xi)
    sim.set_state(x=x)
    u = u0 + v
    values = {name: u[idx].copy() if idx.size > 1 else float(u[idx[0]]) for name, idx in ins.index.items()}
    names = [states.names[r] for r in rows]
    max_residual = float(np.max(np.abs(final), initial=0.0))
    parameters = {name: sim.context.get(name) for name in named.index}
    return TrimResult(x, values, parameters, dict(zip(names, final)), max_residual, bool(solution.success),
                      solution.message, counter[0])

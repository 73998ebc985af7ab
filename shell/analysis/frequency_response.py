"""Frequency responses: from a linear model, and from the nonlinear simulation by small-signal
sinusoidal excitation for cross-checking (the verification idea of TM-2020-5008164 App. F.3).

Linear: ``G(j w) = C (j w I - A)^-1 B + D`` (a complex solve per frequency), Bode magnitude
``20 log10 |G|`` dB and phase ``angle(G)`` deg.

Nonlinear: the named input is opened and driven ``u(t) = u0 + a sin(w t)`` while the scene's
continuous dynamics are integrated (``scipy.integrate.solve_ivp``, DOP853, tight tolerances) over
whole periods. The run starts on the linear model's periodic solution,
``x(0) = x0 + a Im[(j w I - A)^-1 B e_k]`` (tangent coordinates), so no free transient has to decay;
what remains differs from the linear response by the scene's nonlinearity, O(a). The output is fitted
by least squares with ``y0' + s sin(w t) + c cos(w t)`` and ``G = (s + j c) / a``.
"""

from __future__ import annotations

import numpy as np
from scipy.integrate import solve_ivp

from shell.analysis.linearize import LinearModel, Evaluation, input_signals, NamedSignals, TangentStates


def frequency_response(model: LinearModel, frequencies_hz) -> np.ndarray:
    """Complex G (outputs x inputs x frequencies) of the linear model."""
    w = 2.0 * np.pi * np.asarray(frequencies_hz, dtype=float).reshape(-1)
    n = model.A.shape[0]
    out = np.empty((model.C.shape[0], model.B.shape[1], w.size), dtype=complex)
    for k, wk in enumerate(w):
        out[:, :, k] = model.C @ np.linalg.solve(1j * wk * np.eye(n) - model.A, model.B) + model.D
    return out


def bode(response) -> tuple[np.ndarray, np.ndarray]:
    """(magnitude dB, phase deg) of a complex response."""
    return 20.0 * np.log10(np.abs(response)), np.degrees(np.angle(response))


def small_signal_response(sim, model: LinearModel, input_name: str, output_name: str, frequency_hz: float,
                          amplitude: float, periods: int = 3, rtol: float = 1e-11, atol: float = 1e-13,
                          samples_per_period: int = 64, equilibrium_tolerance: float = 1e-9) -> complex:
    """G(j w) from input element ``input_name`` to output element ``output_name`` by exciting the
    nonlinear scene about the model's operating point, which must be an equilibrium (trim it first:
    :func:`shell.analysis.trim.trim`); see the module docstring."""
    drift = float(np.max(np.abs(model.operating_point["xdot"]), initial=0.0))
    if drift > equilibrium_tolerance:
        raise ValueError(f"small_signal_response: the operating point is not an equilibrium (largest state rate "
                         f"{drift:.3g} > {equilibrium_tolerance:g}); trim the scene (shell.analysis.trim.trim) "
                         "and linearize there")
    if input_name not in model.input_names or output_name not in model.output_names:
        raise ValueError(f"small_signal_response: {input_name!r} must be one of the model's inputs "
                         f"{model.input_names} and {output_name!r} one of its outputs {model.output_names}")
    op = model.operating_point
    k = model.input_names.index(input_name)
    w = 2.0 * np.pi * float(frequency_hz)
    n = model.A.shape[0]
    x_periodic = np.linalg.solve(1j * w * np.eye(n) - model.A, model.B[:, k])  # response to e^{j w t}
    xi0 = amplitude * x_periodic.imag                                          # to a sin(w t), at t = 0
    x_saved, signals_saved = sim.x.copy(), sim.signals.copy()
    states = TangentStates(sim, op["x"], {})
    ins = input_signals(sim, [input_name])
    outs = NamedSignals(sim, [output_name], "output")
    u0 = np.array([op["u"][k]])
    t0 = float(op["t"])
    try:
        evaluate = Evaluation(sim, states, ins, outs)
        context = sim.context

        def rhs(t, x):
            context.signals[ins.positions] = u0 + amplitude * np.sin(w * (t - t0))
            context.x[:] = x
            evaluate.derivatives_into(t)
            return context.xdot.copy()

        period = 2.0 * np.pi / w
        times = t0 + np.linspace(0.0, periods * period, periods * samples_per_period, endpoint=False)
        solution = solve_ivp(rhs, (t0, times[-1]), states.retract(xi0), method="DOP853", t_eval=times,
                             rtol=rtol, atol=atol)
        if not solution.success:
            raise RuntimeError(f"small_signal_response: integration failed: {solution.message}")
        y = np.empty(times.size)
        for i, (t, x) in enumerate(zip(times, solution.y.T)):
            context.signals[ins.positions] = u0 + amplitude * np.sin(w * (t - t0))
            context.x[:] = x
            evaluate.opened.evaluate(context, t, evaluate.stages)
            y[i] = outs.read(sim)[0]
    finally:
        sim.x[:] = x_saved
        sim.signals[:] = signals_saved
    phase = w * (times - t0)
    basis = np.column_stack([np.ones_like(phase), np.sin(phase), np.cos(phase)])
    coefficients = np.linalg.lstsq(basis, y, rcond=None)[0]
    return complex(coefficients[1], coefficients[2]) / amplitude

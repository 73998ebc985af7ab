"""Stability margins of a loop: gain, phase, delay and stability (distance to -1) margins, continuous or sampled,
SISO and per channel of a MIMO loop.

Conventions are python-control's ``stability_margins`` (and MATLAB's ``margin``/``allmargin``): ``L`` is the loop
transfer function of a loop closed by negative unity feedback, ``u = -y``; frequencies in rad/s; for a sampled
loop of period T, ``L(exp(j w T))`` for ``0 <= w <= pi / T``.

* phase crossovers: ``w >= 0`` where ``Im L = 0`` and ``Re L <= 0``; gain margin ``1 / |L|`` there; the gain
  margin reported is the one nearest 1 in log (the smallest factor, up or down, that destabilizes);
* gain crossovers: ``w > 0`` where ``|L| = 1``; phase margin ``angle(L) + 180 deg`` wrapped to [-180, 180); the
  one reported is the smallest in magnitude;
* delay margin (MATLAB's ``allmargin``; python-control has none): at each gain crossover the extra delay that
  puts ``L`` on -1, ``((PM mod 360 deg) in rad) / w``; the smallest is reported (seconds);
* stability margin: ``min |1 + L|`` over the frequencies (the radius of the largest disc about -1 that the
  Nyquist curve avoids; ``1 / ||S||_inf``, S the sensitivity).

Crossings are found as eigenvalues, then refined on the response itself, so none is missed between the points
of a grid and each is exact to round-off. ``|F| = rho`` on the imaginary axis holds where ``F(-s) F(s) - rho^2``
has a zero (``F(-j w) = conj F(j w)`` for a real system), ``Im F = 0`` where ``F(s) - F(-s)`` has one; for a
sampled system ``1/z`` replaces ``-s`` (``F(1/z) = conj F(z)`` on the unit circle). With ``F = (A, B, C, D)``,
these zeros are the finite generalized eigenvalues of pencils ``M - lambda N`` over ``[x1; x2; u]`` (x1 the
states of F(s), x2 those of F(-s) or F(1/z), u the input), written without inverting A::

    |F| = rho, continuous:  M = [[A, 0, B], [-B C, -A, -B D], [D C, C, D^2 - rho^2]],  N = diag(I, I, 0)
    |F| = rho, sampled:     M = [[A, 0, B], [0, I, 0], [D C, C, D^2 - rho^2]],  N = [[I, 0, 0], [B C, A, B D], 0]
    Im F = 0, continuous:   M = [[A, 0, B], [0, -A, -B], [C, -C, 0]],               N = diag(I, I, 0)
    Im F = 0, sampled:      M = [[A, 0, B], [0, I, 0], [C, -C, 0]],                N = [[I, 0, 0], [0, A, B], 0]

(the structured-pencil form of the Hamiltonian test of Boyd, Balakrishnan, Kabamba 1989, "A bisection method
for computing the H-infinity norm", Math. Control Signals Systems 2). Every eigenvalue within 1e-3 (relative)
of the axis or circle starts a Newton iteration on ``|F(w)| - rho`` or ``Im F(w)``, evaluated directly
(:class:`shell.linear.response.TransferEvaluator`, analytic derivative); a candidate is kept when the iteration
converges to a residual below 1e-10. The stability margin is found by the level-set iteration of Bruinsma and
Steinbuch (1990, "A fast algorithm to compute the H-infinity norm of a transfer function matrix", Systems &
Control Letters 14) on ``|1 + L|``: the level is lowered to the least value at the midpoints of the intervals
below it until no interval remains; the minimum is then solved as the zero of ``d|1 + L|^2/dw`` (Brent).

MIMO (:func:`channel_loops`): each (output, input) pair is a SISO loop with the other channels open, or, for a
square loop (output k fed back to input k), loop-at-a-time: channel k broken, the others closed with the same
feedback. Each channel says whether its loop, closed, is stable: with the others open, the poles of the pair's
minimal realization (an axis left uncontrolled is not this loop's instability); with the others closed, every
pole of the whole loop. A loop broken at a port of a scene, linearized from the port's input to the signal that drives it, is
closed by positive feedback (``u = +y``); its loop transfer function in the convention above is ``L = -G``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy.linalg import eigvals
from scipy.optimize import brentq

from shell.linear.realization import minimal_realization
from shell.linear.response import TransferEvaluator
from shell.linear.system import LinearSystem, LinearSystemError

FEEDBACK_SIGNS = {"negative": -1.0, "positive": 1.0}
#: relative distance from the imaginary axis (unit circle) within which an eigenvalue is a crossing candidate
CANDIDATE_TOLERANCE = 1e-3
#: relative residual below which a refined candidate is a crossing
CROSSING_TOLERANCE = 1e-10
#: relative step of the level in the stability-margin iteration
LEVEL_STEP = 1e-6
EPS = np.finfo(float).eps


@dataclass(frozen=True)
class Margins:
    """The margins of one SISO loop (module docstring for the definitions; frequencies in rad/s)."""

    gain_margin: float                 # factor (inf: no phase crossover)
    phase_margin: float                # deg (inf: no gain crossover)
    delay_margin: float                # s (inf: no gain crossover)
    stability_margin: float            # min |1 + L|
    phase_crossover: float             # rad/s of gain_margin (nan: none)
    gain_crossover: float              # rad/s of phase_margin (nan: none)
    delay_margin_frequency: float      # rad/s of delay_margin (nan: none)
    stability_margin_frequency: float  # rad/s of stability_margin (inf: approached at infinite frequency)
    phase_crossovers: np.ndarray       # every phase crossover, ascending, and its gain margin
    gain_margins: np.ndarray
    gain_crossovers: np.ndarray        # every gain crossover, ascending, its phase and delay margins
    phase_margins: np.ndarray
    delay_margins: np.ndarray
    sample_time: float | None = None

    @property
    def gain_margin_db(self) -> float:
        return 20.0 * math.log10(self.gain_margin) if self.gain_margin > 0 else -math.inf


def _gain_pencil(F: LinearSystem, level: float):
    A, B, C, D = F.A, F.B, F.C, F.D
    n = A.shape[0]
    Z, I = np.zeros((n, n)), np.eye(n)
    last = np.hstack([D @ C, C, D @ D - level ** 2])
    if F.discrete:
        M = np.block([[A, Z, B], [Z, I, np.zeros_like(B)], [last]])
        N = np.block([[I, Z, np.zeros_like(B)], [B @ C, A, B @ D], [np.zeros_like(last)]])
    else:
        M = np.block([[A, Z, B], [-B @ C, -A, -B @ D], [last]])
        N = np.block([[I, Z, np.zeros_like(B)], [Z, I, np.zeros_like(B)], [np.zeros_like(last)]])
    return M, N


def _phase_pencil(F: LinearSystem):
    A, B, C = F.A, F.B, F.C
    n = A.shape[0]
    Z, I = np.zeros((n, n)), np.eye(n)
    last = np.hstack([C, -C, np.zeros((1, 1))])
    if F.discrete:
        M = np.block([[A, Z, B], [Z, I, np.zeros_like(B)], [last]])
        N = np.block([[I, Z, np.zeros_like(B)], [Z, A, B], [np.zeros_like(last)]])
    else:
        M = np.block([[A, Z, B], [Z, -A, -B], [last]])
        N = np.block([[I, Z, np.zeros_like(B)], [Z, I, np.zeros_like(B)], [np.zeros_like(last)]])
    return M, N


def _candidates(M, N, F: LinearSystem) -> np.ndarray:
    """Frequencies (rad/s, >= 0) of the pencil's finite eigenvalues near the imaginary axis (unit circle)."""
    if M.shape[0] == 1:  # no states: the pencil is a number
        return np.zeros(0)
    alpha, beta = eigvals(M, N, homogeneous_eigvals=True)
    finite = np.abs(beta) > 1e3 * EPS * np.abs(alpha)
    lam = alpha[finite] / beta[finite]
    if F.discrete:
        near = np.abs(np.abs(lam) - 1.0) <= CANDIDATE_TOLERANCE
        return np.abs(np.angle(lam[near])) / F.sample_time
    near = np.abs(lam.real) <= CANDIDATE_TOLERANCE * np.abs(lam)
    return np.abs(lam[near].imag)


class _Loop:
    """A SISO system evaluated at frequencies, with the frequency range it lives on."""

    def __init__(self, system: LinearSystem):
        self.system = system
        self.evaluator = TransferEvaluator(system)
        self.upper = math.pi / system.sample_time if system.discrete else math.inf
        poles = system.poles()
        if system.discrete:
            self.scale = self.upper
        else:
            self.scale = float(np.max(np.abs(poles), initial=0.0)) or 1.0

    def at(self, omega: float) -> tuple[complex, complex]:
        G, dG = self.evaluator.response_and_derivative(omega)
        return complex(G[0, 0]), complex(dG[0, 0])

    def refine(self, omega: float, residual) -> float | None:
        """Newton on ``residual(F, dF) -> (value, slope, size)`` from ``omega``; the root, or None."""
        x = omega
        for _ in range(100):
            F, dF = self.at(x)
            if not (np.isfinite(F) and np.isfinite(dF)):
                return None
            value, slope, size = residual(F, dF)
            if slope == 0.0:
                break
            step = value / slope
            x_next = x - step
            if not 0.0 <= x_next <= self.upper:
                return None
            x = x_next
            if abs(step) <= 4.0 * EPS * max(x, 1e-300):
                break
        F, dF = self.at(x)
        value, _, size = residual(F, dF)
        if not (np.isfinite(value) and abs(value) <= CROSSING_TOLERANCE * size):
            return None
        # a crossing changes sign: not the asymptote of a pole at zero frequency, nor a touching point
        below, above = (residual(*self.at(x * (1.0 + d)))[0] for d in (-1e-6, 1e-6))
        return x if below * above < 0.0 else None

    def unique(self, roots) -> np.ndarray:
        roots = np.sort(np.asarray([r for r in roots if r is not None], dtype=float))
        keep = [r for k, r in enumerate(roots) if k == 0 or r - roots[k - 1] > 1e-9 * max(r, self.scale * 1e-6)]
        return np.asarray(keep, dtype=float)

    def level_crossings(self, level: float) -> np.ndarray:
        """Every frequency where ``|F| = level``, ascending."""
        def residual(F, dF):
            magnitude = abs(F)
            slope = (F.real * dF.real + F.imag * dF.imag) / magnitude if magnitude else 0.0
            return magnitude - level, slope, level

        roots = [self.refine(w, residual) for w in _candidates(*_gain_pencil(self.system, level), self.system)]
        return self.unique(r for r in roots if r is not None and r > 0.0)

    def phase_crossings(self) -> np.ndarray:
        """Every frequency where ``Im F = 0``, ascending; 0 (and pi/T when sampled) always are."""
        def residual(F, dF):
            return F.imag, dF.imag, max(abs(F), 1e-300)

        ends = [0.0] + ([self.upper] if self.system.discrete else [])
        inner = [self.refine(w, residual) for w in _candidates(*_phase_pencil(self.system), self.system)]
        inner = [r for r in inner if r is not None and 1e-9 * self.scale < r < self.upper * (1.0 - 1e-12)]
        return self.unique(ends + inner)


def _minimum_distance(loop: _Loop) -> tuple[float, float]:
    """(min |F|, its frequency) of ``loop``'s system F = 1 + L (module docstring: level sets, then Brent)."""
    system = loop.system
    poles = system.poles()
    if system.discrete:  # the poles' angles, and a few frequencies that are none (the poles may all be at 0)
        tests = [0.0, loop.upper, *np.abs(np.angle(poles)) / system.sample_time,
                 *loop.upper * np.array([0.01, 0.1, 0.5])]
    else:
        tests = [0.0, *np.abs(poles.imag), *np.abs(poles), *loop.scale * np.logspace(-3, 3, 7)]
    values = [abs(loop.at(w)[0]) for w in tests]
    best_value, best_frequency = min((v, w) for v, w in zip(values, tests) if np.isfinite(v))
    if not system.discrete and abs(system.D[0, 0]) < best_value:
        best_value, best_frequency = abs(system.D[0, 0]), math.inf
    for _ in range(60):
        level = best_value * (1.0 - LEVEL_STEP)
        if level <= 0.0:
            return 0.0, best_frequency
        edges = [0.0, *loop.level_crossings(level), loop.upper]
        probes = [0.5 * (a + b) for a, b in zip(edges[:-1], edges[1:]) if math.isfinite(b)]
        if not system.discrete and len(edges) > 2:
            probes.append(2.0 * edges[-2])
        lower = [(abs(loop.at(w)[0]), w) for w in probes]
        lower = [(v, w) for v, w in lower if v < level]
        if not lower:
            break
        best_value, best_frequency = min(lower)
    if best_frequency in (0.0, loop.upper):
        return best_value, best_frequency
    return _refine_minimum(loop, best_value, best_frequency)


def _refine_minimum(loop: _Loop, value: float, omega: float) -> tuple[float, float]:
    """The zero of d|F|^2/dw next to ``omega`` (Brent on a bracket widened until the slope changes sign)."""
    def slope(w):
        F, dF = loop.at(w)
        return F.real * dF.real + F.imag * dF.imag

    width = 1e-5 * omega
    for _ in range(60):
        a, b = max(omega - width, 0.0), min(omega + width, loop.upper)
        if slope(a) <= 0.0 <= slope(b):
            break
        width *= 2.0
    else:
        return value, omega
    if a == 0.0 and slope(a) == 0.0:
        return abs(loop.at(0.0)[0]), 0.0
    root = brentq(slope, a, b, xtol=1e-300, rtol=4.0 * EPS, maxiter=200)
    found = abs(loop.at(root)[0])
    return (found, root) if found <= value else (value, omega)


def stability_margins(L: LinearSystem) -> Margins:
    """The margins of the SISO loop transfer function ``L`` (module docstring)."""
    if L.shape[1:] != (1, 1):
        raise LinearSystemError(f"{L.where}: margins need a SISO loop (1 input, 1 output), given {L.shape[1]} "
                                f"inputs and {L.shape[2]} outputs; pick a channel (channel_loops)")
    loop = _Loop(L)
    phase_crossovers = loop.phase_crossings()
    responses = np.array([loop.at(w)[0] for w in phase_crossovers])
    negative = np.isfinite(responses) & (responses.real <= 0.0)
    phase_crossovers, responses = phase_crossovers[negative], responses[negative]
    with np.errstate(divide="ignore"):
        gain_margins = 1.0 / np.abs(responses)
    gain_crossovers = loop.level_crossings(1.0)
    angles = np.degrees(np.angle([loop.at(w)[0] for w in gain_crossovers]))
    phase_margins = np.remainder(angles, 360.0) - 180.0
    delay_margins = np.radians(np.remainder(phase_margins, 360.0)) / gain_crossovers
    distance = _Loop(LinearSystem(L.A, L.B, L.C, L.D + 1.0, L.sample_time, where=L.where))
    stability_margin, stability_frequency = _minimum_distance(distance)
    if gain_margins.size and np.isfinite(gain_margins).any():
        with np.errstate(divide="ignore"):
            k = int(np.argmin(np.abs(np.log(gain_margins))))
        gain_margin, phase_crossover = float(gain_margins[k]), float(phase_crossovers[k])
    else:
        gain_margin, phase_crossover = math.inf, math.nan
    if gain_crossovers.size:
        k, d = int(np.argmin(np.abs(phase_margins))), int(np.argmin(delay_margins))
        phase_margin, gain_crossover = float(phase_margins[k]), float(gain_crossovers[k])
        delay_margin, delay_frequency = float(delay_margins[d]), float(gain_crossovers[d])
    else:
        phase_margin, gain_crossover, delay_margin, delay_frequency = math.inf, math.nan, math.inf, math.nan
    return Margins(gain_margin, phase_margin, delay_margin, stability_margin, phase_crossover, gain_crossover,
                   delay_frequency, stability_frequency, phase_crossovers, gain_margins, gain_crossovers,
                   phase_margins, delay_margins, L.sample_time)


@dataclass(frozen=True)
class LoopChannel:
    """One channel of a loop: its loop transfer function ``loop`` (negative-feedback convention), whether the
    loop closed as described is stable, and its margins."""

    output: str
    input: str
    loop: LinearSystem
    closed_loop_stable: bool
    margins: Margins


def _closed(system: LinearSystem, sign: float) -> np.ndarray:
    """A of ``system`` with every output fed back to the input of the same index, ``u = sign y``."""
    m = system.D.shape[0]
    algebraic = np.eye(m) - sign * system.D
    if np.linalg.cond(algebraic) > 1e12:
        raise LinearSystemError(f"{system.where}: I - ({sign:+g}) D is singular: the loop closed through D alone "
                                "has no solution (an ill-posed algebraic loop)")
    return system.A + sign * system.B @ np.linalg.solve(algebraic, system.C)


def _loop_at_a_time(system: LinearSystem, k: int, sign: float) -> LinearSystem:
    """Channel k of a square loop with the other channels closed (u_o = sign y_o), as seen from u_k to y_k."""
    others = [i for i in range(system.D.shape[0]) if i != k]
    A, B, C, D = system.A, system.B, system.C, system.D
    Bk, Bo, Ck, Co = B[:, [k]], B[:, others], C[[k]], C[others]
    Dkk, Dko, Dok, Doo = D[np.ix_([k], [k])], D[np.ix_([k], others)], D[np.ix_(others, [k])], D[np.ix_(others, others)]
    E = np.linalg.solve(np.eye(len(others)) - sign * Doo, np.hstack([Co, Dok]))  # y_o = E [x; u_k]
    Ex, Eu = E[:, :A.shape[0]], E[:, A.shape[0]:]
    return LinearSystem(A + sign * Bo @ Ex, Bk + sign * Bo @ Eu, Ck + sign * Dko @ Ex, Dkk + sign * Dko @ Eu,
                        system.sample_time, (system.input_names[k],), (system.output_names[k],),
                        where=system.where)


def channel_loops(system: LinearSystem, feedback: str = "negative", others: str = "open") -> list[LoopChannel]:
    """The channels of ``system`` as loops (module docstring), with their margins. ``feedback``: "negative"
    (``u = -y``: ``system`` is the loop transfer function) or "positive" (``u = +y``: a loop broken at a port).
    ``others``: "open" (every (output, input) pair, the other channels open) or "closed" (a square system:
    output k fed back to input k, channel k broken and the others closed)."""
    if feedback not in FEEDBACK_SIGNS:
        raise LinearSystemError(f"feedback: expected one of {', '.join(FEEDBACK_SIGNS)}, given {feedback!r}")
    sign = FEEDBACK_SIGNS[feedback]
    channels = []
    if others == "closed":
        n_in, n_out = system.B.shape[1], system.C.shape[0]
        if n_in != n_out:
            raise LinearSystemError(f"{system.where}: loop-at-a-time margins need as many outputs as inputs (output "
                                    f"k fed back to input k), given {n_out} outputs and {n_in} inputs")
        closed_stable = LinearSystem(_closed(system, sign), system.B, system.C, system.D, system.sample_time,
                                     where=system.where).is_stable()
        for k in range(n_in):
            G = _loop_at_a_time(system, k, sign)
            L = LinearSystem(G.A, G.B, -sign * G.C, -sign * G.D, G.sample_time, G.input_names, G.output_names,
                             where=G.where)
            channels.append(LoopChannel(G.output_names[0], G.input_names[0], L, closed_stable,
                                        stability_margins(L)))
        return channels
    if others != "open":
        raise LinearSystemError(f"others: expected open or closed, given {others!r}")
    for i in range(system.C.shape[0]):
        for j in range(system.B.shape[1]):
            G = system.select([j], [i])
            L = LinearSystem(G.A, G.B, -sign * G.C, -sign * G.D, G.sample_time, G.input_names, G.output_names,
                             where=G.where)
            seen = minimal_realization(G)  # the other channels' modes are not this loop's business
            stable = LinearSystem(_closed(seen, sign), seen.B, seen.C, seen.D, G.sample_time, where=G.where).is_stable()
            channels.append(LoopChannel(G.output_names[0], G.input_names[0], L, stable, stability_margins(L)))
    return channels

"""Stability margins (shell/analysis/margins.py) against python-control's stability_margins, analytic delay
margins, and dense-grid counts of the crossings.

python-control (0.10, no slycot) finds crossings as roots of polynomials in w (z for a sampled loop): exact for
the low-order loops used here (it agrees with our eigenvalue-and-Newton crossings to a few 1e-15; tolerance 1e-9,
the issue's). For a sampled loop it finds the stability margin's frequency by scipy's L-BFGS-B minimization from
a grid, which stops at about 1e-8 in frequency (measured 6e-9, 1e-8): that one number is compared to 1e-6 and
ours is checked to be a stationary point of |1 + L| instead. Where the infimum of |1 + L| is reached only at
infinite frequency (|1 + D|), python-control reports its least finite local minimum and we the infimum; the loops
here have a finite minimum.
"""

from __future__ import annotations

import math

import control
import numpy as np
import pytest

from shell.analysis.margins import channel_loops, stability_margins
from shell.linear.response import TransferEvaluator
from shell.linear.system import LinearSystem, LinearSystemError
from tests.linearize.loops import attitude_loop

s = control.tf("s")
CONTINUOUS = {
    "type_1_third_order": 50 / (s * (s + 1) * (s + 10)),
    "three_lags": 10 / (s + 1) ** 3,
    "non_minimum_phase": 3 * (-s + 2) / (s * (s + 1) * (s + 3)),
    "lightly_damped_mode": 0.5 * (s ** 2 + 0.04 * s + 1) / (s * (s + 0.3) * (s ** 2 + 0.02 * s + 0.8)),
    "no_phase_crossover": 20 * (s + 0.5) ** 2 / (s ** 2 * (s + 5) * (s + 10)),
    "lead_lag_high_order": 1000 * (s + 1) ** 2 / (s * (s + 0.1) * (s + 10) * (s + 20) * (s + 50)),
    "resonance_near_crossover": 3.2 * (s ** 2 + 0.02 * s + 25) / ((s + 1) ** 2 * (s ** 2 + 0.01 * s + 30)),
}
#: |1 + L| reaches its infimum 1 only at infinite frequency (L ~ 4.5 j / w^3): python-control reports its least
#: finite local minimum instead (1.0375), so this loop is compared with it on the gain and phase margins only
FLEXIBLE = {"mode_above_crossover": 0.5 * (s + 0.2) / s ** 2 / (s ** 2 / 9 + 0.01 * s / 3 + 1)}
SAMPLED = {
    "second_order_z": control.tf([0.2, 0.1], [1, -1.4, 0.45], 0.1),
    "tustin_of_a_resonant_plant": control.c2d(3 * (s + 2) / ((s + 1) * (s ** 2 + 0.4 * s + 4)), 0.2, "tustin"),
}
TOLERANCE = 1e-9


def _ours(loop) -> LinearSystem:
    ss = control.ss(loop)
    return LinearSystem(ss.A, ss.B, ss.C, ss.D, ss.dt if ss.dt else None)


def _same(ours, theirs, tolerance):
    if not math.isfinite(theirs):
        return (math.isnan(ours) and math.isnan(theirs)) or ours == theirs
    return abs(ours - theirs) <= tolerance * max(abs(theirs), 1e-300)


@pytest.mark.parametrize("name", CONTINUOUS)
def test_continuous_margins_equal_python_control(name):
    margins = stability_margins(_ours(CONTINUOUS[name]))
    gm, pm, sm, wpc, wgc, wms = control.stability_margins(CONTINUOUS[name])
    ours = (margins.gain_margin, margins.phase_margin, margins.stability_margin, margins.phase_crossover,
            margins.gain_crossover, margins.stability_margin_frequency)
    for label, a, b in zip(("gm", "pm", "sm", "wpc", "wgc", "wms"), ours, (gm, pm, sm, wpc, wgc, wms)):
        assert _same(a, float(b), TOLERANCE), (label, a, b)


@pytest.mark.parametrize("name", SAMPLED)
def test_sampled_margins_equal_python_control(name):
    loop = SAMPLED[name]
    margins = stability_margins(_ours(loop))
    gm, pm, sm, wpc, wgc, wms = control.stability_margins(loop)
    ours = (margins.gain_margin, margins.phase_margin, margins.stability_margin, margins.phase_crossover,
            margins.gain_crossover)
    for label, a, b in zip(("gm", "pm", "sm", "wpc", "wgc"), ours, (gm, pm, sm, wpc, wgc)):
        assert _same(a, float(b), TOLERANCE), (label, a, b)
    assert _same(margins.stability_margin_frequency, float(wms), 1e-6)
    evaluator = TransferEvaluator(LinearSystem(*(getattr(control.ss(loop), k) for k in "ABC"),
                                               control.ss(loop).D + 1.0, loop.dt))
    F, dF = evaluator.response_and_derivative(margins.stability_margin_frequency)
    assert abs((np.conj(F) * dF).real[0, 0]) <= 1e-12 * abs(F[0, 0]) * abs(dF[0, 0])


def _crossings_on_a_grid(evaluate, upper):
    """Sign changes of |L| - 1 and of Im L on a dense log grid (10^5 points over 7 decades)."""
    omega = np.geomspace(1e-4, min(upper * (1 - 1e-3), 1e3), 100_000)  # short of a zero at z = -1 (Tustin)
    L = evaluate(omega)
    gain = np.count_nonzero(np.diff(np.sign(np.abs(L) - 1.0)))
    phase = np.flatnonzero(np.diff(np.sign(L.imag)))
    return gain, int(np.count_nonzero(L.real[phase] < 0))


@pytest.mark.parametrize("name", [*CONTINUOUS, *FLEXIBLE, *SAMPLED])
def test_every_crossing_is_found_and_exact(name):
    """Each crossing solves its equation to round-off (|L| = 1, Im L = 0), and there are as many as sign changes
    on a dense grid (the eigenvalue test misses none, Newton invents none)."""
    loop = {**CONTINUOUS, **FLEXIBLE, **SAMPLED}[name]
    system = _ours(loop)
    margins = stability_margins(system)
    evaluator = TransferEvaluator(system)
    L = evaluator.response(margins.gain_crossovers)[0, 0]
    np.testing.assert_allclose(np.abs(L), 1.0, rtol=0, atol=1e-13)
    inner = margins.phase_crossovers[margins.phase_crossovers > 0]
    if system.discrete:
        inner = inner[inner < math.pi / system.sample_time]
    L = evaluator.response(inner)[0, 0]
    assert np.all(np.abs(L.imag) <= 1e-13 * np.abs(L)) and np.all(L.real <= 0)
    gain, phase = _crossings_on_a_grid(lambda w: evaluator.response(w)[0, 0],
                                       math.pi / system.sample_time if system.discrete else math.inf)
    assert margins.gain_crossovers.size == gain
    assert inner.size == phase


def test_a_flexible_mode_above_crossover_adds_two_gain_crossovers():
    """0.5 (s + 0.2) / s^2 with a 3 rad/s mode of damping 0.005 peaking at about 17 above the rigid crossover:
    three gain crossovers, three delay margins, the smallest at a crossover of the mode."""
    loop = FLEXIBLE["mode_above_crossover"]
    margins = stability_margins(_ours(loop))
    assert margins.gain_crossovers.size == 3 and margins.delay_margins.size == 3
    assert margins.delay_margin_frequency == margins.gain_crossovers[1]
    gm, pm, sm, wpc, wgc, wms = control.stability_margins(loop)
    for a, b in zip((margins.gain_margin, margins.phase_margin, margins.phase_crossover, margins.gain_crossover),
                    (gm, pm, wpc, wgc)):
        assert _same(a, float(b), TOLERANCE)
    assert margins.stability_margin == 1.0 and margins.stability_margin_frequency == math.inf


@pytest.mark.parametrize("gain", [0.5, 2.0, 40.0])
def test_delay_margin_of_an_integrator_is_analytic(gain):
    """L = k/s: |L| = 1 at w = k, phase margin 90 deg, delay margin (pi / 2) / k."""
    margins = stability_margins(LinearSystem([[0.0]], [[1.0]], [[gain]], [[0.0]]))
    assert abs(margins.gain_crossover - gain) <= 1e-14 * gain
    assert abs(margins.phase_margin - 90.0) <= 1e-12
    assert abs(margins.delay_margin - math.pi / (2 * gain)) <= 1e-14 / gain


def test_delay_margin_of_a_type_1_second_order_loop_is_analytic():
    """L = K / (s (s + a)): w_c^2 = (sqrt(a^4 + 4 K^2) - a^2) / 2, PM = 90 deg - atan(w_c / a), DM = PM / w_c."""
    K, a = 7.0, 1.5
    margins = stability_margins(_ours(K / (s * (s + a))))
    wc = math.sqrt((math.sqrt(a ** 4 + 4 * K * K) - a * a) / 2)
    pm = math.pi / 2 - math.atan(wc / a)
    assert abs(margins.gain_crossover - wc) <= 1e-13 * wc
    assert abs(math.radians(margins.phase_margin) - pm) <= 1e-13
    assert abs(margins.delay_margin - pm / wc) <= 1e-13 * pm / wc


@pytest.mark.parametrize("name", [*CONTINUOUS, *FLEXIBLE, *SAMPLED])
def test_delay_margin_puts_the_loop_on_minus_one(name):
    """L(w_d) e^(-j w_d DM) = -1 at the delay margin's crossover, and no crossover needs less delay."""
    system = _ours({**CONTINUOUS, **FLEXIBLE, **SAMPLED}[name])
    margins = stability_margins(system)
    w = margins.delay_margin_frequency
    L = TransferEvaluator(system).response([w])[0, 0, 0]
    assert abs(L * np.exp(-1j * w * margins.delay_margin) + 1.0) <= 1e-12
    assert margins.delay_margin == min(margins.delay_margins)


@pytest.mark.parametrize("feedback, sign", [("negative", -1), ("positive", 1)])
def test_loop_at_a_time_equals_python_control_feedback(feedback, sign):
    """Channel k broken, the other closed: python-control's feedback(G, K) with K the other channel's unit gain
    gives the same loop (response to 1e-12) and stability_margins the same margins (1e-9). The negative case
    is the same loop written as -G."""
    A, B, C, D = attitude_loop()
    C = C if feedback == "positive" else -C
    system = LinearSystem(A, B, C, D, input_names=("t0", "t1"), output_names=("c0", "c1"))
    plant = control.ss(A, B, C, D)
    channels = channel_loops(system, feedback, "closed")
    omega = np.geomspace(0.01, 100, 50)
    closed_all = control.feedback(plant, np.eye(2), sign=sign)
    for k, channel in enumerate(channels):
        K = np.zeros((2, 2))
        K[1 - k, 1 - k] = 1.0
        L = -sign * control.feedback(plant, K, sign=sign)[k, k]
        np.testing.assert_allclose(TransferEvaluator(channel.loop).response(omega)[0, 0],
                                   L.frequency_response(omega).complex, rtol=1e-12)
        gm, pm, sm, wpc, wgc, wms = control.stability_margins(L)
        m = channel.margins
        for a, b in zip((m.gain_margin, m.phase_margin, m.stability_margin, m.phase_crossover, m.gain_crossover,
                         m.stability_margin_frequency), (gm, pm, sm, wpc, wgc, wms)):
            assert math.isfinite(b) and _same(a, float(b), TOLERANCE), (feedback, k, a, b)
        assert (channel.output, channel.input) == (f"c{k}", f"t{k}")
        assert channel.closed_loop_stable == bool(np.all(closed_all.poles().real < 0))
    assert channels[0].margins.gain_margin != channels[1].margins.gain_margin


@pytest.mark.filterwarnings("ignore:invalid value encountered:RuntimeWarning")  # python-control at w = 0 (1/s^2)
def test_open_channels_are_every_pair_and_positive_feedback_negates():
    A, B, C, D = attitude_loop()
    system = LinearSystem(A, B, C, D)
    channels = channel_loops(system, "positive", "open")
    assert [(c.output, c.input) for c in channels] == [("y[0]", "u[0]"), ("y[0]", "u[1]"), ("y[1]", "u[0]"),
                                                        ("y[1]", "u[1]")]
    for channel, (i, j) in zip(channels, [(0, 0), (0, 1), (1, 0), (1, 1)]):
        L = -control.ss(A, B[:, [j]], C[[i]], D[i, j])
        gm, pm, *_ = control.stability_margins(L)
        assert _same(channel.margins.gain_margin, float(gm), TOLERANCE)
        assert _same(channel.margins.phase_margin, float(pm), TOLERANCE)


def test_refusals():
    A, B, C, D = attitude_loop()
    with pytest.raises(LinearSystemError, match="margins need a SISO loop"):
        stability_margins(LinearSystem(A, B, C, D))
    with pytest.raises(LinearSystemError, match="as many outputs as inputs"):
        channel_loops(LinearSystem(A, B, C[:1], D[:1]), "negative", "closed")
    with pytest.raises(LinearSystemError, match="feedback: expected one of negative, positive"):
        channel_loops(LinearSystem(A, B, C, D), "unity")
    with pytest.raises(LinearSystemError, match="ill-posed algebraic loop"):
        channel_loops(LinearSystem([[-1.0]], [[1.0]], [[1.0]], [[1.0]]), "positive")

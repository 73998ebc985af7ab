"""The LQR workflow example (configs/lqr_plant.yaml, configs/lqr_closed_loop.yaml,
configs/lqr_data/design_lqr.py): linearize the flexible spacecraft, design a discrete LQR, and check
that the committed gain files are that design and that the nonlinear sampled closed loop follows the
linear discrete closed-loop prediction (5 deg initial bus angle: the neglected terms are second order,
measured 9.5e-6 deg over 60 s; tolerance 1e-4 deg over 15 s)."""

from __future__ import annotations

import importlib.util
from pathlib import Path

import numpy as np

from shell.analysis.system_modes import state_space_modes

REPO = Path(__file__).resolve().parents[2]


def load_design():
    spec = importlib.util.spec_from_file_location("design_lqr", REPO / "configs/lqr_data/design_lqr.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def test_lqr_design_and_nonlinear_closed_loop(monkeypatch):
    monkeypatch.chdir(REPO)  # the scenario's gain files are relative to the repository root
    design = load_design()
    model = design.linear_plant()
    modes = state_space_modes(model.A)
    # the array's in-plane bending couples with the bus rotation (0.199 -> 0.579 Hz, 1.245 -> 1.636 Hz);
    # out-of-plane modes keep the cantilever frequencies and the file's 0.5 % damping
    np.testing.assert_allclose(modes.frequencies_hz[[0, 2]], [0.09960184, 0.62243177], rtol=1e-6)
    np.testing.assert_allclose(modes.damping_ratios[[0, 2]], 0.005, rtol=1e-6)
    K, Ad, Bd = design.design(model)
    nq = model.A.shape[0] // 2
    np.testing.assert_allclose(np.loadtxt(REPO / "configs/lqr_data/gain_position.csv", delimiter=",", ndmin=2),
                               K[:, :nq], rtol=1e-6, atol=1e-6 * np.max(np.abs(K)))
    np.testing.assert_allclose(np.loadtxt(REPO / "configs/lqr_data/gain_rate.csv", delimiter=",")[2],
                               K[0, nq:], rtol=1e-6, atol=1e-6 * np.max(np.abs(K)))
    assert np.max(np.abs(np.linalg.eigvals(Ad - Bd @ K))) < 1.0
    times, angle, predicted = design.closed_loop(K, Ad, Bd, t_final=15.0)
    assert np.rad2deg(np.max(np.abs(angle - predicted))) < 1e-4
    assert abs(np.rad2deg(angle[-1])) < 1.0  # regulated from 5 deg

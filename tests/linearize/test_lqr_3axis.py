"""Issue 30's must-show: the 3-axis flexible spacecraft's LQR closed in YAML (configs/gallery/13_lqr_3axis.yaml,
configs/lqr_data/design_lqr_3axis.py).

``flexshell linearize`` of configs/lqr_3axis_plant.yaml, python-control's ``dlqr`` on the zero-order-hold model
(translation states given zero gain): the shipped plant file and gain are that design (A to 1e-9 of its largest
entry: the finite differences are deterministic; K to 1e-6 relative, the bound of the single-axis example's
test). The loop closed through ``LinearizedState`` and ``LqrStateFeedback`` runs compiled, and its logged
command follows the linear discrete prediction ``u_k = -K x_k``, ``x_{k+1} = (Ad - Bd K) x_k`` from the
0.5 deg skew-axis error within 2e-3 of the command's peak over 20 s (measured 2.2e-4 over 60 s: the plant's
second-order terms at 0.5 deg).
"""

from __future__ import annotations

import importlib.util
from pathlib import Path

import numpy as np
import pytest

from shell.analysis.linear_model_file import read_linear_model

REPO = Path(__file__).resolve().parents[2]


def load_design():
    spec = importlib.util.spec_from_file_location("design_lqr_3axis", REPO / "configs/lqr_data/design_lqr_3axis.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def test_lqr_designed_on_the_exported_model_closes_in_yaml(monkeypatch, tmp_path):
    pytest.importorskip("control")
    monkeypatch.chdir(REPO)  # the scene's model and gain files are relative to the repository root
    design = load_design()
    model, _ = design.linear_plant(tmp_path)
    shipped = read_linear_model(REPO / "configs/lqr_data/lqr_3axis_plant.h5")
    assert model.state_names == shipped.state_names
    np.testing.assert_allclose(shipped.A, model.A, rtol=0, atol=1e-9 * np.max(np.abs(model.A)))
    K, Ad, Bd = design.design(model)
    gain = np.loadtxt(REPO / "configs/lqr_data/gain_3axis.csv", delimiter=",", ndmin=2)
    np.testing.assert_allclose(gain, K, rtol=1e-6, atol=1e-6 * np.max(np.abs(K)))
    assert not np.any(gain[:, design.translation_states(model)])
    poles = np.linalg.eigvals(Ad - Bd @ K)
    assert np.max(np.abs(poles[np.abs(poles - 1.0) > 1e-9])) < 1.0  # all but the translation's unit poles

    times, command, predicted = design.closed_loop(K, Ad, Bd, design.initial_error(model), t_final=20.0,
                                                   log=tmp_path / "loop.h5")
    assert times.size == 201 and np.allclose(times, 0.1 * np.arange(201), atol=1e-12)
    peak = np.max(np.abs(predicted))
    assert peak > 30.0  # N m: the loop really acts
    assert np.max(np.abs(command - predicted)) < 2e-3 * peak


def test_observer_based_design_closes_in_yaml_as_a_state_space_block(monkeypatch, tmp_path):
    """The LQG compensator (Kalman predictor from the measured bus rotation vector and rate, the LQR gain on its
    estimate) as one sampled StateSpace block (configs/lqg_3axis.yaml, configs/lqr_data/lqg_3axis.npz): the
    shipped matrices are the design (1e-6 relative), and the logged torque follows the linear closed loop of plant
    and compensator within 2e-3 of its peak over 20 s (measured 1.0e-3 over 60 s)."""
    pytest.importorskip("control")
    monkeypatch.chdir(REPO)
    design = load_design()
    model = read_linear_model(REPO / "configs/lqr_data/lqr_3axis_plant.h5")
    K, Ad, Bd = design.design(model)
    compensator = design.lqg_compensator(model, K, Ad, Bd)
    with np.load(REPO / "configs/lqr_data/lqg_3axis.npz") as shipped:
        for key, matrix in zip("ABCD", compensator):
            np.testing.assert_allclose(shipped[key], matrix, rtol=1e-6, atol=1e-6 * max(np.max(np.abs(matrix)), 1e-300))
        assert float(shipped["sample_time"]) == design.PERIOD
    assert np.max(np.abs(np.linalg.eigvals(compensator[0]))) < 1.0  # the scene asks require_stable: true
    times, torque, predicted = design.lqg_closed_loop(compensator, Ad, Bd, design.initial_error(model), t_final=20.0,
                                                      log=tmp_path / "lqg.h5")
    peak = np.max(np.abs(predicted))
    assert peak > 10.0
    assert np.max(np.abs(torque - predicted)) < 2e-3 * peak

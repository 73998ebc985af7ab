"""Issue 30's must-show: gallery scene 10 with every mode to 100 Hz kept, stabilized by a notch filter designed
from the Bode plot (configs/gallery/14_spacecraft_notch.yaml).

The spacecraft deck through ``flexshell fem2modal`` (20 modes), then:

* ``flexshell bode`` of the plant linearized by ``flexshell linearize`` from the torque at the actuated grid to
  its rate: the z channel peaks at the 26.05 Hz local panel mode the scene's notch is set to (within the
  plot's frequency grid, 0.05 Hz);
* the sampled closed loop (the plant and the scene's continuous notch linearized together, discretized with a
  zero-order hold at the controller's 10 Hz, closed with the PD law ``tau = -kp 2 vec(q) - kd w_filtered``),
  computed here from the linear model: spectral radius 1.77 with the rate fed back directly (diverges, as the
  tutorial reports), 0.98941 through the notch (the rigid loop's slowest pole: the same as with the modes cut
  at 10 Hz, to 1e-4), and above 1 with a notch gain of 0.1 (the design's gain 0.02 is not marginal). The unit
  eigenvalues of the free translation (no feedback) are left out.
"""

from __future__ import annotations

import csv
from pathlib import Path

import numpy as np
import pytest
from scipy.linalg import expm

from shell.analysis.linearize import linearize
from shell.cli import main
from shell.scenario import build_simulation, load_scenario

REPO = Path(__file__).resolve().parents[2]
SCENE = REPO / "configs/gallery/14_spacecraft_notch.yaml"
KP, KD, PERIOD = 4.0, 40.0, 0.1


@pytest.fixture(scope="module")
def body(tmp_path_factory):
    directory = tmp_path_factory.mktemp("spacecraft")
    path = directory / "spacecraft.h5"
    assert main(["fem2modal", str(REPO / "configs/fem/spacecraft.dat"), "--modes", "20", "--modal-integrals",
                 "--damping", "0.005", "-o", str(path)]) == 0
    return path


def _overrides(body, *more):
    return [f"multibody.spacecraft.body_file={body}", "controller.parameters.attitude_command=[1, 0, 0, 0]", *more]


def test_the_bode_plot_shows_the_mode_the_notch_is_set_to(body, tmp_path):
    sets = [item for o in _overrides(body) for item in ("--set", o)]
    assert main(["linearize", str(SCENE), "--inputs", "multibody.bus_top.torque", "--outputs",
                 "multibody.bus_top.angular_velocity", "-o", str(tmp_path / "plant.h5"), *sets]) == 0
    assert main(["bode", str(tmp_path / "plant.h5"), "--inputs", "multibody.bus_top.torque[2]", "--outputs",
                 "multibody.bus_top.angular_velocity[2]", "--frequencies", "10,50", "--points", "2000", "-o",
                 str(tmp_path / "z")]) == 0
    with open(tmp_path / "z_response.csv") as f:
        rows = list(csv.DictReader(f))
    peak = max(rows, key=lambda row: float(row["magnitude_db"]))
    assert abs(float(peak["frequency_hz"]) - 26.05) < 0.05 and float(peak["magnitude_db"]) > 15.0


def _spectral_radius(body, rate_signal, *more):
    """Spectral radius of the 10 Hz sampled PD loop on the linearized scene (translation's unit poles aside)."""
    simulation = build_simulation(load_scenario(SCENE, _overrides(body, *more)))
    model = linearize(simulation, ["multibody.bus_top.torque"], ["multibody.bus_top.attitude", rate_signal],
                      tolerance=1e-8, points=2)
    assert np.max(np.abs(model.D)) < 1e-9  # torque reaches neither attitude nor rate within an instant
    n = model.A.shape[0]
    augmented = np.zeros((n + 3, n + 3))
    augmented[:n, :n], augmented[:n, n:] = model.A, model.B
    E = expm(augmented * PERIOD)
    gain = KP * 2.0 * model.C[1:4] + KD * model.C[4:7]  # e = 2 vec(q) about the identity, the rate as fed back
    poles = np.linalg.eigvals(E[:n, :n] - E[:n, n:] @ gain)
    return float(np.max(np.abs(poles[np.abs(poles - 1.0) > 1e-9])))


def test_the_notch_stabilizes_the_sampled_loop(body):
    direct = _spectral_radius(body, "multibody.bus_top.angular_velocity")
    notched = _spectral_radius(body, "notch.y")
    shallow = _spectral_radius(body, "notch.y", "notch.config.notch_gain=0.1")
    cut = _spectral_radius(body, "multibody.bus_top.angular_velocity", "multibody.spacecraft.max_frequency=10 Hz")
    assert direct == pytest.approx(1.77, abs=0.01)
    assert notched < 1.0 and notched == pytest.approx(cut, abs=1e-4) and cut == pytest.approx(0.98941, abs=1e-4)
    assert shallow > 1.0

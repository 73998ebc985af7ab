"""Why gallery scene 10 diverges with its modes to 100 Hz (an issue 14 finding): sampled-data spillover.

configs/gallery/10_spacecraft_from_deck.yaml closes a 10 Hz PD loop (kp 4 N m/rad, kd 40 N m s/rad, zero-
order hold) on the attitude and rate of one shell grid of the bus (grid 38), and applies the torque at that
grid. With the modes up to 10 Hz it slews; with the modes up to 100 Hz it diverges within a second. Checked
here, through the user's path (fem2modal, the scene's YAML, `flexshell linearize`), independently of the
time integration: the linearized plant from the node torque to the node attitude and rate, discretized at
10 Hz (zero-order hold, ``expm`` of the augmented matrix), closed with the controller's law
``tau = -kp 2 q_vec - kd omega`` (its linearization about the identity command):

* modes to 100 Hz: spectral radius > 1.5 (growth by 1.77 per sample: divergence within a second; 2.55
  with the shells' former drilling penalty, see the next item);
* modes to 10 Hz: no eigenvalue outside the unit circle (1e-7: the rigid translations' unit eigenvalues);
* the continuous PD on either plant: no eigenvalue in the right half-plane (1e-9: passivity of a
  collocated rate feedback), so the instability is the sampling's;
* the mode that does it: the 26.0 Hz local panel mode (16.5 Hz with the shells' former drilling penalty
  1e-4 G t; the penalty on these panels is now 2.7 - 3.3 times that, and the frequency rose by 1.58, about
  its square root: the grid's rotation about the panel normal carries it, docs/fem2modal.md "Drilling
  penalty"), rate/torque
  residue at grid 38 above 5 (an
  effective inertia of ~0.1 kg m^2), against below 0.01 for every mode below 10 Hz.
"""

from __future__ import annotations

import warnings
from pathlib import Path

import numpy as np
from scipy.linalg import expm

from shell.analysis.linear_model_file import read_linear_model
from shell.cli import main

REPO = Path(__file__).resolve().parents[2]
T, KP, KD = 0.1, 4.0, 40.0


def _plant_yaml(tmp_path, body_file, max_frequency):
    text = (REPO / "configs" / "gallery" / "10_spacecraft_from_deck.yaml").read_text()
    text = text.replace("body_file: spacecraft.h5", f"body_file: {body_file}")
    assert "max_frequency: 10 Hz" in text
    text = text.replace("max_frequency: 10 Hz", f"max_frequency: {max_frequency}")
    text = text[:text.index("models:")] + text[text.index("integrator:"):]   # open loop
    text = text.replace("    - controller.torque\n", "")
    path = tmp_path / f"plant_{max_frequency.replace(' ', '')}.yaml"
    path.write_text(text)
    return path


def _linearize(tmp_path, scene):
    out = tmp_path / (scene.stem + ".h5")
    assert main(["linearize", str(scene), "--inputs", "multibody.bus_top.torque", "--outputs",
                 "multibody.bus_top.attitude,multibody.bus_top.angular_velocity", "-o", str(out)]) == 0
    return read_linear_model(out)


def _closed_loops(linear):
    A, B, C = linear.A, linear.B, linear.C
    assert np.abs(linear.D).max() == 0.0
    ns, ni = B.shape
    augmented = np.zeros((ns + ni, ns + ni))
    augmented[:ns, :ns] = A * T
    augmented[:ns, ns:] = B * T
    E = expm(augmented)
    gain = np.zeros((3, 7))                     # outputs: attitude (w, x, y, z), angular velocity
    for i in range(3):
        gain[i, 1 + i] = -2.0 * KP
        gain[i, 4 + i] = -KD
    discrete = E[:ns, :ns] + E[:ns, ns:] @ gain @ C
    continuous = A + B @ gain @ C
    return np.abs(np.linalg.eigvals(discrete)).max(), np.linalg.eigvals(continuous).real.max()


def _rate_residues(linear):
    lam, V = np.linalg.eig(linear.A)
    W = np.linalg.inv(V)
    rows = []
    for k in np.flatnonzero(lam.imag > 1e-6):
        residue = np.abs((linear.C[4:7] @ V[:, k:k + 1]) @ (W[k:k + 1] @ linear.B)).max()
        rows.append((lam[k].imag / (2.0 * np.pi), residue))
    return sorted(rows)


def test_gallery_10_divergence_is_sampled_spillover(tmp_path):
    assert main(["fem2modal", str(REPO / "configs" / "fem" / "spacecraft.dat"), "--modes", "20",
                 "--modal-integrals", "--damping", "0.005", "-o", str(tmp_path / "spacecraft.h5")]) == 0
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        cut = _linearize(tmp_path, _plant_yaml(tmp_path, tmp_path / "spacecraft.h5", "10 Hz"))
        full = _linearize(tmp_path, _plant_yaml(tmp_path, tmp_path / "spacecraft.h5", "100 Hz"))
    radius_cut, real_cut = _closed_loops(cut)
    radius_full, real_full = _closed_loops(full)
    assert radius_full > 1.5
    assert radius_cut <= 1.0 + 1e-7
    assert real_cut <= 1e-9 and real_full <= 1e-9
    residues = _rate_residues(full)
    culprit = max(residues, key=lambda r: r[1])
    assert 25.0 < culprit[0] < 27.0 and culprit[1] > 5.0
    assert all(r < 0.01 for f, r in residues if f < 10.0)

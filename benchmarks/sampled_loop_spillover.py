"""Why configs/gallery/10_spacecraft_from_deck.yaml diverges when every mode up to 100 Hz is kept: the sampled PD
loop's discrete closed-loop eigenvalues (issue 14, finding of a helper session).

The scene (a flexible spacecraft from configs/fem/spacecraft.dat, one free flexible body; a PD attitude controller
sampled at 10 Hz reads and acts at the bus-top panel node, grid 38, kp = 4 N m/rad, kd = 40 N m s/rad) runs with
the modes up to 10 Hz and diverged within 0.3-1.2 s with those up to 100 Hz (etdrk4 at 10 and 1 ms, RK4 at 1 ms),
while the open loop ran. Here: the plant linearized at rest by ``shell.analysis.linearize`` (input the node's
torque, outputs its attitude and rate), discretized with a zero-order hold over the 0.1 s sample (the controller
holds its torque from the sample on), closed with the controller's law ``tau = -kp 2 q_vec - kd omega``;
the largest discrete eigenvalues, the continuous-time loop with the same gains for comparison, and each
flexible mode's collocated rate/torque residue (how strongly the torque at the node drives that mode and the
rate sensor sees it). Then the same with only the mode that the residues single out removed (``modes:``).

    python3 benchmarks/sampled_loop_spillover.py SPACECRAFT_H5
(SPACECRAFT_H5: ``flexshell fem2modal configs/fem/spacecraft.dat --modes 20 --modal-integrals --damping 0.005
-o spacecraft.h5``, as the scene's header says)
"""

from __future__ import annotations

import sys
import warnings
from pathlib import Path

import numpy as np
import scipy.linalg

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from shell.analysis.linearize import linearize  # noqa: E402
from shell.scenario import build_simulation, load_scenario  # noqa: E402

CONFIG = ROOT / "configs" / "gallery" / "10_spacecraft_from_deck.yaml"
KP, KD, T = 4.0, 40.0, 0.1


def analyse(body_file, label, overrides):
    scenario = load_scenario(str(CONFIG), [f"multibody.spacecraft.body_file={body_file}",
                                           "controller.attitude_command=[1, 0, 0, 0]"] + overrides)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        model = linearize(build_simulation(scenario), ["multibody.bus_top.torque"],
                          ["multibody.bus_top.attitude", "multibody.bus_top.angular_velocity"])
    A, B, C = model.A, model.B, model.C
    n = A.shape[0]
    E = scipy.linalg.expm(np.block([[A, B], [np.zeros((3, n + 3))]]) * T)  # zero-order hold
    K = -(KP * 2.0 * C[1:4] + KD * C[4:7])
    discrete = np.linalg.eigvals(E[:n, :n] + E[:n, n:] @ K)
    continuous = np.linalg.eigvals(A + B @ K)
    print(f"{label}: {n} states; sampled loop largest |eigenvalue| {np.abs(discrete).max():.4f} per sample; "
          f"continuous loop largest real part {continuous.real.max():.2e} 1/s")
    w, V = np.linalg.eig(A)
    Vi = np.linalg.inv(V)
    flexible = np.where(w.imag > 1e-6)[0]
    for i in flexible[np.argsort(np.abs(w[flexible]))]:
        residue = np.linalg.norm((C[4:7] @ V[:, i:i + 1]) @ (Vi[i:i + 1] @ B))
        print(f"   mode {abs(w[i]) / 2 / np.pi:7.2f} Hz   rate/torque residue {residue:.2e}   "
              f"kd residue / omega {KD * residue / abs(w[i]):.2e}")
    return np.abs(discrete).max()


def main():
    body_file = sys.argv[1]
    analyse(body_file, "modes to 10 Hz (as shipped)", ["multibody.spacecraft.max_frequency=10 Hz"])
    analyse(body_file, "modes to 100 Hz", ["multibody.spacecraft.max_frequency=100 Hz"])
    kept = [k for k in range(20) if k != 6]  # the file's mode 6 (16.5 Hz) removed
    analyse(body_file, "modes to 100 Hz without the 16.5 Hz mode",
            ["multibody.spacecraft.max_frequency=100 Hz", f"multibody.spacecraft.modes={kept}"])


if __name__ == "__main__":
    main()

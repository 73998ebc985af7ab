"""3-axis LQR on a flexible spacecraft, closed in YAML (docs/gallery/lqr_3axis.md), run from the repository root:

    python3 configs/lqr_data/design_lqr_3axis.py [--output-directory DIR]

Needs python-control (``python3 -m pip install control``). Everything it writes goes to DIR (default
``lqr_3axis_design``), never over the shipped configs/lqr_data files (the committed plant and gain are what
this script computes; the test suite checks that they are):

1. ``flexshell linearize configs/lqr_3axis_plant.yaml`` from the three torques at the bus's acs node:
   24 states (bus rotation vector, position, 6 modal coordinates, and their rates), DIR/lqr_3axis_plant.h5;
2. the translation states (bus position and velocity: 6 states no torque moves the attitude or the modes
   through, their columns of A are exactly 0 in the rotation and modal rows) are taken out; the remaining
   18-state model is discretized with a zero-order hold at the controller period (``control.c2d``, 10 Hz)
   and ``control.dlqr`` gives K; the translation states get zero gain (K padded with zero columns), written
   as DIR/gain_3axis.csv (3 x 24, the linear model's state order);
3. the loop of configs/gallery/13_lqr_3axis.yaml (``LinearizedState`` -> ``LqrStateFeedback`` -> the acs
   torque) runs from a 0.5 deg error about the skew axis (1, 1, 1)/sqrt(3) with these files, and its logged
   command is compared with the linear discrete prediction ``u_k = -K x_k``, ``x_{k+1} = (Ad - Bd K) x_k``
   (the full 24-state ZOH model, the same initial state in the linear model's coordinates).
"""

from __future__ import annotations

import argparse
import math
import os
import sys
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
CONFIGS = HERE.parent
PERIOD = 0.1  # s, controller rate 10 Hz
ANGLE_WEIGHT = 1.0 / np.deg2rad(0.1) ** 2      # 0.1 deg of bus rotation ...
RATE_WEIGHT = 1.0 / np.deg2rad(0.05) ** 2      # ... 0.05 deg/s of bus rate ...
MODAL_WEIGHT = 1.0 / 0.01 ** 2                  # ... and 0.01 of modal coordinate or rate cost as much as ...
TORQUE_WEIGHT = 1.0 / 20.0 ** 2                 # ... 20 N m of torque per axis
ERROR_DEG, ERROR_AXIS = 0.5, np.ones(3) / math.sqrt(3.0)


def linear_plant(directory: Path):
    """The linear model of configs/lqr_3axis_plant.yaml, linearized by the command line into ``directory``."""
    from shell.analysis.linear_model_file import read_linear_model
    from shell.cli import main

    path = Path(directory) / "lqr_3axis_plant.h5"
    code = main(["linearize", os.path.relpath(CONFIGS / "lqr_3axis_plant.yaml"), "--inputs", "multibody.acs.torque",
                 "--outputs", "multibody.acs.angular_velocity", "-o", str(path), "--overwrite"])
    if code:
        raise SystemExit(f"flexshell linearize failed ({code})")
    return read_linear_model(path), path


def translation_states(model) -> np.ndarray:
    """The bus hinge's position and velocity rows (the free hinge: q = [quaternion, position], u = [omega, v])."""
    return np.concatenate([model.state_index["multibody.bus.hinge_q"][3:],
                           model.state_index["multibody.bus.hinge_u"][3:]])


def design(model):
    """(K of the full state with zero translation gains, Ad, Bd of the full ZOH model)."""
    import control

    n = model.A.shape[0]
    drop = translation_states(model)
    keep = np.setdiff1d(np.arange(n), drop)
    assert not np.any(model.A[np.ix_(keep, drop)]), "translation feeds the attitude: cannot drop it"
    rotation = model.state_index["multibody.bus.hinge_q"][:3]
    rate = model.state_index["multibody.bus.hinge_u"][:3]
    weights = np.full(n, MODAL_WEIGHT)
    weights[rotation], weights[rate] = ANGLE_WEIGHT, RATE_WEIGHT
    reduced = control.c2d(control.ss(model.A[np.ix_(keep, keep)], model.B[keep], np.eye(keep.size),
                                     np.zeros((keep.size, 3))), PERIOD, method="zoh")
    K_reduced, _, _ = control.dlqr(reduced.A, reduced.B, np.diag(weights[keep]), TORQUE_WEIGHT * np.eye(3))
    K = np.zeros((3, n))
    K[:, keep] = K_reduced
    full = control.c2d(control.ss(model.A, model.B, np.eye(n), np.zeros((n, 3))), PERIOD, method="zoh")
    return K, full.A, full.B


def write_gain(K, directory: Path) -> Path:
    path = Path(directory) / "gain_3axis.csv"
    np.savetxt(path, K, delimiter=", ", fmt="%.17g")
    return path


def initial_error(model) -> np.ndarray:
    """The 0.5 deg skew-axis error in the linear model's coordinates (rotation vector, all else 0)."""
    x = np.zeros(model.A.shape[0])
    x[model.state_index["multibody.bus.hinge_q"][:3]] = np.deg2rad(ERROR_DEG) * ERROR_AXIS
    return x


def closed_loop(K, Ad, Bd, x0, t_final=60.0, directory=None, log=None):
    """(time, logged command, predicted command) at the controller samples, the loop of
    configs/gallery/13_lqr_3axis.yaml run with the plant and gain of ``directory`` (None: the shipped ones)."""
    from shell.log_file import read_log
    from shell.scenario import build_simulation, load_scenario

    overrides = [f"stop.time={t_final} s"]
    if directory is not None:
        directory = Path(directory).resolve()
        overrides += [f"x_hat.config.linear_model={directory / 'lqr_3axis_plant.h5'}",
                      f"lqr.config.gain_file={directory / 'gain_3axis.csv'}"]
    scenario = load_scenario(CONFIGS / "gallery" / "13_lqr_3axis.yaml", overrides)
    simulation = build_simulation(scenario)
    if simulation.mode != "compiled":
        raise SystemExit(f"the loop runs interpreted: {simulation.interpreted_reason}")
    log = Path(log or "lqr_3axis.h5")
    simulation.run(scenario.t_final, log_path=log)
    data = read_log(log)
    steps = data["time"].size
    predicted, x = [], x0.copy()
    for _ in range(steps):
        predicted.append(-K @ x)
        x = (Ad - Bd @ K) @ x
    return data["time"], data["lqr.command"], np.array(predicted)


def main(argv) -> int:
    parser = argparse.ArgumentParser(description="3-axis LQR on the linearized flexible spacecraft, closed in YAML")
    parser.add_argument("--output-directory", default="lqr_3axis_design",
                        help="where the plant, the gain and the closed-loop log go (default lqr_3axis_design)")
    args = parser.parse_args(argv)
    out = Path(args.output_directory)
    if out.resolve() == HERE:
        parser.error(f"--output-directory {out}: that is the shipped example's folder; choose another")
    out.mkdir(parents=True, exist_ok=True)
    model, _ = linear_plant(out)
    K, Ad, Bd = design(model)
    write_gain(K, out)
    radius = np.max(np.abs(np.linalg.eigvals(Ad - Bd @ K)[np.abs(np.linalg.eigvals(Ad - Bd @ K) - 1.0) > 1e-9]))
    print(f"plant: {model}")
    print(f"K: 3 x {K.shape[1]}, translation columns 0; closed-loop discrete poles (translation's 1 aside) "
          f"|z| <= {radius:.4f}")
    times, command, predicted = closed_loop(K, Ad, Bd, initial_error(model), directory=out, log=out / "lqr_3axis.h5")
    peak = np.max(np.abs(predicted))
    error = np.max(np.abs(command - predicted))
    print(f"peak predicted command {peak:.6g} N m; largest |logged - predicted| over {times[-1]:g} s: {error:.3g} N m "
          f"= {error / peak:.3g} of the peak")
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))

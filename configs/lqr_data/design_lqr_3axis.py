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
   (the full 24-state ZOH model, the same initial state in the linear model's coordinates);
4. the observer-based (LQG) compensator: a steady-state Kalman predictor on the 18 states from the measured bus
   rotation vector and rate (``shell.analysis.kalman.kalman_design``) with K on its estimate, one sampled
   state-space system from LinearizedState's x to the torques (DIR/lqg_3axis.npz); configs/lqg_3axis.yaml closes
   it as a ``StateSpace`` block, and its logged torque is compared with the linear closed loop of plant and
   compensator (the compensator's state starts at 0).
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
TORQUE_NOISE = 1.0                              # N m, process noise on each torque (the LQG's Kalman design) ...
ANGLE_NOISE = np.deg2rad(10.0 / 3600.0)         # ... 10 arcsec of measured rotation vector ...
RATE_NOISE = 1e-5                               # ... and 1e-5 rad/s of measured rate


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


def lqg_compensator(model, K, Ad, Bd):
    """The observer-based compensator, a sampled state-space system from the linear model's full state (the
    output of LinearizedState; it reads only the measured bus rotation vector and rate) to the three torques:
    the steady-state Kalman predictor on the 18 non-translation states (``shell.analysis.kalman.kalman_design``:
    process noise on the torques, measurement noise on the 6 measurements) with the LQR gain on its estimate::

        xh[k+1] = (A - B K - L C) xh[k] + L C_m x[k],    u[k] = -K xh[k]

    (C_m picks the measurements out of the full state, C out of the reduced one). Returns (A, B, C, D)."""
    from shell.analysis.kalman import kalman_design

    n = model.A.shape[0]
    keep = np.setdiff1d(np.arange(n), translation_states(model))
    measured = np.concatenate([model.state_index["multibody.bus.hinge_q"][:3],
                               model.state_index["multibody.bus.hinge_u"][:3]])
    pick = np.eye(n)[measured]
    A, B, C, gain = Ad[np.ix_(keep, keep)], Bd[keep], pick[:, keep], K[:, keep]
    noise = np.diag([ANGLE_NOISE ** 2] * 3 + [RATE_NOISE ** 2] * 3)
    L = kalman_design(A, B, C, TORQUE_NOISE ** 2 * np.eye(3), noise, PERIOD).predictor_gain
    return A - B @ gain - L @ C, L @ pick, -gain, np.zeros((3, n))


def write_compensator(matrices, directory: Path) -> Path:
    path = Path(directory) / "lqg_3axis.npz"
    np.savez(path, **dict(zip("ABCD", matrices)), sample_time=PERIOD)
    return path


def lqg_prediction(matrices, Ad, Bd, x0, steps):
    """The torques u_k of the linear closed loop: plant (full ZOH model) and compensator from xh_0 = 0."""
    Ac, Bc, Cc, _ = matrices
    x, xh, out = x0.copy(), np.zeros(Ac.shape[0]), []
    for _ in range(steps):
        u = Cc @ xh
        out.append(u)
        x, xh = Ad @ x + Bd @ u, Ac @ xh + Bc @ x
    return np.array(out)


def write_gain(K, directory: Path) -> Path:
    path = Path(directory) / "gain_3axis.csv"
    np.savetxt(path, K, delimiter=", ", fmt="%.17g")
    return path


def initial_error(model) -> np.ndarray:
    """The 0.5 deg skew-axis error in the linear model's coordinates (rotation vector, all else 0)."""
    x = np.zeros(model.A.shape[0])
    x[model.state_index["multibody.bus.hinge_q"][:3]] = np.deg2rad(ERROR_DEG) * ERROR_AXIS
    return x


def run_loop(scene: Path, t_final: float, overrides=(), log=None) -> dict:
    """The log (a dict) of ``scene`` run to ``t_final`` with ``overrides``, refused when it would run interpreted."""
    from shell.log_file import read_log
    from shell.scenario import build_simulation, load_scenario

    scenario = load_scenario(scene, [f"stop.time={t_final} s", *overrides])
    simulation = build_simulation(scenario)
    if simulation.mode != "compiled":
        raise SystemExit(f"{scene}: the loop runs interpreted: {simulation.interpreted_reason}")
    log = Path(log or f"{scene.stem}.h5")
    simulation.run(scenario.t_final, log_path=log)
    return read_log(log)


def closed_loop(K, Ad, Bd, x0, t_final=60.0, directory=None, log=None):
    """(time, logged command, predicted command) at the controller samples, the loop of
    configs/gallery/13_lqr_3axis.yaml run with the plant and gain of ``directory`` (None: the shipped ones)."""
    overrides = []
    if directory is not None:
        directory = Path(directory).resolve()
        overrides += [f"x_hat.config.linear_model={directory / 'lqr_3axis_plant.h5'}",
                      f"lqr.config.gain_file={directory / 'gain_3axis.csv'}"]
    data = run_loop(CONFIGS / "gallery" / "13_lqr_3axis.yaml", t_final, overrides, log)
    predicted, x = [], x0.copy()
    for _ in range(data["time"].size):
        predicted.append(-K @ x)
        x = (Ad - Bd @ K) @ x
    return data["time"], data["lqr.command"], np.array(predicted)


def lqg_closed_loop(matrices, Ad, Bd, x0, t_final=60.0, directory=None, log=None):
    """(time, logged torque, predicted torque) of configs/lqg_3axis.yaml (the compensator as a StateSpace block)
    with the plant and compensator of ``directory`` (None: the shipped ones)."""
    overrides = []
    if directory is not None:
        directory = Path(directory).resolve()
        overrides += [f"x_hat.config.linear_model={directory / 'lqr_3axis_plant.h5'}",
                      f"lqg.config.file={directory / 'lqg_3axis.npz'}"]
    data = run_loop(CONFIGS / "lqg_3axis.yaml", t_final, overrides, log)
    return data["time"], data["lqg.y"], lqg_prediction(matrices, Ad, Bd, x0, data["time"].size)


def _compare(what, times, logged, predicted):
    peak = np.max(np.abs(predicted))
    error = np.max(np.abs(logged - predicted))
    print(f"{what}: peak predicted torque {peak:.6g} N m; largest |logged - predicted| over {times[-1]:g} s: "
          f"{error:.3g} N m = {error / peak:.3g} of the peak")


def main(argv) -> int:
    parser = argparse.ArgumentParser(description="3-axis LQR and LQG on the linearized flexible spacecraft, "
                                                 "closed in YAML")
    parser.add_argument("--output-directory", default="lqr_3axis_design",
                        help="where the plant, the gain, the compensator and the logs go (default lqr_3axis_design)")
    args = parser.parse_args(argv)
    out = Path(args.output_directory)
    if out.resolve() == HERE:
        parser.error(f"--output-directory {out}: that is the shipped example's folder; choose another")
    out.mkdir(parents=True, exist_ok=True)
    model, _ = linear_plant(out)
    K, Ad, Bd = design(model)
    write_gain(K, out)
    compensator = lqg_compensator(model, K, Ad, Bd)
    write_compensator(compensator, out)
    poles = np.linalg.eigvals(Ad - Bd @ K)
    print(f"plant: {model}")
    print(f"K: 3 x {K.shape[1]}, translation columns 0; closed-loop discrete poles (translation's 1 aside) "
          f"|z| <= {np.max(np.abs(poles[np.abs(poles - 1.0) > 1e-9])):.4f}; compensator poles |z| <= "
          f"{np.max(np.abs(np.linalg.eigvals(compensator[0]))):.4f}")
    x0 = initial_error(model)
    _compare("LQR", *closed_loop(K, Ad, Bd, x0, directory=out, log=out / "lqr_3axis.h5"))
    _compare("LQG", *lqg_closed_loop(compensator, Ad, Bd, x0, directory=out, log=out / "lqg_3axis.h5"))
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))

"""LQR workflow on a flexible spacecraft (docs/linearization.md), run from the repository root:

    python3 configs/lqr_data/design_lqr.py [--output-directory DIR] [--regenerate-body]

Everything it writes goes to DIR (default ``lqr_design`` in the working directory), never over the
shipped files of configs/lqr_data/ (the committed gains are the design this script computes; the test
suite checks that they are):

1. (--regenerate-body) the array's body file: the FModal beam (20 elements over 9 m) clamped at grid 1,
   6 fixed-interface modes with modal integrals (DIR/array.h5 and its deck DIR/cantilever_array.dat;
   the plant is then linearized with that file);
2. linearize configs/lqr_plant.yaml from the bus hinge torque to the full state [q; u]
   (4-point central differences with Richardson extrapolation) and write DIR/lqr_plant.h5 (HDF5
   linear-model file) and DIR/lqr_plant.mat;
3. discretize with a zero-order hold at the controller period (10 Hz, exact: expm of the augmented
   matrix) and solve the discrete LQR (scipy.linalg.solve_discrete_are):
   K = (R + Bd' P Bd)^-1 Bd' P Ad;
4. write the gain files DIR/gain_position.csv (K_q on q) and DIR/gain_rate.csv (K_u on u), in the
   layout configs/lqr_closed_loop.yaml reads (its ``--set`` overrides are printed);
5. run the closed loop in the nonlinear simulation with those gains and compare the bus angle with the
   linear discrete closed-loop prediction x_{k+1} = (Ad - Bd K) x_k from the same initial state.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np
from scipy.linalg import expm, solve_discrete_are

HERE = Path(__file__).resolve().parent
CONFIGS = HERE.parent
PERIOD = 0.1  # s, controller rate 10 Hz
ANGLE_WEIGHT = 1.0 / np.deg2rad(0.1) ** 2      # 0.1 deg of bus angle ...
RATE_WEIGHT = 1.0 / np.deg2rad(0.05) ** 2      # ... 0.05 deg/s of bus rate ...
MODAL_WEIGHT = 1.0 / 0.01 ** 2                  # ... and 0.01 of modal coordinate cost as much as ...
TORQUE_WEIGHT = 1.0 / 20.0 ** 2                 # ... 20 N m of torque


def regenerate_body_file(directory: Path) -> Path:
    """Write the array's deck and body file into ``directory``; returns the body file."""
    from dynamics.flex import Fem2ModalOptions, fem2modal
    from dynamics.flex.body_file import write_body_file
    from dynamics.modal_analysis import BeamDeck

    deck = BeamDeck()
    deck.add_line(1, (0.0, 0.0, 0.0), (1.0, 0.0, 0.0), 9.0, 20, (0.0, 1.0, 0.0), 1)
    deck.spc.append((1, 123456))
    path = deck.write(Path(directory) / "cantilever_array.dat")
    body = Path(directory) / "array.h5"
    write_body_file(body, fem2modal(str(path), Fem2ModalOptions(n_modes=6, modal_integrals=True)))
    return body


def body_override(body_file) -> list[str]:
    """``--set`` override pointing the array of the LQR scenarios at ``body_file`` (None: the shipped one)."""
    return [] if body_file is None else [f"multibody.array.body_file={Path(body_file).resolve()}"]


def gain_overrides(directory) -> list[str]:
    """``--set`` overrides pointing configs/lqr_closed_loop.yaml at the gain files in ``directory``."""
    if directory is None:
        return []
    directory = Path(directory).resolve()
    return [f"lqr_position.config.gain_file={directory / 'gain_position.csv'}",
            f"lqr_rate.config.gain_file={directory / 'gain_rate.csv'}"]


def linear_plant(output_directory=None, body_file=None):
    from shell.analysis.linear_model_file import write_linear_model, write_mat
    from shell.analysis.linearize import linearize
    from shell.scenario import build_simulation, load_scenario

    sim = build_simulation(load_scenario(CONFIGS / "lqr_plant.yaml", body_override(body_file)))
    model = linearize(sim, ["multibody.bus.torque"], ["multibody.q", "multibody.u"],
                      metadata={"scenario": "configs/lqr_plant.yaml"})
    if output_directory is not None:
        write_linear_model(Path(output_directory) / "lqr_plant.h5", model)
        write_mat(Path(output_directory) / "lqr_plant.mat", model)
    return model


def zero_order_hold(A, B, period):
    n, m = B.shape
    augmented = np.zeros((n + m, n + m))
    augmented[:n, :n], augmented[:n, n:] = A, B
    phi = expm(augmented * period)
    return phi[:n, :n], phi[:n, n:]


def design(model):
    n = model.A.shape[0]
    nq = n // 2
    Q = np.diag([ANGLE_WEIGHT] + [MODAL_WEIGHT] * (nq - 1) + [RATE_WEIGHT] + [MODAL_WEIGHT] * (nq - 1))
    R = np.array([[TORQUE_WEIGHT]])
    Ad, Bd = zero_order_hold(model.A, model.B, PERIOD)
    P = solve_discrete_are(Ad, Bd, Q, R)
    K = np.linalg.solve(R + Bd.T @ P @ Bd, Bd.T @ P @ Ad)
    return K, Ad, Bd


def write_gains(K, nq, directory):
    """Write gain_position.csv and gain_rate.csv into ``directory`` (never the shipped configs/lqr_data)."""
    directory = Path(directory)
    np.savetxt(directory / "gain_position.csv", K[:, :nq], delimiter=", ", fmt="%.17g")
    rate = np.zeros((3, K.shape[1] - nq))
    rate[2] = K[0, nq:]  # z torque at the acs node = generalized force of the revolute bus hinge
    np.savetxt(directory / "gain_rate.csv", rate, delimiter=", ", fmt="%.17g")


def closed_loop(K, Ad, Bd, t_final=60.0, gain_directory=None, body_file=None):
    """(time, nonlinear bus angle, linear prediction) at the controller samples; the scenario reads the
    gains of ``gain_directory`` (None: the shipped configs/lqr_data gains)."""
    from shell.scenario import build_simulation, load_scenario

    overrides = gain_overrides(gain_directory) + body_override(body_file)
    sim = build_simulation(load_scenario(CONFIGS / "lqr_closed_loop.yaml", overrides))
    x = sim.x.copy()
    steps = int(round(t_final / PERIOD))
    times, angle, predicted = [], [], []
    for k in range(steps + 1):
        if k:
            sim.run(k * PERIOD)
        sim.evaluate()
        times.append(sim.t)
        angle.append(float(sim.signal("multibody.bus.q")[0]))
        predicted.append(x[0])
        x = (Ad - Bd @ K) @ x
    return np.array(times), np.array(angle), np.array(predicted)


def main(argv) -> int:
    parser = argparse.ArgumentParser(description="LQR design on the linearized flexible spacecraft")
    parser.add_argument("--output-directory", default="lqr_design",
                        help="where the plant, gains and (with --regenerate-body) body file go (default lqr_design)")
    parser.add_argument("--regenerate-body", action="store_true",
                        help="rebuild the array's body file from its beam deck in the output directory")
    args = parser.parse_args(argv)
    out = Path(args.output_directory)
    if out.resolve() == HERE:
        parser.error(f"--output-directory {out}: that is the shipped example's folder; choose another")
    out.mkdir(parents=True, exist_ok=True)
    body = regenerate_body_file(out) if args.regenerate_body else None
    model = linear_plant(out, body)
    K, Ad, Bd = design(model)
    write_gains(K, model.A.shape[0] // 2, out)
    print(f"wrote {out}/lqr_plant.h5, lqr_plant.mat, gain_position.csv, gain_rate.csv"
          + (", array.h5" if body else ""))
    poles = np.linalg.eigvals(Ad - Bd @ K)
    print(f"plant: {model}")
    print(f"K = {np.array2string(K, precision=4)}; closed-loop discrete poles |z| <= {np.max(np.abs(poles)):.4f}")
    times, angle, predicted = closed_loop(K, Ad, Bd, gain_directory=out, body_file=body)
    for t in (0.0, 5.0, 10.0, 20.0, 40.0, 60.0):
        k = int(round(t / PERIOD))
        print(f"t = {times[k]:5.1f} s  bus angle {np.rad2deg(angle[k]):+.6f} deg (linear prediction "
              f"{np.rad2deg(predicted[k]):+.6f} deg)")
    print(f"largest |nonlinear - linear| over 60 s: {np.rad2deg(np.max(np.abs(angle - predicted))):.3g} deg")
    sets = " ".join(f"--set {item}" for item in gain_overrides(out) + body_override(body))
    print(f"closed loop with these gains: flexshell run configs/lqr_closed_loop.yaml {sets} -o lqr.h5")
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))

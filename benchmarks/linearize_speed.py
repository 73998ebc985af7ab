"""Wall time of linearizing a 400-state flexible scene (the size of TM-2020-5008164 App. G.4's
delivered observatory model: one flexible body with ~200 modes, 4 reaction wheels, 16 thrusters, IMU).

Scene: the FModal single-length beam (normalized component modes with grid 101 in the a-set, 190
fixed-interface modes + 6 = 196 modes) on a free hinge; four wheels (20 kg m^2 about their spin axes
x, y, z and (1, 1, 1)/sqrt(3), TM eq. G.3.1) on revolute hinges at grid 51; sixteen thruster nodes
(force inputs along node z) at grids 5, 11, ..., 95; an IMU node at grid 30 (angular velocity out).
States 2 (6 + 196 + 4) = 404 in tangent coordinates; inputs 4 wheel torques + 16 thruster forces;
outputs IMU rate (3) + wheel rates (4).

Reported: wall time of 4-point central differences with Richardson extrapolation (6 evaluations per
column), and the ratio to (number of evaluations x one derivative evaluation of the same scene,
measured in the same run), i.e. the linearization's overhead over the bare scene evaluations.

    python3 benchmarks/linearize_speed.py [N_FIXED_INTERFACE_MODES]
"""

from __future__ import annotations

import sys
import tempfile
import time
from pathlib import Path

import numpy as np

from dynamics import Multibody
from dynamics.flex import Fem2ModalOptions, fem2modal
from dynamics.modal_analysis import BeamDeck, rest_body_data
from shell.analysis.linearize import linearize
from shell.assembly import Assembly
from shell.models.multibody import MultibodyModel
from shell.simulation import Simulation

WHEEL_AXES = [(1.0, 0.0, 0.0), (0.0, 1.0, 0.0), (0.0, 0.0, 1.0), tuple(np.ones(3) / np.sqrt(3.0))]
THRUSTER_GRIDS = list(range(5, 100, 6))[:16]


def observatory(n_modes: int, tmp: Path):
    deck = BeamDeck()
    deck.add_line(1, (0.0, 0.0, 0.0), (1.0, 0.0, 0.0), 9.0, 100, (0.0, 1.0, 0.0), 1)
    body = fem2modal(str(deck.write(tmp / "beam.dat")),
                     Fem2ModalOptions(n_modes=n_modes, aset=[(101, [1, 2, 3, 4, 5, 6])]))
    mb = Multibody(gravity=(0.0, 0.0, 0.0))
    mb.add_flexible_body("structure", None, modal=rest_body_data(body), hinge="free")
    mb.add_node("wheel_mount", "structure", grid=51)
    mb.add_node("imu", "structure", grid=30)
    for k, grid in enumerate(THRUSTER_GRIDS):
        mb.add_node(f"thruster_{k + 1}", "structure", grid=grid)
    for k, axis in enumerate(WHEEL_AXES):
        axis = np.asarray(axis)
        mb.add_body(f"wheel_{k + 1}", "structure", mass=10.0, inertia=np.diag([20.0, 10.0, 10.0]) if k == 0 else
                    20.0 * np.outer(axis, axis) + 10.0 * (np.eye(3) - np.outer(axis, axis)),
                    hinge="revolute", axis=tuple(axis), parent_node="wheel_mount")
    system = mb.compile()
    scene = Assembly("observatory")
    scene.add(MultibodyModel("multibody", system))
    return Simulation(scene)


def main(n_modes: int = 190) -> None:
    with tempfile.TemporaryDirectory() as tmp:
        sim = observatory(n_modes, Path(tmp))
    inputs = [f"multibody.wheel_{k}.torque" for k in range(1, 5)] + \
             [f"multibody.thruster_{k}.force[2]" for k in range(1, 17)]
    outputs = ["multibody.imu.angular_velocity"] + [f"multibody.wheel_{k}.u" for k in range(1, 5)]
    linearize(sim, inputs[:1], outputs, points=2, richardson=False)  # warm-up (numba dispatch)
    x = sim.x.copy()
    repeats = 20
    start = time.process_time()
    for _ in range(repeats):
        sim.derivative(0.0, x)
    per_derivative = (time.process_time() - start) / repeats
    start_wall, start_cpu = time.perf_counter(), time.process_time()
    model = linearize(sim, inputs, outputs, points=4, richardson=True)
    wall, cpu = time.perf_counter() - start_wall, time.process_time() - start_cpu
    n, m = model.B.shape
    evaluations = 6 * (n + m) + 1
    print(f"scene: {n} states, {m} inputs, {model.C.shape[0]} outputs ({n_modes} fixed-interface modes)")
    print(f"4-point central differences + Richardson: wall {wall:.2f} s, CPU {cpu:.2f} s, {evaluations} evaluations")
    print(f"one derivative evaluation {per_derivative * 1e3:.3f} ms CPU; linearization / (evaluations x "
          f"derivative) = {cpu / (evaluations * per_derivative):.2f}")
    print(f"largest estimated entry error {model.max_error:.3g}")


if __name__ == "__main__":
    main(int(sys.argv[1]) if len(sys.argv) > 1 else 190)

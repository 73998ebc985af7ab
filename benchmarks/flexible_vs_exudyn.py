"""Flexible-body speed race against Exudyn: a free-floating hub + 9 m truss boom, same FE model, same process.

The model is a 9 m truss boom (0.6 m x 0.4 m rectangular section, 0.5 m bays, aluminium rods of
50 mm^2: longerons, battens, face and station diagonals; 4 kg of fittings at every grid) whose root
station carries a 400 kg hub as four 100 kg point masses. It is written here as NASTRAN bulk data
(CROD/PROD/MAT1/CONM2, lumped mass) and goes through flexshell's FEM pipeline
(``dynamics.flex.fem2modal``: 76 grids, 228 translational DOFs once the rods' rotations, which have
neither stiffness nor mass, are removed). A truss because every DOF is a translation carrying a point
mass: the model that Exudyn's floating-frame formulation for displacement-based finite elements
(``ObjectFFRFreducedOrder``, Zwoelfer and Gerstmayr) represents exactly, and which flexshell's order-2
modal integrals (TM-2020-5008164 E.3.1, point masses) also represent exactly, so the two must agree
to round-off. (A CBEAM deck lumps a torsional mass moment on the rotational DOFs, which Exudyn's
3-DOF nodes cannot carry: the comparison would then measure a modelling difference, not speed.)

Both sides get the same data: Exudyn's ``FEMinterface`` is fed flexshell's f-set mass and stiffness
matrices and grid positions and computes its own free-free modes (``ComputeEigenmodes``, 6 rigid-body
modes excluded) and its own FFRF invariants; flexshell reads the body file of ``fem2modal``. The scene:
the body tumbles at omega_0 = [0.05, -0.1, 0.3] rad/s (body axes, frame origin at rest) with an initial
elastic deformation, the elastic part of the clamped boom's static deflection under a lateral tip load
(y and z) scaled to 5 cm at the tip, projected on each side's modes (eta_0 = (Phi^T M Phi)^-1 Phi^T M
u_0); free motion, no damping, RK4 at 1 ms on both sides (Exudyn: explicit RK44 with its Lie-group
update of the rotation vector; flexshell: quaternion, renormalized). Compared: the elastic deflection
of the tip (mean of the 4 tip grids, body axes) and the frame's angular velocity, sampled at 100 Hz,
max difference over the run relative to the peak. Checked before the race: total mass against the
rods and point masses summed here, the two eigen-solutions (frequencies, and Phi_flexshell^T M
Phi_Exudyn = diag(+-1)), the two projections of u_0.

Timing: per-step time = wall time of the run (flexshell ``Simulation.run``'s own clock, Exudyn
``SolveDynamic``) / integration steps, for ``--pairs`` interleaved pairs (the order alternates), each
build excluded, both recording at 100 Hz (Exudyn: internal sensors; flexshell: its HDF5 log). The
table gives the median of the per-pair ratios flexshell / Exudyn. Exudyn runs without end-of-step
accelerations (nothing here uses them) and writes no solution file. Threads are capped at 1 and the
load average is printed (shared machine: only ratios of interleaved runs mean anything).

The flexshell side is the user path: ``fem2modal`` + ``write_body_file``, then a YAML scene through
``parse_scenario`` + ``build_simulation`` + ``Simulation.run``, read with ``read_log``.

The general-mass case (``--case beam``, issue 28): what real decks are, every grid with rotary inertia. A 9 m
aluminium tube of 100 CBEAM (lumped mass with its torsional moment on the rotations) carried by a rigid hub arm
(a stiff 0.5 m CBEAM) from a 200 kg hub (CONM2 with [10, 10, 20] kg m^2) with two 0.3 m lever grids, every grid
with a 0.5 kg CONM2 of rotary inertia [0.002, 0.01, 0.01] kg m^2; the free body spun up from rest by a body-fixed
torque about z on the hub (0.5 rad/s^2 at first: about 1 rad/s after 2 s; Exudyn: on a rigid marker over the hub
and lever grids), RK4 at 1 ms (0.1 ms where the modes kept pass 450 Hz: RK4's stability limit).
flexshell reads its body file (6-DOF grids: order 2 at any mode count, the rotary-inertia terms summed over the
grids); Exudyn gets the same f-set matrices with every rotation condensed out statically (Guyan,
``T = [I; -K_rr^-1 K_rt]``): its 3-DOF nodes cannot carry the rotary inertia, which is the modelling difference
the agreement measures (the tip deflections, not round-off). Compared as in the truss case.

Install the peer: ``pip install -e ".[bench]"`` (bsk, exudyn, threadpoolctl).
Run: ``python benchmarks/flexible_vs_exudyn.py [--case truss beam] [--modes 20 100] [--durations 10 2]
[--pairs 5]`` from the repository root (about 15 minutes per case on a loaded 2-core machine).
"""

from __future__ import annotations

import os

for _var in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS", "NUMBA_NUM_THREADS"):
    os.environ.setdefault(_var, "1")

import argparse  # noqa: E402
import subprocess  # noqa: E402
import sys  # noqa: E402
import tempfile  # noqa: E402
import time  # noqa: E402
from dataclasses import dataclass  # noqa: E402
from pathlib import Path  # noqa: E402

import numpy as np  # noqa: E402
import scipy.sparse as sp  # noqa: E402
import scipy.sparse.linalg as spla  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
if str(ROOT) not in sys.path:
    sys.path.insert(0, str(ROOT))

STEP = 1e-3                                   # s, RK4 on both sides
SAMPLE = 0.01                                 # s, recording period
OMEGA0 = np.array([0.05, -0.1, 0.3])          # rad/s, body axes
TIP_DEFLECTION = 0.05                         # m, initial elastic tip deflection (mean |z| of the tip grids)
AGREEMENT_TOLERANCE = 1e-9                    # relative to the peak, at modal-integral order 2
BEAM_AGREEMENT = 5e-3                         # general-mass case: Exudyn's model lacks the rotary inertia
TRUSS = dict(length=9.0, bay=0.5, width=0.6, height=0.4, youngs_modulus=70e9, density=2700.0, area=5e-5,
             hub_mass=100.0, fitting_mass=4.0)


def truss_deck(length, bay, width, height, youngs_modulus, density, area, hub_mass, fitting_mass):
    """NASTRAN bulk data of the boom along x (root station at x = 0) and its mass summed here
    (rods rho A L plus point masses), an independent check of the pipeline's mass."""
    stations = int(round(length / bay)) + 1
    corners = [(-width / 2, -height / 2), (width / 2, -height / 2), (width / 2, height / 2), (-width / 2, height / 2)]
    positions = {}
    lines = ["$ truss boom with a hub: benchmarks/flexible_vs_exudyn.py"]
    for s in range(stations):
        for c, (y, z) in enumerate(corners):
            gid = 1 + 4 * s + c
            positions[gid] = np.array([s * bay, y, z])
            lines.append(f"GRID, {gid}, 0, {s * bay:.6f}, {y:.6f}, {z:.6f}, 0")
    rods = []
    for s in range(stations):
        rods += [(1 + 4 * s + c, 1 + 4 * s + (c + 1) % 4) for c in range(4)]            # battens
        rods.append((1 + 4 * s, 1 + 4 * s + 2))                                           # station diagonal
        if s + 1 < stations:
            rods += [(1 + 4 * s + c, 1 + 4 * (s + 1) + c) for c in range(4)]              # longerons
            rods += [(1 + 4 * s + c, 1 + 4 * (s + 1) + (c + 1) % 4) for c in range(4)]    # face diagonals
    for eid, (a, b) in enumerate(rods, start=1):
        lines.append(f"CROD, {eid}, 1, {a}, {b}")
    point_mass = 0.0
    for gid in positions:
        m = hub_mass if gid <= 4 else fitting_mass
        point_mass += m
        lines.append(f"CONM2, {1000 + gid}, {gid}, 0, {m}")
    lines += [f"PROD, 1, 1, {area}, 0.0", f"MAT1, 1, {youngs_modulus}, , 0.3, {density}", "ENDDATA"]
    rod_mass = density * area * sum(np.linalg.norm(positions[a] - positions[b]) for a, b in rods)
    return "\n".join(lines) + "\n", rod_mass + point_mass


BEAM = dict(length=9.0, elements=100, arm=0.5, lever=0.3, hub_mass=200.0, hub_inertia=(10.0, 10.0, 20.0),
            grid_mass=0.5, grid_inertia=(0.002, 0.01, 0.01), spin_acceleration=0.5)


def beam_hub_deck(length, elements, arm, lever, hub_mass, hub_inertia, grid_mass, grid_inertia, **_):
    """NASTRAN bulk data of the hub, arm and tube (grid 1 the hub at x = -arm, grids 2, 3, 4 its lever grids at
    y = +-lever and z = lever, grids 10.. the tube along x from 0), and the ids of the lever and tip grids."""
    lines = ["$ hub + arm + tube: benchmarks/flexible_vs_exudyn.py --case beam", "MAT1,1,70.0e9,,0.33,2700.0",
             "MAT1,2,70.0e13,,0.33,1.0", "PBEAM,10,1,6.0e-4,7.0e-7,7.0e-7,,1.4e-6", "PBEAM,20,2,1.0e-2,1.0e-4,1.0e-4,,2.0e-4",
             f"GRID,1,,{-arm},0.0,0.0", f"GRID,2,,{-arm},{lever},0.0", f"GRID,3,,{-arm},{-lever},0.0",
             f"GRID,4,,{-arm},0.0,{lever}"]
    tube = [10 + i for i in range(elements + 1)]
    lines += [f"GRID,{g},,{length * i / elements:.6f},0.0,0.0" for i, g in enumerate(tube)]
    lines += ["CBEAM,1,20,1,10,0.0,0.0,1.0", "CBEAM,2,20,1,2,0.0,0.0,1.0", "CBEAM,3,20,1,3,0.0,0.0,1.0",
              "CBEAM,4,20,1,4,1.0,0.0,0.0"]
    lines += [f"CBEAM,{100 + i},10,{a},{b},0.0,1.0,0.0" for i, (a, b) in enumerate(zip(tube[:-1], tube[1:]))]
    i11, i22, i33 = hub_inertia
    lines += [f"CONM2,1001,1,,{hub_mass},0.0,0.0,0.0", f",{i11},,{i22},,,{i33}"]
    g11, g22, g33 = grid_inertia
    for k, g in enumerate([2, 3, 4] + tube):
        lines += [f"CONM2,{1002 + k},{g},,{grid_mass},0.0,0.0,0.0", f",{g11},,{g22},,,{g33}"]
    return "\n".join(lines + ["ENDDATA"]) + "\n", (2, 3, 4), tube[-1]


@dataclass
class Model:
    """The boom through fem2modal, with what both simulators need."""

    n_modes: int
    body: object                 # dynamics.flex.body_file.ModalBody
    body_file: Path
    mass_matrix: object          # f-set M (228 x 228, CSR), DOFs (grid, component 1..3)
    stiffness_matrix: object     # f-set K
    positions: np.ndarray        # (N, 3) grid positions, f-set grid order
    tip_rows: np.ndarray         # (3, k): rows of x, y, z of the tip grids (in the 3-DOF matrices)
    initial_deformation: np.ndarray   # u_0 (3-DOF rows)
    expected_mass: float
    case: str = "truss"
    step: float = STEP           # RK4 step on both sides
    hub_nodes: tuple = ()        # beam: the 3-DOF node indices of the hub grid and its lever grids
    torque: float = 0.0          # beam: the spin-up torque about z (N m, body-fixed)


def prepare(n_modes: int, workdir: Path) -> Model:
    from dynamics.flex.body_file import write_body_file
    from dynamics.flex.pipeline import Fem2ModalOptions, fem2modal

    text, expected_mass = truss_deck(**TRUSS)
    deck = workdir / "truss_boom.dat"
    deck.write_text(text)
    body = fem2modal(str(deck), Fem2ModalOptions(n_modes=n_modes, modal_integrals=True, write_fset=True))
    body_file = workdir / f"boom_{n_modes}.h5"
    write_body_file(body_file, body)
    uset = body.fset.uset
    if not (np.array_equal(uset[:, 1], np.tile([1, 2, 3], len(uset) // 3))
            and np.array_equal(uset[::3, 0], body.grid_ids)):
        raise AssertionError("expected the f-set to be the grids' three translations in grid order "
                             f"(the rods' rotations removed), given {uset[:8].tolist()}...")
    M, K = body.fset.mass.tocsr(), body.fset.stiffness.tocsc()
    x = body.grid_positions
    tip = np.nonzero(x[:, 0] > TRUSS["length"] - 1e-9)[0]
    tip_rows = np.stack([3 * tip + k for k in range(3)])
    # u_0: clamped root station, lateral unit loads at the tip grids; its elastic part (free-free
    # modes kept here) is what a free body can hold, scaled to TIP_DEFLECTION
    free = np.repeat(x[:, 0] > 1e-9, 3)
    load = np.zeros(K.shape[0])
    load[tip_rows[1]] = load[tip_rows[2]] = 1.0
    static = np.zeros(K.shape[0])
    static[free] = spla.spsolve(K[free][:, free], load[free])
    phi = body.translation_shapes.reshape(-1, n_modes)
    elastic = phi @ project(phi, M, static)
    u0 = elastic * TIP_DEFLECTION / np.abs(elastic[tip_rows[2]]).mean()
    return Model(n_modes, body, body_file, M, K.tocsr(), x, tip_rows, u0, expected_mass)


def prepare_beam(n_modes: int, workdir: Path) -> Model:
    """The hub + arm + tube through fem2modal (6-DOF grids), and its f-set matrices condensed to the grids'
    translations for Exudyn: ``T = [I; -K_rr^-1 K_rt]`` (static, Guyan), ``K_c = T' K T``, ``M_c = T' M T``."""
    from dynamics.flex.body_file import write_body_file
    from dynamics.flex.pipeline import Fem2ModalOptions, fem2modal

    text, levers, tip = beam_hub_deck(**BEAM)
    deck = workdir / "beam_hub.dat"
    deck.write_text("SOL 103\nCEND\nBEGIN BULK\n" + text)
    body = fem2modal(str(deck), Fem2ModalOptions(n_modes=n_modes, modal_integrals=True, write_fset=True))
    body_file = workdir / f"beam_{n_modes}.h5"
    write_body_file(body_file, body)
    uset = body.fset.uset
    grids = list(body.grid_ids)
    if len(uset) != 6 * len(grids) or not np.array_equal(uset[:, 0], np.repeat(grids, 6)):
        raise AssertionError("expected the f-set to hold the six DOFs of every grid in grid order")
    t = np.flatnonzero(uset[:, 1] <= 3)
    r = np.flatnonzero(uset[:, 1] > 3)
    K, M = body.fset.stiffness.toarray(), body.fset.mass.toarray()
    T = np.zeros((len(uset), len(t)))
    T[t, np.arange(len(t))] = 1.0
    T[r] = -np.linalg.solve(K[np.ix_(r, r)], K[np.ix_(r, t)])
    Kc, Mc = T.T @ K @ T, T.T @ M @ T
    x = body.grid_positions
    k_tip = grids.index(tip)
    tip_rows = np.array([[3 * k_tip + a] for a in range(3)])
    torque = BEAM["spin_acceleration"] * body.inertia[2, 2]
    # RK4's stability limit is h omega = 2.83: 1 ms up to 450 Hz, else 0.1 ms (the tube's 100th mode is 2.3 kHz)
    step = STEP if 2 * np.pi * body.frequencies_hz[-1] * STEP <= 2.5 else STEP / 10
    expected = (BEAM["hub_mass"] + (len(grids) - 1) * BEAM["grid_mass"]
                + 2700.0 * 6.0e-4 * BEAM["length"] + 3 * BEAM["lever"] * 1.0e-2 * 1.0 + BEAM["arm"] * 1.0e-2 * 1.0)
    return Model(n_modes, body, body_file, sp.csr_matrix(0.5 * (Mc + Mc.T)), sp.csr_matrix(0.5 * (Kc + Kc.T)), x,
                 tip_rows, np.zeros(len(t)), expected, case="beam",
                 step=step, hub_nodes=tuple(grids.index(g) for g in (1,) + tuple(levers)), torque=torque)


def project(phi, mass, u):
    """Modal coordinates of the displacement field u in the mode set phi (mass-weighted least squares)."""
    return np.linalg.solve(phi.T @ (mass @ phi), phi.T @ (mass @ u))


def tip_deflection(model: Model, phi, eta):
    """Elastic displacement of the tip (mean of its grids), body axes, for modal histories eta (n_t, n)."""
    return np.stack([eta @ phi[rows].mean(axis=0) for rows in model.tip_rows], axis=1)


@dataclass
class Run:
    t: np.ndarray
    eta: np.ndarray              # (n_t, n) modal coordinates
    omega: np.ndarray            # (n_t, 3) frame angular velocity, body axes
    phi: np.ndarray              # (3N, n) the simulator's translational mode shapes
    wall: float
    steps: int

    @property
    def per_step_us(self) -> float:
        return 1e6 * self.wall / self.steps


# ------------------------------------------------------------------------------------------------
def flexshell_scene(model: Model, order, omit=()) -> str:
    """The YAML scene: the boom on a free hinge, RK4, its modal coordinates and rates logged; the beam case spun
    up by a hub torque, the truss case tumbling with its initial deformation."""
    head = f"""
name: {model.case}_{model.n_modes}
multibody:
  bodies:
    - name: boom
      parent: world
      hinge: free
      body_file: {model.body_file.name}
      modal_integrals_order: {order}
"""
    tail = f"""integrator: {{method: rk4, step: {model.step} s}}
log:
  rate: {1.0 / SAMPLE:g} Hz
  signals: [multibody.boom.modal_q, multibody.boom.u]
"""
    if model.case == "beam":
        return head + f"""      omit_terms: {list(omit)}
  nodes:
    - {{name: hub, body: boom, grid: {int(model.body.grid_ids[model.hub_nodes[0]])}}}
models:
  spin_up: {{type: Constant, config: {{unit: N*m, shape: [3]}}, parameters: {{value: "[0, 0, {float(model.torque)!r}] N*m"}}}}
connections:
  - spin_up.y -> multibody.hub.torque
""" + tail
    phi = model.body.translation_shapes.reshape(-1, model.n_modes)
    eta0 = project(phi, model.mass_matrix, model.initial_deformation)
    return head + f"""      initial:
        angular_velocity: "{OMEGA0.tolist()} rad/s"
        modal: {eta0.tolist()}
""" + tail


def run_flexshell(model: Model, duration: float, order: int, omit=()) -> Run:
    from shell.log_file import read_log
    from shell.scenario import build_simulation, parse_scenario

    scene = model.body_file.parent / "boom_scene.yaml"
    simulation = build_simulation(parse_scenario(flexshell_scene(model, order, omit), str(scene)))
    log_path = model.body_file.parent / "boom_log.h5"
    summary = simulation.run(duration, log_path=log_path)
    log = read_log(log_path)
    phi = model.body.translation_shapes.reshape(-1, model.n_modes)
    # free hinge: q = [quaternion (4), position (3), eta], u = [omega, v (body axes), eta_dot]
    return Run(log["time"], log["multibody.boom.modal_q"], log["multibody.boom.u"][:, :3], phi,
               summary.wall_time, summary.steps)


def build_exudyn(model: Model, duration: float):
    """The Exudyn system (assembled) and what run_exudyn needs."""
    import exudyn as exu
    import exudyn.itemInterface as eii
    from exudyn.FEM import FEMinterface, ObjectFFRFreducedOrderInterface

    fem = FEMinterface()
    fem.nodes = {"Position": model.positions.copy()}
    fem.massMatrix = model.mass_matrix.copy()
    fem.stiffnessMatrix = model.stiffness_matrix.copy()
    fem.ComputeEigenmodes(model.n_modes, excludeRigidBodyModes=6, useSparseSolver=False)
    phi = np.asarray(fem.modeBasis["matrix"])
    # rotation vector: Exudyn's explicit solvers refuse Euler parameters (an algebraic constraint)
    cms = ObjectFFRFreducedOrderInterface(fem, rigidBodyNodeType="NodeType.RotationRotationVector")
    system = exu.SystemContainer()
    mbs = system.AddSystem()
    spin = [0.0, 0.0, 0.0] if model.case == "beam" else OMEGA0.tolist()
    items = cms.AddObjectFFRFreducedOrder(mbs, positionRef=[0.0, 0.0, 0.0], initialVelocity=[0.0, 0.0, 0.0],
                                          initialAngularVelocity=spin)
    eta0 = project(phi, model.mass_matrix, model.initial_deformation)
    mbs.SetNodeParameter(items["nGenericODE2"], "initialCoordinates", eta0.tolist())
    if model.hub_nodes:  # the spin-up torque, body-fixed as the engine's node torque, on the hub and its levers
        marker = mbs.AddMarker(eii.MarkerSuperElementRigid(bodyNumber=items["oFFRFreducedOrder"], offset=[0.0, 0.0, 0.0],
                                                           meshNodeNumbers=[int(k) for k in model.hub_nodes],
                                                           weightingFactors=[0.25] * 4))
        mbs.AddLoad(eii.LoadTorqueVector(markerNumber=marker, loadVector=[0.0, 0.0, model.torque], bodyFixed=True))
    modal = mbs.AddSensor(eii.SensorNode(nodeNumber=items["nGenericODE2"], storeInternal=True,
                                         outputVariableType=exu.OutputVariableType.Coordinates))
    rate = mbs.AddSensor(eii.SensorNode(nodeNumber=items["nRigidBody"], storeInternal=True,
                                        outputVariableType=exu.OutputVariableType.AngularVelocityLocal))
    mbs.Assemble()
    settings = exu.SimulationSettings()
    settings.timeIntegration.endTime = duration
    settings.timeIntegration.numberOfSteps = int(round(duration / model.step))
    settings.timeIntegration.verboseMode = 0
    settings.timeIntegration.explicit.useLieGroupIntegration = True
    settings.timeIntegration.explicit.computeEndOfStepAccelerations = False
    settings.solution.file.write = False
    settings.solution.sensors.writePeriod = SAMPLE
    return dict(system=system, mbs=mbs, settings=settings, sensors=(modal, rate), phi=phi, fem=fem, cms=cms,
                eigenvalues=np.asarray(fem.eigenValues))


def run_exudyn(model: Model, duration: float) -> Run:
    import exudyn as exu

    built = build_exudyn(model, duration)
    mbs, settings = built["mbs"], built["settings"]
    start = time.perf_counter()
    exu.SolveDynamic(mbs, settings, solverType=exu.DynamicSolverType.RK44)
    wall = time.perf_counter() - start
    modal, rate = (mbs.GetSensorStoredData(s) for s in built["sensors"])
    return Run(modal[:, 0], modal[:, 1:], rate[:, 1:], built["phi"], wall, settings.timeIntegration.numberOfSteps)


# ------------------------------------------------------------------------------------------------
def input_checks(model: Model) -> list[tuple[str, float, float]]:
    """(quantity, value, tolerance) of the data both simulators start from."""
    built = build_exudyn(model, 1.0)
    if model.case == "beam":
        frequencies_e = np.sqrt(np.abs(np.sort(built["eigenvalues"])[6:6 + model.n_modes])) / (2.0 * np.pi)
        return [
            # the grids' CONM2, the tube's and the arms' rho A L, summed here (the condensation keeps the mass:
            # a rigid translation moves no rotation)
            ("mass, flexshell / deck sum - 1", abs(model.body.mass / model.expected_mass - 1.0), 1e-12),
            ("mass, Exudyn / deck sum - 1", abs(float(built["cms"].totalMass) / model.expected_mass - 1.0), 1e-12),
            # the condensed model loses the rotary inertia (the torsion modes entirely): the lowest frequency, of
            # the bending the spin-up excites, differs by what it carried
            ("lowest frequency, |f_Exudyn / f_flexshell - 1| (Guyan)",
             float(abs(frequencies_e[0] / model.body.frequencies_hz[0] - 1.0)), 1e-2),
        ]
    phi_e = built["phi"]
    phi_f = model.body.translation_shapes.reshape(-1, model.n_modes)
    frequencies_e = np.sqrt(np.abs(np.sort(built["eigenvalues"])[6:6 + model.n_modes])) / (2.0 * np.pi)
    overlap = phi_f.T @ (model.mass_matrix @ phi_e)
    initial_f = tip_deflection(model, phi_f, project(phi_f, model.mass_matrix, model.initial_deformation)[None])
    initial_e = tip_deflection(model, phi_e, project(phi_e, model.mass_matrix, model.initial_deformation)[None])
    return [
        # rods rho A L plus point masses, summed here, against the pipeline's rigid-body mass and
        # Exudyn's total mass: the same 15-digit numbers added in another order
        ("mass, flexshell / truss sum - 1", abs(model.body.mass / model.expected_mass - 1.0), 1e-13),
        ("mass, Exudyn / truss sum - 1", abs(float(built["cms"].totalMass) / model.expected_mass - 1.0), 1e-13),
        # two eigen-solutions of the same K, M (flexshell's shift-invert/LAPACK, Exudyn's scipy eigh);
        # the lowest frequency is 3.7 Hz, well separated from the rigid-body zeros
        ("frequencies, max |f_Exudyn / f_flexshell - 1|",
         float(np.abs(frequencies_e / model.body.frequencies_hz - 1.0).max()), 1e-10),
        ("mode shapes, max ||Phi_f^T M Phi_e| - I|", float(np.abs(np.abs(overlap) - np.eye(model.n_modes)).max()),
         1e-8),
        ("initial tip deflection, max difference (m)", float(np.abs(initial_f - initial_e).max()), 1e-12),
    ]


def agreement(ours: Run, theirs: Run, model: Model) -> list[tuple[str, float]]:
    if ours.t.shape != theirs.t.shape or np.abs(ours.t - theirs.t).max() > 1e-9:
        raise AssertionError(f"sample times differ: {ours.t.shape} against {theirs.t.shape}")
    tip_f = tip_deflection(model, ours.phi, ours.eta)
    tip_e = tip_deflection(model, theirs.phi, theirs.eta)
    return [("tip deflection, max |difference| / peak", float(np.abs(tip_f - tip_e).max() / np.abs(tip_e).max())),
            ("frame angular velocity, max |difference| / peak",
             float(np.abs(ours.omega - theirs.omega).max() / np.abs(theirs.omega).max())),
            ("tip deflection peak (m)", float(np.abs(tip_e).max()))]


def load_average() -> str:
    return subprocess.run(["uptime"], capture_output=True, text=True).stdout.strip()


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--modes", type=int, nargs="+", default=[20, 100], help="flexible modes kept")
    parser.add_argument("--durations", type=float, nargs="+", default=[10.0, 2.0],
                        help="simulated seconds per run, one per --modes entry (100 modes: ~40 ms per flexshell step here)")
    parser.add_argument("--pairs", type=int, default=5, help="interleaved flexshell/Exudyn pairs per mode count")
    parser.add_argument("--order", type=int, default=2, choices=(0, 1, 2),
                        help="flexshell's modal-integral order (2 is exact for point masses, as Exudyn)")
    parser.add_argument("--case", nargs="+", default=["truss", "beam"], choices=("truss", "beam"),
                        help="truss: point masses (agreement to round-off); beam: the general-mass case")
    parser.add_argument("--omit-terms", nargs="*", default=[], choices=("G1", "F2", "G2"),
                        help="beam: leave these terms of the nodes' rotary inertia out (Exudyn's nodes have none)")
    args = parser.parse_args(argv)
    if len(args.durations) != len(args.modes) or args.pairs < 1 or min(args.durations) <= 0.0:
        parser.error(f"expected one positive duration per mode count and --pairs >= 1, given --modes "
                     f"{args.modes}, --durations {args.durations}, --pairs {args.pairs}")

    import exudyn as exu
    from threadpoolctl import threadpool_limits

    failed = False
    rows = []
    with threadpool_limits(1), tempfile.TemporaryDirectory() as tmp:
        print(f"Exudyn {exu.__version__}; load before: {load_average()}")
        for case, n_modes, duration in [(c, n, d) for c in args.case for n, d in zip(args.modes, args.durations)]:
            model = (prepare if case == "truss" else prepare_beam)(n_modes, Path(tmp))
            title = ("truss boom + hub" if case == "truss" else
                     "general mass: tube (CBEAM, rotary inertia on every grid) + arm + 200 kg hub, spun up")
            print(f"\n== {title}, {n_modes} free-free modes ({model.body.frequencies_hz[0]:.2f}.."
                  f"{model.body.frequencies_hz[-1]:.1f} Hz), {model.body.mass:.1f} kg, RK4 {model.step * 1e3:g} ms, "
                  f"{duration:g} s, flexshell modal integrals order {args.order}"
                  + (f" without {', '.join(args.omit_terms)}" if case == "beam" and args.omit_terms else ""))
            for name, value, tolerance in input_checks(model):
                ok = value <= tolerance
                failed |= not ok
                print(f"  {name:48s} {value:10.2e}  (tolerance {tolerance:.0e}) {'ok' if ok else 'FAILED'}")
            omit = args.omit_terms if case == "beam" else ()
            run_flexshell(model, 10 * model.step, args.order, omit)   # load the numba cache before timing
            run_exudyn(model, 10 * model.step)
            pairs = []
            ours = theirs = None
            for pair in range(args.pairs):
                for who in (("flexshell", "exudyn") if pair % 2 == 0 else ("exudyn", "flexshell")):
                    if who == "flexshell":
                        ours = run_flexshell(model, duration, args.order, omit)
                    else:
                        theirs = run_exudyn(model, duration)
                if ours.steps != theirs.steps:
                    raise AssertionError(f"step counts differ: flexshell {ours.steps}, Exudyn {theirs.steps}")
                pairs.append((ours.per_step_us, theirs.per_step_us))
            print("| pair | flexshell (us/step) | Exudyn (us/step) | flexshell / Exudyn |")
            print("| ---: | ---: | ---: | ---: |")
            for k, (a, b) in enumerate(pairs):
                print(f"| {k + 1} | {a:.1f} | {b:.1f} | {a / b:.2f} |")
            ratio = float(np.median([a / b for a, b in pairs]))
            print(f"| median | {np.median([p[0] for p in pairs]):.1f} | {np.median([p[1] for p in pairs]):.1f} | "
                  f"{ratio:.2f} |")
            for name, value in agreement(ours, theirs, model):
                if "peak (m)" in name:
                    print(f"  {name:48s} {value:10.4f}")
                elif args.order == 2:
                    # truss: both exact for point masses, what differs is RK4 in two rotation parametrizations
                    # (rotation vector with Lie-group update against quaternion) and round-off; beam: the rotary
                    # inertia Exudyn's condensed 3-DOF nodes cannot carry (issue 28: within 0.5 %)
                    tolerance = AGREEMENT_TOLERANCE if case == "truss" else BEAM_AGREEMENT
                    ok = value <= tolerance
                    failed |= not ok
                    print(f"  {name:48s} {value:10.2e}  (tolerance {tolerance:.0e}) {'ok' if ok else 'FAILED'}")
                else:
                    print(f"  {name:48s} {value:10.2e}  (order {args.order} drops the deformation-dependent "
                          "inertia terms that Exudyn keeps)")
            rows.append((case, n_modes, ratio))
        print("\nmedian per-step ratio flexshell / Exudyn: "
              + ", ".join(f"{c} {n} modes {r:.2f}" for c, n, r in rows) + " (team goal <= 1.0, stretch 0.5)")
        print(f"load after: {load_average()}")
    return 1 if failed else 0


if __name__ == "__main__":
    sys.exit(main())

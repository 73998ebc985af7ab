"""Gimbaled engine: prescribed gimbal motion followed exactly with the airframe reacting (momentum of
the free vehicle conserved); torque mode with the load-torque loop closed is a frictionless bearing
(TM-2020-5008164 App. F.4): the airframe then feels only the engine's mass at the gimbal, not its
rotational inertia, while the prescribed (rigid) gimbal couples that inertia in. On a flexible (EOTM)
airframe the linearized scene's system frequencies equal whole-structure FE models: engine pinned
(closed loop), welded (open loop), on actuator springs (servo stiffness)."""

import textwrap

import numpy as np
from numpy.testing import assert_allclose

from shell.log_file import read_log
from shell.scenario import build_simulation, parse_scenario

FREE = """
multibody:
  bodies:
    - {name: stage, hinge: free, mass: 2000 kg, inertia: "[7000, 7000, 500] kg*m^2",
       initial: {angular_velocity: "[0.01, -0.02, 0.03] rad/s", velocity: "[0, 0, 50] m/s"}}
    - {name: engine, parent: stage, hinge: ujoint, axes: [[1, 0, 0], [0, 1, 0]], prescribed: true,
       mass: 150 kg, com: "[0, 0, -0.8] m", inertia: "[40, 40, 25] kg*m^2", inboard_position: "[0, 0, -4] m"}
models:
  command: {type: Constant, config: {unit: rad, shape: [2]}, parameters: {value: "[0.05, -0.03] rad"}}
  gimbal: {type: GimbalActuator, attach: {hinge: engine}}
connections: [command.y -> gimbal.angle_command]
integrator: {method: rk4, step: 0.001 s}
log: {rate: 100 Hz, signals: [multibody.q, multibody.u, multibody.engine.q, multibody.engine.u, gimbal.reference]}
"""


def test_prescribed_gimbal_follows_the_servo_and_the_vehicle_reacts(tmp_path):
    sim = build_simulation(parse_scenario(textwrap.dedent(FREE), "free.yaml", None))
    sim.run(1.0, log_path=tmp_path / "free.h5")
    log = read_log(tmp_path / "free.h5")
    # the hinge integrates the prescribed acceleration: it equals the servo reference to round-off
    assert_allclose(log["multibody.engine.q"], log["gimbal.reference"][:, :2], rtol=0, atol=1e-13)
    assert_allclose(log["multibody.engine.u"], log["gimbal.reference"][:, 2:], rtol=0, atol=1e-12)
    # rate limit: the acceleration switches off inside an RK4 step, so the rate may pass the limit by
    # at most one step of the largest acceleration, w^2 * 0.05 rad * 1 ms = 0.045 rad/s
    assert np.max(np.abs(log["multibody.engine.u"])) <= np.radians(20.0) + 0.045
    assert np.max(np.abs(log["multibody.engine.u"])) > np.radians(19.0)             # ... and reached
    assert_allclose(log["multibody.engine.q"][-1], [0.05, -0.03], atol=2e-4)         # settled (w = 30 rad/s)
    # the airframe reacts: internal motion leaves the free vehicle's momenta constant (RK4, 1 ms)
    system = sim.models[sim.model_index["multibody"]].system
    h = np.array([system.angular_momentum(q, u) for q, u in zip(log["multibody.q"], log["multibody.u"])])
    p = np.array([system.linear_momentum(q, u) for q, u in zip(log["multibody.q"], log["multibody.u"])])
    assert_allclose(h, np.tile(h[0], (len(h), 1)), rtol=0, atol=1e-10 * np.linalg.norm(h[0]))
    assert_allclose(p, np.tile(p[0], (len(p), 1)), rtol=0, atol=1e-10 * np.linalg.norm(p[0]))
    assert np.ptp(log["multibody.u"][:, 0]) > 1e-3                                   # the stage did react


PINNED = """
multibody:
  bodies:
    - {name: stage, hinge: revolute, axis: [1, 0, 0], mass: 2000 kg, inertia: "[7000, 7000, 500] kg*m^2"}
    - {name: engine, parent: stage, hinge: ujoint, axes: [[1, 0, 0], [0, 1, 0]], prescribed: PRESCRIBED,
       mass: 150 kg, com: "[0, 0, 0] m", inertia: "[40, 40, 25] kg*m^2", inboard_position: "[0, 0, -4] m"}
models:
  drive: {type: Constant, config: {unit: N*m, shape: [1]}, parameters: {value: "[1000] N*m"}}
  command: {type: Constant, config: {unit: rad, shape: [2]}, parameters: {value: "[0, 0] rad"}}
  gimbal: {type: GimbalActuator, config: {mode: MODE}, attach: {hinge: engine}}
connections: [drive.y -> multibody.stage.torque, command.y -> gimbal.angle_command]
integrator: {method: rk4, step: 0.001 s}
log: {rate: 100 Hz, signals: [multibody.stage.q, multibody.engine.q]}
"""


def test_load_torque_feedback_closed_is_a_frictionless_bearing(tmp_path):
    t_final = 0.5
    results = {}
    for mode, prescribed in (("torque", "false"), ("prescribed", "true")):
        text = textwrap.dedent(PINNED).replace("MODE", mode).replace("PRESCRIBED", prescribed)
        sim = build_simulation(parse_scenario(text, "pinned.yaml", None))
        sim.run(t_final, log_path=tmp_path / f"{mode}.h5")
        results[mode] = read_log(tmp_path / f"{mode}.h5")
    t = results["torque"]["time"]
    # torque mode, zero gains: the engine (COM at the gimbal) keeps its inertial attitude, the stage
    # feels its mass at 4 m only: J = 7000 + 150 * 4^2; the gimbal angle is minus the stage angle.
    # Constant angular acceleration: RK4 exact to round-off.
    theta = 0.5 * 1000.0 / (7000 + 150 * 16) * t**2
    assert_allclose(results["torque"]["multibody.stage.q"][:, 0], theta, rtol=0, atol=1e-13)
    assert_allclose(results["torque"]["multibody.engine.q"][:, 0], -theta, rtol=0, atol=1e-13)
    # prescribed (rigid gimbal, load-torque loop open): the engine's own inertia is coupled in
    theta_rigid = 0.5 * 1000.0 / (7000 + 150 * 16 + 40) * t**2
    assert_allclose(results["prescribed"]["multibody.stage.q"][:, 0], theta_rigid, rtol=0, atol=1e-13)
    assert_allclose(results["prescribed"]["multibody.engine.q"], 0.0, atol=0)


# --------------------------------------------------------------------------------------------------
# TM App. F.4 on a flexible airframe: system frequencies of the shell scene (GimbalActuator in the loop,
# linearized at rest) against whole-structure finite-element models of airframe + engine.

AIRFRAME_ELEMENTS = 10           # the FModal beam section over 9 m, engine gimbal at grid 1 (the aft end)
ENGINE_MASS = 400.0              # a heavy engine, so that the coupling is visible (first mode 0.615 -> 0.419 Hz)
ENGINE_CG = np.array([-1.0, 0.10, 0.20])  # from the gimbal: 1 m aft, lateral offsets (TM complex test case)
ENGINE_INERTIA = 8.0 * np.array([[4.0, 1.1, -0.8], [1.1, 6.5, 0.9], [-0.8, 0.9, 6.0]])  # about its CG
N_COMPARED = 12


def _airframe_deck():
    """EOTM airframe deck: lumped-mass beam plus each grid's rotary inertia (rho l diag(J, I1, I2)) as
    a massless CONM2, so that every DOF has mass and the free-free mode set is complete (60 modes)."""
    from dynamics.modal_analysis import BeamDeck

    deck = BeamDeck()
    deck.add_line(1, (0.0, 0.0, 0.0), (1.0, 0.0, 0.0), 9.0, AIRFRAME_ELEMENTS, (0.0, 1.0, 0.0), 1)
    segment = 9.0 / AIRFRAME_ELEMENTS
    rotary = deck.rho * segment * np.diag([deck.J, deck.I1, deck.I2])
    for grid in range(1, AIRFRAME_ELEMENTS + 2):
        deck.conm2.append((8000 + grid, grid, 0.0, np.zeros(3), rotary))
    return deck


def _fe_frequencies(deck, path, extra_cards=()):
    """Whole-structure FE frequencies (the pipeline's eigen-solver on the assembled deck; rigid-body
    and mechanism modes below 1e-4 Hz set aside)."""
    from dynamics.flex import Fem2ModalOptions, fem2modal

    deck.write(path)
    if extra_cards:
        text = path.read_text().replace("ENDDATA", "\n".join(extra_cards) + "\nENDDATA")
        path.write_text(text)
    return fem2modal(str(path), Fem2ModalOptions(cutoff_hz=40.0)).frequencies_hz


def _pinned_engine_deck(cg):
    """Engine grid 1000 at the gimbal, joined to grid 1 by an RBE2 on components 1234: translations
    and roll shared, pitch and yaw free (the two gimbal axes, linearized), the engine a CONM2 on it."""
    deck = _airframe_deck()
    deck.grids[1000] = np.zeros(3)
    deck.rbe2.append((5001, 1, 1234, 1000))
    deck.conm2.append((9001, 1000, ENGINE_MASS, cg, ENGINE_INERTIA))
    return deck


def _gimbal_scene_modes(tmp_path, mode, cg, kp=0.0):
    """Frequencies of the linearized shell scene: the airframe (complete free-free mode set of the
    airframe deck) on a free hinge, the engine on a ujoint at grid 1 driven by a GimbalActuator."""
    from dynamics import Multibody
    from dynamics.flex import Fem2ModalOptions, fem2modal
    from dynamics.modal_analysis import rest_body_data
    from shell.analysis.linearize import linearize
    from shell.analysis.system_modes import state_space_modes
    from shell.assembly import Assembly
    from shell.models.blocks import Constant
    from shell.models.gimbaled_engine import GimbalActuator
    from shell.models.multibody import MultibodyModel
    from shell.simulation import Simulation

    path = tmp_path / "airframe.dat"
    airframe = fem2modal(str(_airframe_deck().write(path)), Fem2ModalOptions(n_modes=60))
    mb = Multibody(gravity=(0.0, 0.0, 0.0))
    mb.add_flexible_body("airframe", None, modal=rest_body_data(airframe), hinge="free")
    mb.add_node("gimbal", "airframe", grid=1)
    mb.add_body("engine", "airframe", mass=ENGINE_MASS, com=tuple(cg), inertia=ENGINE_INERTIA, hinge="ujoint",
                axes=[(0.0, 1.0, 0.0), (0.0, 0.0, 1.0)], parent_node="gimbal", prescribed=mode == "prescribed")
    scene = Assembly("launch_vehicle")
    scene.add(MultibodyModel("multibody", mb.compile()))
    scene.add(GimbalActuator("gimbal", mode=mode, kp=kp))
    scene.attach("gimbal", hinge="engine")
    scene.add(Constant("command", unit="rad", shape=(2,), value=[0.0, 0.0]))
    scene.connect("command.y", "gimbal.angle_command")
    model = linearize(Simulation(scene), ["gimbal.angle_command"], ["multibody.engine.q"], tolerance=1e-13)
    modes = state_space_modes(model.A)
    # the prescribed mode's servo reference (30 rad/s, damping 0.7) is the only damped pair
    return modes.frequencies_hz[modes.damping_ratios < 0.1], modes


def test_flexible_airframe_gimbal_closed_loop_shows_structure_frequencies_open_loop_coupled(tmp_path):
    """TM-2020-5008164 App. F.4 on a flexible (EOTM) airframe. Load-torque feedback closed (torque mode,
    K_LT = 1, zero servo gains): the gimbal is a frictionless bearing, and the system frequencies are
    those of the FE model with the engine on a pin (RBE2 123 + roll). Loop open (prescribed mode, K_LT =
    0): the gimbal is rigid and they are those of the FE model with the engine welded on (CONM2 at the
    gimbal grid), clearly lower (Fig. F.4.2). With the engine's CG at the gimbal the closed loop shows
    the airframe's own FE frequencies with only the engine's mass (and its roll inertia, locked by the
    U-joint, after condensing the free pitch/yaw inertia) added at the gimbal.

    The airframe mode set is complete, so the multibody model is the FE model exactly; what is left is
    the truncation of the finite-difference linearization (the gimbal on the deforming grid makes the
    accelerations nonlinear in the modal coordinates even at rest). Its error follows the linearization
    tolerance (open loop: 2e-5 / 2e-7 / 2e-9 / 2e-11 at tolerance 1e-6 / 1e-8 / 1e-10 / 1e-12), so the
    scene is linearized at tolerance 1e-13 and compared at 1e-10 relative; measured over the first 12
    modes (0.42 to 12 Hz): 3.6e-13 closed, 2.2e-12 open, 1.2e-14 with the CG at the gimbal."""
    closed, modes = _gimbal_scene_modes(tmp_path, "torque", ENGINE_CG)
    assert modes.n_rigid == 16      # 6 rigid-body + 2 free gimbal DOFs, each a double zero
    opened, _ = _gimbal_scene_modes(tmp_path, "prescribed", ENGINE_CG)
    pinned = _fe_frequencies(_pinned_engine_deck(ENGINE_CG), tmp_path / "pinned.dat")
    welded_deck = _airframe_deck()
    welded_deck.conm2.append((9001, 1, ENGINE_MASS, ENGINE_CG, ENGINE_INERTIA))
    welded = _fe_frequencies(welded_deck, tmp_path / "welded.dat")
    assert_allclose(closed[:N_COMPARED], pinned[:N_COMPARED], rtol=1e-10)
    assert_allclose(opened[:N_COMPARED], welded[:N_COMPARED], rtol=1e-10)
    assert np.all(opened[:6] < 0.97 * closed[:6])  # the rigid gimbal couples the engine in: lower modes

    # CG at the gimbal: closed loop = the structure's own modes + the engine's mass at the gimbal
    at_gimbal, _ = _gimbal_scene_modes(tmp_path, "torque", np.zeros(3))
    free_axes, roll = [1, 2], [0]
    roll_inertia = ENGINE_INERTIA[0, 0] - ENGINE_INERTIA[np.ix_(roll, free_axes)] @ np.linalg.solve(
        ENGINE_INERTIA[np.ix_(free_axes, free_axes)], ENGINE_INERTIA[np.ix_(free_axes, roll)])
    own_deck = _airframe_deck()
    own_deck.conm2.append((9001, 1, ENGINE_MASS, np.zeros(3), np.diag([roll_inertia.item(), 0.0, 0.0])))
    own = _fe_frequencies(own_deck, tmp_path / "own.dat")
    assert_allclose(at_gimbal[:N_COMPARED], own[:N_COMPARED], rtol=1e-10)


def test_flexible_airframe_gimbal_servo_stiffness_is_the_actuator_spring(tmp_path):
    """Torque mode with a servo stiffness kp (K_LT = 1): about a held command the actuator is a
    rotational spring between engine and airframe on each gimbal axis (TM Fig. F.4.1's actuator
    spring). Reference: the pinned FE model plus CELAS2 springs kp between grid 1 and the engine grid
    on components 5 and 6 (the springs add the engine's two rocking modes, near 3 Hz for this engine).
    Tolerance as above (measured 1.0e-11)."""
    kp = 2.0e5  # N m/rad
    sprung, modes = _gimbal_scene_modes(tmp_path, "torque", ENGINE_CG, kp=kp)
    assert modes.n_rigid == 12      # the springs hold the gimbal: 6 rigid-body modes only
    reference = _fe_frequencies(_pinned_engine_deck(ENGINE_CG), tmp_path / "sprung.dat",
                                [f"CELAS2, 7001, {kp!r}, 1, 5, 1000, 5", f"CELAS2, 7002, {kp!r}, 1, 6, 1000, 6"])
    assert_allclose(sprung[:N_COMPARED], reference[:N_COMPARED], rtol=1e-10)

"""Scenes with known linearizations for the linearization tests.

MassSpringDamperChain: masses m_i in a chain, spring k_1 / damper c_1 from the wall to mass 1 and
k_i / c_i between masses i-1 and i; force f_i on mass i. Linear, so
    x = [positions; velocities],  x' = [[0, I], [-M^-1 K, -M^-1 C]] x + [[0], [M^-1]] f
with the tridiagonal chain stiffness K and damping C. Its accelerations are a feedthrough output
(a D matrix of M^-1).
"""

from __future__ import annotations

import numpy as np
from numba import njit

from dynamics import Multibody
from shell.assembly import Assembly
from shell.model import InputPort, Model, OutputPort, Parameter, State
from shell.models.blocks import Constant, Gain
from shell.models.multibody import MultibodyModel
from shell.simulation import Simulation

N_MASSES = 3


@njit(cache=True)
def _chain_accelerations(x, u, p, out):
    n = u.shape[0]
    for i in range(n):
        pos, vel = x[i], x[n + i]
        inner_pos = x[i - 1] if i > 0 else 0.0
        inner_vel = x[n + i - 1] if i > 0 else 0.0
        force = u[i] - p[n + i] * (pos - inner_pos) - p[2 * n + i] * (vel - inner_vel)
        if i + 1 < n:
            force += p[n + i + 1] * (x[i + 1] - pos) + p[2 * n + i + 1] * (x[n + i + 1] - vel)
        out[i] = force / p[i]


@njit(cache=True)
def _chain_state_outputs(t, x, z, u, p, y):
    n = u.shape[0]
    y[:n] = x[:n]


@njit(cache=True)
def _chain_feedthrough(t, x, z, u, p, y):
    n = u.shape[0]
    _chain_accelerations(x, u, p, y[n:])


@njit(cache=True)
def _chain_derivatives(t, x, z, u, p, xdot):
    n = u.shape[0]
    xdot[:n] = x[n:]
    _chain_accelerations(x, u, p, xdot[n:])


class MassSpringDamperChain(Model):
    """Linear chain of masses, springs and dampers (see the module docstring)."""

    summary = "linear mass-spring-damper chain (linearization test plant)"
    parameters = (Parameter("mass", "kg", [2.0, 3.0, 0.5], (N_MASSES,)),
                  Parameter("stiffness", "N/m", [400.0, 250.0, 90.0], (N_MASSES,)),
                  Parameter("damping", "N*s/m", [3.0, 1.5, 0.2], (N_MASSES,)))
    inputs = (InputPort("force", "N", (N_MASSES,), "force on each mass", feedthrough=True),)
    outputs = (OutputPort("position", "m", (N_MASSES,), "mass positions"),
               OutputPort("acceleration", "m/s^2", (N_MASSES,), "mass accelerations", feedthrough=True))
    continuous_states = (State("position", "m", (N_MASSES,), [0.01, -0.02, 0.03]),
                         State("velocity", "m/s", (N_MASSES,), [0.1, 0.0, -0.2]))
    state_outputs = staticmethod(_chain_state_outputs)
    feedthrough_outputs = staticmethod(_chain_feedthrough)
    derivatives = staticmethod(_chain_derivatives)


def chain_matrices(m, k, c):
    """Analytic (A, B) of the chain and its (M^-1 K, M^-1 C)."""
    n = len(m)
    K = np.zeros((n, n))
    C = np.zeros((n, n))
    for i in range(n):
        K[i, i] += k[i]
        C[i, i] += c[i]
        if i > 0:
            K[i - 1, i - 1] += k[i]
            K[i - 1, i] -= k[i]
            K[i, i - 1] -= k[i]
            C[i - 1, i - 1] += c[i]
            C[i - 1, i] -= c[i]
            C[i, i - 1] -= c[i]
    Minv = np.diag(1.0 / np.asarray(m))
    A = np.block([[np.zeros((n, n)), np.eye(n)], [-Minv @ K, -Minv @ C]])
    B = np.vstack([np.zeros((n, n)), Minv])
    return A, B


def chain_scene(force_unit="kN", gain=0.5):
    """A command (in ``force_unit``) through an amplifier (gain) into the chain's forces, and a
    position sensor (gain 1000, output in mm)."""
    scene = Assembly("scene")
    scene.add(Constant("command", unit=force_unit, shape=(N_MASSES,), value=[0.001, 0.0, -0.002]))
    scene.add(Gain("amplifier", unit=force_unit, shape=(N_MASSES,), k=gain))
    scene.add(MassSpringDamperChain("chain"))
    scene.add(Gain("sensor", unit="m", output_unit="mm", shape=(N_MASSES,), k=1000.0))
    scene.connect("command.y", "amplifier.u")
    scene.connect("amplifier.y", "chain.force")
    scene.connect("chain.position", "sensor.u")
    return Simulation(scene, integrator="rk4", step=0.01)


def spinning_body_scene(inertia, omega0, attitude=(1.0, 0.0, 0.0, 0.0)):
    """A rigid body on a free hinge spinning at omega0 (body axes), torque and force at its 'cg' node."""
    mb = Multibody(gravity=(0.0, 0.0, 0.0))
    mb.add_body("body", None, mass=50.0, inertia=inertia, hinge="free")
    mb.add_node("cg", "body")
    system = mb.compile()
    q0 = system.neutral_configuration()
    q0[:4] = attitude
    u0 = np.zeros(system.nu)
    u0[:3] = omega0
    scene = Assembly("scene")
    scene.add(MultibodyModel("multibody", system, initial_q=q0, initial_u=u0))
    return Simulation(scene, integrator="rk4", step=0.01)


def pendulum_scene(angle, length=1.5, mass=2.0, gravity=9.81):
    """A point-like pendulum (mass at ``length`` along -y of a revolute hinge about z), gravity -y."""
    mb = Multibody(gravity=(0.0, -gravity, 0.0))
    mb.add_body("rod", None, mass=mass, com=(0.0, -length, 0.0), inertia=[1e-3, 1e-3, 1e-3], hinge="revolute",
                axis=(0.0, 0.0, 1.0))
    mb.add_node("tip", "rod", position=(0.0, -length, 0.0))
    system = mb.compile()
    scene = Assembly("scene")
    scene.add(MultibodyModel("multibody", system, initial_q=[angle], initial_u=[0.0]))
    return Simulation(scene, integrator="rk4", step=0.01), system


def launch_vehicle_scene(thrust, prescribed):
    """Rigid airframe on a free hinge (origin at its CG) with a gimbaled engine on a U-joint (pitch about
    airframe y, then yaw about the engine's z), thrust along the engine's +x at the gimbal (a Constant
    into the nozzle node's force), a sensor node on the airframe; data of
    tests/linearize/launch_vehicle_reference.py (TM-2020-5008164 App. F complex test case, rigid)."""
    from tests.linearize import launch_vehicle_reference as lv

    mb = Multibody(gravity=(0.0, 0.0, 0.0))
    mb.add_body("airframe", None, mass=lv.AIRFRAME_MASS, inertia=lv.AIRFRAME_INERTIA, hinge="free")
    mb.add_node("sensor", "airframe", position=tuple(lv.SENSOR))
    mb.add_body("engine", "airframe", mass=lv.ENGINE_MASS, com=tuple(lv.ENGINE_CG), inertia=lv.ENGINE_INERTIA,
                hinge="ujoint", axes=[(0.0, 1.0, 0.0), (0.0, 0.0, 1.0)], inboard_position=tuple(lv.GIMBAL),
                prescribed=prescribed)
    mb.add_node("nozzle", "engine")
    system = mb.compile()
    scene = Assembly("launch_vehicle")
    scene.add(MultibodyModel("multibody", system))
    scene.add(Constant("thrust", unit="N", shape=(3,), value=[thrust, 0.0, 0.0]))
    scene.connect("thrust.y", "multibody.nozzle.force")
    return Simulation(scene, integrator="rk4", step=0.01)

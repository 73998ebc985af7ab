"""Closed-chain mechanisms built as a tree plus closure constraints (engine side), and their geometry.

* the crank-rocker four-bar of tests/flexible/test_constraints.py (crank 1 m, coupler 3 m, rocker 2.5 m,
  ground 3 m; slender rods, gravity along -y);
* a slider-crank (crank 1 m, rod 3 m, a slider held on the x axis by a prismatic closure);
* Andrews' squeezing mechanism (seven bodies, three loops closed at one point, a spring and a driving torque;
  Hairer and Wanner, *Solving Ordinary Differential Equations II*, 2nd ed., 1996, sec. VII.7; parameters of
  the IVP test set of Mazzia and Magherini, problem "andrews").
"""

from __future__ import annotations

import numpy as np

from dynamics import Multibody
from dynamics.constraints import ClosureConstraint, ConstrainedSystem
from dynamics.force_elements import SpringDamper

Z = (0.0, 0.0, 1.0)

CRANK, COUPLER, ROCKER, GROUND = 1.0, 3.0, 2.5, 3.0
FOUR_BAR_MASSES = (1.0, 2.0, 1.5)


def rod(length, mass):
    """Slender rod along x from its hinge: mass, CG, inertia about the CG (izz = m L^2 / 12 + 1e-3)."""
    return dict(mass=mass, com=(length / 2, 0.0, 0.0),
                inertia=[1e-3, mass * length ** 2 / 12, mass * length ** 2 / 12 + 1e-3])


def four_bar(gravity=(0.0, -9.81, 0.0), baumgarte=(0.0, 0.0)):
    mb = Multibody(gravity=gravity)
    mb.add_body("crank", None, hinge="revolute", axis=Z, **rod(CRANK, FOUR_BAR_MASSES[0]))
    mb.add_body("coupler", "crank", hinge="revolute", axis=Z, inboard_position=(CRANK, 0, 0),
                **rod(COUPLER, FOUR_BAR_MASSES[1]))
    mb.add_body("rocker", None, hinge="revolute", axis=Z, inboard_position=(GROUND, 0, 0),
                **rod(ROCKER, FOUR_BAR_MASSES[2]))
    mb.add_node("coupler_tip", "coupler", position=(COUPLER, 0, 0))
    mb.add_node("rocker_tip", "rocker", position=(ROCKER, 0, 0))
    return ConstrainedSystem(mb.compile(), [ClosureConstraint("coupler_tip", "rocker_tip", "revolute", axis=Z,
                                                              name="pin")], baumgarte=baumgarte)


def rocker_angle(crank_angle):
    """Analytic loop closure: rocker angle (upper branch) for a crank angle (circle intersection)."""
    P = CRANK * np.array([np.cos(crank_angle), np.sin(crank_angle)])
    C = np.array([GROUND, 0.0])
    dvec = P - C
    dist = np.linalg.norm(dvec)
    along = (ROCKER ** 2 - COUPLER ** 2 + dist ** 2) / (2 * dist)
    h = np.sqrt(ROCKER ** 2 - along ** 2)
    e = dvec / dist
    Q = C + along * e + h * np.array([-e[1], e[0]])
    if Q[1] < 0:
        Q = C + along * e - h * np.array([-e[1], e[0]])
    return np.arctan2(Q[1] - C[1], Q[0] - C[0]), Q, P


def rk4_step(f, y, h):
    """One classical Runge-Kutta step of ``y' = f(t, y)`` (autonomous)."""
    k1 = f(0.0, y)
    k2 = f(0.0, y + h / 2 * k1)
    k3 = f(0.0, y + h / 2 * k2)
    k4 = f(0.0, y + h * k3)
    return y + h / 6 * (k1 + 2 * k2 + 2 * k3 + k4)


def four_bar_state(crank_angle, crank_rate):
    """Tree coordinates on the loop (upper branch), with only the crank rate given (project to finish)."""
    theta3, Q, P = rocker_angle(crank_angle)
    phi2 = np.arctan2(Q[1] - P[1], Q[0] - P[0])
    return np.array([crank_angle, phi2 - crank_angle, theta3]), np.array([crank_rate, 0.0, 0.0])


ROD_LENGTH = 3.0
SLIDER_MASS = 2.0


def slider_crank(gravity=(0.0, -9.81, 0.0), crank_angle=np.radians(60.0), baumgarte=(0.0, 0.0)):
    """Crank (revolute at the origin), rod (revolute on the crank tip), slider (revolute on the rod tip) held
    on the world x axis without turning by a prismatic closure. Returns the system and the assembled q at
    ``crank_angle``."""
    mb = Multibody(gravity=gravity)
    mb.add_body("crank", None, hinge="revolute", axis=Z, **rod(CRANK, 1.0))
    mb.add_body("rod", "crank", hinge="revolute", axis=Z, inboard_position=(CRANK, 0, 0), **rod(ROD_LENGTH, 2.0))
    mb.add_body("slider", "rod", hinge="revolute", axis=Z, inboard_position=(ROD_LENGTH, 0, 0), mass=SLIDER_MASS,
                inertia=[0.01, 0.02, 0.03])
    mb.add_node("slider_pin", "slider")
    system = mb.compile()
    q = slider_crank_angles(crank_angle)
    guide = ClosureConstraint("slider_pin", None, "prismatic", axis=(1.0, 0.0, 0.0), name="guide",
                              world_rotation=np.eye(3), world_position=np.zeros(3))
    return ConstrainedSystem(system, [guide], baumgarte=baumgarte), q


def slider_crank_angles(crank_angle):
    rod_angle = -np.arcsin(CRANK * np.sin(crank_angle) / ROD_LENGTH)
    return np.array([crank_angle, rod_angle - crank_angle, -rod_angle])


# Andrews' squeezing mechanism (test set "andrews": masses, inertias about the centres of mass, geometry)
ANDREWS = dict(m=(0.04325, 0.00365, 0.02373, 0.00706, 0.07050, 0.00706, 0.05498),
               i=(2.194e-6, 4.410e-7, 5.255e-6, 5.667e-7, 1.169e-5, 5.667e-7, 1.912e-5),
               xa=-0.06934, ya=-0.00227, xb=-0.03635, yb=0.03273, xc=0.014, yc=0.072,
               d=28e-3, da=115e-4, e=2e-2, ea=1421e-5, rr=7e-3, ra=92e-5, ss=35e-3, sa=1874e-5, sb=1043e-5,
               sc=18e-3, sd=2e-2, ta=2308e-5, tb=916e-5, u=4e-2, ua=1228e-5, ub=449e-5, zf=2e-2, zt=4e-2,
               fa=1421e-5, mom=0.033, c0=4530.0, l0=0.07785)
# initial angles (beta, Theta, gamma, Phi, delta, Omega, epsilon) and the reference at t = 0.03 s (PSIDE,
# tolerances 1e-14, test set "andrews", solution subroutine)
ANDREWS_Y0 = (-0.0617138900142764496358948458001, 0.0, 0.455279819163070380255912382449,
              0.222668390165885884674473185609, 0.487364979543842550225598953530,
              -0.222668390165885884674473185609, 1.23054744454982119249735015568)
ANDREWS_REFERENCE = (0.1581077119629904e2, -0.1575637105984298e2, 0.4082224013073101e-1, -0.5347301163226948,
                     0.5244099658805304, 0.5347301163226948, 0.1048080741042263e1)
ANDREWS_ORDER = (0, 1, 2, 4, 3, 6, 5)
"""Position in the tree's q (K1, K2, K3, K5, K4, K7, K6) of each of the test set's angles."""


def andrews():
    """Seven bodies in three trees (K1-K2 from O, K3 from B, K5-K4 and K7-K6 from A), revolute closures at
    the common point E (K2's end on K3's, K4's and K6's), the spring from K3's point D to the ground point C,
    and the torque ``mom`` on K1's hinge (apply it as ``tau``). Body frames: x along the angle's direction;
    each body's centre of mass where the test set's mass matrix puts it (bodies pivoting at one fixed point
    have their centre of mass in an arbitrary direction at the given distance)."""
    a = ANDREWS
    m, i = a["m"], a["i"]

    def add(name, parent, k, com, at):
        mb.add_body(name, parent, hinge="revolute", axis=Z, inboard_position=(*at, 0.0), mass=m[k],
                    com=(*com, 0.0), inertia=[i[k], i[k], i[k]])

    mb = Multibody(gravity=(0.0, 0.0, 0.0))
    add("K1", None, 0, (a["ra"], 0.0), (0.0, 0.0))
    add("K2", "K1", 1, (-a["da"], 0.0), (a["rr"], 0.0))
    add("K3", None, 2, (a["sa"], a["sb"]), (a["xb"], a["yb"]))
    add("K5", None, 4, (a["ta"], a["tb"]), (a["xa"], a["ya"]))
    add("K4", "K5", 3, (0.0, -(a["e"] - a["ea"])), (a["zt"], 0.0))
    add("K7", None, 6, (a["ua"], a["ub"]), (a["xa"], a["ya"]))
    add("K6", "K7", 5, (a["zf"] - a["fa"], 0.0), (0.0, -a["u"]))
    mb.add_node("E2", "K2", position=(-a["d"], 0.0, 0.0))
    mb.add_node("E3", "K3", position=(0.0, -a["ss"], 0.0))
    mb.add_node("D", "K3", position=(a["sd"], -a["sc"], 0.0))
    mb.add_node("E4", "K4", position=(0.0, -a["e"], 0.0))
    mb.add_node("E6", "K6", position=(a["zf"], 0.0, 0.0))
    closures = [ClosureConstraint("E2", node, "revolute", axis=Z, name=f"E{k}") for k, node in
                ((3, "E3"), (4, "E4"), (6, "E6"))]
    spring = SpringDamper("spring", "D", world_point=(a["xc"], a["yc"], 0.0), stiffness=a["c0"],
                          free_length=a["l0"])
    return ConstrainedSystem(mb.compile(), closures, [spring])


def andrews_q(angles):
    q = np.empty(7)
    q[list(ANDREWS_ORDER)] = angles
    return q

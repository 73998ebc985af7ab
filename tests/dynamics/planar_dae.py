"""An independent formulation of planar mechanisms: absolute coordinates and a differential-algebraic system.

Each body i has the coordinates ``z_i = (x_i, y_i, theta_i)`` of its centre of mass and orientation; joints
are algebraic constraints ``Phi(z) = 0`` on them (Nikravesh, *Computer-Aided Analysis of Mechanical Systems*,
1988, ch. 6 and 13; Haug, *Computer-Aided Kinematics and Dynamics of Mechanical Systems*, 1989, ch. 6):

* revolute between point ``s_i`` of body i and ``s_j`` of body j (or a ground point): ``r_i + A_i s_i - r_j -
  A_j s_j = 0``, with ``A(theta)`` the planar rotation;
* translational along a ground line (point ``P``, unit direction ``d``, normal ``n``) at a fixed angle:
  ``n . (r_i + A_i s_i - P) = 0``, ``theta_i - theta_0 = 0``.

The equations of motion ``M z'' = Q + Phi_z' lambda``, ``Phi_z z'' = gamma - 2 alpha Phi' - beta^2 Phi``
(``gamma = -(Phi_z z')_z z'``, Baumgarte-stabilized) are solved for ``z''`` at every evaluation and integrated
as an ODE. Nothing here uses the engine: the tests compare the engine's tree-with-closures solution against it.
"""

from __future__ import annotations

import numpy as np


def rotation(theta):
    c, s = np.cos(theta), np.sin(theta)
    return np.array([[c, -s], [s, c]])


def rotation_rate(theta):
    """dA/dtheta."""
    c, s = np.cos(theta), np.sin(theta)
    return np.array([[-s, -c], [c, -s]])


class PlanarMechanism:
    """Bodies ``(mass, inertia about the centre of mass)``, joints, gravity ``(gx, gy)`` and applied torques
    (a function ``torques(t, z, zdot)`` returning one torque per body)."""

    def __init__(self, bodies, gravity=(0.0, 0.0), torques=None, baumgarte=(10.0, 10.0)):
        self.masses = np.array([m for m, _ in bodies], dtype=float)
        self.inertias = np.array([j for _, j in bodies], dtype=float)
        self.n = len(bodies)
        self.gravity = np.asarray(gravity, dtype=float)
        self.torques = torques
        self.alpha, self.beta = baumgarte
        self.joints = []

    def revolute(self, i, s_i, j=None, s_j=(0.0, 0.0)):
        """Point s_i (body i, body axes from its centre of mass) pinned to s_j of body j, or to the ground
        point s_j when j is None."""
        self.joints.append(("revolute", i, np.asarray(s_i, dtype=float), j, np.asarray(s_j, dtype=float)))

    def translational(self, i, s_i, point, direction, theta0):
        d = np.asarray(direction, dtype=float) / np.linalg.norm(direction)
        self.joints.append(("translational", i, np.asarray(s_i, dtype=float), np.asarray(point, dtype=float),
                            np.array([-d[1], d[0]]), float(theta0)))

    def constraints(self, z, zdot):
        """(Phi, Phi_z, gamma)."""
        rows, jac, gam = [], [], []
        for joint in self.joints:
            if joint[0] == "revolute":
                _, i, si, j, sj = joint
                th_i, w_i = z[3 * i + 2], zdot[3 * i + 2]
                phi = z[3 * i:3 * i + 2] + rotation(th_i) @ si
                J = np.zeros((2, 3 * self.n))
                J[:, 3 * i:3 * i + 2] = np.eye(2)
                J[:, 3 * i + 2] = rotation_rate(th_i) @ si
                g = rotation(th_i) @ si * w_i ** 2
                if j is None:
                    phi = phi - sj
                else:
                    th_j, w_j = z[3 * j + 2], zdot[3 * j + 2]
                    phi = phi - z[3 * j:3 * j + 2] - rotation(th_j) @ sj
                    J[:, 3 * j:3 * j + 2] = -np.eye(2)
                    J[:, 3 * j + 2] = -rotation_rate(th_j) @ sj
                    g = g - rotation(th_j) @ sj * w_j ** 2
                rows.extend(phi)
                jac.extend(J)
                gam.extend(g)
            else:
                _, i, si, P, nrm, th0 = joint
                th_i, w_i = z[3 * i + 2], zdot[3 * i + 2]
                rows.append(nrm @ (z[3 * i:3 * i + 2] + rotation(th_i) @ si - P))
                J = np.zeros(3 * self.n)
                J[3 * i:3 * i + 2] = nrm
                J[3 * i + 2] = nrm @ rotation_rate(th_i) @ si
                jac.append(J)
                gam.append(nrm @ rotation(th_i) @ si * w_i ** 2)
                rows.append(th_i - th0)
                J = np.zeros(3 * self.n)
                J[3 * i + 2] = 1.0
                jac.append(J)
                gam.append(0.0)
        return np.array(rows), np.array(jac), np.array(gam)

    def rates(self, t, y):
        n3 = 3 * self.n
        z, zdot = y[:n3], y[n3:]
        M = np.diag(np.repeat(self.masses, 3))
        M[2::3, 2::3] = np.diag(self.inertias)
        Q = np.zeros(n3)
        Q[0::3] = self.masses * self.gravity[0]
        Q[1::3] = self.masses * self.gravity[1]
        if self.torques is not None:
            Q[2::3] += self.torques(t, z, zdot)
        phi, J, gamma = self.constraints(z, zdot)
        rhs = gamma - 2.0 * self.alpha * (J @ zdot) - self.beta ** 2 * phi
        m = len(phi)
        K = np.block([[M, J.T], [J, np.zeros((m, m))]])
        zddot = np.linalg.solve(K, np.concatenate([Q, rhs]))[:n3]
        return np.concatenate([zdot, zddot])

"""Build the same system in flexshell and in Pinocchio and translate coordinates between them.

Coordinate map (flexshell -> Pinocchio), per hinge:
* revolute / prismatic: the same scalar;
* spherical: our [w, x, y, z] -> Pinocchio [x, y, z, w]; the angular velocity (child frame) is the same;
* free: our [w, x, y, z, px, py, pz] -> Pinocchio [px, py, pz, x, y, z, w]; our u = [omega; v] ->
  Pinocchio v = [v; omega] (both in the child frame); generalized forces [torque; force] -> [force; torque];
* U-joint: the same two angles (R = R(a1, q1) R(a2, q2) in both);
* translation: the same position and velocity (Pinocchio's ``JointModelTranslation``).
Pinocchio's joint frame is our hinge outboard frame M; inertias and child placements are re-expressed
in M when a body's outboard frame is not its body frame.
"""

from __future__ import annotations

import numpy as np
import pinocchio as pin


class CoordinateMap:
    """Permutations between flexshell (q, u) and Pinocchio (q, v) for one pair of models."""

    def __init__(self, system, model, joint_ids):
        self.system = system
        self.model = model
        nq_pin, nv_pin = model.nq, model.nv
        self.q_ours_to_pin = np.full(nq_pin, -1)
        self.v_ours_to_pin = np.full(nv_pin, -1)
        for b, jid in enumerate(joint_ids):
            if jid is None:
                continue
            joint = model.joints[jid]
            qs, us = system.q_slices[b], system.u_slices[b]
            hinge = system.hinge_names[b]
            iq, iv = joint.idx_q, joint.idx_v
            if hinge == "free":
                self.q_ours_to_pin[iq:iq + 7] = np.arange(qs.start, qs.stop)[[4, 5, 6, 1, 2, 3, 0]]
                self.v_ours_to_pin[iv:iv + 6] = np.arange(us.start, us.stop)[[3, 4, 5, 0, 1, 2]]
            elif hinge == "spherical":
                self.q_ours_to_pin[iq:iq + 4] = np.arange(qs.start, qs.stop)[[1, 2, 3, 0]]
                self.v_ours_to_pin[iv:iv + 3] = np.arange(us.start, us.stop)
            else:
                n = qs.stop - qs.start
                self.q_ours_to_pin[iq:iq + n] = np.arange(qs.start, qs.stop)
                self.v_ours_to_pin[iv:iv + n] = np.arange(us.start, us.stop)
        assert (self.q_ours_to_pin >= 0).all() and (self.v_ours_to_pin >= 0).all()

    def q_to_pin(self, q):
        return q[self.q_ours_to_pin]

    def v_to_pin(self, v):
        return v[self.v_ours_to_pin]

    def v_from_pin(self, v_pin):
        out = np.empty(self.system.nu)
        out[self.v_ours_to_pin] = v_pin
        return out

    def matrix_from_pin(self, M_pin):
        out = np.empty((self.system.nu, self.system.nu))
        out[np.ix_(self.v_ours_to_pin, self.v_ours_to_pin)] = M_pin
        return out


def pinocchio_from_urdf(system, path, floating_base):
    model = pin.buildModelFromUrdf(str(path), pin.JointModelFreeFlyer()) if floating_base \
        else pin.buildModelFromUrdf(str(path))
    joint_ids = [model.getJointId(name) for name in system.joint_names]
    return model, CoordinateMap(system, model, joint_ids)


def _se3(R, p):
    return pin.SE3(np.asarray(R, dtype=float), np.asarray(p, dtype=float))


def pinocchio_from_builder(mb, system):
    """A Pinocchio model equivalent to a flexshell builder without locked hinges."""
    model = pin.Model()
    model.gravity = pin.Motion(np.concatenate([mb.gravity, np.zeros(3)]))
    T_BM = {}  # per body: pose of its outboard frame M in the body frame
    jid_of = {}
    # Pinocchio's CRBA needs each subtree's DOFs contiguous: add joints depth-first
    children = {None: []}
    for body in mb.bodies:
        children.setdefault(body.name, [])
        children[body.parent].append(body)
    depth_first, stack = [], list(reversed(children[None]))
    while stack:
        body = stack.pop()
        depth_first.append(body)
        stack.extend(reversed(children[body.name]))
    for body in depth_first:
        if body.hinge == "locked":
            raise ValueError("locked hinges have no Pinocchio joint; test them separately")
        T_pF = _se3(body.inboard_rotation, body.inboard_position)
        if body.parent is None:
            parent_jid = 0
            placement = T_pF
        else:
            parent_jid = jid_of[body.parent]
            placement = T_BM[body.parent].inverse() * T_pF
        a = body.axes
        joint = {"revolute": lambda: pin.JointModelRevoluteUnaligned(a[0]),
                 "prismatic": lambda: pin.JointModelPrismaticUnaligned(a[0]),
                 "ujoint": lambda: pin.JointModelUniversal(a[0], a[1]),
                 "spherical": lambda: pin.JointModelSpherical(),
                 "free": lambda: pin.JointModelFreeFlyer(),
                 "translation": lambda: pin.JointModelTranslation()}[body.hinge]()
        jid = model.addJoint(parent_jid, joint, placement, body.joint_name)
        T_BM[body.name] = _se3(body.outboard_rotation, body.outboard_position)
        R_BM, p_BM = body.outboard_rotation, body.outboard_position
        com_M = R_BM.T @ (body.com - p_BM)
        J_M = R_BM.T @ body.inertia @ R_BM
        model.appendBodyToJoint(jid, pin.Inertia(body.mass, com_M, J_M), pin.SE3.Identity())
        jid_of[body.name] = jid
    return model, CoordinateMap(system, model, [jid_of[b.name] for b in mb.bodies])


def random_state(system, rng, spread=1.0):
    q = system.neutral_configuration() + spread * rng.standard_normal(system.nq)
    system.normalize_quaternions(q)
    return q, rng.standard_normal(system.nu), rng.standard_normal(system.nu)

"""Sample models: reproducible random URDF trees for verification and benchmarks.

``random_urdf(n_bodies, ...)`` writes a URDF robot whose ``n_bodies`` moving links hang from a base link
in a chain or a random tree, with random joint placements, axes and physically valid inertias
(principal moments satisfying the triangle inequality, arbitrary principal axes). The same file loads in
flexshell (``Multibody.from_urdf``) and in peers such as Pinocchio, which is how the engine is verified.
"""

from __future__ import annotations

import numpy as np


def _random_rotation(rng):
    q = rng.standard_normal(4)
    q /= np.linalg.norm(q)
    w, x, y, z = q
    return np.array([
        [1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)],
        [2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)],
        [2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)],
    ])


def _random_inertia(rng, mass):
    """A physically valid inertia about the COM: moments obey the triangle inequality."""
    while True:
        moments = mass * rng.uniform(0.01, 0.1, size=3)
        s = np.sort(moments)
        if s[0] + s[1] > 1.05 * s[2]:
            break
    R = _random_rotation(rng)
    return R @ np.diag(moments) @ R.T


def _fmt(values):
    return " ".join(repr(float(v)) for v in values)


def random_urdf(n_bodies, *, topology="chain", joint_types=("revolute", "prismatic"), fixed_fraction=0.0,
                seed=0, name="random_robot"):
    """URDF text of a random robot with ``n_bodies`` moving links.

    ``topology``: ``"chain"`` (each link the child of the previous) or ``"tree"`` (each link the child
    of a uniformly chosen earlier link, including the base). ``joint_types`` are drawn uniformly for the
    moving joints. With ``fixed_fraction`` > 0 that fraction of extra links is welded by fixed joints
    (they carry mass; importers merge them).
    """
    if topology not in ("chain", "tree"):
        raise ValueError(f"topology must be 'chain' or 'tree', got {topology!r}")
    rng = np.random.default_rng(seed)
    lines = [f'<robot name="{name}">']

    def link(link_name):
        mass = rng.uniform(0.5, 3.0)
        com = rng.uniform(-0.2, 0.2, size=3)
        J = _random_inertia(rng, mass)
        lines.append(f'  <link name="{link_name}"><inertial><origin xyz="{_fmt(com)}" rpy="0 0 0"/>'
                     f'<mass value="{_fmt([mass])}"/><inertia ixx="{_fmt([J[0, 0]])}" ixy="{_fmt([J[0, 1]])}" '
                     f'ixz="{_fmt([J[0, 2]])}" iyy="{_fmt([J[1, 1]])}" iyz="{_fmt([J[1, 2]])}" '
                     f'izz="{_fmt([J[2, 2]])}"/></inertial></link>')

    def joint(joint_name, jtype, parent, child):
        xyz = rng.uniform(-0.5, 0.5, size=3)
        rpy = rng.uniform(-np.pi, np.pi, size=3)
        axis = rng.standard_normal(3)
        axis /= np.linalg.norm(axis)
        extra = f'<axis xyz="{_fmt(axis)}"/><limit lower="-3" upper="3" effort="100" velocity="10"/>' \
            if jtype != "fixed" else ""
        lines.append(f'  <joint name="{joint_name}" type="{jtype}"><parent link="{parent}"/>'
                     f'<child link="{child}"/><origin xyz="{_fmt(xyz)}" rpy="{_fmt(rpy)}"/>{extra}</joint>')

    link("base")
    link_names = ["base"]
    for i in range(n_bodies):
        child = f"link{i + 1}"
        parent = link_names[-1] if topology == "chain" else link_names[int(rng.integers(len(link_names)))]
        link(child)
        joint(f"joint{i + 1}", str(rng.choice(joint_types)), parent, child)
        link_names.append(child)
        if fixed_fraction > 0.0 and rng.uniform() < fixed_fraction:
            welded = f"welded{i + 1}"
            link(welded)
            joint(f"weld{i + 1}", "fixed", child, welded)
            link_names.append(welded)
    lines.append("</robot>")
    return "\n".join(lines) + "\n"

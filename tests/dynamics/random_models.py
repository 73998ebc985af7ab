"""Random multibody builders covering every hinge type, frame offsets and branching (test helper)."""

from __future__ import annotations

import numpy as np

from dynamics import Multibody
from dynamics.samples import _random_inertia, _random_rotation


def random_hinge_axes(rng, hinge):
    """Keyword arguments with random unit hinge axes: ``axis`` (revolute, prismatic), two perpendicular
    ``axes`` (U-joint), none otherwise."""
    kwargs = {}
    if hinge in ("revolute", "prismatic"):
        a = rng.standard_normal(3)
        kwargs["axis"] = a / np.linalg.norm(a)
    elif hinge == "ujoint":
        a1 = rng.standard_normal(3)
        a1 /= np.linalg.norm(a1)
        a2 = np.cross(a1, rng.standard_normal(3))
        kwargs["axes"] = [a1, a2 / np.linalg.norm(a2)]
    return kwargs


def random_multibody(n_bodies, seed, hinges=("revolute", "prismatic", "ujoint", "spherical", "free"),
                     root_hinge=None, branched=True, offsets=True, gravity=(0.0, 0.0, -9.81),
                     nodes_per_body=1):
    rng = np.random.default_rng(seed)
    mb = Multibody(gravity=gravity)
    names = []
    for i in range(n_bodies):
        name = f"b{i}"
        if i == 0:
            parent = None
        elif branched:
            parent = names[int(rng.integers(len(names)))]
        else:
            parent = names[-1]
        hinge = root_hinge if (i == 0 and root_hinge) else str(rng.choice(hinges))
        kwargs = random_hinge_axes(rng, hinge)
        mass = rng.uniform(0.5, 3.0)
        mb.add_body(name, parent, mass=mass, com=rng.uniform(-0.3, 0.3, 3), inertia=_random_inertia(rng, mass),
                    hinge=hinge, inboard_position=rng.uniform(-0.5, 0.5, 3),
                    inboard_rotation=_random_rotation(rng),
                    outboard_position=rng.uniform(-0.3, 0.3, 3) if offsets else (0, 0, 0),
                    outboard_rotation=_random_rotation(rng) if offsets else None, **kwargs)
        for k in range(nodes_per_body):
            mb.add_node(f"{name}_n{k}", name, position=rng.uniform(-0.5, 0.5, 3), rotation=_random_rotation(rng))
        names.append(name)
    return mb

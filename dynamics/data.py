"""The per-run data of an engine model: the workspace its algorithms write, and the run's mass properties.

Pinocchio's ``Data`` / MuJoCo's ``mjData``: a :class:`Data` belongs to one
:class:`dynamics.model.Model` (``model.create_data()``) and holds everything an evaluation writes:

* the kernels' workspace (:mod:`dynamics.layout`): ``ws_rot`` (nb, N_ROT, 3, 3), ``ws_vec`` (nb, N_VEC, 6),
  ``ws_mat`` (nb, N_MAT, 6, 6), and ``pool`` (the flexible bodies' and the dense solver's scratch), sized by the
  model; after an algorithm they hold its intermediate results (body poses, velocities, motion subspaces), which
  :func:`dynamics.algorithms.body_poses` and the linearization read;
* zero arrays for omitted inputs (writable like a caller's arrays, so numba compiles one specialization of each
  kernel, not one per read-only combination; nothing writes them);
* ``params``: the parameter array the kernels read for this run. It *is* the model's (read-only, shared, no copy)
  until this data's mass properties change (:func:`dynamics.algorithms.set_mass_properties`: mass depletion, a Monte
  Carlo run's dispersed masses); from then on the data has a private copy, still read-only to everyone but that
  function, and ``masses`` / ``definitions`` follow it. As Drake keeps a plant's mass parameters in each Context, a
  run's mass changes stay in that run and never reach the model or another data.

Two data of one model share nothing written, so they may run in two threads at once (the kernels hold the GIL, so
two threads interleave their calls rather than run them in parallel).
"""

from __future__ import annotations

import numpy as np

from dynamics import kernels as K
from dynamics import layout as L


def frozen(a, dtype=np.float64):
    """``a`` as a C-contiguous array of ``dtype`` that cannot be written (a copy when the conversion needs one): the
    model's arrays, and a data's own mass properties outside :func:`dynamics.algorithms.set_mass_properties`."""
    a = np.ascontiguousarray(a, dtype=dtype)
    a.setflags(write=False)
    return a


class Data:
    """Workspace and per-run mass properties of one run of a :class:`dynamics.model.Model` (module docstring);
    build with ``model.create_data()``."""

    def __init__(self, model, own_mass_properties=False, *, params=None, masses=None, definitions=None):
        self.model = model
        nb = model.nbodies
        self.ws_rot = np.zeros((nb, L.N_ROT, 3, 3))
        self.ws_vec = np.zeros((nb, L.N_VEC, 6))
        self.ws_mat = np.zeros((nb, L.N_MAT, 6, 6))
        self.pool = np.zeros(model.pool_size)
        K.initialize_workspace(model.topology, model.joint_rot, model.joint_vec, self.ws_rot, self.ws_mat)
        self.zero_body_forces = np.zeros((nb, 6))
        self.zero_node_forces = np.zeros((model.nnodes, 6))
        self.zero_u = np.zeros(model.nu)
        self.params = model.params if params is None else params
        self.masses = model.masses if masses is None else masses
        self.definitions = model.definitions if definitions is None else definitions
        if own_mass_properties:
            self.own_mass_properties()

    def __setstate__(self, state):
        # an unpickled or deep-copied data: its mass properties read-only again, as numpy restores arrays writable
        self.__dict__.update(state)
        for name in ("params", "masses"):
            getattr(self, name).setflags(write=False)

    @property
    def owns_mass_properties(self) -> bool:
        """Whether this data has its own copy of the mass properties (else it reads the model's)."""
        return self.params is not self.model.params

    def own_mass_properties(self):
        """Give this data a private copy of its mass properties now (no-op when it has one); returns ``self``.
        Compiled callers take the arrays once for a whole run (:func:`dynamics.engine.engine_data` calls this), so a
        later change must write into the array they hold, not replace it."""
        if not self.owns_mass_properties:
            self.params = frozen(np.array(self.params))
            self.masses = frozen(np.array(self.masses))
        return self

    def copy(self, mass_properties=False):
        """A new data of the same model with the same mass properties as this one (shared while neither changes
        them: copied now when this one has its own, or with ``mass_properties``) and a workspace of its own."""
        if self.owns_mass_properties or mass_properties:
            return Data(self.model, params=frozen(np.array(self.params)), masses=frozen(np.array(self.masses)),
                        definitions=self.definitions)
        return Data(self.model)

    def __repr__(self):
        return f"Data of {self.model!r}{', own mass properties' if self.owns_mass_properties else ''}"

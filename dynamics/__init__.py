"""flexshell's multibody engine: numba-compiled O(N) dynamics of trees of rigid and flexible bodies.

Pure numerics in SI units (no pint, no YAML). Build a system with :class:`dynamics.Multibody`, then
``compile()`` it into a :class:`dynamics.MultibodySystem`: an immutable :class:`dynamics.Model` of float64/int64
arrays (``system.model``) with a :class:`dynamics.Data` of its own (``system.data``: workspace and per-run mass
properties). The algorithms are free functions over ``(model, data, ...)`` (:mod:`dynamics.algorithms`, as
Pinocchio's ``aba(model, data, q, v, tau)``) and methods of the system; underneath they are
``numba.njit(cache=True)`` kernels (:mod:`dynamics.kernels`).
"""

from dynamics.compile_cache import configure as _configure_compile_cache

_configure_compile_cache()  # before any kernel module is imported: see dynamics.compile_cache

from dynamics.algorithms import (NodeKinematics, angular_momentum, bias_forces, body_poses,  # noqa: E402
                                 body_velocities, coordinate_rates, damping_matrix, forward_dynamics, inverse_dynamics, kinetic_energy,
                                 linear_momentum, mass_matrix, node_kinematics, potential_energy, set_mass_properties,
                                 stiffness_matrix)
from dynamics.builder import GROUND, Multibody  # noqa: E402
from dynamics.data import Data  # noqa: E402
from dynamics.errors import ModelDefinitionError, SingularConfigurationError  # noqa: E402
from dynamics.model import Model  # noqa: E402
from dynamics.system import MultibodySystem  # noqa: E402

__all__ = ["GROUND", "Data", "Model", "ModelDefinitionError", "Multibody", "MultibodySystem", "NodeKinematics",
           "SingularConfigurationError", "angular_momentum", "bias_forces", "body_poses", "body_velocities",
           "coordinate_rates", "damping_matrix", "forward_dynamics", "inverse_dynamics", "kinetic_energy",
           "linear_momentum", "mass_matrix", "node_kinematics", "potential_energy", "set_mass_properties",
           "stiffness_matrix"]

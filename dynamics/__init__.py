"""flexshell's multibody engine: numba-compiled O(N) dynamics of trees of rigid and flexible bodies.

Pure numerics in SI units (no pint, no YAML). Build a system with :class:`dynamics.Multibody`, then
``compile()`` it into an immutable :class:`dynamics.MultibodySystem` of float64/int64 arrays whose
algorithms are ``numba.njit(cache=True)`` kernels (:mod:`dynamics.kernels`).
"""

from dynamics.builder import GROUND, ModelDefinitionError, Multibody
from dynamics.system import MultibodySystem, NodeKinematics, SingularConfigurationError

__all__ = ["GROUND", "ModelDefinitionError", "Multibody", "MultibodySystem", "NodeKinematics",
           "SingularConfigurationError"]

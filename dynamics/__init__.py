"""flexshell's multibody engine: numba-compiled O(N) dynamics of trees of rigid and flexible bodies.

Pure numerics in SI units (no pint, no YAML). Build a system with :class:`dynamics.Multibody`, then
``compile()`` it into an immutable :class:`dynamics.MultibodySystem` of float64/int64 arrays whose
algorithms are ``numba.njit(cache=True)`` kernels (:mod:`dynamics.kernels`).
"""

from dynamics.compile_cache import configure as _configure_compile_cache

_configure_compile_cache()  # before any kernel module is imported: see dynamics.compile_cache

from dynamics.builder import GROUND, Multibody  # noqa: E402
from dynamics.errors import ModelDefinitionError, SingularConfigurationError  # noqa: E402
from dynamics.system import MultibodySystem, NodeKinematics  # noqa: E402

__all__ = ["GROUND", "ModelDefinitionError", "Multibody", "MultibodySystem", "NodeKinematics",
           "SingularConfigurationError"]

"""The engine's exceptions, in a module of their own so that every part of :mod:`dynamics` can raise them
without importing another part (the builder, the compiled system, reconfiguration, URDF import and the
flexible-body data all raise them)."""


class ModelDefinitionError(ValueError):
    """A body, hinge or node definition that cannot describe a physical system."""


class SingularConfigurationError(RuntimeError):
    """The articulated inertia of a hinge vanished: the forward dynamics has no unique solution."""

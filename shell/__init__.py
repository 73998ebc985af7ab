"""flexshell's component framework: models, ports with units, assemblies, scenarios, simulation.

The multibody engine lives in the sibling package :mod:`dynamics`; this package turns it and the
device models into scenes a user can run, linearize and disperse.
"""

__version__ = "0.1.0"

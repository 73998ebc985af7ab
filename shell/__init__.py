"""flexshell's component framework: models, ports with units, assemblies, scenarios, simulation.

The multibody engine lives in the sibling package :mod:`dynamics`; this package turns it and the
device models into scenes a user can run, linearize and disperse.
"""

import dynamics  # noqa: F401  (first: it sets numba's cache directory before any shell kernel compiles)

__version__ = "0.1.0"

"""Registers the test-only plants (tests/plants.py: BouncingBall, FiniteEscape) for the YAML scenes of
the tests; they are not among the models a user sees in ``flexshell models``."""

import tests.plants  # noqa: F401  (its @register_model decorators run on import)

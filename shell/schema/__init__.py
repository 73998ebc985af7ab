"""The scenario schema: reading, validating and overriding a YAML scenario, with messages that name the place.

A scenario (docs/scenario_schema.md) is read in three layers, each a module here:

* :mod:`shell.schema.document`: the YAML text with the line of every key and item, within size limits;
* :mod:`shell.schema.validation`: the vocabulary every check uses, :class:`Where` (file, line, key path) and the
  ``expect_*`` checks that refuse with what was expected and what was given;
* :mod:`shell.schema.sections` (the top-level sections, the validated :class:`Scenario`),
  :mod:`shell.schema.overrides` (``--set key.path=value``) and :mod:`shell.schema.multibody` (the
  ``multibody:`` section, read into an engine system).

Building the scene from a validated scenario (models, assemblies, connections, the Simulation) is
:mod:`shell.scenario`; other readers of user files (the Monte Carlo campaign file) reuse the vocabulary.
"""

# the package's public API, imported from here
from shell.schema.document import LineDict, LineList, ScenarioError, decode_scenario, load_yaml, show, type_name
from shell.schema.overrides import apply_override, apply_value, override_value
from shell.schema.sections import Scenario, check_sample_counts, connection_ends, load_scenario, parse_scenario
from shell.schema.validation import (Where, check_rate, check_time, expect_list, expect_mapping, expect_name, find,
                                     refuse_nan, seconds)

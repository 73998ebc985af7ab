"""Tests of the component framework (shell): units, models, wiring, scenarios, simulation, logs."""

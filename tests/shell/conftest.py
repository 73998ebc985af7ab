"""Shared helpers for the shell tests: small scenes built from signal blocks and test plants."""

import textwrap

import pytest

from shell.scenario import build_simulation, parse_scenario


@pytest.fixture
def scene():
    """Build a Simulation from an inline YAML scenario (dedented); file name 'scene.yaml'."""

    def build(text, overrides=None):
        return build_simulation(parse_scenario(textwrap.dedent(text), "scene.yaml", overrides))

    return build

"""The flexible-body verification suite checks the articulated-body recursion (the modal condensation,
hinges on deforming nodes): force it, since compile() would choose the dense solve for the small bodies
used here (dynamics.system.choose_solver). The dense solver is checked against the recursion and the
nodal reference in test_modal_condensation.py, with ``compile(solver="dense")``."""

import pytest

import dynamics.system


@pytest.fixture(autouse=True)
def articulated_body_solver(monkeypatch):
    monkeypatch.setattr(dynamics.system, "choose_solver",
                        lambda topology: ("aba", "articulated-body recursion (forced by tests/flexible/conftest.py)"))

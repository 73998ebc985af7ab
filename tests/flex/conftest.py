import os
import sys

import pytest

sys.path.insert(0, os.path.dirname(__file__))

DATA = os.path.join(os.path.dirname(__file__), "data")


@pytest.fixture
def data_dir():
    return DATA


@pytest.fixture
def write_deck(tmp_path):
    def _write(text, name="model.dat"):
        path = tmp_path / name
        path.write_text(text)
        return str(path)
    return _write


def pytest_collection_modifyitems(config, items):
    """Tests marked slow run only when asked for (-m slow), as pyproject's marker says."""
    if "slow" in (config.getoption("-m") or ""):
        return
    skip = pytest.mark.skip(reason="slow: run with -m slow")
    for item in items:
        if "slow" in item.keywords:
            item.add_marker(skip)

"""A run of a reused scene takes its dispersed values as objects (Campaign.dispersed_values), not as --set text
parsed again: those objects must be exactly what the text would read back as (same types, same bits), for every
kind of value a dispersion produces, including the awkward ones (exponents without a '.', -0.0, bare strings that
YAML resolves, non-finite numbers)."""

import math

import numpy as np

from shell.model import parse_period
from shell.montecarlo.campaign import _as_read, yaml_text
from shell.schema import Where, override_value


def _kind(x):
    return dict if isinstance(x, dict) else list if isinstance(x, list) else type(x)


def _same(a, b) -> bool:
    if _kind(a) is not _kind(b):  # YAML's LineDict/LineList (lines for messages) are dicts and lists
        return False
    if isinstance(a, float):
        return repr(a) == repr(b) or (math.isnan(a) and math.isnan(b))
    if isinstance(a, list):
        return len(a) == len(b) and all(_same(x, y) for x, y in zip(a, b))
    if isinstance(a, dict):
        return list(a) == list(b) and all(_same(a[k], b[k]) for k in a)
    return a == b


VALUES = [
    {"value": [400.00000000000006, 1e-05, -0.0, 3.0], "unit": "kg*m^2"},
    {"value": np.float64(2.5e-300), "unit": ""},
    {"value": [[1.0, 2.0], [3.5, -7e22]], "unit": "N*m/rad"},
    np.float64(0.1), np.int64(7), 3, True, None,
    "10 Hz", "5", "yes", "0.1 s", "[1, 2] N*m",
    [1.5, "on", 2], {"y": 1.0}, {"value": float("nan"), "unit": "m"}, float("inf"),
]


def test_direct_objects_equal_the_text_read_back():
    where = Where("campaign", 0, "test")
    for value in VALUES:
        expected = override_value(yaml_text(value), where)
        assert _same(_as_read(value), expected), (value, _as_read(value), expected)


def test_parsed_values_are_not_shared_between_runs():
    first = _as_read({"value": [1.5], "on": "x"})
    first["value"].append("changed by a run")
    assert _as_read({"value": [1.5], "on": "x"}) == {"value": [1.5], True: "x"}


def test_period_text_remembered_gives_the_same_fraction_and_still_refuses_bad_text():
    for text in ("10 Hz", "0.1 s", "1 kHz", "3 ms"):
        assert parse_period(text, "x") == parse_period(text, "y")
    import pytest

    from shell.model import ModelError
    with pytest.raises(ModelError, match="rate.x: a sample period must be positive"):
        parse_period("-1 s", "rate.x")
    with pytest.raises(ModelError, match="rate.y: a sample period must be positive"):
        parse_period("-1 s", "rate.y")  # remembered text still refused, naming the new place

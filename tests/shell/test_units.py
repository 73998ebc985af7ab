"""Units at the boundary: parsing user values, conversion factors, refusals."""

import subprocess
import sys

import numpy as np
import pytest
from numpy.testing import assert_allclose

from shell.units import UnitError, conversion_factor, to_magnitude


def test_value_forms_convert_to_declared_unit():
    # reference: 1 deg = pi/180 rad exactly (definition)
    assert_allclose(to_magnitude("5 deg/s", "rad/s"), 5 * np.pi / 180, rtol=1e-15)
    assert_allclose(to_magnitude("[1, 2, 3] deg", "rad", (3,)), np.radians([1, 2, 3]), rtol=1e-15)
    assert_allclose(to_magnitude(["1 deg", "2 deg"], "rad"), np.radians([1, 2]), rtol=1e-15)
    assert_allclose(to_magnitude({"value": [1, 2], "unit": "mm"}, "m"), [1e-3, 2e-3], rtol=1e-15)
    assert to_magnitude("20 kg*m^2", "kg*m**2") == 20.0
    assert to_magnitude(3, "N*m") == 3.0  # bare numbers are in the declared unit
    assert to_magnitude("100 ms", "s") == pytest.approx(0.1, rel=1e-15)
    # exponents without a dot (YAML 1.1 would read "1e5" as a string) and nested lists
    assert_allclose(to_magnitude("[1e5, 2E-6, -3.5e+2] kg*m^2", "kg*m^2", (3,)), [1e5, 2e-6, -350.0], rtol=0)
    assert_allclose(to_magnitude("[[1e3, 0], [0, 2e3]] g", "kg", (2, 2)), [[1.0, 0.0], [0.0, 2.0]], rtol=1e-15)


def test_conversion_factor_between_ports():
    assert conversion_factor("deg/s", "rad/s") == pytest.approx(np.pi / 180, rel=1e-15)
    assert conversion_factor("N*m", "N*m") == 1.0
    assert conversion_factor("km", "m") == pytest.approx(1000.0, rel=1e-15)


@pytest.mark.parametrize("value, unit, shape, fragment", [
    ("5 kg", "m", None, "unit dimensions differ: kg"),
    ("5 furlongz", "m", None, "furlongz"),
    (True, "m", None, "boolean"),
    ("[1, 2] m", "m", (3,), "expected shape (3,), given shape (2,)"),
    ({"value": 1}, "m", None, "exactly the keys 'value' and 'unit'"),
])
def test_refusals_name_the_place_and_the_mismatch(value, unit, shape, fragment):
    with pytest.raises(UnitError, match="where.key") as info:
        to_magnitude(value, unit, shape, "where.key")
    assert fragment in str(info.value)


def test_offset_units_are_refused_on_ports():
    with pytest.raises(UnitError, match="offset units"):
        conversion_factor("degC", "kelvin", "port")


_CONVERT = ("import shell.units as U; print(U.ureg.Quantity('5 deg/s').to('rad/s').magnitude, "
            "U.ureg.Quantity('1 lbf').to('N').magnitude)")


def _convert_in_a_fresh_process(cache_home):
    import shell  # noqa: F401 - sets numba's cache directory for this process

    env = {"XDG_CACHE_HOME": str(cache_home), "PATH": "/usr/bin:/bin", "HOME": str(cache_home)}
    import os

    import numba

    env.update({k: v for k, v in os.environ.items() if k in ("PYTHONPATH", "VIRTUAL_ENV")})
    env["NUMBA_CACHE_DIR"] = numba.config.CACHE_DIR  # the suite's warm kernels, whatever HOME says
    done = subprocess.run([sys.executable, "-c", _CONVERT], capture_output=True, text=True, env=env, timeout=300)
    assert done.returncode == 0, done.stderr
    return [float(v) for v in done.stdout.split()]


def test_registry_definitions_cache_gives_the_same_units(tmp_path):
    """The parsed pint definitions are cached under $XDG_CACHE_HOME/flexshell/pint (start-up time); a
    first process writes the cache, a second reads it, and an unusable cache location falls back to
    parsing: the same conversions every time."""
    expected = [np.radians(5.0), 4.4482216152605]
    first = _convert_in_a_fresh_process(tmp_path)
    assert list((tmp_path / "flexshell" / "pint").iterdir()), "no cache written"
    second = _convert_in_a_fresh_process(tmp_path)
    blocked = tmp_path / "not_a_directory"
    blocked.write_text("")
    fallback = _convert_in_a_fresh_process(blocked)
    for got in (first, second, fallback):
        np.testing.assert_allclose(got, expected, rtol=1e-12)


def test_pint_is_imported_without_dask_and_dask_still_imports():
    """shell.units keeps pint from importing dask (0.1-0.3 s of every start); a later `import dask` (Monte Carlo
    on Dask) must still work, in a fresh process where neither was imported before."""
    code = ("import sys; import shell.units as u; assert 'dask' not in sys.modules, 'pint imported dask'; "
            "assert float(u.ureg('3 km').to('m').magnitude) == 3000.0; "
            "import dask.distributed; print('ok')")
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120)
    assert done.returncode == 0, done.stderr
    assert done.stdout.strip() == "ok"

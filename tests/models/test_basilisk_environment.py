"""Eclipse, centered dipole, magnetometer and coarse sun sensor against Basilisk 2.12's modules in the
same process (benchmarks/basilisk_environment.py). Slow-marked: the default suite does not need bsk."""

import sys
import warnings
from pathlib import Path

import pytest

pytestmark = pytest.mark.slow

sys.path.insert(0, str(Path(__file__).resolve().parents[2] / "benchmarks"))


@pytest.fixture(scope="module")
def bsk(request):
    if "slow" not in (request.config.getoption("-m") or ""):
        pytest.skip("slow: run with -m slow")  # as tests/flex/conftest.py does for the whole suite
    pytest.importorskip("Basilisk")  # the bench extra
    import basilisk_environment
    warnings.simplefilter("ignore")  # Basilisk 2.12's deprecation notice on EclipseMsgPayload.shadowFactor
    return basilisk_environment


def test_conical_eclipse_equals_basilisk(bsk):
    result = bsk.compare_eclipse()
    assert result["points in penumbra"] > 50
    assert result["max |shadow difference|"] < 1e-12  # the same apparent-disc formula: measured 0


def test_dipole_and_magnetometer_equal_basilisk(bsk):
    result = bsk.compare_dipole_and_magnetometer()
    assert result["dipole max relative difference"] < 1e-13         # measured 1.9e-15
    assert result["magnetometer max relative difference"] < 1e-13   # measured 2.1e-15


def test_coarse_sun_sensor_equals_basilisk(bsk):
    result = bsk.compare_css()
    assert result["lit samples"] > 30
    # Basilisk's AU is 149597870.693 km, ours the IAU 2012 149597870.700 km: (AU/d)^2 differs by 9.4e-11
    assert result["max |output difference| (scale 2.5)"] < 1e-9     # measured 2.4e-10


def test_facet_srp_equals_basilisk(bsk):
    # 4 random facets, 100 random attitudes, positions and Sun directions; Basilisk's flux 1368 W/m^2
    result = bsk.compare_srp()
    assert result["force max relative difference"] < 1e-12    # measured 8.9e-15
    assert result["torque max relative difference"] < 1e-12   # measured 7.1e-15

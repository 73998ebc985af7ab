"""Hierarchical assemblies: nesting, exposed ports with fan-out, dotted paths, registry."""

import numpy as np
import pytest

from shell.assembly import Assembly
from shell.model import ModelError, Parameter
from shell.models.blocks import Constant, Gain, Integrator
from shell.registry import RegistryError, lookup, register_model
from shell.simulation import Simulation


class ScaledIntegrators(Assembly):
    """Two integrators of the same input, one scaled: exposes u (fan-out) and both outputs."""

    parameters = (Parameter("scale", "", 2.0),)

    def build(self):
        self.add(Integrator("plain", unit="m"))
        self.add(Gain("gain", unit="m/s", k=float(self.parameter("scale"))))
        self.add(Integrator("scaled", unit="m"))
        self.connect("gain.y", "scaled.u")
        self.expose_input("u", "plain.u", "gain.u")
        self.expose_output("plain", "plain.y")
        self.expose_output("scaled", "scaled.y")


class Vehicle(Assembly):
    def build(self):
        self.add(ScaledIntegrators("nav", scale=3.0))
        self.expose_input("speed", "nav.u")
        self.expose_output("distance", "nav.scaled")


def test_nested_assemblies_flatten_with_dotted_paths_and_fan_out():
    scene = Assembly("scene")
    scene.add(Constant("speed", unit="km/h", value="36 km/h"))
    scene.add(Vehicle("car"))
    scene.connect("speed.y", "car.speed")
    sim = Simulation(scene, step=0.1)
    assert [m.path for m in sim.models] == ["speed", "car.nav.plain", "car.nav.gain", "car.nav.scaled"]
    sim.run(2.0)
    # 36 km/h = 10 m/s (factor 1/3.6 on the wire); plain = 10 t, scaled = 3 * 10 t
    assert sim.signal("car.nav.plain.y") == pytest.approx(20.0, rel=1e-14)
    assert sim.signal("car.nav.scaled.y") == pytest.approx(60.0, rel=1e-14)


def test_inner_ports_reachable_by_path_and_unknown_exposed_port_refused():
    scene = Assembly("scene")
    scene.add(Constant("speed", unit="m/s", value=1.0))
    scene.add(Vehicle("car"))
    scene.connect("speed.y", "car.nav.plain.u")   # a dotted path into the hierarchy
    scene.connect("speed.y", "car.nav.gain.u")
    Simulation(scene)
    bad = Assembly("scene")
    bad.add(Constant("speed", unit="m/s", value=1.0))
    bad.add(Vehicle("car"))
    bad.connect("speed.y", "car.velocity")
    with pytest.raises(ModelError, match=r"assembly car exposes inputs \['speed'\]"):
        Simulation(bad)


def test_member_overrides_and_names():
    loop = lookup("AttitudeHoldLoop")("loop", **{"controller.kp": "[1, 2, 3] N*m/rad", "gyro_noise": "0.1 deg/s"})
    np.testing.assert_array_equal(loop.children["controller"].parameter("kp"), [1, 2, 3])
    assert loop.children["gyro"].parameter("sigma") == pytest.approx(np.radians(0.1), rel=1e-15)
    with pytest.raises(ModelError, match=r"overrides for unknown member\(s\) \['controler'\]"):
        lookup("AttitudeHoldLoop")("loop", **{"controler.kp": [1, 2, 3]})
    with pytest.raises(ModelError, match="no dots"):
        Constant("a.b")


def test_registry_refuses_a_second_class_under_a_taken_name():
    with pytest.raises(RegistryError, match="model type 'Gain' is already registered by shell.models.blocks.Gain"):
        @register_model(name="Gain")
        class AnotherGain(Gain):
            pass

"""A failing run stops, names the model and the time, and keeps its log up to the failure."""

import re

import h5py
import numpy as np
import pytest
from numba import njit

from shell.assembly import Assembly
from shell.log_file import read_log
from shell.model import Model, OutputPort, State
from tests.plants import FiniteEscape
from shell.simulation import Simulation, SimulationError


def test_non_finite_state_stops_the_run_and_keeps_the_log(tmp_path):
    root = Assembly("root")
    root.add(FiniteEscape("blowup"))  # x = 1 / (1 - t): infinite at t = 1 s
    sim = Simulation(root, step=0.01)
    sim.log(["blowup.x"], "100 Hz")
    path = tmp_path / "failed.h5"
    with pytest.raises(SimulationError) as info:
        sim.run(2.0, log_path=path)
    message = str(info.value)
    assert re.search(r"non-finite model blowup (state|derivative of) x = \[(inf|nan)\]", message), message
    t_fail = float(message.split("at t = ")[1].split(" s")[0])
    # RK4 with h = 0.01 follows 1/(1 - t) to overflow within a few steps of the singularity
    assert 0.95 < t_fail < 1.1
    log = read_log(path)
    with h5py.File(path) as f:
        assert f.attrs["status"] == "failed"
        assert "model blowup" in f.attrs["message"]
    assert log["time"][0] == 0.0 and log["time"][-1] < t_fail
    assert len(log["time"]) > 90
    # what was logged is the solution up to the failure: x(t) = 1 / (1 - t) (RK4 error grows near t = 1)
    early = log["time"] <= 0.5
    np.testing.assert_allclose(log["blowup.x"][early], 1 / (1 - log["time"][early]), rtol=1e-8)


@njit(cache=True)
def _nan_after_half_second(t, x, z, u, p, xdot):
    xdot[0] = np.sqrt(0.5 - t)  # NaN for t > 0.5 s


@njit(cache=True)
def _copy_x(t, x, z, u, p, y):
    y[0] = x[0]


class _SqrtOfTime(Model):
    outputs = (OutputPort("x", "", ()),)
    continuous_states = (State("x", "", (), 0.0),)
    state_outputs = staticmethod(_copy_x)
    derivatives = staticmethod(_nan_after_half_second)


def test_nan_derivative_names_the_model(tmp_path):
    root = Assembly("root")
    root.add(FiniteEscape("healthy", ))
    root.children["healthy"].set_initial("x", 0.1)
    root.add(_SqrtOfTime("sick"))
    sim = Simulation(root, step=0.01)
    sim.log(["sick.x"], "10 Hz")
    with pytest.raises(SimulationError, match=r"non-finite model sick (state|derivative of) x = \[nan\] at t = 0\.51 s") as info:
        sim.run(1.0, log_path=tmp_path / "nan.h5")
    assert "healthy" not in str(info.value)
    assert read_log(tmp_path / "nan.h5")["time"][-1] == pytest.approx(0.5)


class _Raises(Model):
    outputs = (OutputPort("x", "", ()),)
    continuous_states = (State("x", "", (), 0.0),)
    state_outputs = staticmethod(_copy_x)

    def derivatives(self, t, x, z, u, p, xdot):
        if t > 0.25:
            raise RuntimeError("lookup table exhausted")
        xdot[0] = 1.0


def test_exception_in_a_model_names_the_model_and_time(tmp_path):
    root = Assembly("root")
    root.add(_Raises("table"))
    sim = Simulation(root, step=0.1)
    sim.log(["table.x"], "10 Hz")
    with pytest.raises(SimulationError, match=r"model table failed computing derivatives at t = 0\.3 s: "
                                              r"RuntimeError: lookup table exhausted"):
        sim.run(1.0, log_path=tmp_path / "raise.h5")
    with h5py.File(tmp_path / "raise.h5") as f:
        assert f.attrs["status"] == "failed"
        assert f["every_0.1s/time"][-1] == pytest.approx(0.2)


class _Interrupts(Model):
    outputs = (OutputPort("x", "", ()),)
    continuous_states = (State("x", "", (), 0.0),)
    state_outputs = staticmethod(_copy_x)

    def derivatives(self, t, x, z, u, p, xdot):
        if t > 0.35:
            raise KeyboardInterrupt
        xdot[0] = 1.0


def test_interrupted_run_closes_its_log(tmp_path):
    root = Assembly("root")
    root.add(_Interrupts("user"))
    sim = Simulation(root, step=0.1)
    sim.log(["user.x"], "10 Hz")
    with pytest.raises(KeyboardInterrupt):
        sim.run(1.0, log_path=tmp_path / "ctrl_c.h5")
    with h5py.File(tmp_path / "ctrl_c.h5") as f:
        assert f.attrs["status"] == "interrupted"
        np.testing.assert_allclose(f["every_0.1s/time"][()], [0.0, 0.1, 0.2, 0.3], atol=1e-15)

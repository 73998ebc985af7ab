"""Adding an integrator that steps in the compiled loop touches its own file and the registry only.

A toy method written here, Ralston's second-order Runge-Kutta (``y1 = y + h (k1 / 4 + 3 k2 / 4)``, ``k2 =
f(t + 2h/3, y + 2h/3 k1)``; A. Ralston, Math. Comp. 16:431-437, 1962), with its own stepper and kernels (not the
tableau-driven stepper of the built-in Runge-Kutta methods), registered from this file with
``register_integrator``: a YAML scene names it, the command line runs it, and it steps in the compiled loop
(nothing of shell/ knows it) bit for bit as its Python integrator steps in the Python loop; its cubic Hermite dense
output locates a bouncing ball's contacts in the compiled loop as in the Python one. Its second order is checked on
an exponential decay against the closed form.
"""

from typing import NamedTuple

import numpy as np
import pytest
from numba import njit

from shell.integrators import INTEGRATORS, register_integrator
from shell.integrators.base import HermiteDenseOutput
from shell.integrators.compiled import (I_F_VALID, I_FAILED_STAGE, I_NFEV, R_FAILED_T, START_FAILED, STEP_FAILED,
                                        CompiledStepping, derivative, normalize, register_stepper, state)
from shell.integrators.fixed import FixedStepRungeKutta
from shell.integrators.kernels import all_finite, copy_into, hermite_cubic
from shell.log_file import read_log
from shell.scenario import build_root, load_scenario
from shell.simulation import Simulation

TWO_THIRDS = 2.0 / 3.0


@njit(cache=True)
def _stage(y, k1, h, out):
    """y + 2/3 h k1."""
    for i in range(y.shape[0]):
        out[i] = y[i] + TWO_THIRDS * h * k1[i]


@njit(cache=True)
def _combine(y, k1, k2, h, out):
    """y + h (k1 / 4 + 3 k2 / 4); True when finite."""
    for i in range(y.shape[0]):
        out[i] = y[i] + h * (0.25 * k1[i] + 0.75 * k2[i])
    return all_finite(out)


class Ralston(FixedStepRungeKutta):
    """The toy method's Python integrator (the reference): FixedStepRungeKutta's stepping with its own step."""

    name = "toy_ralston"
    order = 2
    hermite_dense_output = True

    def _setup(self):
        self.h = min(self.step_option, self.max_step)
        self.y_stage = np.empty(self.n)

    def _step_impl(self):
        t, y = self.t, self.y
        remaining = self.t_bound - t
        last = remaining <= self.h * (1.0 + 1e-9)
        h = remaining if last else self.h
        t_new = self.t_bound if last else t + h
        _stage(y, self.f, h, self.y_stage)
        k2 = np.asarray(self.fun(t + TWO_THIRDS * h, self.y_stage), dtype=np.float64)
        self.nfev += 1
        y_new = np.empty(self.n)
        if not _combine(y, self.f, k2, h, y_new):
            return self._fail("non-finite state", t_new, y_new, "reduce the step")
        if self.normalize is not None:
            self.normalize(y_new)
        if last and self.skip_final_slope:
            self.t_old, self.y_old, self.f_old = t, y, self.f
            self.t, self.y, self.f = t_new, y_new, None
            return True
        f_new = np.array(self.fun(t_new, y_new), dtype=np.float64)
        self.nfev += 1
        self.t_old, self.y_old, self.f_old = t, y, self.f
        self.t, self.y, self.f = t_new, y_new, f_new
        return True


class RalstonStepper(NamedTuple):
    h: float
    Y: np.ndarray
    F: np.ndarray
    YS: np.ndarray
    K2: np.ndarray
    YN: np.ndarray
    FN: np.ndarray


@njit(cache=True)
def _start(system, st, t, ints, reals):
    if ints[I_F_VALID] == 0:
        copy_into(st.Y, state(system))
        normalize(system, st.Y)
        f = derivative(system, t, st.Y)
        ints[I_NFEV] += 1
        if not all_finite(f):
            return START_FAILED
        copy_into(st.F, f)
        ints[I_F_VALID] = 1
    return 0


@njit(cache=True)
def _step(system, st, t, h, t_new, skip_slope, ints, reals):
    _stage(st.Y, st.F, h, st.YS)
    copy_into(st.K2, derivative(system, t + TWO_THIRDS * h, st.YS))
    ints[I_NFEV] += 1
    if not _combine(st.Y, st.F, st.K2, h, st.YN):
        reals[R_FAILED_T] = t_new
        ints[I_FAILED_STAGE] = 0
        return STEP_FAILED
    normalize(system, st.YN)
    if skip_slope:
        return 0
    copy_into(st.FN, derivative(system, t_new, st.YN))
    ints[I_NFEV] += 1
    return 0


@njit(cache=True)
def _keep(st, ev):
    copy_into(ev.y_old, st.Y)
    copy_into(ev.f_old, st.F)


@njit(cache=True)
def _accept(st, ints, skipped):
    copy_into(st.Y, st.YN)
    if skipped:
        ints[I_F_VALID] = 0
    else:
        copy_into(st.F, st.FN)


@njit(cache=True)
def _prepare_dense(st, ev):
    return


@njit(cache=True)
def _dense(st, ev, theta, h, out):
    hermite_cubic(theta, h, ev.y_old, ev.f_old, st.Y, st.F, out)


register_stepper(RalstonStepper, start=_start, step=_step, keep=_keep, accept=_accept, prepare_dense=_prepare_dense,
                 dense=_dense)


class RalstonStepping(CompiledStepping):
    @classmethod
    def applies(cls, method, options, has_events):
        return options.get("step") is not None

    def stepper(self, stale):
        h = min(float(self.run.options["step"]), float(self.run.options.get("max_step", np.inf)))
        if self.st is None or self.st.h != h:
            n = self.run.x.size
            self.st = RalstonStepper(h, self.run.x.copy(), *(np.zeros(n) for _ in range(5)))
            stale = True
        return self.st, 0 if stale else 1

    def dense_output(self, st, t_old, t_new, y_old, f_old):
        return HermiteDenseOutput(t_old, t_new, y_old, f_old, st.Y, st.F)


@pytest.fixture(scope="module", autouse=True)
def toy_method():
    register_integrator(Ralston, compiled_stepping=RalstonStepping)
    yield
    INTEGRATORS.pop(Ralston.name)


SCENE = """
seed: 4
models:
  truth: {type: Constant, config: {unit: rad/s, shape: [3]}, parameters: {value: "[1, 2, 3] deg/s"}}
  gyro: {type: NoisySampler, rate: 30 Hz, config: {unit: rad/s, shape: [3]}, parameters: {sigma: 0.01 deg/s}}
  angle: {type: Integrator, config: {unit: rad, shape: [3]}}
  loop: {type: Gain, config: {unit: rad, output_unit: rad/s}, parameters: {k: "-0.5 1/s"}}
  spin: {type: Integrator, config: {unit: rad}, initial: {x: 1 rad}}
connections:
  - truth.y -> gyro.u
  - gyro.y -> angle.u
  - spin.y -> loop.u
  - loop.y -> spin.u
integrator: {method: toy_ralston, step: 7 ms}
stop: {time: 2 s}
log:
  rate: 20 Hz
  signals: [angle.y, spin.y, gyro.y]
"""


def _runs(scenario, tmp_path):
    runs = {}
    for mode in ("interpreted", "compiled"):
        sim = Simulation(build_root(scenario), integrator=scenario.integrator, step=scenario.step, seed=scenario.seed,
                         integrator_options=scenario.integrator_options, mode=mode)
        for name, rate, _ in scenario.log_signals:
            sim.log([name], rate)
        sim.run(scenario.t_final, log_path=tmp_path / f"{mode}.h5")
        runs[mode] = sim
    return runs


def test_a_registered_toy_method_steps_compiled_as_its_python_integrator(tmp_path):
    from shell.cli import main

    path = tmp_path / "toy.yaml"
    path.write_text(SCENE)
    assert main(["run", str(path), "-o", str(tmp_path / "cli.h5"), "--quiet"]) == 0
    runs = _runs(load_scenario(path), tmp_path)
    compiled, interpreted = runs["compiled"], runs["interpreted"]
    assert compiled._compiled_loop_applies() and type(compiled._stepper) is RalstonStepper
    assert not interpreted._compiled_loop_applies()
    assert compiled.x.tobytes() == interpreted.x.tobytes() and compiled.counters == interpreted.counters
    logs = [read_log(tmp_path / name) for name in ("compiled.h5", "interpreted.h5", "cli.h5")]
    for key in logs[0]:
        assert logs[0][key].tobytes() == logs[1][key].tobytes() == logs[2][key].tobytes(), key
    # spin' = -0.5 spin from 1: e^(-t/2); the method's global error at 7 ms is about t h^2 / 48 e^(-t/2) ~ 2e-6
    t = logs[0]["time"]
    error = np.abs(logs[0]["spin.y"] - np.exp(-0.5 * t))
    assert error.max() < 5e-6 and error[-1] > 1e-8


def test_the_toy_method_locates_zero_crossings_in_the_compiled_loop(tmp_path):
    from shell.assembly import Assembly
    from tests.plants import BouncingBall

    runs = []
    for mode in ("interpreted", "compiled"):
        root = Assembly("root")
        root.add(BouncingBall("ball"))
        sim = Simulation(root, integrator="toy_ralston", step=0.01, mode=mode)
        sim.run(5.0)
        runs.append(sim)
    interpreted, compiled = runs
    assert compiled._compiled_loop_applies() and not interpreted._compiled_loop_applies()
    assert compiled.events == interpreted.events
    assert compiled.x.tobytes() == interpreted.x.tobytes()
    # free fall from 10 m: the method and its cubic dense output are exact for the parabola, so the contacts are
    # the closed form's (tests/plants.py) to the location tolerance
    g, e = 9.81, 0.8
    t1, v1 = np.sqrt(2 * 10.0 / g), np.sqrt(2 * g * 10.0)
    np.testing.assert_allclose([t for t, _ in compiled.events], [t1, t1 + 2 * e * v1 / g], rtol=0, atol=1e-9)


def test_the_toy_method_is_second_order():
    """y' = -y from 1 over 1 s: the error against e^-1 falls by 4 per halving of the step (2 +- 0.05 in log2)."""
    from shell.integrators import integrate

    errors = []
    for h in (0.02, 0.01, 0.005):
        result = integrate("toy_ralston", lambda t, y: -y, 0.0, [1.0], 1.0, step=h)
        errors.append(abs(result.y[0, -1] - np.exp(-1.0)))
    slopes = np.log2(np.array(errors[:-1]) / np.array(errors[1:]))
    np.testing.assert_allclose(slopes, 2.0, atol=0.05)

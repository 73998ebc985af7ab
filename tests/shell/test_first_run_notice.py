"""A run that compiles says so and for how long, instead of a silent wait; and compiles only what its scene needs.

`shell.commands.run.CompileNotice` listens to numba's ``numba:compile`` event (raised when a kernel is compiled,
not when it is loaded from the on-disk cache). History: on 2026-11-23 the notice never appeared (the cache check
read an attribute numba's cache object does not have and answered "cached"); until 2026-11-26 the first run
compiled every stepper and the whole engine whatever the scene, so a scene of 200 trivial blocks took 155 s CPU
from an empty cache instead of ~25 s (the engine's kernel was compiled to fill the loop's engine slot).
"""

from __future__ import annotations

import os
import subprocess
import sys
import textwrap
from pathlib import Path

from shell.cli import main

ROOT = Path(__file__).resolve().parents[2]

_NOTICE = """
import numba
from shell.commands.run import CompileNotice

@numba.njit
def tiny(x):
    return x + 1.0

with CompileNotice(quiet=False) as notice:
    tiny(1.0)
print("first", notice.announced, notice.seconds > 0.0)
with CompileNotice(quiet=False) as notice:
    tiny(2.0)                       # already compiled: nothing to say
print("again", notice.announced)
"""


def test_compilation_is_announced_with_its_time():
    done = subprocess.run([sys.executable, "-c", _NOTICE], capture_output=True, text=True, timeout=300)
    assert done.returncode == 0, done.stderr
    assert "first True True" in done.stdout and "again False" in done.stdout
    assert done.stderr.count("flexshell: compiling the scene's kernels") == 1
    assert done.stderr.count("flexshell: compiled in") == 1


SCENE = """
models:
  truth: {type: Constant, config: {unit: rad/s, shape: [3]}, parameters: {value: "[1, 2, 3] deg/s"}}
  angle: {type: Integrator, config: {unit: rad, shape: [3]}}
connections:
  - truth.y -> angle.u
integrator: {method: rk4, step: 10 ms}
stop: {time: 1 s}
log: {rate: 10 Hz, signals: [angle.y]}
"""


def test_flexshell_run_announces_what_it_compiles(tmp_path, monkeypatch, capsys):
    """The command's wiring: a compilation during the scene's build is announced, timed, and closed before the
    run's summary (here a kernel compiled for the first time stands in for a cold cache)."""
    import numba

    import shell.scenario as scenario

    @numba.njit
    def first_time(x):
        return 2.0 * x

    build = scenario.build_simulation

    def building(*args, **kwargs):
        first_time(1.0)
        return build(*args, **kwargs)

    monkeypatch.setattr(scenario, "build_simulation", building)
    path = tmp_path / "scene.yaml"
    path.write_text(SCENE)
    assert main(["run", str(path), "-o", str(tmp_path / "log.h5")]) == 0
    captured = capsys.readouterr()
    assert "flexshell: compiling the scene's kernels" in captured.err
    assert "flexshell: compiled in" in captured.err
    assert "completed" in captured.out


def test_warm_run_says_nothing_about_compiling(tmp_path, capsys):
    path = tmp_path / "scene.yaml"
    path.write_text(SCENE)
    assert main(["run", str(path), "-o", str(tmp_path / "first.h5")]) == 0   # compiles or loads
    capsys.readouterr()
    assert main(["run", str(path), "-o", str(tmp_path / "second.h5")]) == 0
    assert "compil" not in capsys.readouterr().err


_NO_ENGINE = textwrap.dedent("""
    from shell.assembly import Assembly
    from shell.models.blocks import Gain, Integrator
    from shell.models.multibody import ENGINE_KERNELS
    from shell.simulation import Simulation

    root = Assembly("root")
    root.add(Integrator("x", unit="m"))
    root.add(Gain("k", unit="m", output_unit="m/s", k="-1 1/s"))
    root.connect("x.y", "k.u")
    root.connect("k.y", "x.u")
    simulation = Simulation(root, step=1e-3)
    simulation.run(0.01)
    print("mode", simulation.mode, "engine", sum(len(k.overloads) for k in ENGINE_KERNELS.values()))
""")


def test_a_scene_without_the_engine_neither_compiles_nor_loads_it():
    """In a fresh process (the engine's kernel would be compiled, or loaded from the cache, if the loop took it
    whatever the scene): the compiled loop runs, and the engine kernel has no overload."""
    env = dict(os.environ, PYTHONPATH=os.getcwd())
    done = subprocess.run([sys.executable, "-c", _NO_ENGINE], capture_output=True, text=True, env=env, timeout=900)
    assert done.returncode == 0, done.stderr
    assert "mode compiled engine 0" in done.stdout


_SINGLE_BODY = textwrap.dedent("""
    import sys
    from shell.cli import main
    from shell.kernel_protocol import forms
    from shell.models.multibody import ENGINE_KERNELS

    assert main(["run", sys.argv[1], "--t-final", "1 s", "-o", sys.argv[2]]) == 0
    print("paths", sorted(name for name, kernel in ENGINE_KERNELS.items()
                          if kernel.overloads or any(form.overloads for form in forms(kernel))))
""")


def test_a_rigid_single_body_scene_compiles_only_its_engine_path(tmp_path):
    """The demo (one rigid body on a free hinge) in a fresh process: only the single-body engine kernel is
    compiled or loaded, not the articulated-body recursion or the dense solve (they were 3/4 of a cold start:
    110 s CPU before, 24 s after, issue 31)."""
    env = dict(os.environ, PYTHONPATH=os.getcwd())
    done = subprocess.run([sys.executable, "-c", _SINGLE_BODY, str(ROOT / "configs" / "demo_attitude_hold.yaml"),
                           str(tmp_path / "demo.h5")], capture_output=True, text=True, env=env, timeout=900)
    assert done.returncode == 0, done.stderr
    assert "paths ['single_body']" in done.stdout, done.stdout

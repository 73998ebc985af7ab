"""No stale machine code, and an edit recompiles only what it touched (dynamics/compile_cache.py).

numba's own cache keys a function on its own file, so a cached caller keeps the machine code of a callee in another
file after that callee changed (numba compiles the callee into the caller). flexshell keys each entry on the
function's unit: its code and that of everything numba compiles into it, followed through globals, attribute chains,
closures, ``@overload`` and ``@intrinsic``, with the values of the constants they read. These tests edit a small
package in a temporary directory between fresh processes sharing one cache directory, and check each time both the
result (a stale entry would give the old number) and which functions numba compiled (an untouched one must load).
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
import textwrap
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]

PACKAGE = {
    "constants.py": """
        GAIN = 2.0
        OFFSETS = (1.0, 10.0)
    """,
    "callee.py": """
        from numba import njit

        from probe import constants as C
        from probe.constants import OFFSETS


        @njit(cache=True, inline="always")
        def scaled(x):
            return C.GAIN * x


        @njit(cache=True)
        def shifted(x):
            return x + OFFSETS[1]


        @njit(cache=True)
        def untouched(x):
            return x - 1.0
    """,
    "extension.py": """
        from numba.extending import overload

        from probe.callee import shifted


        def twice_shifted(x):
            raise NotImplementedError("compiled only")


        @overload(twice_shifted)
        def _twice_shifted(x):
            def implementation(x):
                return 2.0 * shifted(x)
            return implementation
    """,
    "caller.py": """
        from numba import njit

        from probe import callee
        from probe.extension import twice_shifted


        def make(kernel):
            @njit(cache=True)
            def through_closure(x):
                return kernel(x) + 0.5
            return through_closure


        closure = make(callee.scaled)


        @njit(cache=True)
        def result(x):
            return callee.scaled(x) + callee.shifted(x)


        @njit(cache=True)
        def overloaded(x):
            return twice_shifted(x)


        @njit(cache=True)
        def alone(x):
            return callee.untouched(x)
    """,
}

SCRIPT = """
import json

import dynamics  # installs the dependency-keyed cache
from dynamics.compile_cache import CompileClock

compiled = []
with_clock = CompileClock(on_start=lambda d: compiled.append(d.py_func.__qualname__)).start()
from probe import caller

values = {"result": caller.result(1.0), "overloaded": caller.overloaded(1.0), "closure": caller.closure(1.0),
          "alone": caller.alone(1.0)}
with_clock.stop()
print(json.dumps({"values": values, "compiled": sorted(set(compiled))}))
"""


def _write(package: Path, name: str, text: str) -> None:
    (package / name).write_text(textwrap.dedent(text))


def _run(tmp_path: Path) -> dict:
    env = dict(os.environ, PYTHONPATH=f"{tmp_path}{os.pathsep}{ROOT}", NUMBA_CACHE_DIR=str(tmp_path / "cache"),
               PYTHONDONTWRITEBYTECODE="1")
    done = subprocess.run([sys.executable, "-c", SCRIPT], capture_output=True, text=True, env=env, timeout=600,
                          cwd=tmp_path)
    assert done.returncode == 0, done.stderr
    return json.loads(done.stdout.strip().splitlines()[-1])


@pytest.fixture
def package(tmp_path):
    directory = tmp_path / "probe"
    directory.mkdir()
    (directory / "__init__.py").write_text("")
    for name, text in PACKAGE.items():
        _write(directory, name, text)
    return directory


def test_an_edited_callee_or_constant_in_another_file_recompiles_its_callers_only(tmp_path, package):
    first = _run(tmp_path)
    # result = 2 x + (x + 10); overloaded = 2 (x + 10); closure = 2 x + 0.5; alone = x - 1
    assert first["values"] == {"result": 13.0, "overloaded": 22.0, "closure": 2.5, "alone": 0.0}
    assert {"result", "overloaded", "make.<locals>.through_closure", "alone"} <= set(first["compiled"])

    warm = _run(tmp_path)
    assert warm == {"values": first["values"], "compiled": []}

    # a comment appended and lines inserted above every function: the code is the same, nothing recompiles
    (package / "caller.py").write_text((package / "caller.py").read_text() + "# a comment\n")
    (package / "callee.py").write_text('"""A docstring\nover two lines."""\n' + (package / "callee.py").read_text())
    assert _run(tmp_path) == warm

    # a callee in another file changes: its callers (direct, and through the overload) recompile, the rest loads
    _write(package, "callee.py", PACKAGE["callee.py"].replace("x + OFFSETS[1]", "x + 3.0 * OFFSETS[1]"))
    edited = _run(tmp_path)
    assert edited["values"] == {"result": 33.0, "overloaded": 62.0, "closure": 2.5, "alone": 0.0}
    assert "alone" not in edited["compiled"] and "untouched" not in edited["compiled"]
    assert "make.<locals>.through_closure" not in edited["compiled"]
    assert {"result", "overloaded", "shifted"} <= set(edited["compiled"])

    # a constant of a third module, read by an inline="always" callee through a module attribute, and one imported
    # by name: every reader recompiles
    _write(package, "constants.py", "GAIN = 5.0\nOFFSETS = (1.0, 10.0)\n")
    gain = _run(tmp_path)
    assert gain["values"] == {"result": 36.0, "overloaded": 62.0, "closure": 5.5, "alone": 0.0}
    assert {"result", "make.<locals>.through_closure"} <= set(gain["compiled"])
    assert "overloaded" not in gain["compiled"] and "alone" not in gain["compiled"]
    _write(package, "constants.py", "GAIN = 5.0\nOFFSETS = (1.0, 100.0)\n")
    offsets = _run(tmp_path)
    assert offsets["values"] == {"result": 306.0, "overloaded": 602.0, "closure": 5.5, "alone": 0.0}

    # back to the first sources: their entries are still there, nothing compiles
    for name, text in PACKAGE.items():
        _write(package, name, text)
    assert _run(tmp_path) == warm


def test_an_edited_overload_implementation_recompiles_its_callers(tmp_path, package):
    assert _run(tmp_path)["values"]["overloaded"] == 22.0
    _write(package, "extension.py", PACKAGE["extension.py"].replace("2.0 * shifted(x)", "4.0 * shifted(x)"))
    edited = _run(tmp_path)
    assert edited["values"]["overloaded"] == 44.0
    assert "overloaded" in edited["compiled"]  # and the overload's implementation, which numba never caches
    assert not {"result", "shifted", "alone", "make.<locals>.through_closure"} & set(edited["compiled"])


def test_every_cached_kernel_uses_the_dependency_keyed_cache():
    from dynamics.compile_cache import DependencyCache
    from shell.compiled_loop import advance
    from shell.models.multibody import ENGINE_KERNELS

    assert isinstance(advance._cache, DependencyCache)
    assert all(isinstance(kernel._cache, DependencyCache) for kernel in ENGINE_KERNELS.values())


def test_units_follow_the_architecture():
    """The compiled loop calls model kernels and the engine through function pointers, so neither is in its unit (a
    model edit does not recompile the loop); the engine's unit is dynamics/ and its shell model; a model kernel's
    unit is its own module and the attitude-library functions it calls (shell/attitude.py)."""
    from dynamics.compile_cache import unit_members
    from shell.compiled_loop import advance
    from shell.models.multibody import ENGINE_KERNELS
    from shell.models.pd_attitude import _pd_update

    loop = unit_members(advance)
    assert "shell.compiled_loop.advance" in loop and "shell.compiled_loop._integrate" in loop
    assert not [m for m in loop if m.startswith(("shell.models.", "dynamics.kernels", "dynamics.single_body"))]
    engine = unit_members(ENGINE_KERNELS["articulated"])
    assert "dynamics.kernels.articulated_body.forward_dynamics" in engine and "dynamics.spatial.mat6_vec" in engine
    assert not [m for m in engine if m.startswith("shell.") and not m.startswith("shell.models.multibody.")]
    # each path's kernel holds that path only: a rigid single-body scene (the demo) compiles neither the
    # recursion nor the dense solve nor the tree's node kinematics (issue 31: most of a cold start)
    single = unit_members(ENGINE_KERNELS["single_body"])
    assert "dynamics.single_body.forward_dynamics" in single
    assert not [m for m in single if m.startswith(("dynamics.kernels.articulated_body", "dynamics.kernels.dense_forward",
                                                     "dynamics.kernels.node_frames"))], single
    dense = unit_members(ENGINE_KERNELS["dense"])
    assert "dynamics.kernels.dense_forward.forward_dynamics_dense" in dense
    assert "dynamics.kernels.articulated_body.forward_dynamics" not in dense
    assert "dynamics.kernels.dense_forward.forward_dynamics_dense" not in engine
    assert unit_members(_pd_update) == ["shell.attitude.error_rotation_vector", "shell.attitude.quaternion_conjugate",
                                        "shell.attitude.quaternion_multiply", "shell.models.pd_attitude._pd_update"]


def test_a_constant_rebound_at_run_time_changes_the_key(monkeypatch):
    """Keys are hashed once per process, but a global read by a unit and rebound since is seen (numba would freeze
    the new value into code compiled now)."""
    import dynamics.kernels.articulated_body as articulated_body
    from dynamics.compile_cache import unit_key
    from shell.models.multibody import ENGINE_KERNELS

    engine_kernel = ENGINE_KERNELS["articulated"]
    before = unit_key(engine_kernel.py_func)
    monkeypatch.setattr(articulated_body, "GROUND_ACCEL", articulated_body.GROUND_ACCEL + 1)
    assert unit_key(engine_kernel.py_func) != before
    monkeypatch.undo()
    assert unit_key(engine_kernel.py_func) == before


# what numba's low-level extension API registers is not followed by the unit keys (module docstring)
_UNFOLLOWED = {"lower_builtin", "lower_cast", "lower_getattr", "lower_getattr_generic", "lower_setattr",
               "lower_setattr_generic", "type_callable", "typeof_impl", "make_attribute_wrapper", "box", "unbox",
               "NativeValue", "infer", "infer_global", "infer_getattr", "register_jitable", "jitclass", "structref",
               "models", "imputils", "generated_jit"}


def test_flexshell_uses_only_the_numba_extensions_the_keys_follow():
    import ast

    offenders = []
    for package in ("dynamics", "shell"):
        for path in sorted((ROOT / package).rglob("*.py")):
            tree = ast.parse(path.read_text(), filename=str(path))
            for node in ast.walk(tree):
                if isinstance(node, ast.ImportFrom) and (node.module or "").startswith("numba"):
                    names = {alias.name for alias in node.names} | set(node.module.split("."))
                elif isinstance(node, ast.Import):
                    names = {part for alias in node.names if alias.name.startswith("numba")
                             for part in alias.name.split(".")}
                elif isinstance(node, ast.Attribute):
                    names = {node.attr} if ast.unparse(node).startswith("numba.") else set()
                else:
                    continue
                if names & _UNFOLLOWED:
                    offenders.append(f"{path.relative_to(ROOT)}:{node.lineno}: {sorted(names & _UNFOLLOWED)}")
    assert not offenders, offenders


def test_flexshell_compile_compiles_what_a_first_run_needs(tmp_path, capsys):
    """The verb compiles the common set (here into the suite's cache, mostly loading it); afterwards its parts are
    compiled in this process, and a fresh process running the demo scene compiles nothing."""
    from numba.core.registry import CPUDispatcher

    from shell.cli import main
    from shell.commands.compile import FAMILIES, engine_signature, work_items
    from shell.compiled_loop import advance
    from shell.models.multibody import ENGINE_KERNELS
    from shell.registry import registered

    assert main(["compile"]) == 0
    captured = capsys.readouterr()
    parts = work_items()
    assert f"[{len(parts)}/{len(parts)}]" in captured.err and "functions compiled" in captured.out
    assert [label for label, _ in parts][:2] == [f"simulation loop, {FAMILIES[0][1]}", "multibody engine"]
    assert all(engine_signature().args in kernel.overloads for kernel in ENGINE_KERNELS.values())
    steppers = {signature[2].instance_class.__name__ for signature in advance.signatures}  # advance(k, b, st
    assert {"RungeKuttaStepper", "ExponentialStepper"} <= steppers
    kernels = ("state_outputs", "feedthrough_outputs", "state_outputs_for_derivatives",
               "feedthrough_outputs_for_derivatives", "derivatives", "zero_crossing_values", "update")
    uncompiled = [f"{name}.{kernel}" for name, cls in registered().items() for kernel in kernels
                  if isinstance(getattr(cls, kernel, None), CPUDispatcher) and not getattr(cls, kernel).overloads]
    assert not uncompiled

    env = dict(os.environ, PYTHONPATH=str(ROOT))
    done = subprocess.run([sys.executable, "-m", "shell.cli", "run", str(ROOT / "configs" / "demo_attitude_hold.yaml"),
                           "--t-final", "1 s", "-o", str(tmp_path / "demo.h5")], capture_output=True, text=True,
                          env=env, timeout=600, cwd=tmp_path)
    assert done.returncode == 0, done.stderr
    assert "compil" not in done.stderr


def test_the_first_run_notice_says_what_compiles(tmp_path):
    """A kernel compiled for the first time (a fresh function in a fresh process) is announced with its part."""
    script = textwrap.dedent("""
        import numba
        from shell.commands.run import CompileNotice

        @numba.njit
        def fresh(x):
            return x + 1.0

        with CompileNotice(quiet=False) as notice:
            fresh(1.0)
        print(notice.parts)
    """)
    env = dict(os.environ, PYTHONPATH=str(ROOT))
    done = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True, env=env, timeout=300)
    assert done.returncode == 0, done.stderr
    assert "['model kernels']" in done.stdout
    assert "flexshell: compiling model kernels (up to ~" in done.stderr

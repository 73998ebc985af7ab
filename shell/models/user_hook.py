"""Hook for user flight software: a Python function called at a discrete rate, named signals in and out.

The bridge between a scene and G&C code written outside flexshell (TM-2020-5008164 App. D.1: flight
software in the loop). At each sample t_k the hook gathers its inputs into a dict of numpy arrays (in the
declared units), calls ``function(t, inputs)`` and expects a mapping with every declared output, which it
holds until the next sample (zero-order hold, like a flight computer's output registers)::

    # configs/flight_software/unload.py
    def momentum_unloading(t, signals):
        return {"torque_command": -0.01 * signals["wheel_momentum"]}

    models:
      fsw:
        type: UserFunction
        rate: 1 Hz
        config:
          function: flight_software/unload.py:momentum_unloading   # or an importable "package.module:name"
          inputs: {wheel_momentum: {unit: N*m*s, shape: [3]}}
          outputs: {torque_command: {unit: N*m, shape: [3]}}

A file path is relative to the working directory (``flexshell run`` resolves it as given). The object
named may be any callable; a class instance keeps the software's own state between calls. Outputs are
checked (missing names, shapes, non-finite values) and refused with the model path and the time.
This hook runs interpreted Python at its sample rate (``python_update``: a compiled loop returns to
Python at each of its samples); everything else stays compiled. Its layout is the user's: the held
outputs are its discrete states, one per output in the same order and shape, so the output kernel
copies z to y; the update packs and unpacks by name through the instance's layouts.

A scenario with a UserFunction runs code: building the scene imports the user's file. ``flexshell check``
does not: it reads the file (:func:`inspect_callable`: the file exists, parses, and defines the name at
its top level) without running it, unless given ``--trust`` (:func:`user_code`).
"""

from __future__ import annotations

import ast
import contextlib
import contextvars
import importlib
import importlib.machinery
import importlib.util
from pathlib import Path

import numpy as np
from numba import njit

from shell.model import Declarations, InputPort, Layout, Model, ModelError, OutputPort, State
from shell.registry import register_model


#: False while a scene is only checked (flexshell check without --trust): user code is read, not run
_USER_CODE_RUNS = contextvars.ContextVar("flexshell_user_code_runs", default=True)


@contextlib.contextmanager
def user_code(runs: bool):
    """Within the block, UserFunction models import their code (``runs``) or only inspect it."""
    token = _USER_CODE_RUNS.set(runs)
    try:
        yield
    finally:
        _USER_CODE_RUNS.reset(token)


def _split_spec(spec, where: str) -> tuple[str, str]:
    if not isinstance(spec, str) or ":" not in spec:
        raise ModelError(f"{where}: function {spec!r}: expected 'file.py:name' or 'package.module:name'")
    source, _, attribute = spec.rpartition(":")
    if not source or not attribute.isidentifier():
        raise ModelError(f"{where}: function {spec!r}: expected 'file.py:name' or 'package.module:name'")
    return source, attribute


def _module_file(source: str) -> Path | None:
    """The file of module ``source`` found on sys.path without importing it (nor its packages)."""
    spec, search = None, None
    for part in source.split("."):
        spec = importlib.machinery.PathFinder.find_spec(part, search)
        if spec is None:
            return None
        search = spec.submodule_search_locations
    return Path(spec.origin) if spec is not None and spec.origin and spec.origin.endswith(".py") else None


def inspect_callable(spec: str, where: str) -> Path | None:
    """Check ``spec`` without running any of its code: the file exists, is valid Python and defines
    ``name`` (a function, class or assignment) at its top level. Returns the file (None for a module
    that is not a Python source file, e.g. compiled: then only importing can tell)."""
    source, attribute = _split_spec(spec, where)
    if source.endswith(".py"):
        path = Path(source)
        if not path.is_file():
            raise ModelError(f"{where}: function {spec!r}: file {path} not found")
    else:
        path = _module_file(source)
        if path is None:
            if importlib.util.find_spec(source.split(".")[0]) is None:
                raise ModelError(f"{where}: function {spec!r}: no module {source} on the Python path")
            return None
    try:
        tree = ast.parse(path.read_bytes(), filename=str(path))
    except SyntaxError as exc:
        raise ModelError(f"{where}: function {spec!r}: {path}:{exc.lineno}: syntax error: {exc.msg}") from None
    except (OSError, ValueError) as exc:
        raise ModelError(f"{where}: function {spec!r}: cannot read {path} ({exc})") from None
    defined = set()
    for node in tree.body:
        if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef, ast.ClassDef)):
            defined.add(node.name)
        elif isinstance(node, (ast.Assign, ast.AnnAssign)):
            targets = node.targets if isinstance(node, ast.Assign) else [node.target]
            defined.update(t.id for t in targets if isinstance(t, ast.Name))
        elif isinstance(node, (ast.Import, ast.ImportFrom)):
            defined.update((a.asname or a.name).split(".")[0] for a in node.names)
    if attribute not in defined:
        raise ModelError(f"{where}: function {spec!r}: {path} has no {attribute!r} (it does not define it at its "
                         f"top level; it defines {sorted(defined)})")
    return path


def load_callable(spec: str, where: str):
    """``path/to/file.py:name`` or ``package.module:name`` -> the object (the file is inspected first,
    so a missing file or name or a syntax error is reported without running anything)."""
    inspect_callable(spec, where)
    source, attribute = _split_spec(spec, where)
    if source.endswith(".py"):
        path = Path(source)
        module_spec = importlib.util.spec_from_file_location(f"flexshell_user_{path.stem}", path)
        module = importlib.util.module_from_spec(module_spec)
        try:
            module_spec.loader.exec_module(module)
        except Exception as exc:
            raise ModelError(f"{where}: function {spec!r}: importing {path} raised {type(exc).__name__}: "
                             f"{exc}") from None
    else:
        try:
            module = importlib.import_module(source)
        except Exception as exc:
            raise ModelError(f"{where}: function {spec!r}: cannot import {source}: {type(exc).__name__}: "
                             f"{exc}") from None
    if not hasattr(module, attribute):
        raise ModelError(f"{where}: function {spec!r}: {source} has no {attribute!r}")
    function = getattr(module, attribute)
    if not callable(function):
        raise ModelError(f"{where}: function {spec!r} is not callable")
    return function


def _port_specs(specs, kind, where):
    if not isinstance(specs, dict) or not specs:
        raise ModelError(f"{where}: config {kind}: expected a mapping name -> {{unit, shape}}, given {specs!r}")
    out = []
    for name, spec in specs.items():
        spec = spec or {}
        unknown = set(spec) - {"unit", "shape", "description"}
        if unknown:
            raise ModelError(f"{where}: config {kind}.{name}: unknown key(s) {sorted(unknown)}; known: unit, shape")
        shape = spec.get("shape", ())
        shape = (int(shape),) if isinstance(shape, int) else tuple(int(n) for n in shape)
        out.append((str(name), str(spec.get("unit", "")), shape, str(spec.get("description", ""))))
    return out


@njit(cache=True)
def _held_outputs(t, x, z, u, p, y):
    for i in range(y.shape[0]):
        y[i] = z[i]  # output k is held in discrete state k: same names, order and shapes (declare)


@register_model
class UserFunction(Model):
    """Calls a user Python function at its rate: named inputs in, named outputs out (held)."""

    summary = "user flight-software hook: function(t, inputs) -> outputs at a discrete rate (config: function, inputs, outputs)"
    #: the user's function is arbitrary Python
    python_update = True
    state_outputs = staticmethod(_held_outputs)

    def __init__(self, name: str, *, function: str | None = None, inputs=None, outputs=None, **kwargs):
        where = f"model {name}"
        if function is None:
            raise ModelError(f"{where}: UserFunction needs config: function ('file.py:name' or 'module:name')")
        self.function_spec = function
        if _USER_CODE_RUNS.get():
            self.function = load_callable(function, where)
        else:  # checked, not run: the scene is built but never stepped
            inspect_callable(function, where)
            self.function = None
        self._input_specs = _port_specs(inputs, "inputs", where)
        self._output_specs = _port_specs(outputs, "outputs", where)
        super().__init__(name, **kwargs)

    def declare(self):
        declarations = Declarations(
            inputs=(InputPort(n, u, s, d or "input of the user function") for n, u, s, d in self._input_specs),
            outputs=(OutputPort(n, u, s, d or "output of the user function (held)") for n, u, s, d in self._output_specs),
            discrete=(State(n, u, s, None, "held output") for n, u, s, d in self._output_specs))
        self.use_declarations(declarations)
        # the output kernel copies z to y: the held states must have the outputs' layout
        self.offsets = {"y": declarations.Y, "z": declarations.Y}

    def configure(self):
        self._in_layout = Layout.of(self.inputs)
        self._out_layout = Layout.of(self.outputs)

    def update(self, t, x, z, u, p):
        """Python (``python_update``): calls the user's Python function with named signals."""
        signals = {name: u[self._in_layout.slice(name)].reshape(shape).copy()
                   for name, shape in self._in_layout.shapes.items()}
        try:
            result = self.function(t, signals)
        except Exception as exc:
            raise ModelError(f"model {self.path}: user function {self.function_spec} failed at t = {t:.12g} s: "
                             f"{type(exc).__name__}: {exc}") from exc
        if not isinstance(result, dict):
            raise ModelError(f"model {self.path}: user function {self.function_spec} returned {type(result).__name__} "
                             f"at t = {t:.12g} s; expected a dict with {self._out_layout.names}")
        missing = [n for n in self._out_layout.names if n not in result]
        if missing:
            raise ModelError(f"model {self.path}: user function {self.function_spec} at t = {t:.12g} s: missing "
                             f"output(s) {missing}; returned {sorted(result)}")
        for name, shape in self._out_layout.shapes.items():
            value = np.asarray(result[name], dtype=float)
            if value.shape != shape and not (value.size == 1 and shape == ()):
                raise ModelError(f"model {self.path}: user function output {name!r} at t = {t:.12g} s: expected "
                                 f"shape {shape}, given {value.shape}")
            if not np.all(np.isfinite(value)):
                raise ModelError(f"model {self.path}: user function output {name!r} at t = {t:.12g} s is not "
                                 f"finite: {value}")
            z[self._out_layout.slice(name)] = value.reshape(-1)

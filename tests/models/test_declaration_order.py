"""Reordering a model's declarations changes nothing: kernels read their arrays by name.

For every model module with module-level declaration tuples, a copy of its source with each tuple
reversed (``ast``: the tuples assigned to module-level names ending in PARAMETERS, INPUTS, OUTPUTS,
CONTINUOUS or DISCRETE, also when given by a name or a call, as the shared port bundles of
``shell.ports`` are, and the tuples returned by module-level ``*_parameters`` functions) is imported
under a new name; every model of the module, from the original and from the copy, runs all its kernels
on the same values placed by name (``model_cases.kernel_results``), and the results must agree bit for
bit: the same floating-point operations on the same numbers, only at other places in the arrays.
The copy's layouts must really differ from the original's (checked), so the test cannot pass vacuously.
"""

import ast
import importlib
import importlib.util
import sys
from pathlib import Path

import pytest

from tests.models.model_cases import DRAWS, assert_identical, cases, kernel_results

MODELS = Path(__file__).resolve().parents[2] / "shell" / "models"
DECLARATION_SUFFIXES = ("PARAMETERS", "INPUTS", "OUTPUTS", "CONTINUOUS", "DISCRETE")
#: modules with module-level declaration tuples (the test below checks that the list is complete)
REORDERED = ["aerodynamics", "allocation", "atmosphere", "controllers", "eclipse", "ephemeris", "gimbaled_engine", "gravity", "imu",
             "magnetic", "magnetic_control", "mass_depletion", "pd_attitude", "reaction_wheel", "slosh", "srp",
             "star_tracker", "sun_sensors", "third_body", "thruster",
             "mrp_feedback", "guidance", "mekf", "mode_manager", "cmg"]


def _is_declarations(node):
    return (isinstance(node, ast.Tuple) and len(node.elts) > 1) or isinstance(node, (ast.Name, ast.Call))


def _reversed(node, local_names):
    """The declarations of ``node`` in reverse order: a tuple reversed in place, a bundle (a name imported from
    another module or a call) wrapped in ``tuple(reversed(...))``; a name of this module's own tuple (reversed
    where it is assigned) is left as it is."""
    if isinstance(node, ast.Tuple):
        node.elts.reverse()
        return node
    if isinstance(node, ast.Name) and node.id in local_names:
        return node
    return ast.Call(ast.Name("tuple", ast.Load()), [ast.Call(ast.Name("reversed", ast.Load()), [node], [])], [])


class _Reverse(ast.NodeTransformer):
    """Reverse the declaration tuples of a module; drop @register_model (the copy must not register)."""

    def __init__(self):
        self.reversed = []

    def visit_Module(self, node):
        local_names = {t.id for statement in node.body if isinstance(statement, ast.Assign)
                       for t in statement.targets if isinstance(t, ast.Name)}
        for statement in node.body:
            if isinstance(statement, ast.Assign) and _is_declarations(statement.value) and any(
                    isinstance(t, ast.Name) and t.id.endswith(DECLARATION_SUFFIXES) for t in statement.targets):
                statement.value = _reversed(statement.value, local_names)
                self.reversed.append(statement.targets[0].id)
            elif isinstance(statement, ast.FunctionDef) and statement.name.endswith("_parameters"):
                for inner in ast.walk(statement):
                    if isinstance(inner, ast.Return) and _is_declarations(inner.value):
                        inner.value.elts.reverse()
                        self.reversed.append(f"{statement.name}()")
            elif isinstance(statement, ast.ClassDef):
                statement.decorator_list = [d for d in statement.decorator_list
                                            if not (isinstance(d, ast.Name) and d.id == "register_model")]
        return node


def _reordered_module(name, directory):
    tree = ast.parse((MODELS / f"{name}.py").read_text())
    reverse = _Reverse()
    tree = reverse.visit(tree)
    module_name = f"reordered_{name}"
    path = directory / f"{module_name}.py"
    path.write_text(ast.unparse(ast.fix_missing_locations(tree)))
    spec = importlib.util.spec_from_file_location(module_name, path)
    module = importlib.util.module_from_spec(spec)
    sys.modules[module_name] = module  # numba's cache locates a module's functions through sys.modules
    spec.loader.exec_module(module)
    return module, reverse.reversed


def test_every_module_with_declaration_tuples_is_reordered():
    with_tuples = set()
    for path in MODELS.glob("*.py"):
        tree = ast.parse(path.read_text())
        for statement in tree.body:
            if isinstance(statement, ast.Assign) and _is_declarations(statement.value) and any(
                    isinstance(t, ast.Name) and t.id.endswith(DECLARATION_SUFFIXES) for t in statement.targets):
                with_tuples.add(path.stem)
    assert with_tuples - {"multibody"} == set(REORDERED)


@pytest.fixture(scope="module")
def reordered(tmp_path_factory):
    directory = tmp_path_factory.mktemp("reordered")
    modules = {name: _reordered_module(name, directory) for name in REORDERED}
    yield modules
    for name in REORDERED:
        sys.modules.pop(f"reordered_{name}", None)


@pytest.mark.parametrize("module_name", REORDERED)
def test_reordering_declarations_changes_nothing(module_name, reordered, tmp_path):
    copy, reversed_tuples = reordered[module_name]
    assert reversed_tuples, f"{module_name}: no declaration tuple was reordered"
    original = importlib.import_module(f"shell.models.{module_name}")
    selected = [c for c in cases(tmp_path) if c[1] == module_name]
    assert selected, f"no model case for {module_name}"
    moved = 0
    for case, _, class_name, kwargs in selected:
        a = getattr(original, class_name)(case, **kwargs)
        b = getattr(copy, class_name)(case, **kwargs)
        for key in ("p", "u", "y", "x", "z"):
            la, lb = getattr(a, f"{key}_layout"), getattr(b, f"{key}_layout")
            assert sorted(la.names) == sorted(lb.names)
            moved += la.offsets != lb.offsets
        for draw in DRAWS:
            assert_identical(kernel_results(a, case, draw), kernel_results(b, case, draw),
                             f"{module_name}.{class_name} ({case}, draw {draw})")
    assert moved, f"{module_name}: reversing {reversed_tuples} moved no declaration"

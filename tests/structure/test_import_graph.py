"""The import graph of ``shell/`` and ``dynamics/`` (docs/architecture.md): no import circle, no module
importing another module's private name, and no library depending on the command line.

The graph is read from the source (tests/structure/import_graph.py), imports inside functions included:
deferring an import into a function hides a circle from Python, not from the design. The circles and private
imports the redesign of issue 32 removed (scenario <-> simulation <-> compiled plan <-> engine model, the
integrators' registry <-> driver, linearize's private evaluator, the dynamics circle) had a pending table here; it
emptied, so any of them coming back fails.
"""

from __future__ import annotations

from pathlib import Path

from tests.structure.import_graph import PrivateImport, circles, read

ROOT = Path(__file__).resolve().parents[2]
PACKAGES = ("shell", "dynamics")


def _graph():
    return read(ROOT, PACKAGES)


def test_no_import_circle():
    found = sorted(sorted(c) for c in circles(_graph()[0]))
    assert not found, f"import circles (modules that import each other, also inside functions): {found}"


def test_no_module_imports_another_modules_private_name():
    found = [f"{p.module}:{p.line} takes {p.name} from {p.source}" for p in sorted(_graph()[1], key=lambda p: (p.module, p.line, p.name))]
    assert not found, "private names imported across modules (make them public, or move the code):\n" + "\n".join(found)


def test_no_library_depends_on_the_command_line():
    graph = _graph()[0]
    libraries = [m for m in graph if not (m == "shell.cli" or m.startswith("shell.commands"))]
    users = sorted(f"{m} -> {t}" for m in libraries for t in graph[m] if t == "shell.cli" or t.startswith("shell.commands"))
    assert not users, f"library modules importing the command line: {users}"


def test_a_planted_circle_and_private_import_are_found(tmp_path):
    package = tmp_path / "planted"
    package.mkdir()
    (package / "__init__.py").write_text("")
    (package / "a.py").write_text("from planted.b import helper\n_hidden = 1\n")
    (package / "b.py").write_text("def helper():\n    from planted import a\n    return a._hidden\n")
    (package / "c.py").write_text("from . import a\nfrom .a import _hidden\n")
    graph, private = read(tmp_path, ("planted",))
    assert circles(graph) == [frozenset({"planted.a", "planted.b"})]
    assert set(private) == {PrivateImport("planted.b", "planted.a", "_hidden", 3),
                            PrivateImport("planted.c", "planted.a", "_hidden", 2)}

"""The import graph of ``shell/`` and ``dynamics/`` (docs/architecture.md): no import circle, no module
importing another module's private name, and no library depending on the command line.

The graph is read from the source (tests/structure/import_graph.py), imports inside functions included:
deferring an import into a function hides a circle from Python, not from the design. The two PENDING tables
name what other branches of the same redesign remove (issue 32; the dynamics circle builder <-> system
<-> reconfigure <-> urdf <-> flexible_body went with branch flex-orders), each with its owner; an entry that no longer occurs fails too, so the tables only shrink and are deleted when empty.
"""

from __future__ import annotations

from pathlib import Path

from tests.structure.import_graph import PrivateImport, circles, read

ROOT = Path(__file__).resolve().parents[2]
PACKAGES = ("shell", "dynamics")

#: circles other branches remove: circle -> who removes it
PENDING_CIRCLES = {
    frozenset({"shell.integrators", "shell.integrators.driver"}): "branch shell-core (issue 32: one simulator core)",
}
#: private imports other branches remove: (importing module, source module, name) -> who removes it
PENDING_PRIVATE = {
    **{("shell.analysis.frequency_response", "shell.analysis.linearize", name): "branch shell-core (issue 32: one "
       "public evaluation object)" for name in ("_Evaluator", "_Signals", "_StateMap", "_input_signals")},
    **{("shell.analysis.trim", "shell.analysis.linearize", name): "branch shell-core (issue 32: one public "
       "evaluation object)" for name in ("_Evaluator", "_Signals", "_StateMap", "_input_signals")},
    ("shell.compiled_loop", "shell.integrators.exponential", "_phi_into"): "branch shell-core (issue 32: "
    "integrators own their compiled stepping)",
}


def _graph():
    return read(ROOT, PACKAGES)


def test_no_import_circle():
    found = set(circles(_graph()[0]))
    new = [sorted(c) for c in found if c not in PENDING_CIRCLES]
    assert not new, f"import circles (modules that import each other, also inside functions): {new}"
    gone = [sorted(c) for c in PENDING_CIRCLES if c not in found]
    assert not gone, f"no longer circles: remove them from PENDING_CIRCLES: {gone}"


def test_no_module_imports_another_modules_private_name():
    found = {(p.module, p.source, p.name): p for p in _graph()[1]}
    new = [f"{p.module}:{p.line} takes {p.name} from {p.source}" for key, p in sorted(found.items())
           if key not in PENDING_PRIVATE]
    assert not new, "private names imported across modules (make them public, or move the code):\n" + "\n".join(new)
    gone = sorted(set(PENDING_PRIVATE) - set(found))
    assert not gone, f"no longer imported: remove them from PENDING_PRIVATE: {gone}"


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

"""The import graph of a source tree, read from the source (``ast``), nothing imported.

Every ``import`` and ``from ... import`` statement of a module counts, at module level or inside a
function: an import deferred into a function to dodge a circle still makes the circle. An edge goes from a
module to the module it names (``from shell.models import blocks`` names ``shell.models.blocks``; ``from
shell.model import Model`` names ``shell.model``). A *private import* is a module taking another module's
private name (``_name``, not ``__dunder__``): ``from m import _x``, or ``m._x`` on a module bound by an import.
Circles are the strongly connected components of two or more modules (:mod:`shell.graphs`, Tarjan's
algorithm, itself checked against networkx in tests/shell/test_graphs.py).
"""

from __future__ import annotations

import ast
from dataclasses import dataclass
from pathlib import Path

from shell.graphs import strongly_connected_components


@dataclass(frozen=True)
class PrivateImport:
    """``module`` (at ``line``) takes ``name`` from ``source``."""

    module: str
    source: str
    name: str
    line: int


def modules(root: Path, packages: tuple[str, ...]) -> dict[str, Path]:
    """Dotted module name -> source file of every module of ``packages`` under ``root``."""
    found = {}
    for package in packages:
        for path in sorted((root / package).rglob("*.py")):
            parts = list(path.relative_to(root).with_suffix("").parts)
            if parts[-1] == "__init__":
                parts = parts[:-1]
            found[".".join(parts)] = path
    return found


def _is_private(name: str) -> bool:
    return name.startswith("_") and not (name.startswith("__") and name.endswith("__"))


def _dotted(node) -> str | None:
    if isinstance(node, ast.Name):
        return node.id
    if isinstance(node, ast.Attribute):
        base = _dotted(node.value)
        return None if base is None else f"{base}.{node.attr}"
    return None


class _Module:
    """The imports of one module: its edges and its private imports."""

    def __init__(self, name: str, path: Path, known: dict[str, Path]):
        self.name, self.known = name, known
        self.package = name if path.name == "__init__.py" else name.rpartition(".")[0]
        self.edges: set[str] = set()
        self.private: list[PrivateImport] = []
        self.bound: dict[str, str] = {}  # local name -> module it is bound to (module aliases)
        tree = ast.parse(path.read_text(), str(path))
        for node in ast.walk(tree):
            if isinstance(node, ast.Import):
                self._import(node)
            elif isinstance(node, ast.ImportFrom):
                self._import_from(node)
        for node in ast.walk(tree):
            if isinstance(node, ast.Attribute) and _is_private(node.attr):
                base = _dotted(node.value)
                target = self.bound.get(base) if base in self.bound else (base if base in known else None)
                if target is not None and target != name:
                    self.private.append(PrivateImport(name, target, node.attr, node.lineno))

    def _resolve(self, dotted: str) -> str | None:
        """The module of ``dotted``: itself, or the longest module prefix of it."""
        while dotted and dotted not in self.known:
            dotted = dotted.rpartition(".")[0]
        return dotted or None

    def _edge(self, target: str | None) -> None:
        if target is not None and target != self.name:
            self.edges.add(target)

    def _import(self, node: ast.Import) -> None:
        for alias in node.names:
            target = self._resolve(alias.name)
            self._edge(target)
            if target is not None:
                if alias.asname:
                    self.bound[alias.asname] = alias.name if alias.name in self.known else target
                else:  # ``import a.b.c`` binds ``a`` and makes ``a.b.c`` reachable by its dotted name
                    self.bound[alias.name] = alias.name if alias.name in self.known else target

    def _import_from(self, node: ast.ImportFrom) -> None:
        if node.level:
            base = self.package.split(".")
            base = base[:len(base) - (node.level - 1)]
            source = ".".join(base + ([node.module] if node.module else []))
        else:
            source = node.module or ""
        if self._resolve(source) is None:
            return  # a module outside the checked packages
        for alias in node.names:
            submodule = f"{source}.{alias.name}"
            if submodule in self.known:  # ``from package import module``
                self._edge(submodule)
                self.bound[alias.asname or alias.name] = submodule
                continue
            target = self._resolve(source)
            self._edge(target)
            if _is_private(alias.name):
                self.private.append(PrivateImport(self.name, target, alias.name, node.lineno))


def read(root: Path, packages: tuple[str, ...]) -> tuple[dict[str, set[str]], list[PrivateImport]]:
    """(module -> modules it imports, private imports) of ``packages`` under ``root``."""
    known = modules(root, packages)
    graph, private = {}, []
    for name, path in known.items():
        module = _Module(name, path, known)
        graph[name] = module.edges
        private += module.private
    return graph, private


def circles(graph: dict[str, set[str]]) -> list[frozenset[str]]:
    """The import circles: strongly connected components of two or more modules."""
    components = strongly_connected_components({module: sorted(targets) for module, targets in graph.items()})
    return [frozenset(c) for c in components if len(c) > 1]

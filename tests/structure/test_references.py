"""No dangling references (docs/architecture.md): every document and every module or name that the code and
the guides cite exists in this repository.

Scanned: the source of ``shell/`` and ``dynamics/``, README.md and docs/*.md. A document is cited by its
file name (``docs/conventions.md``, ``conventions.md``, ``README.md``): it must be a file of the repository
(relative to the repository, to docs/, or to the citing document), unless it is a file the programs write
(WRITTEN). A module or name is cited by its dotted
path (``shell.schema.Where``, ``:mod:`dynamics.engine```): the longest prefix that is a module must exist
and define the next part (a function, class, constant or submodule); ``dynamics.flexible_kernels.FX_*`` names
a family and ``NAME`` a placeholder, not checked.
"""

from __future__ import annotations

import ast
import re
from functools import cache
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
DOCUMENT = re.compile(r"(?<![\w.-])([\w./-]*[A-Za-z_]\w*\.md)\b")
DOTTED = re.compile(r"(?<![\w/.-])((?:shell|dynamics)(?:\.[A-Za-z_]\w*)+)(?![\w*])")
#: a dotted match that is a file name, not a module path
FILE_SUFFIXES = {"md", "py", "h5", "yaml", "png", "rst", "html", "csv", "npy", "txt", "dat", "json"}
#: documents the programs write (cited as outputs, not as references)
WRITTEN = {"percentiles.md"}
#: a placeholder for any name (``dynamics.kernels.NAME``: each layout column re-exported)
PLACEHOLDERS = {"NAME"}


def _sources() -> list[Path]:
    files = [ROOT / "README.md", *sorted((ROOT / "docs").glob("*.md"))]
    for package in ("shell", "dynamics"):
        files += sorted((ROOT / package).rglob("*.py"))
    return files


@cache
def _module_file(module: str) -> Path | None:
    path = ROOT.joinpath(*module.split("."))
    for candidate in (path.with_suffix(".py"), path / "__init__.py"):
        if candidate.is_file():
            return candidate
    return None


@cache
def _defined(module: str) -> frozenset[str]:
    """Names a module defines at its top level (functions, classes, assignments, imports) and its submodules."""
    path = _module_file(module)
    names = set()
    for node in ast.parse(path.read_text()).body:
        if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef, ast.ClassDef)):
            names.add(node.name)
        elif isinstance(node, (ast.Assign, ast.AnnAssign)):
            targets = node.targets if isinstance(node, ast.Assign) else [node.target]
            for target in targets:
                names.update(n.id for n in ast.walk(target) if isinstance(n, ast.Name))
        elif isinstance(node, ast.ImportFrom) and node.names[0].name == "*" and _module_file(node.module or ""):
            names.update(n for n in _defined(node.module) if not n.startswith("_"))
        elif isinstance(node, (ast.Import, ast.ImportFrom)):
            names.update((a.asname or a.name).split(".")[0] for a in node.names)
    if path.name == "__init__.py":
        names.update(p.stem for p in path.parent.glob("*.py"))
        names.update(p.name for p in path.parent.iterdir() if (p / "__init__.py").is_file())
    return frozenset(names)


def dangling_documents(path: Path, text: str) -> list[str]:
    missing = []
    for match in DOCUMENT.finditer(text):
        cited = match.group(1).lstrip("./")
        if cited in WRITTEN:
            continue
        if not any((base / cited).is_file() for base in (ROOT, ROOT / "docs", path.parent)):
            missing.append(cited)
    return missing


def dangling_names(text: str) -> list[str]:
    missing = []
    for match in DOTTED.finditer(text):
        parts = match.group(1).split(".")
        if parts[-1] in FILE_SUFFIXES or parts[-1] in PLACEHOLDERS:
            continue
        k = len(parts)
        while k > 1 and _module_file(".".join(parts[:k])) is None:
            k -= 1
        module = ".".join(parts[:k])
        if k < len(parts) and parts[k] not in _defined(module):
            missing.append(match.group(1))
    return missing


def test_every_cited_document_and_name_exists():
    found = []
    for path in _sources():
        text = path.read_text()
        where = path.relative_to(ROOT)
        found += [f"{where}: document {cited}" for cited in dangling_documents(path, text)]
        found += [f"{where}: name {cited}" for cited in dangling_names(text)]
    assert not found, "dangling references:\n" + "\n".join(sorted(set(found)))


def test_planted_dangling_references_are_found():
    text = "see CONVENTIONS.md and docs/conventions.md; :mod:`shell.codegen` writes, shell.model.Declarations holds"
    assert dangling_documents(ROOT / "shell" / "model.py", text) == ["CONVENTIONS.md"]
    assert dangling_names(text) == ["shell.codegen"]

"""Small modules (docs/architecture.md): no file of ``shell/`` over 900 lines, no function over 120 lines
(from its ``def`` line to its last line, nested functions included in their parent and counted alone too).

The simulator core's split (issue 32) emptied the table of what was pending; the check names any new offender.
"""

from __future__ import annotations

import ast
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
MAX_FILE_LINES = 900
MAX_FUNCTION_LINES = 120


def _too_long() -> dict[tuple[str, str | None], int]:
    found = {}
    for path in sorted((ROOT / "shell").rglob("*.py")):
        name = str(path.relative_to(ROOT))
        text = path.read_text()
        lines = text.count("\n") + (not text.endswith("\n"))
        if lines > MAX_FILE_LINES:
            found[(name, None)] = lines
        stack = [(ast.parse(text), "")]
        while stack:
            node, prefix = stack.pop()
            if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef, ast.ClassDef)):
                prefix = f"{prefix}{node.name}"
                if not isinstance(node, ast.ClassDef) and node.end_lineno - node.lineno + 1 > MAX_FUNCTION_LINES:
                    found[(name, prefix)] = node.end_lineno - node.lineno + 1
                prefix += "."
            stack += [(child, prefix) for child in ast.iter_child_nodes(node)]
    return found


def test_files_and_functions_of_shell_are_small():
    found = _too_long()
    too_long = [f"{file}{'' if function is None else ':' + function}: {lines} lines"
                for (file, function), lines in sorted(found.items(), key=str)]
    assert not too_long, (f"over {MAX_FILE_LINES} lines per file or {MAX_FUNCTION_LINES} per function (split by "
                          "concept):\n" + "\n".join(too_long))

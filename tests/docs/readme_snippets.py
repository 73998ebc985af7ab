"""Code snippets of README.md, read as a user would copy them: fenced blocks, shell lines (``\\``
continuations joined, ``&&`` chains split, comments dropped) and Python blocks."""

from __future__ import annotations

import re
import shlex
from dataclasses import dataclass
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
FENCE = re.compile(r"^```([A-Za-z0-9_+-]*)[^\n]*\n(.*?)^```\s*$", re.MULTILINE | re.DOTALL)
#: lines that set up the machine or run the test suite: not run by the snippet tests (the CI runs them)
SETUP = (re.compile(r"^python3 -m pip install"), re.compile(r"^python3 -m pytest"))
#: programs a shell line of the README may start with (a block of other lines is text, e.g. a file tree)
PROGRAMS = ("flexshell", "python3", "python", "pip", "cd", "git", "mkdir")
#: command templates with placeholders in capitals (CAMPAIGN.yaml, OUT.h5, HOST): shown, not run
TEMPLATE = re.compile(r"\b(CAMPAIGN|SCENE|LOG|OUT|HOST|DECK|BODY|R)\b(\.yaml|\.h5|:)?")


@dataclass
class Snippet:
    kind: str       # "shell" or "python" (or "yaml": a scenario shown, checked by flexshell check)
    text: str
    line: int       # line of README.md where its block starts


def snippets(path=ROOT / "README.md") -> list[Snippet]:
    text = Path(path).read_text()
    found = []
    for match in FENCE.finditer(text):
        language, body = match.group(1).lower(), match.group(2)
        line = text.count("\n", 0, match.start()) + 1
        if language in ("python", "py"):
            found.append(Snippet("python", body, line))
        elif language in ("yaml", "yml"):
            found.append(Snippet("yaml", body, line))
        elif language in ("sh", "bash", "console", "shell") or (language == "" and is_shell(body)):
            for command in shell_lines(body):
                found.append(Snippet("shell", command, line))
    return found


def is_shell(body: str) -> bool:
    """A block without a language is shell when each of its commands starts with a known program."""
    commands = shell_lines(body)
    return bool(commands) and all(c.split()[0] in PROGRAMS for c in commands)


def shell_lines(body: str) -> list[str]:
    """Commands of a shell block as typed: continuations joined, comments dropped, ``&&`` chains split
    (the text is kept as written, so ``$PWD`` still expands in the user's shell)."""
    joined = re.sub(r"\\\n\s*", " ", body)
    commands = []
    for raw in joined.splitlines():
        raw = re.sub(r"(^|\s)#.*$", "", raw).strip()
        commands += [part.strip() for part in raw.split("&&") if part.strip()]
    return commands


def is_setup(command: str) -> bool:
    return any(p.match(command) for p in SETUP)


def is_template(command: str) -> bool:
    return bool(TEMPLATE.search(command))

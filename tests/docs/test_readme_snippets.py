"""Every code snippet of README.md runs as written (issue 18: the engine snippet named a body file that is
not shipped). Snippets are read from README.md itself (tests/docs/readme_snippets.py), so a new or
edited snippet is tested without editing this file.

Fast: the extraction finds the snippets, every ``flexshell`` line parses with the real command-line
parser and names files that exist, every Python block compiles, the YAML scenario passes
``flexshell check``; a broken snippet is caught (a planted one fails). Slow: every snippet runs, from a
scratch directory that sees the repository's configs/ and benchmarks/ (README lines are run from the
repository root; their outputs land in the scratch directory, never in the repository), except the
machine set-up lines (pip install, the test suite itself) and the templates with placeholders."""

from __future__ import annotations

import os
import shlex
import subprocess
import sys
import textwrap

import pytest

from shell.cli import build_parser, main
from tests.docs.readme_snippets import ROOT, is_setup, is_template, snippets

SNIPPETS = snippets()
RUNNABLE = [s for s in SNIPPETS if not (s.kind == "shell" and (is_setup(s.text) or is_template(s.text)))]
TUTORIAL = ROOT / "docs" / "tutorial_nastran_to_closed_loop.md"
#: the tutorial's commands (its YAML blocks are fragments of the shipped scene it runs)
TUTORIAL_COMMANDS = [s for s in snippets(TUTORIAL) if s.kind == "shell"]


def _id(s):
    return f"README:{s.line}:{s.kind}:{s.text.splitlines()[0][:40]}"


def test_the_readme_has_the_snippets_a_newcomer_copies():
    kinds = [s.kind for s in SNIPPETS]
    assert kinds.count("python") >= 2 and kinds.count("yaml") >= 1 and kinds.count("shell") >= 10
    skipped = [s.text for s in SNIPPETS if s not in RUNNABLE]
    # only machine set-up and placeholder templates are not run; nothing else is skipped silently
    assert all(is_setup(t) or is_template(t) for t in skipped) and len(skipped) <= 6


@pytest.mark.parametrize("snippet", [s for s in RUNNABLE + TUTORIAL_COMMANDS
                                     if s.kind == "shell" and s.text.startswith("flexshell ")], ids=_id)
def test_flexshell_lines_parse_and_name_existing_inputs(snippet):
    words = shlex.split(snippet.text)[1:]
    args = build_parser().parse_args(words)
    for attribute in ("scenario", "campaign", "deck"):
        value = getattr(args, attribute, None)
        if value is not None:
            assert (ROOT / value).exists(), f"README line {snippet.line}: {value} does not exist"


@pytest.mark.parametrize("snippet", [s for s in RUNNABLE if s.kind == "python"], ids=_id)
def test_python_blocks_compile(snippet):
    compile(snippet.text, f"README.md:{snippet.line}", "exec")


@pytest.mark.parametrize("snippet", [s for s in RUNNABLE if s.kind == "yaml"], ids=_id)
def test_yaml_scenarios_pass_flexshell_check(snippet, tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    (tmp_path / "scene.yaml").write_text(snippet.text)
    assert main(["check", "scene.yaml"]) == 0


def test_a_broken_snippet_is_caught(tmp_path):
    readme = tmp_path / "README.md"
    readme.write_text(textwrap.dedent("""\
        # x
        ```
        flexshell run configs/no_such_scene.yaml -o a.h5
        ```
        ```python
        print(undefined_name)
        ```
        """))
    found = snippets(readme)
    assert [s.kind for s in found] == ["shell", "python"] and found[0].line == 2
    with pytest.raises(AssertionError, match="does not exist"):
        test_flexshell_lines_parse_and_name_existing_inputs(found[0])
    with pytest.raises(NameError):
        _run_python(found[1], tmp_path)


def _scratch(tmp_path):
    for name in ("configs", "benchmarks"):
        link = tmp_path / name
        if not link.exists():
            link.symlink_to(ROOT / name)
    return tmp_path


def _run_python(snippet, directory):
    cwd = os.getcwd()
    os.chdir(directory)
    try:
        exec(compile(snippet.text, f"README.md:{snippet.line}", "exec"), {"__name__": "__readme__"})
    finally:
        os.chdir(cwd)


@pytest.mark.slow
def test_every_readme_snippet_runs_as_written(tmp_path):
    """In README order (a plot reads the log a run above it wrote), from one scratch directory."""
    directory = _scratch(tmp_path)
    env = dict(os.environ, PYTHONPATH=str(ROOT) + os.pathsep + os.environ.get("PYTHONPATH", ""))
    failures = []
    for snippet in RUNNABLE:
        try:
            if snippet.kind == "python":
                _run_python(snippet, directory)
            elif snippet.kind == "yaml":
                (directory / "scene.yaml").write_text(snippet.text)
                code = subprocess.run([sys.executable, "-m", "shell.cli", "run", "scene.yaml", "-o", "scene.h5",
                                       "--quiet"], cwd=directory, env=env).returncode
                assert code == 0, f"exit {code}"
            else:
                code = _run_shell(snippet.text, directory, env)
                assert code == 0, f"exit {code}"
        except Exception as exc:  # collect them all: one report names every broken snippet
            failures.append(f"README.md:{snippet.line}: {snippet.text.splitlines()[0]!r}: {exc!r}")
    assert not failures, "\n".join(failures)


def _run_shell(line, directory, env):
    """A command line as a user's shell runs it (``$PWD`` expanded), flexshell and python3 from this
    interpreter."""
    program, _, rest = line.partition(" ")
    program = {"flexshell": f"{shlex.quote(sys.executable)} -m shell.cli",
               "python3": shlex.quote(sys.executable)}.get(program, program)
    return subprocess.run(["bash", "-c", f"{program} {rest}"], cwd=directory, env=env).returncode


@pytest.mark.slow
def test_the_tutorial_runs_as_written(tmp_path):
    directory = _scratch(tmp_path)
    env = dict(os.environ, PYTHONPATH=str(ROOT) + os.pathsep + os.environ.get("PYTHONPATH", ""))
    assert len(TUTORIAL_COMMANDS) >= 5
    for snippet in TUTORIAL_COMMANDS:
        assert _run_shell(snippet.text, directory, env) == 0, f"tutorial line {snippet.line}: {snippet.text}"
    assert (directory / "tutorial" / "slew.png").exists()

"""Helpers for the safety tests: a small scene on disk and the command line called in-process."""

import os
import subprocess
import sys
import textwrap
from pathlib import Path

import pytest

from shell.cli import main

ROOT = Path(__file__).resolve().parents[2]

# A ramp x' = v read by a noisy sampler: the tiniest scene (no engine, a few milliseconds to run).
# Block style: every key on its own line, so that a refusal's line number says which key it is.
RAMP = """\
name: ramp
seed: 0
models:
  rate:
    type: Constant
    config: {unit: m/s}
    parameters: {value: 1 m/s}
  position:
    type: Integrator
    config: {unit: m}
  sensor:
    type: NoisySampler
    rate: 10 Hz
    config: {unit: m}
    parameters: {sigma: 0.01 m}
connections:
  - rate.y -> position.u
  - position.y -> sensor.u
integrator:
  method: rk4
  step: 0.01 s
stop:
  time: 2 s
log:
  rate: 10 Hz
  signals: [sensor.y]
"""


def line_of(text: str, needle: str) -> int:
    """1-based number of the line of ``text`` that is ``needle``, else of the first containing it."""
    lines = text.splitlines()
    if needle in lines:
        return lines.index(needle) + 1
    for number, line in enumerate(lines, start=1):
        if needle in line:
            return number
    raise AssertionError(f"{needle!r} not in the scenario")


def run_cli(argv, capsys) -> tuple[int, str, str]:
    """``flexshell ARGV`` in this process: (exit status, stdout, stderr). An exception escaping the
    command line fails the test (the user would have seen a traceback)."""
    try:
        code = main([str(a) for a in argv])
    except SystemExit as exc:  # argparse refusals
        code = exc.code
    captured = capsys.readouterr()
    return code, captured.out, captured.err


def subprocess_env() -> dict:
    env = dict(os.environ)
    env["PYTHONPATH"] = str(ROOT) + os.pathsep + env.get("PYTHONPATH", "")
    env.setdefault("OMP_NUM_THREADS", "1")
    env.setdefault("OPENBLAS_NUM_THREADS", "1")
    return env


def flexshell(argv, cwd, **kwargs) -> subprocess.CompletedProcess:
    """``flexshell ARGV`` as a separate process (for what only a process shows: tracebacks, signals)."""
    return subprocess.run([sys.executable, "-m", "shell.cli", *map(str, argv)], cwd=cwd, env=subprocess_env(),
                          capture_output=True, text=True, **kwargs)


@pytest.fixture
def cli(capsys):
    return lambda *argv: run_cli(argv, capsys)


@pytest.fixture
def put(tmp_path):
    """put(name, text or bytes) -> path of a file in the test's directory."""

    def write(name, content):
        path = tmp_path / name
        path.parent.mkdir(parents=True, exist_ok=True)
        if isinstance(content, bytes):
            path.write_bytes(content)
        else:
            path.write_text(textwrap.dedent(content))
        return path

    return write

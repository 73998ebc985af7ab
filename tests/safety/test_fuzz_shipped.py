"""Hypothesis fuzzing of the shipped inputs through the command line (issue 34): scenario files, campaign files,
``--set`` values and NASTRAN decks, each mutated from the ones in configs/ (keys deleted, values replaced by
junk, lists and mappings swapped, numbers scaled to huge, tiny, negative or non-integer values, deck lines
deleted, duplicated, cut or given junk fields), run as ``flexshell check``, ``flexshell montecarlo
--print-overrides``, ``flexshell fem2modal``. Every command must end in success or a clean flexshell message:

* never a traceback: an exception escaping the command line fails the case;
* never a hang: a command still running after ``LIMIT_S`` seconds is stopped (SIGALRM) and fails the case;
* never a lost file: every file of the work directory (a copy of configs/) is compared (size, modification
  time, inode) before and after each command, and a fem2modal output is aimed, now and then, at a deck or a
  scenario of the work directory, which the output guard must refuse.

Seeded (``derandomize``): CI sees the same inputs every run. The default suite tries 310 inputs on a few
configs and the small decks (scenes are built, never run; a campaign's check runs two steps of a scene compiled
once); ``-m slow`` tries 5,100 over every shipped config and deck.
"""

from __future__ import annotations

import contextlib
import copy
import io
import os
import shutil
import signal
import time
from pathlib import Path

import pytest
import yaml
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from shell.cli import main
from shell.schema.document import load_yaml, plain
from tests.safety.conftest import ROOT
from tests.safety.test_fuzz import junk_text, paths, values

LIMIT_S = 20.0
CONFIGS = ROOT / "configs"
SCENES = sorted(str(p.relative_to(CONFIGS)) for p in CONFIGS.rglob("*.yaml") if "campaign" not in p.name)
CAMPAIGNS = sorted(str(p.relative_to(CONFIGS)) for p in CONFIGS.rglob("campaign*.yaml"))
DECKS = sorted(str(p.relative_to(CONFIGS)) for p in CONFIGS.rglob("*.dat"))
#: the default suite's share: scenes other tests build too (their kernels compiled anyway), the small decks
FAST_SCENES = ["demo_attitude_hold.yaml", "lqr_plant.yaml", "observatory.yaml", "rw_attitude.yaml",
               "spacecraft_slew.yaml", "launch_vehicle_stage.yaml"]
FAST_DECKS = ["fem/five_particle.dat", "fem/SimpleBeam.dat", "lqr_data/cantilever_array.dat"]


class Hang(BaseException):
    """A command ran longer than LIMIT_S (BaseException: no ``except Exception`` of the code under test takes it)."""


@contextlib.contextmanager
def time_limit(seconds: float):
    def stop(signum, frame):
        raise Hang(f"still running after {seconds:g} s")

    previous = signal.signal(signal.SIGALRM, stop)
    signal.setitimer(signal.ITIMER_REAL, seconds)
    try:
        yield
    finally:
        signal.setitimer(signal.ITIMER_REAL, 0)
        signal.signal(signal.SIGALRM, previous)


def snapshot(directory: Path) -> dict:
    return {str(p.relative_to(directory)): (s.st_size, s.st_mtime_ns, s.st_ino)
            for p in directory.rglob("*") if p.is_file() for s in [p.stat()]}


class Workspace:
    """A copy of configs/ to run commands in, with the checks of the module docstring."""

    def __init__(self, root: Path):
        self.root = root
        shutil.copytree(CONFIGS, root / "configs")
        self.count = 0
        self.limit = LIMIT_S

    def command(self, argv, outputs=()) -> tuple[int, str]:
        """``flexshell ARGV`` in this process: (exit status, stderr); ``outputs``: files it may create."""
        before = snapshot(self.root)
        err = io.StringIO()
        start = time.perf_counter()
        with contextlib.redirect_stderr(err), contextlib.redirect_stdout(io.StringIO()), time_limit(self.limit):
            try:
                code = main([str(a) for a in argv])
            except SystemExit as exc:  # argparse
                code = exc.code
        seconds = time.perf_counter() - start
        after = snapshot(self.root)
        made = {str(Path(o).relative_to(self.root)) for o in outputs}
        changed = [p for p, stat in before.items() if after.get(p) != stat and p not in made]
        assert not changed, f"files lost or changed: {changed}"
        stray = set(after) - set(before) - made
        assert not stray, f"files left behind: {stray}"
        for output in outputs:
            if str(Path(output).relative_to(self.root)) not in before:
                Path(output).unlink(missing_ok=True)
        message = err.getvalue()
        assert code in (0, 1, 2), (code, message)
        if code:
            assert message.startswith(("flexshell", "usage:")), message
        assert "Traceback" not in message, message
        self.count += 1
        return code, f"{message} ({seconds:.2f} s)"

    def write(self, relative: str, text: str) -> Path:
        """A mutated input beside the original (its relative paths resolve as the original's)."""
        path = self.root / "configs" / relative
        path = path.with_name(f"{path.stem}.fuzz{path.suffix}")
        path.write_text(text)
        return path


@pytest.fixture(scope="module")
def workspace(tmp_path_factory):
    work = Workspace(tmp_path_factory.mktemp("fuzz_shipped"))
    previous = os.getcwd()
    os.chdir(work.root / "configs")  # relative gain files and meshes are read from the working directory
    yield work
    os.chdir(previous)


def settings_for(examples: int):
    return settings(max_examples=examples, deadline=None, derandomize=True, database=None,
                    suppress_health_check=list(HealthCheck))


# ------------------------------------------------------------------------------------------------
# documents (scenarios, campaigns)
numbers = st.sampled_from([0, -1, -0.5, 0.5, 2.5, 3000000.0, 3000000, 10**9, 1e300, -1e300, float("nan"),
                           float("inf"), 1e-300, True])


@st.composite
def mutated_documents(draw, document):
    """``document`` with 1-3 mutations: a key or item deleted, a value replaced by junk, a list made a mapping
    or a mapping a list, a number scaled or made non-integer, an item duplicated."""
    document = copy.deepcopy(document)
    targets = [p for p in paths(document) if p]
    counts = [p for p in targets if isinstance(_at(document, p), int) and not isinstance(_at(document, p), bool)]
    for _ in range(draw(st.integers(1, 3))):
        if not targets:
            break
        if counts and draw(st.integers(0, 3)) == 0:  # a whole number (a count, a size, a seed) made huge or odd
            path = draw(st.sampled_from(counts))
        else:
            path = draw(st.sampled_from(targets))
        try:
            container = document
            for key in path[:-1]:
                container = container[key]
            key, value = path[-1], container[path[-1]]
        except (KeyError, IndexError, TypeError):  # an earlier mutation moved it
            continue
        action = draw(st.sampled_from(["delete", "junk", "junk", "swap", "number", "duplicate"]))
        if action == "delete":
            del container[key]
        elif action == "junk":
            container[key] = draw(values)
        elif action == "swap" and isinstance(value, list):
            container[key] = {str(k): item for k, item in enumerate(value)}
        elif action == "swap" and isinstance(value, dict):
            container[key] = list(value.values())
        elif action == "number":
            container[key] = draw(numbers)
        elif action == "duplicate" and isinstance(container, list):
            container.append(copy.deepcopy(value))
        else:
            container[key] = draw(st.one_of(numbers, junk_text))
    return yaml.safe_dump(document, allow_unicode=True, sort_keys=False, width=1000)


def _at(document, path):
    for key in path:
        document = document[key]
    return document


def load(relative: str):
    return plain(load_yaml((CONFIGS / relative).read_text(), relative))  # the scenario loader: q[0] inside { }


def scenario_case(workspace, relative, text):
    path = workspace.write(relative, text)
    workspace.command(["check", path])


def campaign_case(workspace, relative, text):
    path = workspace.write(relative, text)
    workspace.command(["montecarlo", path, "--print-overrides", "0", "--quiet"])


# ------------------------------------------------------------------------------------------------
# --set values
def override_keys(document) -> list[str]:
    """Keys a user would --set in ``document``: sections' dotted paths, model parameters, body keys."""
    keys = []
    for path in paths(document):
        if path and path[0] not in ("models", "multibody") and all(isinstance(p, str) for p in path):
            keys.append(".".join(path))
    for name, spec in (document.get("models") or {}).items():
        keys.append(f"{name}.rate")
        for parameter in ((spec or {}).get("parameters") or {}):
            keys += [f"{name}.{parameter}", f"{name}.parameters.{parameter}"]
    for body in ((document.get("multibody") or {}).get("bodies") or []):
        keys += [f"multibody.{body.get('name')}.{key}" for key in body]
    return keys or ["stop.time"]


@st.composite
def overrides(draw, document):
    keys = override_keys(document)
    items = []
    for _ in range(draw(st.integers(1, 3))):
        key = draw(st.one_of(st.sampled_from(keys), junk_text))
        value = draw(st.one_of(numbers.map(str), junk_text, values.map(
            lambda v: yaml.safe_dump(v, default_flow_style=True, width=1000).strip())))
        items += ["--set", f"{key}={value}"]
    return items


def override_case(workspace, relative, items):
    workspace.command(["check", workspace.root / "configs" / relative, *items])


# ------------------------------------------------------------------------------------------------
# NASTRAN decks
deck_fields = st.sampled_from(["", "abc", "1e400", "-1", "0", "nan", "1.+5", "9999999999", "THRU", "*", "$", "+",
                               "1e-300", "3000000.", "-3000000.", "1.5", "0.0", "123456", "7", "GRID", "=", "'"])
deck_lines = st.sampled_from(["GRID,99,,0.0,0.0,0.0", "CONM2,999,1,,-2.0", "CONM2,998,99,,1.0", "PARAM,GRDPNT,77",
                              "SPC1,1,123456,1", "INCLUDE 'missing.dat'", "INCLUDE '{self}'", "CELAS2,299,1e300,1,1,2,1",
                              "MAT1,1,-2.1e11,,0.3,7800.", "PBAR,1,1,0.0", "ENDDATA", "BEGIN BULK", "$ comment",
                              "CBAR,999,1,1,1,0.,0.,1.", "GRID,1,,nan,0.0,0.0", "\t", "GRID*,5", "+,"])


@st.composite
def mutated_decks(draw, text: str, name: str):
    lines = text.splitlines()
    for _ in range(draw(st.integers(1, 3))):
        if not lines:
            break
        k = draw(st.integers(0, len(lines) - 1))
        action = draw(st.sampled_from(["delete", "duplicate", "field", "field", "insert", "swap", "cut"]))
        if action == "delete":
            del lines[k]
        elif action == "duplicate":
            lines.insert(k, lines[k])
        elif action == "field":
            separator = "," if "," in lines[k] else None
            fields = lines[k].split(",") if separator else [lines[k][i:i + 8] for i in range(0, len(lines[k]), 8)]
            if fields:
                fields[draw(st.integers(0, len(fields) - 1))] = draw(deck_fields).ljust(0 if separator else 8)
                lines[k] = (separator or "").join(fields)
        elif action == "insert":
            lines.insert(k, draw(deck_lines).replace("{self}", name))
        elif action == "swap":
            j = draw(st.integers(0, len(lines) - 1))
            lines[k], lines[j] = lines[j], lines[k]
        else:
            lines = lines[:k]
    return "\n".join(lines) + "\n"


deck_options = st.one_of(st.just(["--modes", "2"]), st.just(["--modes", "4"]),
                         st.sampled_from([["--modes", "0"], ["--modes", "3000000"], ["--cutoff", "1e9"],
                                          ["--cutoff", "nan"], ["--modes", "2", "--damping", "-1"],
                                          ["--modes", "2", "--grdpnt", "12345"], ["--modes", "2", "--aset", "1:123456"],
                                          ["--modes", "2", "--residual", "99:1"], ["--modes", "2", "--preload",
                                                                                 "t:1:3:1e300"]]))
deck_targets = st.sampled_from(["out.h5", "out.h5", "out.h5", "deck", "scenario"])


def deck_case(workspace, relative, text, options, target):
    deck = workspace.write(relative, text)
    output = {"out.h5": deck.with_name("out.h5"), "deck": deck,
              "scenario": workspace.root / "configs" / "rw_attitude.yaml"}[target]
    code, message = workspace.command(["fem2modal", deck, *options, "-q", "-o", output],
                                      outputs=[output] if target == "out.h5" else [])
    if target != "out.h5":  # the guard refuses; the snapshot shows the file untouched
        assert code == 1 and "--overwrite" in message, message


# ------------------------------------------------------------------------------------------------
# the tests: each asserts how many inputs it tried
def fuzz(strategy, case, examples):
    @settings_for(examples)
    @given(strategy)
    def run(drawn):
        case(*drawn)

    return run


def cases(workspace, names, make):
    return st.sampled_from(names).flatmap(make)


def scenario_inputs(workspace, names):
    return cases(workspace, names, lambda r: mutated_documents(load(r)).map(lambda t: (workspace, r, t)))


def override_inputs(workspace, names):
    return cases(workspace, names, lambda r: overrides(load(r)).map(lambda items: (workspace, r, items)))


def campaign_inputs(workspace, names):
    return cases(workspace, names, lambda r: mutated_documents(load(r)).map(lambda t: (workspace, r, t)))


def deck_inputs(workspace, names):
    return cases(workspace, names, lambda r: st.tuples(
        st.just(workspace), st.just(r), mutated_decks((CONFIGS / r).read_text(), Path(r).stem + ".fuzz.dat"),
        deck_options, deck_targets))


PLAN = {  # kind: (inputs, case, default names, default count, slow names, slow count)
    "scenarios": (scenario_inputs, scenario_case, FAST_SCENES, 150, SCENES, 2400),
    "overrides": (override_inputs, override_case, FAST_SCENES, 60, SCENES, 1000),
    "campaigns": (campaign_inputs, campaign_case, CAMPAIGNS, 40, CAMPAIGNS, 700),
    "decks": (deck_inputs, deck_case, FAST_DECKS, 60, DECKS, 1000),
}


def warm_up(workspace, names, kind):
    """Each original once, without a time limit (its kernels compiled or loaded before the limit applies)."""
    workspace.limit = 3600.0
    try:
        for relative in names:
            if kind == "decks":
                deck_case(workspace, relative, (CONFIGS / relative).read_text(), ["--modes", "2"], "out.h5")
            elif kind == "campaigns":
                campaign_case(workspace, relative, (CONFIGS / relative).read_text())
            else:
                scenario_case(workspace, relative, (CONFIGS / relative).read_text())
    finally:
        workspace.limit = LIMIT_S


def fuzz_kind(workspace, kind, slow):
    inputs, case, names, count, slow_names, slow_count = PLAN[kind]
    names, count = (slow_names, slow_count) if slow else (names, count)
    warm_up(workspace, names, kind)
    start = workspace.count
    fuzz(inputs(workspace, names), case, count)()
    tried = workspace.count - start
    print(f"\n{kind}: {tried} mutated inputs, 0 tracebacks, hangs or lost files")
    assert tried >= count, f"{kind}: hypothesis tried only {tried} of {count} inputs"


@pytest.mark.parametrize("kind", list(PLAN))
def test_mutated_shipped_inputs_end_cleanly(kind, workspace):
    fuzz_kind(workspace, kind, slow=False)


@pytest.mark.slow
@pytest.mark.parametrize("kind", list(PLAN))
def test_mutated_shipped_inputs_end_cleanly_slow(kind, workspace):
    fuzz_kind(workspace, kind, slow=True)


# ------------------------------------------------------------------------------------------------
# what the fuzzing found (issue 34), each kept as a case of its own
def shipped(relative: str, old: str, new: str) -> str:
    text = (CONFIGS / relative).read_text()
    assert old in text, old
    return text.replace(old, new, 1)


@pytest.mark.parametrize("new, expected", [
    ("actuators: 3000000.0}", "config actuators: expected a whole number of actuators from 1 to 10000"),
    ("actuators: 2.5}", "given 2.5"),  # was read as 2 actuators
    ("actuators: 3000000}", "from 1 to 10000"),
])
def test_counts_are_whole_and_bounded(new, expected, workspace):
    path = workspace.write("rw_attitude.yaml", shipped("rw_attitude.yaml", "actuators: 3}", new))
    start = time.perf_counter()
    code, message = workspace.command(["check", path])
    assert code == 1 and expected in message and "models.allocator" in message, message
    assert time.perf_counter() - start < 10


@pytest.mark.parametrize("parent", ["[bus]", "{name: bus}"])
def test_a_parent_that_is_not_a_name_is_refused(parent, workspace):
    """Was a TypeError from dynamics/builder.py (a body's parent given as a list or a mapping)."""
    text = shipped("rw_attitude_slosh_panels.yaml", "      parent: bus", f"      parent: {parent}")
    code, message = workspace.command(["check", workspace.write("rw_attitude_slosh_panels.yaml", text)])
    assert code == 1 and ".parent: expected a body name or world (text)" in message, message


def test_a_missing_include_leaves_no_pyNastran_file_and_prints_only_flexshell(workspace):
    """pyNastran dumped the lines it had read to pyNastran_crash.bdf in the working directory (replacing a file
    of that name) and logged raw lines to stderr before flexshell's message."""
    keep = workspace.root / "configs" / "pyNastran_crash.bdf"
    keep.write_text("a user's file\n")
    deck = workspace.write("fem/five_particle.dat",
                           shipped("fem/five_particle.dat", "ENDDATA", "INCLUDE 'missing.dat'\nENDDATA"))
    code, message = workspace.command(["fem2modal", deck, "--modes", "2", "-q", "-o", deck.with_name("out.h5")])
    assert code == 1 and message.startswith("flexshell fem2modal: error: ") and "missing.dat" in message, message
    assert keep.read_text() == "a user's file\n"
    keep.unlink()

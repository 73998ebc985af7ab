"""The output guard (shell/outputs.py, issue 34): for every verb that writes, its output cannot replace one of
its inputs (the same file under another name, a symbolic or a hard link included) nor an existing file of
another kind, unless ``--overwrite`` is given; a refused file is left byte for byte as it was.

Verbs that write: run (log, --save-state), montecarlo (results, --rerun log), linearize (model, --mat),
fem2modal (body file), view (page), plot (figures), report (directory). slosh and check write no file.
"""

import os
import shutil

import h5py
import pytest

from tests.safety.conftest import RAMP, ROOT
from tests.safety.test_logs import write_log
from tests.safety.test_refusals import CAMPAIGN

DECK = ROOT / "configs" / "fem" / "five_particle.dat"
NOTES = "my notes: keep me\n"


def refused(result, path, *needles):
    """A clean refusal naming ``path`` and the flag, the file untouched (``before``: its bytes)."""
    code, _, err = result
    assert code == 1 and "Traceback" not in err, err
    assert str(path) in err and "--overwrite" in err, err
    for needle in needles:
        assert needle in err, err


def aliases(tmp_path, target):
    """Other names of ``target``: a symbolic link, a hard link, a path through '..'."""
    symbolic, hard = tmp_path / f"sym_{target.name}", tmp_path / f"hard_{target.name}"
    symbolic.symlink_to(target)
    os.link(target, hard)
    (tmp_path / "sub").mkdir(exist_ok=True)
    return [target, symbolic, hard, tmp_path / "sub" / ".." / target.name]


@pytest.fixture
def scene(put):
    return put("scene.yaml", RAMP)


# ------------------------------------------------------------------------------------------------
# run: the log and --save-state
def test_run_refuses_its_scenario_by_any_name(scene, cli, tmp_path):
    for name in aliases(tmp_path, scene):
        refused(cli("run", scene, "-o", name, "--quiet"), name, "the scenario itself")
        assert scene.read_text() == RAMP


def test_run_refuses_a_file_of_another_kind_and_replaces_it_when_told(scene, put, cli, tmp_path):
    notes = put("notes.h5", NOTES)
    refused(cli("run", scene, "-o", notes, "--quiet"), notes, "not an HDF5 file", "flexshell-log")
    assert notes.read_text() == NOTES
    body = tmp_path / "body.h5"
    with h5py.File(body, "w") as f:
        f.attrs["FLEXSHELL_BODY_FILE_VERSION"] = 1
    refused(cli("run", scene, "-o", body, "--quiet"), body, "a flexshell body file")
    code, out, err = cli("run", scene, "-o", notes, "--quiet", "--overwrite")
    assert code == 0, err
    with h5py.File(notes, "r") as f:
        assert f.attrs["format"] == "flexshell-log" and f.attrs["status"] == "completed"


def test_run_replaces_a_log_without_being_told(scene, cli, tmp_path):
    log = tmp_path / "run.h5"
    write_log(log)
    code, _, err = cli("run", scene, "-o", log, "--quiet")
    assert code == 0, err
    with h5py.File(log, "r") as f:
        assert "scenario" in f.attrs, "the new run's log"


def test_save_state_cannot_replace_the_restart_it_continues_from(scene, cli, tmp_path):
    state = tmp_path / "state.h5"
    assert cli("run", scene, "-o", tmp_path / "a.h5", "--save-state", state, "--quiet")[0] == 0
    before = state.read_bytes()
    result = cli("run", scene, "-o", tmp_path / "b.h5", "--restore", state, "--save-state", state, "--quiet",
                 "--t-final", "3 s")
    refused(result, state, "the restart file of --restore")
    assert state.read_bytes() == before
    notes = tmp_path / "notes.txt"
    notes.write_text(NOTES)
    refused(cli("run", scene, "-o", tmp_path / "c.h5", "--save-state", notes, "--quiet"), notes, "flexshell-restart")
    assert notes.read_text() == NOTES
    code, _, err = cli("run", scene, "-o", state, "--save-state", state, "--quiet")
    assert code == 1 and "its own file" in err, "a log and a restart on one file: refused whatever the flag"
    code, _, err = cli("run", scene, "-o", tmp_path / "b.h5", "--restore", state, "--save-state", state, "--quiet",
                       "--t-final", "3 s", "--overwrite")
    assert code == 0, err
    with h5py.File(state, "r") as f:
        assert f.attrs["t"] == pytest.approx(3.0), "advanced in place when told"


# ------------------------------------------------------------------------------------------------
# montecarlo: the results file and the log of --rerun
def test_montecarlo_refuses_its_campaign_and_files_of_another_kind(scene, put, cli, tmp_path):
    campaign = put("campaign.yaml", CAMPAIGN)
    for name in aliases(tmp_path, campaign):
        refused(cli("montecarlo", campaign, "-o", name, "--quiet"), name, "the campaign file itself")
        refused(cli("montecarlo", campaign, "-o", name, "--rerun", "0"), name, "the campaign file itself")
    refused(cli("montecarlo", campaign, "-o", scene, "--quiet"), scene, "flexshell-campaign")
    log = tmp_path / "run.h5"
    write_log(log)
    refused(cli("montecarlo", campaign, "-o", log, "--quiet"), log, "'flexshell-log'")
    assert campaign.read_text() == CAMPAIGN and scene.read_text() == RAMP


def test_montecarlo_overwrite_replaces_a_file_of_another_kind(scene, put, cli, tmp_path):
    campaign = put("campaign.yaml", CAMPAIGN)
    notes = put("notes.h5", NOTES)
    code, _, err = cli("montecarlo", campaign, "-o", notes, "--quiet", "--overwrite")
    assert code == 0, err
    with h5py.File(notes, "r") as f:
        assert f.attrs["format"] == "flexshell-campaign"


# ------------------------------------------------------------------------------------------------
# linearize: the model and --mat
def test_linearize_refuses_its_scenario_and_files_of_another_kind(scene, put, cli, tmp_path):
    io = ["--inputs", "rate.y", "--outputs", "sensor.y"]
    for name in aliases(tmp_path, scene):
        refused(cli("linearize", scene, *io, "-o", name), name, "the scenario itself")
        refused(cli("linearize", scene, *io, "-o", tmp_path / "lin.h5", "--mat", name), name, "the scenario itself")
    notes = put("notes.mat", NOTES)
    refused(cli("linearize", scene, *io, "-o", tmp_path / "lin.h5", "--mat", notes), notes, "MAT-file")
    log = tmp_path / "run.h5"
    write_log(log)
    refused(cli("linearize", scene, *io, "-o", log), log, "flexshell-linear-model")
    code, _, err = cli("linearize", scene, *io, "-o", tmp_path / "x.h5", "--mat", tmp_path / "x.h5")
    assert code == 1 and "its own file" in err, err
    assert scene.read_text() == RAMP and notes.read_text() == NOTES and not (tmp_path / "lin.h5").exists()


# ------------------------------------------------------------------------------------------------
# fem2modal: the body file
def test_fem2modal_refuses_to_replace_its_deck(cli, tmp_path):
    """The finding of issue 34: ``fem2modal DECK -o DECK`` replaced the user's deck by the body file."""
    deck = tmp_path / "five.dat"
    shutil.copy(DECK, deck)
    text = deck.read_text()
    for name in aliases(tmp_path, deck):
        refused(cli("fem2modal", deck, "--modes", "2", "-o", name, "-q"), name, "the deck itself")
        assert deck.read_text() == text
    other = tmp_path / "other.dat"
    other.write_text(text)
    refused(cli("fem2modal", deck, "--modes", "2", "-o", other, "-q"), other, "not an HDF5 file", "body file")
    assert other.read_text() == text
    body = tmp_path / "five.h5"
    assert cli("fem2modal", deck, "--modes", "2", "-o", body, "-q")[0] == 0
    assert cli("fem2modal", deck, "--modes", "3", "-o", body, "-q")[0] == 0, "a body file is replaced"
    assert cli("fem2modal", deck, "--modes", "2", "-o", other, "-q", "--overwrite")[0] == 0
    with h5py.File(other, "r") as f:
        assert "FLEXSHELL_BODY_FILE_VERSION" in f.attrs


# ------------------------------------------------------------------------------------------------
# view: the page
def test_view_refuses_its_input_and_files_of_another_kind(scene, put, cli, tmp_path):
    log = tmp_path / "run.h5"
    write_log(log)
    before = log.read_bytes()
    for name in aliases(tmp_path, log):
        refused(cli("view", log, "-o", name), name)
    assert log.read_bytes() == before
    notes = put("notes.html", NOTES)
    refused(cli("view", scene, "-o", notes), notes, "a text file", "HTML page")
    refused(cli("view", scene, "-o", scene), scene, "the input itself")
    assert notes.read_text() == NOTES and scene.read_text() == RAMP


# ------------------------------------------------------------------------------------------------
# plot: the figures
def test_plot_refuses_a_format_it_cannot_write_without_a_traceback(scene, cli, tmp_path):
    """The finding of issue 34: ``plot LOG -o figure.yaml`` ended in matplotlib's unsupported-format error."""
    log = tmp_path / "run.h5"
    write_log(log)
    for output in (tmp_path / "figure.yaml", scene, log, tmp_path / "figure"):
        code, _, err = cli("plot", log, "-o", output)
        assert code == 1 and "Traceback" not in err and "not a figure format" in err and ".png" in err, err
        assert not (tmp_path / "figure.yaml").exists()
    assert scene.read_text() == RAMP


def test_plot_refuses_a_file_of_another_kind_and_keeps_its_own(put, cli, tmp_path):
    log = tmp_path / "run.h5"
    write_log(log)
    paper = put("paper.pdf", b"%PDF-1.5\n% a paper typeset by LaTeX\n")
    refused(cli("plot", log, "-o", paper), paper, "PDF figure drawn by matplotlib")
    assert paper.read_bytes() == b"%PDF-1.5\n% a paper typeset by LaTeX\n"
    text = put("notes.png", NOTES)
    refused(cli("plot", log, "-o", text), text, "a text file")
    figure = tmp_path / "fig.png"
    assert cli("plot", log, "-o", figure)[0] == 0
    assert cli("plot", log, "-o", figure)[0] == 0, "a figure plot drew is replaced"
    assert cli("plot", log, "-o", paper, "--overwrite")[0] == 0
    assert paper.read_bytes().startswith(b"%PDF") and b"matplotlib" in paper.read_bytes().lower()


# ------------------------------------------------------------------------------------------------
# report: the directory
def test_report_refuses_files_of_its_names_that_it_did_not_write(scene, put, cli, tmp_path):
    from shell.montecarlo.campaign import load_campaign
    from shell.montecarlo.results import open_results

    results_path = tmp_path / "out" / "results.h5"
    results_path.parent.mkdir()
    results = open_results(results_path, load_campaign(put("campaign.yaml", CAMPAIGN), validate=False))
    results.close("partial")
    mine = put("out/percentiles.md", "# My own table\n")
    refused(cli("report", results_path, "-o", tmp_path / "out"), mine, "campaign report")
    assert mine.read_text() == "# My own table\n"
    os.link(results_path, tmp_path / "out" / "percentiles.csv")
    refused(cli("report", results_path, "-o", tmp_path / "out"), tmp_path / "out" / "percentiles.csv",
            "the campaign results itself")
    (tmp_path / "out" / "percentiles.csv").unlink()
    code, _, err = cli("report", results_path, "-o", tmp_path / "out", "--overwrite")
    assert code == 0, err
    assert (tmp_path / "out" / "percentiles.md").read_text().startswith("# Campaign ")
    code, _, err = cli("report", results_path, "-o", tmp_path / "out")
    assert code == 0, "a report directory is written again without being told"


# ------------------------------------------------------------------------------------------------
# slosh and check write nothing
def test_slosh_and_check_write_no_file(scene, cli, tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    before = sorted(os.listdir(tmp_path))
    code, out, _ = cli("slosh", "--radius", "1 m", "--fill", "1 m", "--density", "1000 kg/m^3",
                       "--acceleration", "10 m/s^2")
    assert code == 0 and "multibody:" in out
    assert cli("check", scene)[0] == 0
    assert sorted(os.listdir(tmp_path)) == before


def test_every_verb_that_writes_takes_overwrite():
    """A verb added later with an output option and no guard fails here (slosh, check and models write none)."""
    import argparse

    from shell.cli import build_parser

    verbs = next(a for a in build_parser()._actions if isinstance(a, argparse._SubParsersAction)).choices
    writers = []
    for verb, parser in verbs.items():
        options = {option for action in parser._actions for option in action.option_strings}
        if options & {"-o", "--output", "--save-state", "--mat"}:
            writers.append(verb)
            assert "--overwrite" in options, f"flexshell {verb} writes a file but takes no --overwrite"
    assert sorted(writers) == ["bode", "fem2modal", "linearize", "montecarlo", "plot", "report", "run", "view"]

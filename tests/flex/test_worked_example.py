"""The worked example of issue 16: configs/fem/make_spacecraft.py's deck (bus of CQUAD4 panels, solar
array on a CBAR yoke and CBUSH hinge with an RBE2 fitting, CBAR boom with a tip CONM2, payload CONM2
on an RBE3) through fem2modal and into the scene configs/fem/spacecraft_scene.yaml."""

import importlib.util
import shutil
import warnings
from pathlib import Path

import numpy as np
from numpy.testing import assert_allclose

from dynamics.flex.pipeline import Fem2ModalOptions, fem2modal

FEM = Path(__file__).resolve().parents[2] / "configs" / "fem"


def _generator():
    spec = importlib.util.spec_from_file_location("make_spacecraft", FEM / "make_spacecraft.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def test_committed_deck_is_what_the_generator_writes():
    text, _ = _generator().spacecraft_deck()
    assert (FEM / "spacecraft.dat").read_text() == text


def test_spacecraft_deck_through_fem2modal_and_a_scene(tmp_path):
    gen = _generator()
    _, grids = gen.spacecraft_deck()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        body = fem2modal(str(FEM / "spacecraft.dat"),
                         Fem2ModalOptions(n_modes=20, modal_integrals=True, damping=0.005))
    # mass: the sum of the parts' budgets (panel areas x t x rho, beams, CONM2s), exact
    assert_allclose(body.mass, sum(gen.MASS_BUDGET.values()), rtol=1e-12)
    assert body.n_rigid_modes_removed == 6 and body.mode_set == "free-free"
    assert np.all(body.frequencies_hz > 1.0)             # no near-rigid mode kept as flexible
    assert_allclose(body.modal_mass, np.eye(20), atol=1e-10)

    from dynamics.flex.body_file import write_body_file
    write_body_file(tmp_path / "spacecraft.h5", body)
    scene = tmp_path / "spacecraft_scene.yaml"
    shutil.copy(FEM / "spacecraft_scene.yaml", scene)
    text = scene.read_text()
    for name in ("bus_top", "boom_tip", "array_tip"):
        assert f"{{name: {name}, body: spacecraft, grid: {grids[name]}}}" in text
    from shell.cli import main
    from shell.log_file import read_log
    log_path = tmp_path / "log.h5"
    assert main(["run", str(scene), "-o", str(log_path), "--t-final", "2 s", "--quiet"]) == 0
    log = read_log(log_path)
    tip = log["multibody.boom_tip.position"]
    assert np.all(np.isfinite(tip))
    # the slow tumble (1.2 deg/s) turns the boom tip, 2.6 m from the centre of mass, by ~5 cm in
    # 2 s; it must move, and stay on its rigid-body circle to within the small elastic motion
    radius = np.linalg.norm(tip - tip.mean(axis=0), axis=1)
    assert 0.01 < np.linalg.norm(tip[-1] - tip[0]) < 0.2
    assert radius.max() < 0.2

"""Examples write to a working directory, never over tracked files (issue 18: the LQR example rewrote
configs/lqr_data/gain_*.csv). The full design run is tests/linearize/test_lqr_workflow.py."""

from __future__ import annotations

import importlib.util
from pathlib import Path

import numpy as np
import pytest

ROOT = Path(__file__).resolve().parents[2]


def _design():
    spec = importlib.util.spec_from_file_location("design_lqr", ROOT / "configs/lqr_data/design_lqr.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def test_lqr_gains_go_to_the_output_directory(tmp_path):
    design = _design()
    shipped = {p.name: p.read_bytes() for p in (ROOT / "configs/lqr_data").iterdir() if p.is_file()}
    K = np.arange(14.0).reshape(1, 14) + 0.5
    design.write_gains(K, 7, tmp_path)
    np.testing.assert_array_equal(np.loadtxt(tmp_path / "gain_position.csv", delimiter=",", ndmin=2), K[:, :7])
    np.testing.assert_array_equal(np.loadtxt(tmp_path / "gain_rate.csv", delimiter=",")[2], K[0, 7:])
    assert {p.name: p.read_bytes() for p in (ROOT / "configs/lqr_data").iterdir() if p.is_file()} == shipped
    sets = design.gain_overrides(tmp_path)
    assert sets == [f"lqr_position.config.gain_file={tmp_path.resolve() / 'gain_position.csv'}",
                    f"lqr_rate.config.gain_file={tmp_path.resolve() / 'gain_rate.csv'}"]


def test_lqr_example_refuses_to_write_into_the_shipped_folder(capsys):
    with pytest.raises(SystemExit):
        _design().main(["--output-directory", str(ROOT / "configs/lqr_data")])
    assert "shipped example's folder" in capsys.readouterr().err

"""``flexshell bode`` on the user's path: a YAML scene linearized with its loop broken at a port
(``flexshell linearize``), then its Bode data and margins from the HDF5 file and the .mat export; MIMO and
sampled models from .npz files; the refusals.

References: the scene's loop is analytic (a 50 kg m^2 rigid body under torque -20 theta - 30 omega:
L = (30 s + 20) / (50 s^2), |L| = 1 at w^2 = (900 + sqrt(900^2 + 4 2500 400)) / 5000, phase margin atan(1.5 w));
python-control's frequency_response (to 1e-12) and stability_margins (to 1e-9) on the same matrices.
"""

from __future__ import annotations

import csv
import math

import control
import numpy as np
import pytest

from shell.analysis.linear_model_file import read_linear_model, to_statespace
from shell.cli import main
from tests.linearize.loops import attitude_loop

PD_LOOP = """\
name: pd_loop
multibody:
  gravity: "[0, 0, 0] m/s^2"
  bodies:
    - name: bus
      parent: world
      hinge: revolute
      axis: [0, 0, 1]
      mass: 100 kg
      com: "[0, 0, 0] m"
      inertia: "[50, 50, 50] kg*m^2"
models:
  attitude_gain:
    type: Gain
    config: {unit: "", output_unit: N*m, shape: [1]}
    parameters: {k: -20 N*m}
  rate_gain:
    type: Gain
    config: {unit: "", output_unit: N*m, shape: [1]}
    parameters: {k: -30 N*m}
  torque:
    type: Sum
    config: {count: 2, unit: N*m, shape: [1]}
connections:
  - multibody.q -> attitude_gain.u
  - multibody.u -> rate_gain.u
  - attitude_gain.y -> torque.u_1
  - rate_gain.y -> torque.u_2
  - torque.y -> multibody.bus.torque
integrator: {method: rk4, step: 0.01 s}
stop: {time: 1 s}
"""


def _cli(capsys, *argv):
    code = main([str(a) for a in argv])
    captured = capsys.readouterr()
    return code, captured.out, captured.err


def _rows(path):
    with open(path, newline="") as f:
        return list(csv.DictReader(f))


def _margins_equal_python_control(row, L, tolerance=1e-9):
    gm, pm, sm, wpc, wgc, wms = (float(v) for v in control.stability_margins(L))
    pairs = [("gain_margin", gm), ("phase_margin_deg", pm), ("stability_margin", sm),
             ("phase_crossover_hz", wpc / (2 * math.pi)), ("gain_crossover_hz", wgc / (2 * math.pi)),
             ("stability_margin_hz", wms / (2 * math.pi))]
    for key, expected in pairs:
        found = float(row[key])
        if math.isfinite(expected):
            assert abs(found - expected) <= tolerance * abs(expected), (key, found, expected)
        else:
            assert found == expected or (math.isnan(found) and math.isnan(expected)), (key, found, expected)


def _response_equals_python_control(rows, L):
    omega = np.array([float(r["frequency_rad_s"]) for r in rows])
    ours = np.array([complex(float(r["real"]), float(r["imag"])) for r in rows])
    theirs = L.frequency_response(omega)
    np.testing.assert_allclose(ours, theirs.complex.reshape(-1), rtol=1e-12)
    np.testing.assert_allclose([float(r["magnitude_db"]) for r in rows], 20 * np.log10(theirs.magnitude.reshape(-1)),
                               rtol=0, atol=1e-12 * 120)
    phase = np.radians([float(r["phase_deg"]) for r in rows])
    assert np.all(np.abs(np.angle(np.exp(1j * (phase - np.angle(theirs.complex.reshape(-1)))))) <= 1e-12)


def test_loop_broken_at_a_port_of_a_yaml_scene(tmp_path, capsys):
    scene = tmp_path / "pd_loop.yaml"
    scene.write_text(PD_LOOP)
    code, out, err = _cli(capsys, "linearize", scene, "--inputs", "multibody.bus.torque", "--outputs", "torque.y",
                          "-o", tmp_path / "loop.h5", "--mat", tmp_path / "loop.mat")
    assert code == 0, err
    code, out, err = _cli(capsys, "bode", tmp_path / "loop.h5", "--feedback", "positive")
    assert code == 0, err
    assert "L = -G (positive feedback)" in out and "phase margin 49.715" in out and "gain margin none" in out
    for suffix in ("bode", "nichols", "nyquist"):
        data = (tmp_path / f"loop_{suffix}.png").read_bytes()
        assert data.startswith(b"\x89PNG") and b"matplotlib" in data.lower()
    row, = _rows(tmp_path / "loop_margins.csv")
    wc = math.sqrt((900 + math.sqrt(900 ** 2 + 4 * 2500 * 400)) / 5000)
    pm = math.atan(1.5 * wc)
    assert (row["output"], row["input"], row["feedback"]) == ("torque.y", "multibody.bus.torque", "positive")
    assert abs(float(row["gain_crossover_hz"]) - wc / (2 * math.pi)) < 1e-9 * wc
    assert abs(math.radians(float(row["phase_margin_deg"])) - pm) < 1e-9
    assert abs(float(row["delay_margin_s"]) - pm / wc) < 1e-9
    assert row["closed_loop_stable"] == "True" and float(row["gain_margin"]) == math.inf
    L = -to_statespace(read_linear_model(tmp_path / "loop.h5"))
    _margins_equal_python_control(row, L)
    _response_equals_python_control(_rows(tmp_path / "loop_response.csv"), L)
    code, out, err = _cli(capsys, "bode", tmp_path / "loop.mat", "--feedback", "positive", "-o", tmp_path / "mat")
    assert code == 0, err
    assert _rows(tmp_path / "mat_margins.csv") == [row]
    assert _rows(tmp_path / "mat_response.csv") == _rows(tmp_path / "loop_response.csv")


def _attitude_loop_file(path, sample_time=None):
    """Two attitude axes broken at the commanded torque (tests/linearize/loops.py), names as linearize
    writes them; sampled by a zero-order hold when sample_time is given."""
    A, B, C, D = attitude_loop()
    if sample_time is not None:
        held = control.c2d(control.ss(A, B, C, D), sample_time, "zoh")
        A, B = held.A, held.B
    names = dict(input_names=np.array(["acs.torque[0]", "acs.torque[1]"]),
                 output_names=np.array(["controller.torque[0]", "controller.torque[1]"]))
    extra = {} if sample_time is None else {"sample_time": sample_time}
    np.savez(path, A=A, B=B, C=C, D=D, **names, **extra)
    return control.ss(A, B, C, D, sample_time or 0)


@pytest.mark.filterwarnings("ignore:invalid value encountered:RuntimeWarning")  # python-control at w = 0 (1/s^2)
def test_mimo_loop_at_a_time_from_an_npz_file(tmp_path, capsys):
    plant = _attitude_loop_file(tmp_path / "attitude.npz")
    code, out, err = _cli(capsys, "bode", tmp_path / "attitude.npz", "--feedback", "positive", "--others", "closed",
                          "--inputs", "acs.torque", "--outputs", "controller.torque", "--points", "300")
    assert code == 0, err
    rows = _rows(tmp_path / "attitude_margins.csv")
    assert [(r["output"], r["input"]) for r in rows] == [("controller.torque[0]", "acs.torque[0]"),
                                                          ("controller.torque[1]", "acs.torque[1]")]
    response = _rows(tmp_path / "attitude_response.csv")
    for k, row in enumerate(rows):
        K = np.zeros((2, 2))
        K[1 - k, 1 - k] = 1.0
        L = -control.feedback(plant, K, sign=1)[k, k]
        _margins_equal_python_control(row, L)
        _response_equals_python_control([r for r in response if r["input"] == row["input"]], L)
    code, out, err = _cli(capsys, "bode", tmp_path / "attitude.npz", "--feedback", "positive",
                          "--inputs", "acs.torque[1]", "--outputs", "controller.torque[1]", "-o", tmp_path / "siso")
    assert code == 0, err
    row, = _rows(tmp_path / "siso_margins.csv")
    _margins_equal_python_control(row, -plant[1, 1])


def _brute_force_margins(L, upper):
    """Gain margin and phase margin of a sampled SISO loop from sign changes on a dense grid (2e5 points), each
    refined by Brent's method on L(e^(j w T)) = C (z I - A)^-1 B + D by a dense solve: a reference independent
    of the eigenvalue search."""
    from scipy.optimize import brentq

    A, B, C, D, T = L.A, L.B, L.C, L.D, L.dt

    def value(w):
        return (C @ np.linalg.solve(np.exp(1j * w * T) * np.eye(A.shape[0]) - A, B) + D)[0, 0]

    omega = np.geomspace(1e-3, upper * (1 - 1e-9), 200_000)
    shifted = np.exp(1j * omega * T)[:, None, None] * np.eye(A.shape[0]) - A
    G = (C @ np.linalg.solve(shifted, np.broadcast_to(B, (omega.size, *B.shape))) + D)[:, 0, 0]
    phase = [brentq(lambda w: value(w).imag, omega[i], omega[i + 1], xtol=1e-15, rtol=1e-15)
             for i in np.flatnonzero(np.diff(np.sign(G.imag)))]
    gains = [1 / abs(value(w)) for w in phase if value(w).real < 0]
    crossings = [brentq(lambda w: abs(value(w)) - 1, omega[i], omega[i + 1], xtol=1e-15, rtol=1e-15)
                 for i in np.flatnonzero(np.diff(np.sign(np.abs(G) - 1)))]
    margins = [(math.degrees(np.angle(value(w))) % 360) - 180 for w in crossings]
    return min(gains, key=lambda g: abs(math.log(g))), min(margins, key=abs)


def test_sampled_model_reports_the_delay_margin_in_samples(tmp_path, capsys):
    """The zero-order-hold model of the attitude loop at 20 Hz (8 states). python-control's polynomial method
    fails on it (an 8th-order polynomial in z: it reports 26 spurious phase crossovers and a gain margin of 1.01);
    the reference is a dense grid refined by Brent's method."""
    plant = _attitude_loop_file(tmp_path / "sampled.npz", sample_time=0.05)
    code, out, err = _cli(capsys, "bode", tmp_path / "sampled.npz", "--feedback", "positive", "--inputs",
                          "acs.torque[0]", "--outputs", "controller.torque[0]")
    assert code == 0, err
    assert "sampled every 0.05 s" in out and "samples" in out
    row, = _rows(tmp_path / "sampled_margins.csv")
    assert abs(float(row["delay_margin_samples"]) - float(row["delay_margin_s"]) / 0.05) < 1e-12
    L = -plant[0, 0]
    gm, pm = _brute_force_margins(L, math.pi / 0.05)
    assert abs(float(row["gain_margin"]) - gm) <= 1e-9 * gm
    assert abs(float(row["phase_margin_deg"]) - pm) <= 1e-9 * abs(pm)
    response = _rows(tmp_path / "sampled_response.csv")
    assert max(float(r["frequency_hz"]) for r in response) <= 10.0  # the Nyquist frequency
    _response_equals_python_control(response, L)


def test_refusals_and_warnings(tmp_path, capsys):
    _attitude_loop_file(tmp_path / "attitude.npz")
    code, out, err = _cli(capsys, "bode", tmp_path / "attitude.npz", "--inputs", "acs.torqe")
    assert code == 1 and "--inputs acs.torqe: no such input; did you mean acs.torque[" in err
    bad = tmp_path / "bad.npz"
    np.savez(bad, A=np.eye(2), B=np.ones((2, 1)), C=np.ones((1, 2)), D=np.array([[np.inf]]))
    code, out, err = _cli(capsys, "bode", bad)
    assert code == 1 and f"flexshell bode: {bad}: D: entry [0, 0] is inf" in err
    wide = tmp_path / "wide.npz"
    np.savez(wide, A=-np.eye(2), B=np.ones((2, 5)), C=np.ones((4, 2)), D=np.zeros((4, 5)))
    code, out, err = _cli(capsys, "bode", wide)
    assert code == 1 and "20 channels (4 outputs x 5 inputs) make unreadable plots" in err
    notes = tmp_path / "attitude_bode.png"
    notes.write_text("my notes\n")
    code, out, err = _cli(capsys, "bode", tmp_path / "attitude.npz", "--feedback", "positive")
    assert code == 1 and "attitude_bode.png: exists and is a text file, not a PNG figure" in err
    assert notes.read_text() == "my notes\n"
    code, out, err = _cli(capsys, "bode", tmp_path / "attitude.npz", "--feedback", "positive", "--overwrite")
    assert code == 0 and notes.read_bytes().startswith(b"\x89PNG")
    unstable = tmp_path / "unstable.npz"
    np.savez(unstable, A=[[-1.0]], B=[[1.0]], C=[[-2.0]], D=[[0.0]])  # 1 + L = (s - 1)/(s + 1)
    code, out, err = _cli(capsys, "bode", unstable)
    assert code == 0 and "flexshell bode: warning:" in err and "is unstable" in err

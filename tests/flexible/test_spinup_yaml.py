"""The Kane-Ryan-Banerjee spin-up through the user's path (issue 15): a CBAR deck -> ``flexshell fem2modal
--geometric-stiffness`` -> a YAML scene whose hub acceleration comes from a ``Profile`` block (the
one-minus-cosine law ``theta_ddot = (6 / 15) (1 - cos(2 pi t / 15))`` rad/s^2 for t < 15 s, written as one
segment with ``c0`` and ``cosine``) wired to ``multibody.hub.prescribed_accel`` -> ``flexshell run``.

Compared with (1) the same engine driven through Python by the hand-written RK4 of
:mod:`tests.flexible.test_spinup_beam` (same body file, same 2 ms step): the two integrate the same equations
at the same stage times, so they agree to round-off accumulated over 5000 steps (tolerance 1e-8 of the
peak); (2) the independent finite-segment reference :func:`tests.flexible.spinup_reference.chain_reference`
(10 links): within 2 % of the peak deflection, as the Python test; and (3) with ``geometric_stiffening:
false`` in the scene the run diverges (more than 10 times the peak by 10 s).
"""

from __future__ import annotations

import numpy as np
import pytest

from dynamics.flex.body_file import read_body_file
from shell.cli import main
from shell.log_file import read_log
from tests.flexible.spinup_reference import chain_reference
from tests.flexible.test_spinup_beam import N_ELEMENTS, engine_tip_deflection, krb_deck

T_FINAL = 10.0


def scene(stiffening=True):
    return f"""name: krb_spin_up
description: Kane-Ryan-Banerjee spin-up beam, hub spun up to 6 rad/s in 15 s by a Profile block
multibody:
  bodies:
    - name: hub
      parent: world
      hinge: revolute
      axis: [0, 0, 1]
      prescribed: true
      mass: 10 kg
      inertia: "[1, 1, 1] kg*m^2"
      initial: {{angle: 0 deg, angle_rate: 0 rad/s}}
    - name: beam
      parent: hub
      hinge: locked
      body_file: krb.h5
      geometric_stiffening: {'true' if stiffening else 'false'}
  nodes:
    - {{name: tip, body: beam, grid: {N_ELEMENTS + 1}}}
models:
  spin_up:
    type: Profile
    config: {{unit: rad/s^2, shape: [1]}}
    parameters: {{times: "[0, 15] s", c0: "[[0.4]] rad/s^2", cosine: "[[-0.4]] rad/s^2"}}
connections:
  - spin_up.y -> multibody.hub.prescribed_accel
integrator:
  method: rk4
  step: 2 ms
stop:
  time: {T_FINAL} s
log:
  rate: 2 Hz
  signals:
    - multibody.q
    - multibody.tip.position
"""


@pytest.fixture(scope="module")
def body_file(tmp_path_factory):
    tmp = tmp_path_factory.mktemp("krb_yaml")
    (tmp / "krb.dat").write_text(krb_deck().replace("ENDDATA", "SPC1,1,123456,1\nENDDATA"))
    assert main(["fem2modal", str(tmp / "krb.dat"), "--modes", "6", "--modal-integrals", "--geometric-stiffness",
                 "-q", "-o", str(tmp / "krb.h5")]) == 0
    return tmp / "krb.h5"


def run_scene(body_file, stiffening):
    path = body_file.parent / f"scene_{stiffening}.yaml"
    path.write_text(scene(stiffening))
    log = body_file.parent / f"log_{stiffening}.h5"
    main(["run", str(path), "-o", str(log), "--quiet"])
    data = read_log(log)
    t = data["time"]
    theta = data["multibody.q"][:, 0]
    p = data["multibody.tip.position"]
    return t, -np.sin(theta) * p[:, 0] + np.cos(theta) * p[:, 1]


def test_spin_up_through_yaml_matches_the_python_run_and_the_reference(body_file):
    t, deflection = run_scene(body_file, True)
    np.testing.assert_allclose(t, np.linspace(0.0, T_FINAL, 21), atol=1e-9)
    python = engine_tip_deflection(read_body_file(body_file), None, t)
    ref = chain_reference(t, n_links=10)
    peak = np.abs(ref).max()
    assert np.abs(deflection - python).max() < 1e-8 * peak, np.abs(deflection - python).max()
    assert np.abs(deflection - ref).max() < 0.02 * peak, np.abs(deflection - ref).max() / peak


def test_spin_up_through_yaml_diverges_without_stiffening(body_file):
    t, deflection = run_scene(body_file, False)
    assert np.nanmax(np.abs(deflection)) > 10.0 * np.abs(chain_reference(np.linspace(0, T_FINAL, 21), n_links=10)).max()


def test_profile_block_values_and_bad_input(tmp_path):
    """The Profile kernel against the closed forms: the spin-up law, a two-segment ramp-and-hold vector with
    ``after``; descending breakpoints refused naming the model and the parameter; a jump at the end warned."""
    from shell.models.blocks import Profile, _profile
    from shell.model import ModelError

    def value(model, t):
        y = np.zeros(model.size)
        _profile(t, np.zeros(0), np.zeros(0), np.zeros(0), model.p, y)
        return y

    law = Profile("spin", unit="rad/s^2", shape=[1], times="[0, 15] s", c0="[[0.4]] rad/s^2",
                  cosine="[[-0.4]] rad/s^2")
    for t in (-1.0, 0.0, 3.0, 7.5, 14.99, 15.0, 20.0):
        expected = 0.4 * (1 - np.cos(2 * np.pi * t / 15)) if 0.0 <= t < 15.0 else 0.0
        assert value(law, t)[0] == pytest.approx(expected, abs=1e-15)
    ramp = Profile("ramp", unit="m", shape=[2], segments=2, times=[0.0, 2.0, 3.0], c1=[[1.0, 2.0], [0.0, 0.0]],
                   c0=[[0.0, 0.0], [1.0, 2.0]], after=[1.0, 2.0])
    np.testing.assert_allclose(value(ramp, 0.5), [0.25, 0.5])
    np.testing.assert_allclose(value(ramp, 2.5), [1.0, 2.0])
    np.testing.assert_allclose(value(ramp, 9.0), [1.0, 2.0])
    cubic = Profile("blend", unit="", times=[1.0, 3.0], c2=[3.0], c3=[-2.0], after=1.0)  # smoothstep 0 -> 1
    assert value(cubic, 2.0)[0] == pytest.approx(0.5) and value(cubic, 2.5)[0] == pytest.approx(0.84375)
    with pytest.raises(ModelError, match="model bad: Profile parameter times must be finite and strictly ascending"):
        Profile("bad", unit="m", times=[0.0, 0.0])
    with pytest.raises(ModelError, match="segments must be a whole number"):
        Profile("bad", unit="m", segments=0)
    with pytest.warns(UserWarning, match="jumps at its last breakpoint"):
        Profile("step", unit="m", times=[0.0, 1.0], c0=[2.0])

"""Force elements declared in a scenario (``multibody.forces:``) and run through the command line (issue 29).

The configs in configs/mechanisms/ against references of their own:
* bouncing_ball.yaml (plane_contact, restitution 0.8): the ball's flight after the bounce equals an independent DOP853
  integration of the same Hunt-Crossley law with gravity (1e-5 m), and its rebound height is e^2 times the drop
  height up to the impulse gravity gives during the contact (bounded by ``2 g T_c / v``, T_c the contact time);
* bushing_mount.yaml (bushing to the world, diagonal stiffness and damping in rotation and translation): its run
  along x is the analytic damped oscillator; ``flexshell linearize --trim`` gives six modes, ``sqrt(k / m)`` and
  ``sqrt(k / I)`` with damping ratios ``c / (2 sqrt(k m))``;
* arm_on_stop.yaml (hinge_stop): the arm falls on its stop and rests where the stop holds gravity's torque;
* braked_wheel.yaml (hinge_friction): the wheel's rate follows the regularized Coulomb law's closed-form solution and
  stops at ``I w0 / T``;
and the refusals of bad entries with file, line and key.
"""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from scipy.integrate import solve_ivp
from scipy.optimize import brentq

from dynamics.force_elements import hunt_crossley_damping
from shell.analysis.linear_model_file import read_linear_model
from shell.analysis.system_modes import state_space_modes
from shell.log_file import read_log
from shell.scenario import build_root, load_scenario
from shell.schema.document import ScenarioError

ROOT = Path(__file__).resolve().parents[2]
MECHANISMS = ROOT / "configs" / "mechanisms"


def _cli(*args):
    result = subprocess.run([sys.executable, "-m", "shell.cli", *map(str, args)], cwd=ROOT, capture_output=True,
                            text=True, timeout=900)
    assert result.returncode == 0, result.stderr + result.stdout
    return result.stdout + result.stderr


def _run(config, tmp_path):
    log = tmp_path / f"{config}.h5"
    out = _cli("run", MECHANISMS / f"{config}.yaml", "-o", log)
    return read_log(log), out


def test_a_bouncing_ball_rebounds_to_e_squared_times_its_drop(tmp_path):
    """Dropped from 1 m with e = 0.8 asked at the impact speed: after the bounce the ball flies as the independent
    integration says (apex to 1e-5 m, measured 3.1e-6 m: RK4 at 20 us through a 1.2 ms contact whose force has an
    unbounded second derivative at its onset, delta^1.5, converges there at a lower order) and rebounds to 0.64 m within the
    gravity impulse of the contact (measured 0.13 % low, bound 2 g T_c / v = 0.5 %). Its logged energy is m g (h + r)
    before the bounce (1e-9 J) and the independent exit speed's after (1e-4 J, the apex's 1e-5 m)."""
    log, out = _run("bouncing_ball", tmp_path)
    assert "force elements ground (plane_contact)" in out
    t, z, w = log["time"], log["multibody.ball.q"][:, 0], log["multibody.ball.u"][:, 0]
    g, m, r, k, h = 9.81, 1.0, 0.1, 1e8, 1.0
    v = np.sqrt(2 * g * h)
    D = hunt_crossley_damping(0.8, 4.429446918, "ball")

    def rates(_, y):  # the same law, written here: penetration r - z, never pulling
        delta = r - y[0]
        force = k * max(delta, 0.0) ** 1.5 * max(1.0 - D * y[1], 0.0) if delta > 0 else 0.0
        return [y[1], -g + force / m]

    def leaves(_, y):
        return y[0] - r if y[1] > 0 else -1.0
    leaves.terminal, leaves.direction = True, 1

    def touches(_, y):
        return y[0] - r
    touches.direction = -1
    reference = solve_ivp(rates, (0.0, 1.0), [r + h, 0.0], events=[leaves, touches], method="DOP853", rtol=1e-12,
                          atol=1e-14, max_step=1e-4)
    v_out = reference.y_events[0][0][1]
    contact_time = reference.t_events[0][0] - reference.t_events[1][0]
    flight = t > t[np.argmin(z)] + 0.05
    apex = z[flight] + w[flight] ** 2 / (2 * g)  # ballistic: every sample of the flight gives the apex
    assert np.abs(apex - (r + v_out ** 2 / (2 * g))).max() < 1e-5
    assert 0.0 < contact_time < 2e-3 and np.count_nonzero(z < r) <= 2  # the log at 1 kHz sees it once or twice
    assert abs((apex.mean() - r) / (0.8 ** 2 * h) - 1.0) < 2 * g * contact_time / v
    # the energy output: m g z + m w^2 / 2 before and after; the contact's own only while it touches; what the
    # bounce lost is what the independent integration's exit speed says
    energy = log["multibody.energy"]
    before, after = t < t[np.argmin(z)] - 0.05, flight
    assert np.abs(energy[before, 3] - m * g * (r + h)).max() < 1e-9
    assert np.abs(energy[after, 3] - m * g * (r + v_out ** 2 / (2 * g))).max() < 1e-4
    assert np.all(energy[z >= r, 2] == 0.0) and np.all(energy[z < r, 2] > 0.0)


def test_a_bushing_rings_at_its_analytic_frequencies(tmp_path):
    """The box on its bushing: along x the analytic damped oscillation (1e-8 m, RK4 1 ms; the other coordinates stay
    0); linearized about rest, six modes with ``omega = sqrt(k / m)``, ``sqrt(k / I)`` and ``zeta = c / (2 sqrt(k
    m))`` per axis to 1e-8 relative."""
    log, _ = _run("bushing_mount", tmp_path)
    t, q = log["time"], log["multibody.box.q"]
    m, k, c, x0 = 10.0, 1e4, 10.0, 0.01
    zw, wd = c / (2 * m), np.sqrt(k / m - (c / (2 * m)) ** 2)
    assert np.abs(q[:, 4] - np.exp(-zw * t) * x0 * (np.cos(wd * t) + zw / wd * np.sin(wd * t))).max() < 1e-8
    assert np.abs(q[:, [1, 2, 3, 5, 6]]).max() == 0.0
    _cli("linearize", MECHANISMS / "bushing_mount.yaml", "--trim", "--inputs", "multibody.box.torque", "--outputs",
         "multibody.box.q", "-o", tmp_path / "lin.h5")
    modes = state_space_modes(read_linear_model(tmp_path / "lin.h5").A)
    pairs = [(200.0, 0.2, 1.0), (300.0, 0.3, 2.0), (400.0, 0.4, 3.0), (1e4, 10.0, 10.0), (2e4, 20.0, 10.0),
             (3e4, 30.0, 10.0)]
    expected = sorted((np.sqrt(k / mass), c / (2 * np.sqrt(k * mass))) for k, c, mass in pairs)
    assert modes.frequencies_hz.size == 6 and modes.n_rigid == 0
    np.testing.assert_allclose(modes.frequencies_hz * 2 * np.pi, [w for w, _ in expected], rtol=1e-8)
    np.testing.assert_allclose(modes.damping_ratios, [z for _, z in expected], rtol=1e-8)


def test_a_hinge_stop_holds_an_arm(tmp_path):
    """Released 0.3 rad above its lower stop, the arm bounces, settles and rests on the stop at the penetration
    where ``k delta = m g L/2 cos(delta)`` (1e-12 rad after 5 s, at rest to 1e-12 rad/s); it never sinks more than
    the first impact's 8.4 mrad."""
    log, out = _run("arm_on_stop", tmp_path)
    assert "force elements stop (hinge_stop)" in out
    q, u = log["multibody.arm.q"][:, 0], log["multibody.arm.u"][:, 0]
    delta = brentq(lambda d: 1e4 * d - 1.0 * 9.81 * 0.5 * np.cos(d), 0.0, 1e-2)
    assert abs(q[-1] + delta) < 1e-12 and abs(u[-1]) < 1e-12
    assert -0.01 < q.min() < -delta


def test_hinge_friction_stops_a_wheel_in_the_coulomb_time(tmp_path):
    """The braked wheel: its rate follows the closed-form solution of ``I u' = -T u / sqrt(u^2 + v_s^2)``,
    ``t(u) = I/T [F(u0) - F(u)]`` with ``F(u) = sqrt(u^2 + v_s^2) - v_s ln((v_s + sqrt(u^2 + v_s^2)) / u)`` (1e-9 s
    while u > 0.1 rad/s), and it falls below the regularization speed at ``t(v_s)``, which is ``I w0 / T`` = 2.5 s
    less ``I v_s / T (sqrt(2) - ln(1 + sqrt(2)))`` = 1.3 ms (within one log interval); then it is at rest."""
    log, out = _run("braked_wheel", tmp_path)
    t, u = log["time"], log["multibody.wheel.u"][:, 0]
    inertia, level, slip, u0 = 0.5, 2.0, 0.01, 10.0

    def F(rate):
        root = np.sqrt(rate * rate + slip * slip)
        return root - slip * np.log((slip + root) / rate)
    moving = u > 0.1
    assert np.abs(inertia / level * (F(u0) - F(u[moving])) - t[moving]).max() < 1e-9
    stop = inertia / level * (F(u0) - F(slip))  # = I/T (u0 - v_s (sqrt(2) - ln(1 + sqrt(2)))) for u0 >> v_s
    assert abs(stop - inertia * u0 / level) < inertia * slip / level
    crossing = t[np.argmax(u < slip)]
    assert 0.0 <= crossing - stop <= t[1] - t[0]
    assert np.abs(u[t > 2.6]).max() < 1e-12


BALL = (MECHANISMS / "bouncing_ball.yaml").read_text()
ENTRY = ("    - {name: ground, kind: plane_contact, node: center, radius: 0.1 m, stiffness: \"1e8 N/m**1.5\",\n"
         "       restitution: 0.8, impact_speed: 4.429446918 m/s}\n")


@pytest.mark.parametrize("entry, key, message", [
    ("{name: ground, kind: plane_contact, node: centre, stiffness: 1e8}", "node", "unknown node 'centre'"),
    ("{name: ground, kind: plane_contact, node: center, stiffness: 1e8, restitution: 1.2, impact_speed: 1 m/s}",
     "restitution", "expected a value in (0, 1]"),
    ("{name: ground, kind: plane_contact, node: center, stiffness: 1e8, restitution: 0.5}", "restitution",
     "needs the impact_speed"),
    ("{name: ground, kind: plane_contact, node: center, stiffness: 1e8, normal: [0, 0, 2]}", "normal",
     "normal must be a unit 3-vector"),
    ("{name: ground, kind: plane_contact, node: center, stiffness: 1e8, lower: 0 rad}", "lower",
     "not a key of a plane_contact"),
    ("{name: ground, kind: hinge_stop, body: ball, stiffness: 1e4, lower: 1 m, upper: 0 m}", "upper",
     "must be below upper"),
    ("{name: ground, kind: hinge_stop, body: bal, stiffness: 1e4, lower: 0 m}", "body", "unknown body 'bal'"),
    ("{name: ground, kind: hinge_stop, body: ball, stiffness: 1e4 N*m/rad, lower: 0 m}", "stiffness",
     "cannot become N/m"),
    ("{name: ground, kind: hinge_friction, body: ball, level: 2 N*m}", "level", "cannot become N ["),
    ("{name: ground, kind: bushing, node_a: center, stiffness: [1, 2, 3]}", "stiffness", "expected 6 entries"),
    ("{name: ground, kind: bushing, node_a: center, stiffness: [[0, 1, 0, 0, 0, 0], [0, 0, 0, 0, 0, 0], "
     "[0, 0, 0, 0, 0, 0], [0, 0, 0, 0, 0, 0], [0, 0, 0, 0, 0, 0], [0, 0, 0, 0, 0, 0]]}", "stiffness",
     "stiffness must be"),
    ("{name: ground, kind: sphere_contact, node_a: center, node_b: center, stiffness: 1e8, radius_a: 0.1 m}",
     "node_b", "same body"),
])
def test_bad_force_elements_are_refused_with_file_line_and_key(tmp_path, entry, key, message):
    text = BALL.replace(ENTRY, f"    - {entry}\n")
    assert text != BALL
    path = tmp_path / "scene.yaml"
    path.write_text(text)
    with pytest.raises(ScenarioError) as caught:
        build_root(load_scenario(path))
    line = next(n for n, row in enumerate(text.splitlines(), 1) if entry[:30] in row)
    assert f"scene.yaml:{line}: multibody.forces[0](ground).{key}:" in str(caught.value), str(caught.value)
    assert message in str(caught.value)

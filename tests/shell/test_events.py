"""Zero crossings located before the event is handled: a bouncing ball against its analytic contacts."""

import numpy as np
import pytest
from numba import njit

from shell.assembly import Assembly
from shell.model import Model, State, ZeroCrossing
from tests.plants import BouncingBall
from shell.simulation import Simulation

H0, G, E = 10.0, 9.81, 0.8


def analytic_contact_times(n):
    """t_1 = sqrt(2 h0 / g); each later flight lasts 2 e^k v_1 / g with v_1 = sqrt(2 g h0)."""
    v1 = np.sqrt(2 * G * H0)
    times = [np.sqrt(2 * H0 / G)]
    for k in range(1, n):
        times.append(times[-1] + 2 * E**k * v1 / G)
    return np.array(times)


def ball_scene(step, stop_events=()):
    root = Assembly("root")
    ball = root.add(BouncingBall("ball", gravity=G, restitution=E))
    ball.set_initial("height", H0)
    return Simulation(root, step=step, stop_events=stop_events, event_tol=1e-12)


@pytest.mark.parametrize("step", [0.01, 0.037])
def test_contact_times_match_the_analytic_ones(step):
    sim = ball_scene(step)
    sim.run(12.0)
    times = np.array([t for t, name in sim.events])
    assert [name for _, name in sim.events] == ["ball.ground_contact"] * len(times)
    all_contacts = analytic_contact_times(40)
    assert len(times) == np.count_nonzero(all_contacts < 12.0)  # 12 contacts (they accumulate at 12.85 s)
    expected = all_contacts[:len(times)]
    # free fall is quadratic: RK4 and its cubic Hermite dense output are exact, so the error is the
    # root-finder tolerance (1e-12 s) plus round-off accumulated through 12 restarts
    np.testing.assert_allclose(times, expected, atol=1e-11)  # measured <= 1.1e-12 s
    assert sim.signal("ball.bounces") == len(times)


@pytest.mark.parametrize("method", ["heun", "rk8", "bs32", "dopri5", "dop853", "radau5"])
def test_contact_times_with_other_integrators(method):
    # free fall is a parabola: every method of order >= 2 and its dense output reproduce it, so all find
    # the 12 contacts to the root-finder tolerance (measured <= 1.6e-12 s). Adaptive methods take ~16
    # steps in all, each flight in one step: the step after an event is always searched, since the ball
    # leaves the ground and returns below it within that step without a sign change at its ends.
    root = Assembly("root")
    ball = root.add(BouncingBall("ball", gravity=G, restitution=E))
    ball.set_initial("height", H0)
    sim = Simulation(root, integrator=method, step=0.01, integrator_options={"rtol": 1e-10, "atol": 1e-12},
                     event_tol=1e-12)
    sim.run(12.0)
    times = np.array([t for t, _ in sim.events])
    all_contacts = analytic_contact_times(40)
    assert len(times) == np.count_nonzero(all_contacts < 12.0)
    np.testing.assert_allclose(times, all_contacts[:len(times)], atol=1e-11)


def test_terminal_event_stops_the_run_at_the_contact():
    sim = ball_scene(0.01, stop_events=["ball.ground_contact"])
    summary = sim.run(10.0)
    assert summary.status == "stopped"
    assert "ball.ground_contact" in summary.reason
    assert sim.t == pytest.approx(np.sqrt(2 * H0 / G), abs=1e-10)
    # the handler ran before stopping: the ball leaves the ground at e v_1
    assert sim.signal("ball.velocity") == pytest.approx(E * np.sqrt(2 * G * H0), rel=1e-10)


def test_unknown_stop_event_is_refused():
    from shell.model import ModelError

    with pytest.raises(ModelError, match=r"stop event 'ball.contact': no such zero crossing; declared: "
                                         r"\['ball.ground_contact'\]"):
        ball_scene(0.01, stop_events=["ball.contact"])


@njit(cache=True)
def _clock_rate(t, x, z, u, p, xdot):
    xdot[0] = 1.0


@njit(cache=True)
def _dip(t, x, z, u, p, g):
    g[0] = (x[0] - 0.505) ** 2 - 1e-6  # negative only on (0.504, 0.506): inside one 10 ms step


class _Dip(Model):
    continuous_states = (State("clock", "s", (), 0.0),)
    discrete_states = (State("crossings", "", (), 0.0),)
    zero_crossings = (ZeroCrossing("dip"),)
    derivatives = staticmethod(_clock_rate)
    zero_crossing_values = staticmethod(_dip)

    def on_event(self, index, t, x, z, p):
        z[0] += 1.0


@pytest.mark.parametrize("detection, expected", [("sign_change", []), ("subdivided", [0.504, 0.506]),
                                                 (None, [0.504, 0.506])])
def test_two_crossings_inside_one_step(detection, expected):
    """The default search finds both crossings of a pair inside one step."""
    root = Assembly("root")
    root.add(_Dip("probe"))
    options = {} if detection is None else {"event_detection": detection}
    sim = Simulation(root, step=0.01, event_tol=1e-13, **options)
    sim.run(1.0)
    # g is negative only between 0.504 and 0.506 s, inside the step [0.50, 0.51]: its ends have the same
    # sign, so only the subdivided search sees the pair (clock = t exactly: RK4 on x' = 1)
    np.testing.assert_allclose([t for t, _ in sim.events], expected, atol=1e-12)
    assert sim.signal("probe.crossings") == len(expected)


def test_event_options_from_yaml(scene):
    sim = scene("""
    models:
      ball: {type: BouncingBall}
    events: {detection: subdivided, tolerance: 1e-12 s}
    """)
    assert sim.event_detection == "subdivided" and sim.event_tol == 1e-12
    from shell.scenario import ScenarioError

    with pytest.raises(ScenarioError, match=r"scene.yaml:4: events.detection: expected sign_change or subdivided"):
        scene("""
        models:
          ball: {type: BouncingBall}
        events: {detection: always}
        """)

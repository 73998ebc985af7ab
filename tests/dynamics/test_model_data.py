"""The engine's immutable Model apart from its per-run Data (dynamics.model, dynamics.data, dynamics.algorithms).

References: a model compiled afresh from definitions with the changed mass properties (an independent build of the
same numbers), and each data's own serial results (two data running together must give bit for bit what each gives
alone: they share no written array, so any difference is interference, not round-off).
"""

from __future__ import annotations

import copy
import dataclasses
import pickle
import threading

import numpy as np
import pytest
from numba import njit
from numba.core.errors import TypingError

import dynamics
from dynamics import ModelDefinitionError
from dynamics import engine as E
from dynamics.system import MultibodySystem

from tests.dynamics.random_models import random_multibody
from tests.flexible.test_flexible_tree import flexible_tree, random_state


@pytest.fixture(scope="module", params=["rigid", "flexible"])
def system(request):
    if request.param == "rigid":
        return random_multibody(8, seed=5).compile()
    return flexible_tree()


def _arrays(obj):
    return {name: value for name, value in vars(obj).items() if isinstance(value, np.ndarray)}


def test_every_array_of_the_model_is_read_only_and_the_model_cannot_be_rebound(system):
    model = system.model
    arrays = _arrays(model)
    assert {"topology", "nodes", "joint_rot", "joint_vec", "params", "masses", "quaternion_q_indices"} <= set(arrays)
    for name, a in arrays.items():
        assert not a.flags.writeable, name
        with pytest.raises(ValueError, match="read-only"):
            a.reshape(-1)[:1] = 0
    assert not model.definitions[2].flags.writeable
    with pytest.raises(AttributeError, match="immutable"):
        model.params = np.zeros(3)
    with pytest.raises(AttributeError, match="immutable"):
        del model.topology
    # the system reads its model's description: the same arrays, not copies
    assert system.topology is model.topology and system.params is model.params


def test_a_pickled_or_copied_system_keeps_its_model_read_only_and_its_numbers(system):
    """numpy unpickles arrays writable: the model and data freeze theirs again (else the copy's model could be
    written, and numba would compile the kernels again for writable arrays)."""
    rng = np.random.default_rng(2)
    q, u, tau = random_state(system, rng)
    for other in (pickle.loads(pickle.dumps(system)), copy.deepcopy(system)):
        assert other.data.model is other.model
        for name, a in _arrays(other.model).items():
            assert not a.flags.writeable, name
        assert not other.data.params.flags.writeable and not other.data.masses.flags.writeable
        np.testing.assert_array_equal(other.forward_dynamics(q, u, tau), system.forward_dynamics(q, u, tau))


@njit
def _write_first(a):
    a[0] = 1.0


def test_a_kernel_writing_into_the_description_fails_to_compile(system):
    """numba types a read-only array as such and refuses a store into it: no kernel can write the model."""
    with pytest.raises(TypingError, match="readonly|read-only"):
        _write_first(system.model.params)
    _write_first(np.zeros(1))  # the same function on a writable array compiles: the refusal is the read-only flag


def test_two_data_of_one_model_give_the_same_numbers_and_do_not_interfere(system):
    model = system.model
    rng = np.random.default_rng(11)
    (qa, ua, ta), (qb, ub, tb) = random_state(system, rng), random_state(system, rng)
    d1, d2 = model.create_data(), model.create_data()
    a1 = dynamics.forward_dynamics(model, d1, qa, ua, ta)
    np.testing.assert_array_equal(dynamics.forward_dynamics(model, d2, qa, ua, ta), a1)
    np.testing.assert_array_equal(system.forward_dynamics(qa, ua, ta), a1)  # the method is the same function
    for f, args in ((dynamics.inverse_dynamics, (qa, ua, ta)), (dynamics.mass_matrix, (qa,)),
                    (dynamics.kinetic_energy, (qa, ua)), (dynamics.body_poses, (qa,))):
        r1, r2 = f(model, d1, *args), f(model, d2, *args)
        for x, y in zip(np.atleast_1d(r1) if not isinstance(r1, tuple) else r1,
                        np.atleast_1d(r2) if not isinstance(r2, tuple) else r2):
            np.testing.assert_array_equal(x, y)
    # what a data's workspace holds after a call is that data's: d2 running at another state in between leaves
    # d1's poses and velocities (which node_kinematics_after_dynamics reuses) as they were
    e1, e2 = E.engine_data(model, d1), E.engine_data(model, d2)
    n = model.nnodes

    def kinematics(d, after, q, u, udot):
        out = [np.zeros((n, 3, 3)), np.zeros((n, 3)), np.zeros((n, 6)), np.zeros((n, 6))]
        (E.node_kinematics_after_dynamics if after else E.node_kinematics)(d, q, u, udot, *out)
        return out

    udot_a, udot_b = np.zeros(model.nu), np.zeros(model.nu)
    nf, tau_out = np.zeros((n, 6)), np.zeros(model.nu)
    assert E.forward_dynamics(e1, qa, ua, ta, nf, udot_a, tau_out) == 0
    assert E.forward_dynamics(e2, qb, ub, tb, nf, udot_b, tau_out) == 0
    reused = kinematics(e1, True, qa, ua, udot_a)
    for x, y in zip(reused, kinematics(e1, False, qa, ua, udot_a)):
        np.testing.assert_allclose(x, y, rtol=0, atol=1e-12)  # reuse vs recompute: same formulas, round-off apart
    # the check can fail: one data for both states leaves state b's workspace to the reuse
    assert E.forward_dynamics(e1, qb, ub, tb, nf, udot_b, tau_out) == 0
    shared = kinematics(e1, True, qa, ua, udot_a)
    assert not np.allclose(shared[1], reused[1], rtol=0, atol=1e-6)


def test_two_threads_each_with_its_own_data_give_their_serial_results():
    system = flexible_tree()
    model = system.model
    rng = np.random.default_rng(4)
    states = [[random_state(system, rng) for _ in range(40)] for _ in range(2)]
    serial = [[dynamics.forward_dynamics(model, model.create_data(), *s) for s in run] for run in states]
    results = [None, None]

    def run(k):
        data = model.create_data()
        out = []
        for _ in range(5):
            out = [dynamics.forward_dynamics(model, data, *s) for s in states[k]]
        results[k] = out

    threads = [threading.Thread(target=run, args=(k,)) for k in range(2)]
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    for k in range(2):
        for x, y in zip(results[k], serial[k]):
            np.testing.assert_array_equal(x, y)


def test_mass_properties_change_in_one_data_only_and_equal_a_fresh_build():
    system = flexible_tree()
    model = system.model
    params_before = np.array(model.params)
    rng = np.random.default_rng(8)
    q, u, tau = random_state(system, rng)
    new = dict(mass=2.5, com=(0.1, 0.05, 0.0), inertia=np.diag([0.03, 0.04, 0.05]))
    d1, d2 = model.create_data(), model.create_data()
    e1 = E.engine_data(model, d1)  # taken before the change: a compiled caller holds these arrays for the run
    assert d1.owns_mass_properties and not d2.owns_mass_properties and d2.params is model.params
    dynamics.set_mass_properties(model, d1, "arm", **new)
    bodies, nodes, gravity = model.definitions
    i = model.body_index("arm")
    fresh = MultibodySystem.from_definitions(
        [b if k != i else dataclasses.replace(b, **new) for k, b in enumerate(bodies)], list(nodes), gravity,
        solver=model.requested_solver)
    expected = fresh.forward_dynamics(q, u, tau)
    np.testing.assert_allclose(dynamics.forward_dynamics(model, d1, q, u, tau), expected, rtol=1e-13, atol=1e-13)
    udot, tau_out = np.zeros(model.nu), np.zeros(model.nu)
    assert E.forward_dynamics(e1, q, u, tau, np.zeros((model.nnodes, 6)), udot, tau_out) == 0
    np.testing.assert_allclose(udot, expected, rtol=1e-13, atol=1e-13)  # the change reached the compiled caller
    assert d1.masses[i] == 2.5 and d1.definitions[0][i].mass == 2.5
    # the model and the other data kept theirs
    np.testing.assert_array_equal(model.params, params_before)
    assert model.masses[i] == 1.0 and model.definitions[0][i].mass == 1.0
    np.testing.assert_array_equal(dynamics.forward_dynamics(model, d2, q, u, tau), system.forward_dynamics(q, u, tau))
    assert not d1.params.flags.writeable
    # a new model with those mass properties: the same numbers, the unchanged arrays shared
    other = model.with_mass_properties({"arm": (new["mass"], new["com"], new["inertia"])})
    assert other.topology is model.topology and other.joint_rot is model.joint_rot and other.params is not model.params
    np.testing.assert_array_equal(dynamics.forward_dynamics(other, other.create_data(), q, u, tau),
                                  dynamics.forward_dynamics(model, d1, q, u, tau))
    # a copy of a data carries its mass properties, and changes in either stay in it
    d3 = d1.copy()
    np.testing.assert_array_equal(dynamics.forward_dynamics(model, d3, q, u, tau),
                                  dynamics.forward_dynamics(model, d1, q, u, tau))
    dynamics.set_mass_properties(model, d3, "arm", 1.0, (0.2, 0.0, 0.0), np.diag([0.01, 0.02, 0.025]))
    np.testing.assert_array_equal(dynamics.forward_dynamics(model, d3, q, u, tau), system.forward_dynamics(q, u, tau))
    np.testing.assert_allclose(dynamics.forward_dynamics(model, d1, q, u, tau), expected, rtol=1e-13, atol=1e-13)


def test_bad_pairs_and_bad_mass_properties_are_refused():
    system = flexible_tree()
    model, other = system.model, flexible_tree().model
    q, u, _ = random_state(system, np.random.default_rng(1))
    with pytest.raises(ValueError, match="not a data of"):
        dynamics.forward_dynamics(model, other.create_data(), q, u)
    with pytest.raises(ValueError, match="not a data of"):
        E.engine_data(model, other.create_data())
    with pytest.raises(ValueError, match="not a data of"):
        MultibodySystem(model, other.create_data())
    with pytest.raises(ModelDefinitionError, match="mass must be positive"):
        model.with_mass_properties({"arm": (0.0, (0, 0, 0), np.eye(3))})
    with pytest.raises(ModelDefinitionError, match="'bus' is flexible"):
        dynamics.set_mass_properties(model, model.create_data(), "bus", 1.0, (0, 0, 0), np.eye(3))
    with pytest.raises(KeyError, match="unknown body 'nope'"):
        model.with_mass_properties({"nope": (1.0, (0, 0, 0), np.eye(3))})

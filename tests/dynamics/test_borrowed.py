"""dynamics.engine.borrowed: the compiled loop's arrays as borrowed references (meminfo nulled).

Checked: the data and type are unchanged (reads and writes go to the owner's memory), every array of
a nested (named) tuple loses its meminfo (read through an intrinsic), other members pass through, and
the loop's results do not depend on it (the compiled == interpreted tests of tests/shell cover that).
"""

from typing import NamedTuple

import numpy as np
from numba import njit, types
from numba.core import cgutils
from numba.extending import intrinsic
from numba.np.arrayobj import make_array

from dynamics.engine import borrowed


class Inner(NamedTuple):
    a: np.ndarray
    flag: bool


class Outer(NamedTuple):
    inner: Inner
    b: np.ndarray
    n: int


@intrinsic
def _has_meminfo(typingctx, array):
    def codegen(context, builder, sig, args):
        meminfo = make_array(sig.args[0])(context, builder, args[0]).meminfo
        return builder.zext(cgutils.is_not_null(builder, meminfo), context.get_value_type(types.int64))

    return types.int64(array), codegen


@njit
def _probe(value):
    v = borrowed(value)
    v.inner.a[0] += 1.0
    v.b[1, 1] = 7.0
    return (_has_meminfo(value.inner.a), _has_meminfo(v.inner.a), _has_meminfo(v.b), v.inner.flag, v.n,
            v.inner.a.sum() + v.b.sum())


def test_borrowed_nulls_every_meminfo_and_keeps_the_data():
    a = np.arange(3.0)
    b = np.zeros((2, 2))
    owned, a_borrowed, b_borrowed, flag, n, total = _probe(Outer(Inner(a, True), b, 5))
    assert owned == 1 and a_borrowed == 0 and b_borrowed == 0
    assert flag is True and n == 5
    assert a[0] == 1.0 and b[1, 1] == 7.0          # writes reach the owner's arrays
    assert total == a.sum() + b.sum()


def test_borrowed_of_a_bare_array():
    @njit
    def f(x):
        y = borrowed(x)
        return _has_meminfo(y), y.shape[0], y[2]

    assert f(np.arange(4.0)) == (0, 4, 2.0)


def test_python_calls_borrow_the_systems_arrays():
    """MultibodySystem's algorithms from Python pass the system's arrays to the kernels as borrowed references:
    the same numbers as the kernels called on owned arrays (bit for bit) and the owner's reference counts
    unchanged over many calls. The speed gain depends on the machine (2.3x on a random tree of 100 bodies on
    2026-11-28; within 5 % on the AMD EPYC of 2026-12-07, whose atomic reference counts cost little), so it is
    measured by benchmarks/rigid_vs_pinocchio.py, not asserted here."""
    import sys
    import time

    from dynamics import kernels as K
    from tests.dynamics.random_models import random_multibody

    system = random_multibody(100, seed=3, hinges=("revolute", "prismatic", "spherical")).compile(solver="aba")
    rng = np.random.default_rng(3)
    q = system.normalize_quaternions(rng.uniform(-1, 1, system.nq))
    u, tau = rng.standard_normal(system.nu), rng.standard_normal(system.nu)
    owned = (system.topology, system.nodes, system.joint_rot, system.joint_vec, system.params)
    workspace = (system.ws_rot, system.ws_vec, system.ws_mat, system.pool)
    udot, tau_out = np.zeros(system.nu), np.empty(system.nu)

    def owned_call():
        return K.forward_dynamics(*owned, q, u, tau, system.data.zero_node_forces, system.data.zero_body_forces, udot,
                                  tau_out, *workspace)

    assert owned_call() == 0
    assert np.array_equal(system.forward_dynamics(q, u, tau), udot)
    tau_id = np.empty(system.nu)
    K.inverse_dynamics(*owned, q, u, udot, system.data.zero_node_forces, system.data.zero_body_forces, tau_id,
                       *workspace)
    assert np.array_equal(system.inverse_dynamics(q, u, udot), tau_id)
    M = np.empty((system.nu, system.nu))
    K.mass_matrix(*owned, q, system.data.zero_u, M, *workspace)
    assert np.array_equal(system.mass_matrix(q), M)

    arrays = owned + workspace
    counts = [sys.getrefcount(a) for a in arrays]
    for _ in range(50):
        system.forward_dynamics(q, u, tau)
    assert [sys.getrefcount(a) for a in arrays] == counts


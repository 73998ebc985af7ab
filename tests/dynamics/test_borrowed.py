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

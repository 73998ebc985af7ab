"""The per-run count of kernels compiled in a worker (RunRecord.compiled_kernels) counts real compilations of
flexshell's kernels and nothing else: a kernel compiled in this process raises it by one, a kernel of another
package does not, a second call (already compiled) does not."""

import numba

from shell.montecarlo.campaign import _numba_compilations


def _kernel(module: str):
    namespace = {"__name__": module}
    exec("def probe(x):\n    return x + 1.0\n", namespace)
    return numba.njit(cache=False)(namespace["probe"])


def test_counts_compilations_of_flexshell_kernels_only():
    before = _numba_compilations()
    ours, theirs = _kernel("shell._compile_counter_probe"), _kernel("elsewhere._probe")
    assert ours(1.0) == 2.0
    assert _numba_compilations() == before + 1
    assert ours(2.0) == 3.0                      # already compiled: no new compilation
    assert theirs(1.0) == 2.0                    # another package's kernel: not ours
    assert _numba_compilations() == before + 1
    assert ours(1) == 2.0                        # a new signature is a new compilation
    assert _numba_compilations() == before + 2

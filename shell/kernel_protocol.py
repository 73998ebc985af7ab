"""How a model's kernels are called in the compiled loop: their signatures, and the op-kernel protocol of models
that keep typed per-run data (the multibody engine).

Most kernels have the uniform signature of :mod:`shell.model` and are called through function pointers
(:mod:`shell.compiled_loop`): ``kernel(t, x, z, u, p, out)``, ``update(t, x, z, u, p)``. A model whose per-run data
(``Model.create_data``) is one float64 array (tables, scratch: its *data slot*) receives a view of it after ``p``:
``kernel(t, x, z, u, p, d, out)``, ``update(t, x, z, u, p, d)``; with ``noise_size``, the noise after that.

A model whose per-run data is a typed tuple (the engine's arrays and workspace) implements the *op-kernel protocol*
instead: one numba function ``compiled_kernel(op, t, x, z, u, p, d, out)`` (an attribute of the model; the engine's
depends on its system's solver path) serving every kernel of the model, ``op`` one of the codes below. The compiled
plan recognizes such a model by that attribute; any number of them may share a scene when their data have the same
numba type (the loop is compiled once per such type, not per scene). Having every kernel in one function compiles the
model's code once.
"""

from numba import types

_ARRAY = types.float64[::1]
#: output, derivative and zero-crossing kernels, updates with noise, updates of a model with a data slot:
#: kernel(t, x, z, u, p, out)
KERNEL_SIGNATURE = types.void(types.float64, _ARRAY, _ARRAY, _ARRAY, _ARRAY, _ARRAY)
#: updates without noise: update(t, x, z, u, p)
UPDATE_SIGNATURE = types.void(types.float64, _ARRAY, _ARRAY, _ARRAY, _ARRAY)
#: kernels of a model with a data slot, and its updates with noise: kernel(t, x, z, u, p, d, out)
DATA_KERNEL_SIGNATURE = types.void(types.float64, _ARRAY, _ARRAY, _ARRAY, _ARRAY, _ARRAY, _ARRAY)


def op_kernel_signature(data_type):
    """The signature of an op kernel whose data has numba type ``data_type``: kernel(op, t, x, z, u, p, d, out)."""
    return types.void(types.int64, types.float64, _ARRAY, _ARRAY, _ARRAY, _ARRAY, data_type, _ARRAY)


# op codes of the op-kernel protocol
STATE_OUTPUTS = 0                  # out: the model's output block (outputs not marked feedthrough)
FEEDTHROUGH_OUTPUTS = 1            # out: the output block (feedthrough outputs)
DERIVATIVES = 2                    # out: xdot
DERIVATIVES_AFTER_FEEDTHROUGH = 3  # out: xdot, reusing what FEEDTHROUGH_OUTPUTS computed at the same state and inputs
NORMALIZE = 4                      # x (passed in every array argument): renormalize its quaternions in place

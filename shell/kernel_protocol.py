"""How a model's kernels are called in the compiled loop: their signatures, and the op-kernel protocol of models
that keep typed per-run data (the multibody engine).

Most kernels have the uniform signature of :mod:`shell.model` and are called through function pointers
(:mod:`shell.compiled_loop`): ``kernel(t, x, z, u, p, out)``, ``update(t, x, z, u, p)``. A model whose per-run data
(``Model.create_data``) is one float64 array (tables, scratch: its *data slot*) receives a view of it after ``p``:
``kernel(t, x, z, u, p, d, out)``, ``update(t, x, z, u, p, d)``; with ``noise_size``, the noise after that.

A model whose per-run data is a typed tuple (the engine's arrays and workspace) implements the *op-kernel protocol*
instead: one numba function ``compiled_kernel(op, t, x, z, u, p, d, out)`` (an attribute of the model; the engine's
depends on its system's solver path) serving every kernel of the model, ``op`` one of the codes below. Having every
kernel in one function compiles the model's code once. The compiled loop does not see the tuple's type: it passes
the data *by reference* (:func:`reference`: the tuple's numba representation written once into an int64 array,
its arrays as borrowed pointers) to the op kernel's :func:`by_reference` form, which reads the tuple back and calls
the op kernel with it. So the loop is compiled once per stepper whatever the scene: any number of op-kernel models,
with data of any types, share it (each type compiles only its small by-reference form), and a call passes one array
instead of the tuple's few hundred words.
"""

import hashlib

import numpy as np
from numba import njit, typeof, types
from numba.core import cgutils
from numba.core.registry import cpu_target
from numba.extending import intrinsic

from dynamics.engine import strip_references

_ARRAY = types.float64[::1]
_REFERENCE = types.int64[::1]
#: output, derivative and zero-crossing kernels, updates with noise, updates of a model with a data slot:
#: kernel(t, x, z, u, p, out)
KERNEL_SIGNATURE = types.void(types.float64, _ARRAY, _ARRAY, _ARRAY, _ARRAY, _ARRAY)
#: updates without noise: update(t, x, z, u, p)
UPDATE_SIGNATURE = types.void(types.float64, _ARRAY, _ARRAY, _ARRAY, _ARRAY)
#: kernels of a model with a data slot, and its updates with noise: kernel(t, x, z, u, p, d, out)
DATA_KERNEL_SIGNATURE = types.void(types.float64, _ARRAY, _ARRAY, _ARRAY, _ARRAY, _ARRAY, _ARRAY)
#: an op kernel's by-reference form, as the compiled loop calls it: kernel(op, t, x, z, u, p, reference, out)
REFERENCE_KERNEL_SIGNATURE = types.void(types.int64, types.float64, _ARRAY, _ARRAY, _ARRAY, _ARRAY, _REFERENCE,
                                        _ARRAY)


def op_kernel_signature(data_type):
    """The signature of an op kernel whose data has numba type ``data_type``: kernel(op, t, x, z, u, p, d, out)."""
    return types.void(types.int64, types.float64, _ARRAY, _ARRAY, _ARRAY, _ARRAY, data_type, _ARRAY)


# op codes of the op-kernel protocol
STATE_OUTPUTS = 0                  # out: the model's output block (outputs not marked feedthrough)
FEEDTHROUGH_OUTPUTS = 1            # out: the output block (feedthrough outputs)
DERIVATIVES = 2                    # out: xdot
DERIVATIVES_AFTER_FEEDTHROUGH = 3  # out: xdot, reusing what FEEDTHROUGH_OUTPUTS computed at the same state and inputs
NORMALIZE = 4                      # x (passed in every array argument): renormalize its quaternions in place
#: the output stages within a derivative evaluation (the integrator's right-hand side, where only the derivatives
#: are read): as STATE_OUTPUTS and FEEDTHROUGH_OUTPUTS, but outputs that only sampled updates, logs and names read
#: may be left out (NaN: never a stale value); used for a model that declares ``state_outputs_for_derivatives``
STATE_OUTPUTS_FOR_DERIVATIVES = 5
FEEDTHROUGH_OUTPUTS_FOR_DERIVATIVES = 6


# -- typed data by reference ---------------------------------------------------------------------------------------
def reference_words(data_type) -> int:
    """int64 words holding a value of numba type ``data_type`` (its in-memory representation)."""
    context = cpu_target.target_context
    return -(-context.get_abi_sizeof(context.get_value_type(data_type)) // 8)


def _address(builder, context, reference_type, reference, value_type):
    array = cgutils.create_struct_proxy(reference_type)(context, builder, value=reference)
    return builder.bitcast(array.data, context.get_value_type(value_type).as_pointer())


@intrinsic
def _write(typingctx, reference, value):
    """Store ``value`` with its arrays borrowed (no reference counts: :func:`dynamics.engine.borrowed`) into the int64
    array ``reference``, which holds :func:`reference_words` of its type."""
    def codegen(context, builder, sig, args):
        stripped = strip_references(context, builder, sig.args[1], args[1])
        builder.store(stripped, _address(builder, context, sig.args[0], args[0], sig.args[1]))
        return context.get_dummy_value()

    return types.none(reference, value), codegen


@njit(cache=True)
def _store(reference, value):
    _write(reference, value)


def reference(data) -> np.ndarray:
    """``data`` (a tuple of arrays, nested) by reference: an int64 array holding its numba representation, its arrays
    as borrowed pointers. Valid while ``data``'s arrays live: the caller keeps ``data`` beside it."""
    words = np.zeros(reference_words(typeof(data)), dtype=np.int64)
    _store(words, data)
    return words


def reader(data_type):
    @intrinsic
    def read(typingctx, reference):
        """The value of type ``data_type`` that :func:`reference` wrote into ``reference``."""
        def codegen(context, builder, sig, args):
            return builder.load(_address(builder, context, sig.args[0], args[0], data_type))

        return data_type(reference), codegen

    return read


_BY_REFERENCE: dict = {}


def by_reference(kernel, data_type):
    """The op kernel ``kernel`` for data of numba type ``data_type`` in the loop's form: ``f(op, t, x, z, u, p,
    reference, out)`` (:data:`REFERENCE_KERNEL_SIGNATURE`, ``reference`` made by :func:`reference`) reads the data
    back and calls ``kernel`` with them (one call, as the loop's call with the tuple was: the kernel's code is
    compiled once, shared with Python callers of the typed kernel)."""
    key = (kernel, data_type)
    if key not in _BY_REFERENCE:
        read = reader(data_type)

        def op_kernel(op, t, x, z, u, p, reference, out):
            kernel(op, t, x, z, u, p, read(reference), out)

        # a name of its own (compiled code is named after the function, and these share one code object)
        digest = hashlib.sha256(str(data_type).encode()).hexdigest()[:12]
        op_kernel.__name__ = op_kernel.__qualname__ = f"{kernel.py_func.__name__}_by_reference_{digest}"
        _BY_REFERENCE[key] = njit(cache=True)(op_kernel)
    return _BY_REFERENCE[key]


def forms(kernel) -> list:
    """The by-reference forms of ``kernel`` made in this process (a compiled run loads the kernel's code with its
    form's: the kernel's own dispatcher then has no overload)."""
    return [form for (typed, _), form in _BY_REFERENCE.items() if typed is kernel]

"""One compiled derivative for a whole scene: code generation over the Simulation's evaluation plan.

The interpreted derivative (:meth:`shell.simulation.Simulation.derivative`) walks the output plan and
the derivative plan in Python, one numba dispatch per kernel and per input gather (~0.7 us each). When
every kernel on those plans is a numba dispatcher, the same sequence can be written out as the source
of a single function, with every buffer slice and gather range as a literal constant, and compiled
with ``numba.njit``: the kernels are inlined or called directly by LLVM, and a derivative costs one
dispatch. Parameters of all models are packed into one float64 vector at fusion time.

Limitations (refused with the model names): models whose kernels are Python methods (the multibody
engine model today, which calls the engine's Python API) cannot be fused; the engine's low-level
kernels in ``dynamics.kernels`` would have to be wrapped into a shell kernel of the uniform signature
first. The generated function is compiled per scene (no on-disk cache: its source is not a file).
"""

from __future__ import annotations

import numpy as np
from numba import njit
from numba.core.registry import CPUDispatcher

from shell.model import ModelError


def _range(s: slice) -> str:
    return f"{s.start}:{s.stop}"


def fuse_derivative(simulation):
    """A compiled ``fun(t, y) -> xdot`` equivalent to ``simulation.derivative`` (bit-identical results).

    Raises :class:`ModelError` naming the models whose kernels are not numba-compiled.
    """
    sim = simulation
    python_kernels = sorted({entry[0].path for entry in sim._output_plan + sim._derivative_plan
                             if not isinstance(entry[1], CPUDispatcher)})
    if python_kernels:
        raise ModelError(f"cannot fuse the derivative: models {python_kernels} have kernels that are not "
                         "numba-compiled functions")
    offsets, parameters, start = {}, [], 0
    for m in sim.models:
        offsets[m.path] = slice(start, start + m.p.size)
        parameters.append(m.p)
        start += m.p.size
    packed = np.concatenate(parameters) if parameters else np.zeros(0)
    namespace: dict = {}
    lines = ["def fused(t, y, x, z, s, P, src, dst, fac, xdot):", "    x[:] = y"]
    for n, (m, fn, *_rest, k0, k1) in enumerate(sim._output_plan):
        i = sim.model_index[m.path]
        namespace[f"output_{n}"] = fn
        if k1 > k0:
            lines += [f"    for k in range({k0}, {k1}):", "        s[dst[k]] = fac[k] * s[src[k]]"]
        lines.append(f"    output_{n}(t, x[{_range(sim._x_block[i])}], z[{_range(sim._z_block[i])}], "
                     f"s[{_range(sim._u_block[i])}], P[{_range(offsets[m.path])}], s[{_range(sim._y_block[i])}])")
    if sim._n_gather:
        lines += [f"    for k in range({sim._n_gather}):", "        s[dst[k]] = fac[k] * s[src[k]]"]
    for n, (m, fn, *_rest) in enumerate(sim._derivative_plan):
        i = sim.model_index[m.path]
        namespace[f"derivative_{n}"] = fn
        lines.append(f"    derivative_{n}(t, x[{_range(sim._x_block[i])}], z[{_range(sim._z_block[i])}], "
                     f"s[{_range(sim._u_block[i])}], P[{_range(offsets[m.path])}], "
                     f"xdot[{_range(sim._x_block[i])}])")
    lines.append("    return xdot.copy()")
    source = "\n".join(lines)
    exec(compile(source, f"<fused derivative of {len(sim.models)} models>", "exec"), namespace)  # noqa: S102
    compiled = njit(namespace["fused"])
    x, z, signals, xdot = sim.x, sim.z, sim.signals, sim.xdot
    src, dst, fac = sim._src, sim._dst, sim._factor

    def derivative(t, y):
        return compiled(t, y, x, z, signals, packed, src, dst, fac, xdot)

    derivative.source = source
    return derivative

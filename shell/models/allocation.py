"""Actuator allocation and load summation for clusters of wheels and thrusters.

``NonnegativeAllocator`` (thrusters push only), sampled at the thruster cycle: the minimum-fuel
solution ``min sum c  s.t.  A c = d, c >= 0`` (a linear program, scipy HiGHS, solved in Python at the
thruster rate: the classical jet-selection LP, Wie sec. 7.7), scaled down along the demand when one
command exceeds ``max_command``. At build it checks that A has a strictly positive null vector, the
condition for every demand to be producible by push-only jets.

``PseudoInverseAllocator``: commands ``c = A^+ d`` for a demanded vector d (torque, or [torque; force])
and an actuator effectiveness matrix A (columns: what one unit command of each actuator produces),
the minimum-norm solution of ``A c = d`` (Moore-Penrose, e.g. Wie sec. 7.5 for wheel clusters); the
pseudo-inverse is formed once at build time. Saturation-aware: with ``max_command`` > 0, a solution
whose largest command exceeds it is scaled as a whole by ``max_command / max |c_k|``, so the actuators
produce ``s d`` (0 < s <= 1): the demand's direction is kept and no actuator is asked beyond its limit
(clipping each command instead would turn the produced torque away from the demand). ``NodeLoadSum`` adds the torques and forces of several
actuators acting at one node, so a cluster attaches to a node with one torque and one force.

Array layouts depend on the numbers of actuators n and demands m (configuration): ``effectiveness``
(m x n, row-major) starts the parameters, ``pseudo_inverse`` (n x m) follows it at ``m n`` and
``max_command`` at ``2 m n``; the
commands are one scalar output (and held state) per actuator in actuator order, ``command_k`` at
``k - 1``; NodeLoadSum's inputs repeat the block ``LOAD_INPUTS`` (torque, force) once per load, load k
at ``k * LOAD_SIZE``. Each model sets the named offsets of its instance from these rules, and its
kernels derive the same from array sizes.
"""

from __future__ import annotations

from collections import namedtuple
from dataclasses import replace

import numpy as np
from numba import njit


from shell.model import (Declarations, InputPort, Layout, Model, ModelError, OutputPort, Parameter, State, count_option,
                         named_offsets)
from shell.ports import node_load_inputs, node_load_outputs
from shell.registry import register_model


#: demand and actuator counts and units are configurations: the shapes and units below are set per instance,
#: the outputs are command_1 .. command_n (:func:`_command_offsets`)
PSEUDO_INVERSE = Declarations(
    parameters=(Parameter("effectiveness", "", None, (1, 1), None,
                          "A: column k is the demand produced by a unit command of actuator k"),
                Parameter("pseudo_inverse", "", 0.0, (1, 1), None, "computed from A at build time (do not give)"),
                Parameter("max_command", "", 0.0, (), (0.0, None),
                          "largest single command; a larger solution is scaled down as a whole, keeping the "
                          "direction of the produced vector (0: no limit)")),
    inputs=(InputPort("demand", "", (1,), "demanded vector d", feedthrough=True),),
    sized=("effectiveness", "pseudo_inverse", "demand"),
)
NONNEGATIVE = Declarations(
    parameters=(PSEUDO_INVERSE.parameters[0],
                Parameter("max_command", "", 0.0, (), (0.0, None),
                          "largest single command; a solution above it is scaled down along the demand (0: no limit)")),
    inputs=(InputPort("demand", "", (1,), "demanded vector d"),),
    discrete=(State("command", "", (1,), None, "held commands"),),
    sized=("effectiveness", "demand", "command"),
)
P_PINV, U_PINV = PSEUDO_INVERSE.P, PSEUDO_INVERSE.U
P_NONNEGATIVE, Z_NONNEGATIVE = NONNEGATIVE.P, NONNEGATIVE.Z


def _command_offsets(n: int):
    """Named offsets of the n scalar outputs command_1..command_n (actuator order)."""
    return namedtuple("CommandOutputs", [f"command_{k + 1}" for k in range(n)])(*range(n))


def _commands(n: int, unit: str, feedthrough: bool):
    """The n scalar outputs command_1..command_n."""
    return tuple(OutputPort(f"command_{k + 1}", unit, (), f"command of actuator {k + 1}", feedthrough=feedthrough)
                 for k in range(n))


@njit(cache=True)
def _allocate(t, x, z, u, p, y):
    # y[k] is command_{k+1}; m demands, n actuators from the array sizes
    n = y.shape[0]
    m = u.shape[0]
    start = P_PINV.effectiveness + m * n  # pseudo_inverse follows the m x n effectiveness
    largest = 0.0
    for i in range(n):
        acc = 0.0
        for j in range(m):
            acc += p[start + i * m + j] * u[U_PINV.demand + j]
        y[i] = acc
        largest = max(largest, abs(acc))
    limit = p[start + n * m]  # max_command follows the n x m pseudo-inverse
    if limit > 0.0 and largest > limit:
        scale = limit / largest  # the whole command scaled: the produced vector keeps the demand's direction
        for i in range(n):
            y[i] *= scale


@register_model
class PseudoInverseAllocator(Model):
    """c = pinv(A) d, outputs command_1..command_n; config: demand (size of d), actuators, units."""

    summary = "minimum-norm allocation c = pinv(A) d (config: demand, actuators, demand_unit, command_unit)"
    declarations = PSEUDO_INVERSE
    feedthrough_outputs = staticmethod(_allocate)

    def __init__(self, name: str, *, demand: int = 3, actuators: int = 4, demand_unit: str = "N*m",
                 command_unit: str = "N*m", **kwargs):
        if "pseudo_inverse" in kwargs:
            raise ModelError(f"model {name}: pseudo_inverse is computed from effectiveness; do not give it")
        self.n_demand = count_option(name, "demand", demand, "demanded components")
        self.n_actuators = count_option(name, "actuators", actuators, "actuators")
        self.demand_unit, self.command_unit = demand_unit, command_unit
        super().__init__(name, **kwargs)

    def declare(self):
        m, n = self.n_demand, self.n_actuators
        self.use_declarations(PSEUDO_INVERSE.replace(
            effectiveness={"unit": f"({self.demand_unit})/({self.command_unit})", "shape": (m, n)},
            pseudo_inverse={"unit": f"({self.command_unit})/({self.demand_unit})", "default": np.zeros((n, m)),
                            "shape": (n, m)},
            max_command={"unit": self.command_unit}, demand={"unit": self.demand_unit, "shape": (m,)}))
        self.outputs = _commands(n, self.command_unit, feedthrough=True)
        self.offsets = {**PSEUDO_INVERSE.offsets, "y": _command_offsets(n)}

    def configure(self):
        a = self.parameter("effectiveness")
        if np.linalg.matrix_rank(a) < self.n_demand:
            raise ModelError(f"model {self.path}: parameter effectiveness: rank {np.linalg.matrix_rank(a)} < "
                             f"{self.n_demand}; the actuators cannot produce every demand direction")
        self.parameter("pseudo_inverse")[...] = np.linalg.pinv(a)


#: the inputs of one load; NodeLoadSum declares them once per load (torque_k, force_k)
LOAD_INPUTS = node_load_inputs("torque", "force", torque="torque (zero if unconnected)",
                               force="force (zero if unconnected)")
LOAD, LOAD_SIZE = named_offsets(LOAD_INPUTS), Layout.of(LOAD_INPUTS).size
#: the inputs torque_k, force_k are declared per instance (config: count), their offsets k LOAD_SIZE + LOAD
LOAD_SUM = Declarations(outputs=node_load_outputs("torque", "force", torque="total torque", force="total force"))
Y_LOAD_SUM = LOAD_SUM.Y


@njit(cache=True)
def _sum_loads(t, x, z, u, p, y):
    for i in range(3):
        y[Y_LOAD_SUM.torque + i] = 0.0
        y[Y_LOAD_SUM.force + i] = 0.0
    for k in range(u.shape[0] // LOAD_SIZE):
        block = k * LOAD_SIZE
        for i in range(3):
            y[Y_LOAD_SUM.torque + i] += u[block + LOAD.torque + i]
            y[Y_LOAD_SUM.force + i] += u[block + LOAD.force + i]


@register_model
class NodeLoadSum(Model):
    """torque = sum of torque_k, force = sum of force_k (config: count)."""

    summary = "sum of several torques and forces acting at one node (config: count)"
    declarations = LOAD_SUM
    feedthrough_outputs = staticmethod(_sum_loads)

    def __init__(self, name: str, *, count: int = 2, **kwargs):
        self.count = count_option(name, "count", count, "loads")
        super().__init__(name, **kwargs)

    def declare(self):
        self.inputs = tuple(replace(d, name=f"{d.name}_{k}", description=f"{d.name} {k} (zero if unconnected)")
                            for k in range(self.count) for d in LOAD_INPUTS)
        names = [f"{name}_{k}" for k in range(self.count) for name in LOAD._fields]
        offsets = [k * LOAD_SIZE + offset for k in range(self.count) for offset in LOAD]
        self.offsets = {"u": namedtuple("LoadSumInputs", names)(*offsets), "y": Y_LOAD_SUM}


@njit(cache=True)
def _held_commands(t, x, z, u, p, y):
    for k in range(y.shape[0]):
        y[k] = z[Z_NONNEGATIVE.command + k]  # y[k] is command_{k+1}


@register_model
class NonnegativeAllocator(PseudoInverseAllocator):
    """Sampled push-only minimum-fuel allocation c >= 0, A c = d (thrusters); config as
    PseudoInverseAllocator, plus its period (the thruster cycle)."""

    summary = "sampled push-only minimum-fuel allocation for thrusters (linear program; config: demand, actuators)"
    #: the minimum-fuel linear program is scipy's HiGHS (linprog), called from Python at each sample
    python_update = True
    declarations = NONNEGATIVE
    feedthrough_outputs = None
    state_outputs = staticmethod(_held_commands)
    default_period = "0.1 s"

    def declare(self):
        m, n = self.n_demand, self.n_actuators
        self.use_declarations(NONNEGATIVE.replace(
            effectiveness={"unit": f"({self.demand_unit})/({self.command_unit})", "shape": (m, n)},
            max_command={"unit": self.command_unit}, demand={"unit": self.demand_unit, "shape": (m,)},
            command={"unit": self.command_unit, "shape": (n,)}))
        self.outputs = _commands(n, self.command_unit, feedthrough=False)
        self.offsets = {**NONNEGATIVE.offsets, "y": _command_offsets(n)}

    def configure(self):
        a = self.parameter("effectiveness")
        n, m = a.shape[1], a.shape[0]
        # every demand is producible by push-only actuators iff a strictly positive null vector exists
        from scipy.optimize import linprog  # imported here: ~0.5 s at start-up for scenes without it

        result = linprog(np.r_[np.zeros(n), -1.0], A_ub=np.c_[-np.eye(n), np.ones(n)], b_ub=np.zeros(n),
                         A_eq=np.c_[a, np.zeros(m)], b_eq=np.zeros(m), bounds=[(0.0, 1.0)] * (n + 1), method="highs")
        if np.linalg.matrix_rank(a) < m or result.status != 0 or result.x[-1] <= 1e-9:
            raise ModelError(f"model {self.path}: parameter effectiveness: no strictly positive combination of "
                             "the actuators cancels out, so push-only actuators cannot produce every demand "
                             "direction (add or reorient thrusters)")
        self._cost = np.ones(n)
        self._bounds = [(0.0, None)] * n
        #: (effectiveness and demand bytes, solution) of the last program: a held demand (a constant unloading
        #: torque) asks the same program at every sample, ~4 ms of HiGHS each
        self._solved = None

    def update(self, t, x, z, u, p):
        """Python (``python_update``): the linear program is scipy's HiGHS (``linprog``)."""
        a = self.parameter("effectiveness")
        held = slice(Z_NONNEGATIVE.command, Z_NONNEGATIVE.command + self.n_actuators)
        demand = u[U_PINV.demand:U_PINV.demand + self.n_demand]
        if not np.any(demand):
            z[held] = 0.0
            return
        key = (a.tobytes(), demand.tobytes())
        if self._solved is not None and self._solved[0] == key:
            c = self._solved[1].copy()  # the same program as last time: HiGHS is deterministic, same answer
        else:
            from scipy.optimize import linprog

            result = linprog(self._cost, A_eq=a, b_eq=demand, bounds=self._bounds, method="highs")
            if result.status != 0:
                raise ModelError(f"model {self.path}: allocation failed at t = {t:.12g} s for demand {demand}: "
                                 f"{result.message}")
            c = np.maximum(result.x, 0.0)
            self._solved = (key, c.copy())
        limit = float(self.parameter("max_command"))
        if limit > 0.0 and c.max() > limit:
            c *= limit / c.max()
        z[held] = c

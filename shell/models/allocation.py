"""Actuator allocation and load summation for clusters of wheels and thrusters.

``NonnegativeAllocator`` (thrusters push only): ``c = A^+ d + s n`` with n > 0 a strictly positive
null vector of A (A n = 0, found once by linear programming) and s the smallest shift that makes every
command nonnegative, so ``A c = d`` still holds exactly (the null-motion method for redundant jet
sets, Wie sec. 7.7; the demand must be producible, which the existence of n guarantees).

``PseudoInverseAllocator``: commands ``c = A^+ d`` for a demanded vector d (torque, or [torque; force])
and an actuator effectiveness matrix A (columns: what one unit command of each actuator produces),
the minimum-norm solution of ``A c = d`` (Moore-Penrose, e.g. Wie sec. 7.5 for wheel clusters); the
pseudo-inverse is formed once at build time. ``NodeLoadSum`` adds the torques and forces of several
actuators acting at one node, so a cluster attaches to a node with one torque and one force.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from scipy.optimize import linprog

from shell.model import InputPort, Model, ModelError, OutputPort, Parameter
from shell.registry import register_model


@njit(cache=True)
def _allocate(t, x, z, u, p, y):
    # p = [A (m x n), A^+ (n x m)] flattened; u demand (m); y the n scalar commands in order
    n = y.shape[0]
    m = u.shape[0]
    start = m * n
    for i in range(n):
        acc = 0.0
        for j in range(m):
            acc += p[start + i * m + j] * u[j]
        y[i] = acc


@register_model
class PseudoInverseAllocator(Model):
    """c = pinv(A) d, outputs command_1..command_n; config: demand (size of d), actuators, units."""

    summary = "minimum-norm allocation c = pinv(A) d (config: demand, actuators, demand_unit, command_unit)"
    feedthrough_outputs = staticmethod(_allocate)

    def __init__(self, name: str, *, demand: int = 3, actuators: int = 4, demand_unit: str = "N*m",
                 command_unit: str = "N*m", **kwargs):
        if "pseudo_inverse" in kwargs:
            raise ModelError(f"model {name}: pseudo_inverse is computed from effectiveness; do not give it")
        self.n_demand, self.n_actuators = int(demand), int(actuators)
        self.demand_unit, self.command_unit = demand_unit, command_unit
        super().__init__(name, **kwargs)

    def declare(self):
        m, n = self.n_demand, self.n_actuators
        self.parameters = (
            Parameter("effectiveness", f"({self.demand_unit})/({self.command_unit})", None, (m, n), None,
                      "A: column k is the demand produced by a unit command of actuator k"),
            Parameter("pseudo_inverse", f"({self.command_unit})/({self.demand_unit})", np.zeros((n, m)), (n, m),
                      None, "computed from A at build time (do not give)"),
        )
        self.inputs = (InputPort("demand", self.demand_unit, (m,), "demanded vector d", feedthrough=True),)
        self.outputs = tuple(OutputPort(f"command_{k + 1}", self.command_unit, (), f"command of actuator {k + 1}",
                                        feedthrough=True) for k in range(n))

    def configure(self):
        a = self.parameter("effectiveness")
        if np.linalg.matrix_rank(a) < self.n_demand:
            raise ModelError(f"model {self.path}: parameter effectiveness: rank {np.linalg.matrix_rank(a)} < "
                             f"{self.n_demand}; the actuators cannot produce every demand direction")
        self.parameter("pseudo_inverse")[...] = np.linalg.pinv(a)


@njit(cache=True)
def _sum_loads(t, x, z, u, p, y):
    y[:] = 0.0
    for k in range(u.shape[0] // 6):
        for i in range(6):
            y[i] += u[6 * k + i]


@register_model
class NodeLoadSum(Model):
    """torque = sum of torque_k, force = sum of force_k (config: count)."""

    summary = "sum of several torques and forces acting at one node (config: count)"
    feedthrough_outputs = staticmethod(_sum_loads)

    def __init__(self, name: str, *, count: int = 2, **kwargs):
        self.count = int(count)
        super().__init__(name, **kwargs)

    def declare(self):
        inputs = []
        for k in range(self.count):
            inputs.append(InputPort(f"torque_{k}", "N*m", (3,), f"torque {k} (zero if unconnected)", feedthrough=True,
                                    required=False))
            inputs.append(InputPort(f"force_{k}", "N", (3,), f"force {k} (zero if unconnected)", feedthrough=True,
                                    required=False))
        self.inputs = tuple(inputs)
        self.outputs = (OutputPort("torque", "N*m", (3,), "total torque", feedthrough=True),
                        OutputPort("force", "N", (3,), "total force", feedthrough=True))


@njit(cache=True)
def _allocate_nonnegative(t, x, z, u, p, y):
    # p = [A (m x n), A^+ (n x m), null vector (n)]
    n = y.shape[0]
    m = u.shape[0]
    start = m * n
    null = start + n * m
    shift = 0.0
    for i in range(n):
        acc = 0.0
        for j in range(m):
            acc += p[start + i * m + j] * u[j]
        y[i] = acc
        shift = max(shift, -acc / p[null + i])
    for i in range(n):
        y[i] = max(y[i] + shift * p[null + i], 0.0)  # >= 0 up to round-off


@register_model
class NonnegativeAllocator(PseudoInverseAllocator):
    """c = pinv(A) d + s n >= 0 with A n = 0, n > 0 (thrusters); config as PseudoInverseAllocator."""

    summary = "nonnegative allocation for thrusters: pinv plus null-vector shift (config: demand, actuators, ...)"
    feedthrough_outputs = staticmethod(_allocate_nonnegative)

    def __init__(self, name: str, **kwargs):
        if "null_vector" in kwargs:
            raise ModelError(f"model {name}: null_vector is computed from effectiveness; do not give it")
        super().__init__(name, **kwargs)

    def declare(self):
        super().declare()
        self.parameters = self.parameters + (
            Parameter("null_vector", "", np.zeros(self.n_actuators), (self.n_actuators,), None,
                      "computed: positive null vector of A (do not give)"),)

    def configure(self):
        super().configure()
        a = self.parameter("effectiveness")
        n = a.shape[1]
        # the most balanced null vector: maximize t with t <= n_k <= 1, A n = 0 (small shifts for any demand)
        m = a.shape[0]
        result = linprog(np.r_[np.zeros(n), -1.0], A_ub=np.c_[-np.eye(n), np.ones(n)], b_ub=np.zeros(n),
                         A_eq=np.c_[a, np.zeros(m)], b_eq=np.zeros(m), bounds=[(0.0, 1.0)] * (n + 1), method="highs")
        if result.status != 0 or result.x[-1] <= 1e-9:
            raise ModelError(f"model {self.path}: parameter effectiveness: no strictly positive combination of "
                             "the actuators cancels out, so push-only actuators cannot produce every demand "
                             "direction (add or reorient thrusters)")
        self.parameter("null_vector")[...] = result.x[:n]

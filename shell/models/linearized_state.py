"""The engine's state in a linear model's coordinates: what a controller designed on ``flexshell linearize``'s
model (an LQR gain, an estimator) takes as its state.

``flexshell linearize`` writes A, B in deviations from the operating point ``(q0, u0)``, with every unit
quaternion of ``q`` replaced by a rotation vector (:mod:`shell.analysis.linearize`: ``q = q0 (x) Exp(phi)``, a
right, body-frame perturbation). This model inverts that map, compiled, at the engine's rate of evaluation::

    plain coordinate k of q:         x_i = q_k - q0_k
    unit quaternion q[k:k+4]:        x_i..i+2 = Log(q0[k:k+4]^* (x) q[k:k+4])      (short rotation, |phi| <= pi)
    velocity j:                      x_i = u_j - u0_j

in the order of the linear model's states (its ``names/states``), with the exact inverse of the Exp map of the
linearization (:func:`shell.attitude.quaternion_rotation_vector`; Sola 2017, eq. 105). So
``x_hat.x -> lqr.state`` closes, in YAML, an LQR designed on the exported model::

    x_hat: {type: LinearizedState, config: {linear_model: plant.h5}}
    connections: [multibody.q -> x_hat.q, multibody.u -> x_hat.u, x_hat.x -> lqr.state,
                  lqr.command -> multibody.acs.torque]

The linear model's states must all be the engine's ``q`` and ``u`` (a scene linearized with other
continuous states, a filter's or an integrator's, is refused: those states are not in ``q`` and ``u``).

Array layout: parameters ``[q0 (nq), u0 (nu), rotation (nq)]`` (``rotation``: 1 at the first element of each
quaternion the linear model writes as a rotation vector, 0 elsewhere; set by the file, checked), inputs ``[q
(nq), u (nu)]``: the kernel takes nq as the parameter size less the input size.
"""

from __future__ import annotations

import re
from pathlib import Path

import numpy as np
from numba import njit

from shell.attitude import quaternion_multiply, quaternion_rotation_vector
from shell.model import Declarations, InputPort, Model, ModelError, OutputPort, Parameter
from shell.registry import register_model

LINEARIZED_STATE = Declarations(
    parameters=(Parameter("q0", "", None, (1,), None, "operating point of q (default: the linear model's)"),
                Parameter("u0", "", None, (1,), None, "operating point of u (default: the linear model's)"),
                Parameter("rotation", "", None, (1,), (0.0, 1.0),
                          "1 where a quaternion starts in q (written as a rotation vector; set by the file)")),
    inputs=(InputPort("q", "", (1,), "the engine's generalized coordinates (SI)", feedthrough=True),
            InputPort("u", "", (1,), "the engine's generalized velocities (SI)", feedthrough=True)),
    outputs=(OutputPort("x", "", (1,), "state deviation in the linear model's order and coordinates (SI, rad)",
                        feedthrough=True),),
    sized=("q0", "u0", "rotation", "q", "u", "x"))
P, U, Y = LINEARIZED_STATE.P, LINEARIZED_STATE.U, LINEARIZED_STATE.Y

_PLAIN = re.compile(r"^(?P<model>.+)\.(?P<state>[qu])(\[(?P<k>\d+)\])?$")
_ROTATION = re.compile(r"^(?P<model>.+)\.q\[(?P<k>\d+):(?P<end>\d+)\]\.rotation_vector\[(?P<axis>[012])\]$")


@njit(cache=True)
def _linearized_state(t, x, z, u, p, y):
    nq = p.shape[0] - u.shape[0]
    nu = u.shape[0] - nq
    rotation = P.q0 + nq + nu
    i = 0
    k = 0
    while k < nq:
        if p[rotation + k] == 1.0:
            q = (u[U.q + k], u[U.q + k + 1], u[U.q + k + 2], u[U.q + k + 3])
            q0 = (p[P.q0 + k], -p[P.q0 + k + 1], -p[P.q0 + k + 2], -p[P.q0 + k + 3])
            phi = quaternion_rotation_vector(quaternion_multiply(q0, q))
            y[Y.x + i], y[Y.x + i + 1], y[Y.x + i + 2] = phi
            i += 3
            k += 4
        else:
            y[Y.x + i] = u[U.q + k] - p[P.q0 + k]
            i += 1
            k += 1
    for j in range(nu):
        y[Y.x + i + j] = u[nq + j] - p[nq + j]


def read_state_map(path) -> tuple[np.ndarray, np.ndarray, np.ndarray, list]:
    """(q0, u0, rotation flags, state names) of the linear-model file ``path`` (``flexshell linearize``'s HDF5),
    refused with the file and the key when its states are not the engine's q and u."""
    from shell.analysis.linear_model_file import read_linear_model

    path = Path(path)
    if path.suffix.lower() not in (".h5", ".hdf5") or not path.is_file():
        raise ModelError(f"{path}: expected the HDF5 linear-model file of flexshell linearize (-o plant.h5)"
                         + ("" if path.is_file() else ": no such file"))
    try:
        model = read_linear_model(path)
    except (OSError, KeyError, ValueError) as exc:
        raise ModelError(f"{path}: cannot read as a flexshell linear-model file ({exc})") from None
    names = list(model.state_names)
    engines, plain, quaternions = set(), {"q": set(), "u": set()}, {}
    for name in names:
        rotation, match = _ROTATION.match(name), _PLAIN.match(name)
        if rotation:
            engines.add(rotation["model"])
            k = int(rotation["k"])
            quaternions.setdefault(k, set()).add(int(rotation["axis"]))
        elif match:
            engines.add(match["model"])
            plain[match["state"]].add(int(match["k"] or 0))
        else:
            raise ModelError(f"{path}: names/states: state {name!r} is not a coordinate of the engine's q or u; "
                             "LinearizedState maps only multibody.q and multibody.u (linearize a scene whose "
                             "other models have no continuous states)")
    if len(engines) != 1:
        raise ModelError(f"{path}: names/states: states of several models {sorted(engines)}; expected one engine's "
                         "q and u")
    nq = max([k + 1 for k in plain["q"]] + [k + 4 for k in quaternions], default=0)
    nu = max([k + 1 for k in plain["u"]], default=0)
    covered = sorted(plain["q"] | {k + j for k in quaternions for j in range(4)})
    if covered != list(range(nq)) or sorted(plain["u"]) != list(range(nu)) or any(
            axes != {0, 1, 2} for axes in quaternions.values()):
        raise ModelError(f"{path}: names/states: q and u are not covered exactly once ({len(names)} states)")
    x0 = np.asarray(model.operating_point["x"], dtype=float).reshape(-1)
    if x0.size != nq + nu:
        raise ModelError(f"{path}: operating_point/x: expected {nq + nu} values (q, u), given {x0.size}")
    rotation = np.zeros(nq)
    rotation[list(quaternions)] = 1.0
    return x0[:nq], x0[nq:], rotation, names


@register_model
class LinearizedState(Model):
    """x = the engine's (q, u) as deviations from a linear model's operating point, in its coordinates."""

    summary = ("state of a linear model (flexshell linearize) from multibody.q and multibody.u: deviations, "
               "quaternions as rotation vectors (config: linear_model)")
    declarations = LINEARIZED_STATE
    feedthrough_outputs = staticmethod(_linearized_state)
    config_note = ("port sizes follow the linear model: q and u the engine's, x its states, e.g. "
                   "config: {linear_model: plant.h5} of `flexshell linearize scene.yaml --inputs "
                   "multibody.acs.torque --outputs multibody.acs.angular_velocity -o plant.h5`")

    def __init__(self, name: str, *, linear_model: str | None = None, **kwargs):
        if linear_model is None:
            raise ModelError(f"model {name}: config linear_model: required (the HDF5 file of flexshell linearize)")
        try:
            self._q0, self._u0, self._rotation, self.state_names = read_state_map(linear_model)
        except ModelError as exc:
            raise ModelError(f"model {name}: config linear_model: {exc}") from None
        self.linear_model = str(linear_model)
        super().__init__(name, **kwargs)

    def declare(self):
        nq, nu, n = self._q0.size, self._u0.size, len(self.state_names)
        self.use_declarations(LINEARIZED_STATE.replace(
            q0={"default": self._q0, "shape": (nq,)}, u0={"default": self._u0, "shape": (nu,)},
            rotation={"default": self._rotation, "shape": (nq,)}, q={"shape": (nq,)}, u={"shape": (nu,)},
            x={"shape": (n,)}))

    def configure(self):
        if not np.array_equal(self.parameter("rotation"), self._rotation):
            raise ModelError(f"model {self.path}: parameter rotation: set by the linear model {self.linear_model} "
                             f"({self._rotation.tolist()}), given {self.parameter('rotation').tolist()}")
        q0 = self.parameter("q0")
        for k in np.flatnonzero(self._rotation):
            norm = float(np.linalg.norm(q0[k:k + 4]))
            if abs(norm - 1.0) > 1e-9:
                raise ModelError(f"model {self.path}: parameter q0: the quaternion q0[{k}:{k + 4}] has norm "
                                 f"{norm:.12g}; expected a unit quaternion")

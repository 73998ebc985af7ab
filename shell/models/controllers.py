"""Flight-software controllers: discrete PID attitude control and LQR state feedback from a gain file.

``PidAttitudeController`` (sampled at its own rate T): with the error quaternion ``q_e = q_c^* (x) q``
and its rotation vector ``e = 2 sign(w_e) v_e`` (Wie, "Space Vehicle Dynamics and Control", 2nd ed.,
sec. 7.3, quaternion-feedback regulator)::

    I_k   = clip(I_{k-1} + e_k T, -I_max, I_max)          (backward-Euler integral, anti-windup clamp)
    tau_k = -K_p e_k - K_i I_k - K_d (omega_k - omega_c)   held until the next sample

``K_i = 0`` gives the PD law of :class:`shell.models.pd_attitude.PdAttitudeController`.

``LqrStateFeedback``: ``u_k = -K (x_k - x_ref)``, held, with the gain matrix K (m x n) read at build
time from a file (the default of parameter ``gain``; ``config: {gain_file: ...}``, relative to the working directory or absolute):
``.npy``, ``.csv``/``.txt`` (comma or white space separated rows), or ``.h5`` (dataset ``K``, or the
dataset named by ``gain_dataset``). K fixes the port sizes: ``state`` (n,), ``command`` (m,).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
from numba import njit

from shell.model import InputPort, Model, ModelError, OutputPort, Parameter, State, parse_period
from shell.registry import register_model


@njit(cache=True)
def _held(t, x, z, u, p, y):
    for i in range(y.shape[0]):
        y[i] = z[i]


@njit(cache=True)
def _pid_update(t, x, z, u, p):
    # u = [q (4), omega (3)]; p = [kp (3), ki (3), kd (3), integral limit (3), q_c (4), omega_c (3)]
    # z = [torque (3), integral (3), period]
    qw, qx, qy, qz = u[0], u[1], u[2], u[3]
    cw, cx, cy, cz = p[12], -p[13], -p[14], -p[15]
    ew = cw * qw - cx * qx - cy * qy - cz * qz
    ex = cw * qx + cx * qw + cy * qz - cz * qy
    ey = cw * qy - cx * qz + cy * qw + cz * qx
    ez = cw * qz + cx * qy - cy * qx + cz * qw
    sign = 1.0 if ew >= 0.0 else -1.0
    error = (2.0 * sign * ex, 2.0 * sign * ey, 2.0 * sign * ez)
    period = z[6]
    for i in range(3):
        integral = z[3 + i] + error[i] * period
        z[3 + i] = min(max(integral, -p[9 + i]), p[9 + i])
        z[i] = -p[i] * error[i] - p[3 + i] * z[3 + i] - p[6 + i] * (u[4 + i] - p[16 + i])


@register_model
class PidAttitudeController(Model):
    """Sampled quaternion-feedback PID attitude controller with an anti-windup clamp."""

    summary = "sampled PID attitude controller: attitude, angular_velocity in, torque out (held)"
    parameters = (
        Parameter("kp", "N*m/rad", (1.0, 1.0, 1.0), (3,), (0.0, None), "proportional gain per axis"),
        Parameter("ki", "N*m/(rad*s)", (0.0, 0.0, 0.0), (3,), (0.0, None), "integral gain per axis"),
        Parameter("kd", "N*m*s/rad", (1.0, 1.0, 1.0), (3,), (0.0, None), "derivative gain per axis"),
        Parameter("integral_limit", "rad*s", (1e3, 1e3, 1e3), (3,), (0.0, None), "anti-windup clamp of the integral"),
        Parameter("attitude_command", "", (1.0, 0.0, 0.0, 0.0), (4,), (-1.0, 1.0),
                  "commanded quaternion [w, x, y, z], command frame -> world"),
        Parameter("angular_velocity_command", "rad/s", (0.0, 0.0, 0.0), (3,), None, "commanded rate, node axes"),
    )
    inputs = (
        InputPort("attitude", "", (4,), "measured quaternion [w, x, y, z], node -> world"),
        InputPort("angular_velocity", "rad/s", (3,), "measured angular velocity, node axes"),
    )
    outputs = (OutputPort("torque", "N*m", (3,), "commanded torque, node axes (held between samples)"),)
    default_period = "0.1 s"
    state_outputs = staticmethod(_held)
    update = staticmethod(_pid_update)

    def __init__(self, name: str, *, period=None, **kwargs):
        self._given_period = period
        super().__init__(name, period=period, **kwargs)

    def configure(self):
        command = self.parameter("attitude_command")
        norm = float(np.sqrt(command @ command))
        if abs(norm - 1.0) > 1e-9:
            raise ModelError(f"model {self.path}: parameter attitude_command: expected a unit quaternion "
                             f"[w, x, y, z], given norm {norm:.12g}")
        period = float(parse_period(self._given_period if self._given_period is not None else self.default_period,
                                    f"model {self.path}: period"))
        self.discrete_states = (State("torque", "N*m", (3,), None, "held torque command"),
                                State("integral", "rad*s", (3,), None, "integral of the attitude error"),
                                State("period", "s", (), period, "sample period (from the rate)"))


def read_gain_matrix(path, dataset: str = "K") -> np.ndarray:
    """The gain matrix in ``path`` (.npy, .csv, .txt, .h5) as a 2-D float array."""
    path = Path(path)
    if not path.is_file():
        raise ModelError(f"gain file {path}: not found")
    suffix = path.suffix.lower()
    try:
        if suffix == ".npy":
            gain = np.load(path)
        elif suffix in (".csv", ".txt"):
            text = path.read_text()
            gain = np.loadtxt(path, delimiter="," if "," in text else None, ndmin=2)
        elif suffix in (".h5", ".hdf5"):
            import h5py

            with h5py.File(path, "r") as f:
                if dataset not in f:
                    raise ModelError(f"gain file {path}: no dataset {dataset!r}; datasets: {sorted(f)}")
                gain = f[dataset][()]
        else:
            raise ModelError(f"gain file {path}: expected .npy, .csv, .txt or .h5, given {suffix or 'no suffix'}")
    except ValueError as exc:
        if isinstance(exc, ModelError):
            raise
        raise ModelError(f"gain file {path}: cannot read a matrix: {exc}") from None
    gain = np.atleast_2d(np.asarray(gain, dtype=float))
    if gain.ndim != 2 or not np.all(np.isfinite(gain)):
        raise ModelError(f"gain file {path}: expected a finite 2-D matrix, given shape {gain.shape}")
    return gain


@njit(cache=True)
def _lqr_update(t, x, z, u, p):
    # p = [K (m x n) row-major, x_ref (n)]
    m = z.shape[0]
    n = u.shape[0]
    for i in range(m):
        acc = 0.0
        for j in range(n):
            acc += p[i * n + j] * (u[j] - p[m * n + j])
        z[i] = -acc


@register_model
class LqrStateFeedback(Model):
    """u = -K (x - x_ref), sampled and held; K from a file (config: gain_file, gain_dataset, units)."""

    summary = "sampled state feedback u = -K (x - x_ref) with K read from a file (config: gain_file)"
    state_outputs = staticmethod(_held)
    update = staticmethod(_lqr_update)
    default_period = "0.1 s"

    def __init__(self, name: str, *, gain_file: str | None = None, gain_dataset: str = "K", state_unit: str = "",
                 command_unit: str = "", **kwargs):
        if gain_file is None:
            raise ModelError(f"model {name}: LqrStateFeedback needs config: gain_file (.npy, .csv, .txt or .h5)")
        try:
            self.gain = read_gain_matrix(gain_file, gain_dataset)
        except ModelError as exc:
            raise ModelError(f"model {name}: {exc}") from None
        self.state_unit, self.command_unit = state_unit, command_unit
        super().__init__(name, **kwargs)

    def declare(self):
        m, n = self.gain.shape
        self.parameters = (
            Parameter("gain", f"({self.command_unit or '1'})/({self.state_unit or '1'})", self.gain, (m, n), None,
                      "K (default: the gain file's matrix)"),
            Parameter("state_reference", self.state_unit, np.zeros(n), (n,), None, "x_ref"),
        )
        self.inputs = (InputPort("state", self.state_unit, (n,), "state vector x (SI, the gain file's order)"),)
        self.outputs = (OutputPort("command", self.command_unit, (m,), "u = -K (x - x_ref), held"),)
        self.discrete_states = (State("command", self.command_unit, (m,), None, "held command"),)

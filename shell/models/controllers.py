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

Array layouts: the PID controller's are the module-level declarations (named offsets). The LQR's
depend on K's shape: its kernel takes m from the size of the held command and n from the size of the
state input, so ``gain`` (m x n, row-major) starts at ``P_LQR.gain`` and ``state_reference`` right
after it, at ``P_LQR.gain + m n`` (its offset is ``None`` in ``P_LQR``: derived, order checked).
"""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path

import numpy as np
from numba import njit

from shell.model import Declarations, InputPort, Model, ModelError, OutputPort, Parameter, State, parse_period
from shell.attitude import error_rotation_vector
from shell.ports import COMMANDED_TORQUE, HELD_TORQUE, MEASURED_ATTITUDE_AND_RATE
from shell.registry import register_model


PID_PARAMETERS = (
    Parameter("kp", "N*m/rad", (1.0, 1.0, 1.0), (3,), (0.0, None), "proportional gain per axis"),
    Parameter("ki", "N*m/(rad*s)", (0.0, 0.0, 0.0), (3,), (0.0, None), "integral gain per axis"),
    Parameter("kd", "N*m*s/rad", (1.0, 1.0, 1.0), (3,), (0.0, None), "derivative gain per axis"),
    Parameter("integral_limit", "rad*s", (1e3, 1e3, 1e3), (3,), (0.0, None), "anti-windup clamp of the integral"),
    Parameter("attitude_command", "", (1.0, 0.0, 0.0, 0.0), (4,), (-1.0, 1.0),
              "commanded quaternion [w, x, y, z], command frame -> world"),
    Parameter("angular_velocity_command", "rad/s", (0.0, 0.0, 0.0), (3,), None, "commanded rate, node axes"),
)
PID_DISCRETE = (HELD_TORQUE,
                State("integral", "rad*s", (3,), None, "integral of the attitude error"),
                State("period", "s", (), None, "sample period (from the rate)"))
PID = Declarations(parameters=PID_PARAMETERS, inputs=MEASURED_ATTITUDE_AND_RATE, outputs=COMMANDED_TORQUE,
                   discrete=PID_DISCRETE)
P_PID, U_PID, Y_PID, Z_PID = PID.P, PID.U, PID.Y, PID.Z


@njit(cache=True)
def _held_pid_torque(t, x, z, u, p, y):
    for i in range(3):
        y[Y_PID.torque + i] = z[Z_PID.torque + i]


@njit(cache=True)
def _pid_update(t, x, z, u, p):
    P, U, Z = P_PID, U_PID, Z_PID
    q, c = U.attitude, P.attitude_command
    error = error_rotation_vector((p[c], p[c + 1], p[c + 2], p[c + 3]), (u[q], u[q + 1], u[q + 2], u[q + 3]))
    period = z[Z.period]
    for i in range(3):
        integral = z[Z.integral + i] + error[i] * period
        limit = p[P.integral_limit + i]
        z[Z.integral + i] = min(max(integral, -limit), limit)
        z[Z.torque + i] = (-p[P.kp + i] * error[i] - p[P.ki + i] * z[Z.integral + i]
                           - p[P.kd + i] * (u[U.angular_velocity + i] - p[P.angular_velocity_command + i]))


@register_model
class PidAttitudeController(Model):
    """Sampled quaternion-feedback PID attitude controller with an anti-windup clamp."""

    summary = "sampled PID attitude controller: attitude, angular_velocity in, torque out (held)"
    declarations = PID
    default_period = "0.1 s"
    state_outputs = staticmethod(_held_pid_torque)
    update = staticmethod(_pid_update)

    def __init__(self, name: str, *, period=None, **kwargs):
        self._given_period = period
        super().__init__(name, period=period, **kwargs)

    def configure(self):
        self.require_unit_norm("attitude_command")
        period = float(parse_period(self._given_period if self._given_period is not None else self.default_period,
                                    f"model {self.path}: period"))
        self.discrete_states = tuple(replace(s, initial=period) if s.name == "period" else s
                                     for s in PID_DISCRETE)

    def sampled_coordinates(self, z):
        """Positions in ``z`` of its coordinates in the sampled closed-loop model (:mod:`shell.analysis.sampled_loop`):
        the held torque and the integral; the stored period (a constant, not a signal) left out."""
        return np.array([k for k in range(z.shape[0]) if k != Z_PID.period], dtype=np.int64)


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


#: the shapes follow K (m x n): gain at the start, state_reference after it at gain + m n (derived in the kernel)
LQR = Declarations(
    parameters=(Parameter("gain", "", None, (1, 1), None, "K (default: the gain file's matrix)"),
                Parameter("state_reference", "", 0.0, (1,), None, "x_ref")),
    inputs=(InputPort("state", "", (1,), "state vector x (SI, the gain file's order)"),),
    outputs=(OutputPort("command", "", (1,), "u = -K (x - x_ref), held"),),
    discrete=(State("command", "", (1,), None, "held command"),),
    sized=("gain", "state_reference", "state", "command"),
)
P_LQR, U_LQR, Y_LQR, Z_LQR = LQR.P, LQR.U, LQR.Y, LQR.Z


@njit(cache=True)
def _lqr_update(t, x, z, u, p):
    m = z.shape[0]
    n = u.shape[0]
    reference = P_LQR.gain + m * n
    for i in range(m):
        acc = 0.0
        for j in range(n):
            acc += p[P_LQR.gain + i * n + j] * (u[U_LQR.state + j] - p[reference + j])
        z[Z_LQR.command + i] = -acc


@njit(cache=True)
def _held_lqr_command(t, x, z, u, p, y):
    for i in range(y.shape[0]):
        y[Y_LQR.command + i] = z[Z_LQR.command + i]


@register_model
class LqrStateFeedback(Model):
    """u = -K (x - x_ref), sampled and held; K from a file (config: gain_file, gain_dataset, units)."""

    summary = "sampled state feedback u = -K (x - x_ref) with K read from a file (config: gain_file)"
    state_outputs = staticmethod(_held_lqr_command)
    update = staticmethod(_lqr_update)
    declarations = LQR
    default_period = "0.1 s"
    config_note = ("port sizes follow K (m x n): state (n,), command (m,), e.g. config: {gain_file: "
                   "configs/lqr_data/gain_position.csv, command_unit: N*m} (K 1 x 7: state (7,), command (1,))")

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
        self.use_declarations(LQR.replace(
            gain={"unit": f"({self.command_unit or '1'})/({self.state_unit or '1'})", "default": self.gain,
                  "shape": (m, n)},
            state_reference={"unit": self.state_unit, "default": np.zeros(n), "shape": (n,)},
            state={"unit": self.state_unit, "shape": (n,)}, command={"unit": self.command_unit, "shape": (m,)}))

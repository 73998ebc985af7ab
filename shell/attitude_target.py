"""Attitude targets written the way a G&C engineer writes them, turned into a unit quaternion.

A target (the frame the spacecraft should take, rotating target axes into world axes) may be given
in a scenario as

* a quaternion ``[w, x, y, z]`` (normalized, refused if its norm is off by more than 1e-6);
* ``{axis: [x, y, z], angle: 30 deg}``: a rotation by ``angle`` about ``axis`` (world = body axes at
  identity, so the same components in both), normalized;
* ``{euler: [a1, a2, a3], sequence: ZYX}``: Euler angles (each with its unit; bare numbers are
  radians) about the named axes; upper-case letters are intrinsic rotations (about the rotating
  axes: ``ZYX`` is yaw, pitch, roll), lower-case extrinsic (about the fixed axes), scipy's
  convention (``scipy.spatial.transform.Rotation.from_euler``);
* ``{point: [x, y, z], at: [x, y, z]}``: the shortest rotation taking the body axis ``point`` onto
  the world direction ``at`` (an eigenaxis about ``point x at``; 180 deg about an axis perpendicular
  to ``point`` when they are opposite).

``parse_attitude_target(value, where)`` returns the quaternion as a numpy array (scalar first,
``w >= 0``) or raises ``ModelError`` naming ``where`` (the model and key, e.g. ``model slew:
parameter target``), the form expected and the value given; the scenario loader puts the file and
line of the key in front.
"""

from __future__ import annotations

import numpy as np

from shell.attitude import axis_angle_quaternion
from shell.model import ModelError
from shell.units import UnitError, to_magnitude

FORMS = ("a quaternion [w, x, y, z]", "{axis: [x, y, z], angle: 30 deg}",
         "{euler: [yaw, pitch, roll], sequence: ZYX}", "{point: [0, 0, 1], at: [x, y, z]}")


def _expected() -> str:
    return "expected " + ", ".join(FORMS[:-1]) + " or " + FORMS[-1]


def _vector(value, where: str, key: str) -> np.ndarray:
    try:
        v = np.asarray(to_magnitude(value, "", (3,), f"{where}: {key}"), float)
    except (UnitError, ModelError, ValueError, TypeError) as exc:
        raise ModelError(f"{where}: {key}: expected three numbers [x, y, z], given {value!r} ({exc})") from None
    n = float(np.linalg.norm(v))
    if not np.isfinite(n) or n < 1e-12:
        raise ModelError(f"{where}: {key}: expected a nonzero finite vector, given {value!r}")
    return v / n


def _angle(value, where: str) -> float:
    try:
        return float(to_magnitude(value, "rad", (), where))
    except (UnitError, ModelError, ValueError, TypeError) as exc:
        raise ModelError(f"{where}: expected an angle such as 30 deg, given {value!r} ({exc})") from None


def _keys(value: dict, where: str, allowed: set[str]) -> None:
    if set(value) != allowed:
        unknown = sorted(set(value) - allowed)
        missing = sorted(allowed - set(value))
        detail = "; ".join(s for s in (f"unknown key(s) {unknown}" if unknown else "",
                                       f"missing key(s) {missing}" if missing else "") if s)
        raise ModelError(f"{where}: {detail}; {_expected()}, given {value!r}")


def shortest_rotation(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Quaternion of the smallest rotation taking unit vector a onto unit vector b."""
    c = float(np.dot(a, b))
    if c < -1.0 + 1e-12:
        helper = np.eye(3)[int(np.argmin(np.abs(a)))]
        axis = np.cross(a, helper)
        axis /= np.linalg.norm(axis)
        return np.r_[0.0, axis]
    q = np.r_[1.0 + c, np.cross(a, b)]
    return q / np.linalg.norm(q)


def parse_attitude_target(value, where: str) -> np.ndarray:
    """The unit quaternion [w, x, y, z] (target -> world, w >= 0) of a target in one of ``FORMS``."""
    if isinstance(value, dict):
        if "axis" in value:
            _keys(value, where, {"axis", "angle"})
            axis = _vector(value["axis"], where, "axis")
            angle = _angle(value["angle"], f"{where}: angle")
            q = np.array(axis_angle_quaternion.py_func(axis, angle))
        elif "euler" in value:
            _keys(value, where, {"euler", "sequence"})
            sequence = value["sequence"]
            if (not isinstance(sequence, str) or len(sequence) != 3 or not (sequence.isupper() or sequence.islower())
                    or any(c not in "xyzXYZ" for c in sequence) or sequence[0].lower() == sequence[1].lower()
                    or sequence[1].lower() == sequence[2].lower()):
                raise ModelError(f"{where}: sequence: expected three axis letters, no two neighbours equal, all "
                                 f"upper case (intrinsic, e.g. ZYX) or all lower case (extrinsic, e.g. xyz), "
                                 f"given {sequence!r}")
            angles = value["euler"]
            if not isinstance(angles, (list, tuple)) or len(angles) != 3:
                raise ModelError(f"{where}: euler: expected three angles [a1, a2, a3], given {angles!r}")
            radians = [_angle(a, f"{where}: euler[{i}]") for i, a in enumerate(angles)]
            from scipy.spatial.transform import Rotation  # here: scipy.spatial costs ~0.3 s at every start

            x, y, z, w = Rotation.from_euler(sequence, radians).as_quat()
            q = np.array([w, x, y, z])
        elif "point" in value:
            _keys(value, where, {"point", "at"})
            q = shortest_rotation(_vector(value["point"], where, "point"), _vector(value["at"], where, "at"))
        else:
            raise ModelError(f"{where}: {_expected()}, given {value!r}")
    else:
        try:
            q = np.asarray(value, float).reshape(-1)
        except (ValueError, TypeError):
            raise ModelError(f"{where}: {_expected()}, given {value!r}") from None
        if q.shape != (4,) or not np.all(np.isfinite(q)):
            raise ModelError(f"{where}: {_expected()}, given {value!r}")
        norm = float(np.linalg.norm(q))
        if abs(norm - 1.0) > 1e-6:
            raise ModelError(f"{where}: expected a unit quaternion [w, x, y, z], given norm {norm:.9g}")
        q = q / norm
    return q if q[0] >= 0.0 else -q

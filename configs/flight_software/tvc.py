"""Thrust-vector control law for configs/launch_vehicle_stage.yaml (a UserFunction at 50 Hz).

Attitude-hold PD on pitch and yaw, converted into gimbal angles: an engine deflection delta about a
gimbal axis tilts the thrust T at the lever arm l below the center of mass, giving the torque
``-l T delta`` about that axis, so ``delta = (K_p e + K_d omega) / (l T)`` realizes
``tau = -K_p e - K_d omega``. Roll is left uncontrolled (a single gimbaled engine has no roll authority).
"""

import numpy as np

THRUST = 3.0e5          # N
LEVER_ARM = 10.5        # m, gimbal below the (moving) center of mass
KP = 1.5e6              # N m/rad: bandwidth ~1.5 rad/s on 6.7e5 kg m^2
KD = 1.4e6              # N m s/rad: damping ~0.7


def tvc(t, signals):
    q = signals["attitude"]
    error = 2.0 * np.sign(q[0]) * q[1:3] if q[0] != 0.0 else 2.0 * q[1:3]   # pitch (x), yaw (y)
    rate = signals["angular_rate"][:2]
    return {"gimbal_command": (KP * error + KD * rate) / (LEVER_ARM * THRUST)}

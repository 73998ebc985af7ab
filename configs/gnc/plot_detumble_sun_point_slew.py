"""Figures of configs/gnc/detumble_sun_point_slew.yaml from its log.

    flexshell run configs/gnc/detumble_sun_point_slew.yaml -o gnc.h5
    python configs/gnc/plot_detumble_sun_point_slew.py gnc.h5 [-o docs/gnc_detumble_sun_point_slew.png]

Panels: body rate and mode; true pointing error against the reference (Sun pointing, then the slew);
MEKF attitude error against its 3-sigma; wheel speeds; magnetorquer dipole. Prints the numbers the
docs quote (mode switch times, errors).
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[2]))

from shell.log_file import read_log  # noqa: E402


def angle_between(a, b):
    """Rotation angle of a^* (x) b for rows of quaternions [w, x, y, z]."""
    w = np.abs(np.einsum("ki,ki->k", a, b))
    v = (a[:, :1] * b[:, 1:] - b[:, :1] * a[:, 1:] - np.cross(a[:, 1:], b[:, 1:]))
    return 2.0 * np.arctan2(np.linalg.norm(v, axis=1), w)


def summary(log) -> dict:
    t = log["time"]
    mode = log["modes.mode"]
    truth = log["multibody.cm.attitude"]
    switches = {int(m): float(t[np.argmax(mode >= m)]) for m in (1, 2) if np.any(mode >= m)}
    pointing = np.degrees(angle_between(truth, log["slew.reference_attitude"]))
    knowledge = np.degrees(angle_between(truth, log["navigation.attitude"])) * 3600.0
    rate = np.degrees(np.linalg.norm(log["multibody.cm.angular_velocity"], axis=1))
    out = {"switch_times": switches, "initial_rate_deg_s": float(rate[0])}
    if 2 in switches:
        slew = t >= switches[2]
        angle = log["slew.slew_angle"][slew]
        done = np.flatnonzero(np.diff(angle) == 0.0)
        out["slew_angle_deg"] = float(np.degrees(angle.max()))
        # tracking: from the start to the end of the profile (the first sample at its final angle)
        profile = slew & (t <= t[slew][np.argmax(angle >= angle.max())])
        out["slew_tracking_error_deg_max"] = float(pointing[profile].max())
        end = t[-1]
        last = t > end - 200.0
        out["final_pointing_error_deg_max_last_200s"] = float(pointing[last].max())
        out["final_knowledge_error_arcsec_rms_last_200s"] = float(np.sqrt(np.mean(knowledge[last] ** 2)))
        out["slew_done_samples"] = int(done.size)
    if 1 in switches:
        sun = (t >= switches[1] + 120.0) & (t < switches.get(2, t[-1]))
        if np.any(sun):
            out["sun_pointing_error_deg_max_after_120s"] = float(pointing[sun].max())
    out["max_wheel_speed_rpm"] = float(max(np.abs(log[f"rw{k}.wheel_speed"]).max() for k in (1, 2, 3, 4)) * 30 / np.pi)
    out["tracker_valid_fraction"] = float(np.mean(log["tracker.valid"]))
    return out


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("log")
    parser.add_argument("-o", "--output", default="docs/gnc_detumble_sun_point_slew.png")
    args = parser.parse_args(argv)
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    log = read_log(args.log)
    t = log["time"]
    truth = log["multibody.cm.attitude"]
    mode = log["modes.mode"]
    fig, axes = plt.subplots(5, 1, figsize=(9, 13), sharex=True)
    ax = axes[0]
    ax.semilogy(t, np.degrees(np.linalg.norm(log["multibody.cm.angular_velocity"], axis=1)), label="|omega| (deg/s)")
    ax2 = ax.twinx()
    ax2.step(t, mode, "k--", where="post", label="mode")
    ax2.set_ylabel("mode (0 detumble, 1 Sun, 2 slew)")
    ax.set_ylabel("body rate (deg/s)")
    ax.legend(loc="upper right")
    ax = axes[1]
    ax.semilogy(t, np.degrees(angle_between(truth, log["slew.reference_attitude"])) + 1e-6)
    ax.set_ylabel("pointing error (deg)\n(true vs reference)")
    ax = axes[2]
    knowledge = np.degrees(angle_between(truth, log["navigation.attitude"])) * 3600.0
    sigma = np.degrees(np.linalg.norm(log["navigation.attitude_sigma"], axis=1)) * 3600.0
    ax.semilogy(t, knowledge, label="MEKF error")
    ax.semilogy(t, 3 * sigma, label="3 sigma (filter)")
    ax.plot(t, np.where(log["tracker.valid"] > 0.5, np.nan, 1.0), "r|", label="no star tracker")
    ax.set_ylabel("knowledge error (arcsec)")
    ax.legend(loc="upper right")
    ax = axes[3]
    for k in (1, 2, 3, 4):
        ax.plot(t, log[f"rw{k}.wheel_speed"] * 30 / np.pi, label=f"rw{k}")
    ax.set_ylabel("wheel speed (rpm)")
    ax.legend(loc="upper right", ncol=4)
    ax = axes[4]
    ax.plot(t, log["torquers.dipole"])
    ax.set_ylabel("dipole (A m^2)")
    ax.set_xlabel("time (s)")
    fig.suptitle("configs/gnc/detumble_sun_point_slew.yaml")
    fig.tight_layout()
    Path(args.output).parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(args.output, dpi=90)
    for key, value in summary(log).items():
        print(f"{key}: {value}")
    print(f"figure: {args.output}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())

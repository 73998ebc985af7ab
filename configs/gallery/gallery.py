"""The example gallery: run every scene of configs/gallery/, plot it, and print the numbers that show it
did what its page says (docs/gallery/). Everything is written to a working directory, never over the
shipped files. From the repository root (scenes name files relative to it, as every config does):

    python3 configs/gallery/gallery.py                      (all scenes, outputs in gallery_out/)
    python3 configs/gallery/gallery.py 01 08 --output-directory /tmp/g
    python3 configs/gallery/gallery.py --figures docs/gallery    (also copy each figure to the docs)

Each entry runs the way a user would: ``flexshell fem2modal`` when a scene needs a body file made from a
deck, ``flexshell run`` with ``--set`` overrides that point at the prepared files, ``flexshell plot`` of
the signals its page shows. ``outcome(entry, log)`` computes the page's numbers from the log; the slow
test tests/docs/test_gallery.py checks them against their analytic or documented values.
"""

from __future__ import annotations

import argparse
import json
import shutil
import sys
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
ROOT = HERE.parent.parent


@dataclass(frozen=True)
class Entry:
    key: str                     # "01"
    name: str                    # page and file stem
    title: str
    scene: str                   # file in configs/gallery/
    plot: tuple                  # signals of its figure
    prepare: str = ""            # name of a preparation step (PREPARATIONS)
    overrides: tuple = field(default_factory=tuple)


GALLERY = (
    Entry("01", "attitude_hold", "Rigid attitude hold (PD)", "01_attitude_hold.yaml",
          ("multibody.acs.attitude", "controller.torque")),
    Entry("02", "torque_free_tumble", "Torque-free tumble (tennis-racket flips)", "02_torque_free_tumble.yaml",
          ("multibody.cm.angular_velocity",)),
    Entry("03", "pid_slew_disturbance", "PID slew rejecting a constant disturbance", "03_pid_slew_disturbance.yaml",
          ("multibody.acs.attitude", "controller.torque")),
    Entry("04", "reaction_wheels", "Reaction-wheel attitude control in orbit (Basilisk's scene)",
          "04_reaction_wheels.yaml",
          ("multibody.acs.attitude", "rw1.wheel_speed", "rw2.wheel_speed", "rw3.wheel_speed")),
    Entry("05", "wheels_thrusters_slew", "Wheel cluster slew with thruster momentum unloading",
          "05_wheels_thrusters_slew.yaml",
          ("multibody.acs.attitude", "wheels.rw1.wheel_speed", "wheels.rw2.wheel_speed", "wheels.rw3.wheel_speed",
           "wheels.rw4.wheel_speed", "jets.loads.torque")),
    Entry("06", "slosh_and_panels", "Reaction wheels with slosh particles and hinged panels",
          "06_slosh_and_panels.yaml",
          ("multibody.acs.attitude", "multibody.particle1.q", "multibody.panel1.q", "multibody.panel2.q")),
    Entry("07", "orbit_j2", "Orbit under J2: nodal regression", "07_orbit_j2.yaml",
          ("multibody.cg.position",)),
    Entry("08", "flexible_array_torque_step", "Flexible array on a rotating bus: torque step",
          "08_flexible_array_torque_step.yaml", ("multibody.q", "multibody.array_tip.position")),
    Entry("09", "lqr_flexible", "LQR regulation of a flexible spacecraft", "09_lqr_flexible.yaml",
          ("multibody.bus.q", "multibody.array_tip.position", "lqr_position.command")),
    Entry("10", "spacecraft_from_deck", "Flexible spacecraft from a NASTRAN deck, PD slew",
          "10_spacecraft_from_deck.yaml",
          ("multibody.bus_top.attitude", "multibody.spacecraft.modal_q", "controller.torque"),
          prepare="spacecraft_body"),
    Entry("11", "launch_vehicle_tvc_slosh", "Launch-vehicle stage: TVC, slosh, mass depletion",
          "11_launch_vehicle_tvc_slosh.yaml",
          ("multibody.nav.attitude", "multibody.engine.q", "multibody.slosh.q", "tanks.mass")),
    Entry("12", "observatory_flexible_jets", "60-mode observatory: wheels, pulsing jets, IMU vibration",
          "12_observatory_flexible_jets.yaml",
          ("multibody.acs.angular_velocity", "imu.angular_rate", "multibody.tip.position")),
    Entry("13", "lqr_3axis", "3-axis LQR on a flexible spacecraft, closed in YAML", "13_lqr_3axis.yaml",
          ("lqr.command", "multibody.acs.attitude", "multibody.acs.angular_velocity")),
    Entry("14", "spacecraft_notch", "Scene 10 with every mode to 100 Hz, stabilized by a notch",
          "14_spacecraft_notch.yaml",
          ("multibody.bus_top.attitude", "multibody.spacecraft.modal_q", "controller.torque"),
          prepare="spacecraft_body"),
    Entry("15", "stage_separation", "Stage separation with a separation spring", "15_stage_separation.yaml",
          ("multibody.lower_cm.position", "multibody.upper_cm.position", "multibody.upper_cm.linear_velocity")),
    Entry("16", "array_latch", "Solar-array deployment ending in a latch", "16_array_latch.yaml",
          ("multibody.array.q", "multibody.array.u", "multibody.bus_cm.angular_velocity", "multibody.latch.load")),
    Entry("17", "docking", "Docking through a probe and a latch", "17_docking.yaml",
          ("gap.y", "multibody.chaser_cm.linear_velocity", "multibody.target_cm.linear_velocity")),
)


def spacecraft_body(work: Path) -> list[str]:
    """The deck configs/fem/spacecraft.dat through fem2modal (20 free-free modes, modal integrals, 0.5 %
    damping) into ``work``; the override that points scene 10 at it."""
    from shell.cli import main

    body = work / "spacecraft.h5"
    if not body.exists():
        code = main(["fem2modal", str(ROOT / "configs/fem/spacecraft.dat"), "--modes", "20", "--modal-integrals",
                     "--damping", "0.005", "-o", str(body)])
        if code:
            raise RuntimeError(f"fem2modal of configs/fem/spacecraft.dat failed (exit {code})")
    return [f"multibody.spacecraft.body_file={body.resolve()}"]


PREPARATIONS = {"spacecraft_body": spacecraft_body}


def overrides(entry: Entry, work: Path) -> list[str]:
    """``--set`` overrides of ``entry`` (its prepared files in ``work``)."""
    extra = PREPARATIONS[entry.prepare](work) if entry.prepare else []
    return list(entry.overrides) + extra


def run_entry(entry: Entry, work, figures=None) -> tuple[Path, list[Path]]:
    """Run and plot ``entry`` in ``work``; returns (log, figure pages). ``figures``: also copy the first
    page there as ``<name>.png``."""
    from shell.cli import main

    work = Path(work)
    work.mkdir(parents=True, exist_ok=True)
    log = work / f"{entry.name}.h5"
    sets = [item for o in overrides(entry, work) for item in ("--set", o)]
    code = main(["run", str(HERE / entry.scene), "-o", str(log), "--quiet"] + sets)
    if code:
        raise RuntimeError(f"gallery {entry.key} ({entry.scene}): flexshell run failed (exit {code})")
    figure = work / f"{entry.name}.png"
    code = main(["plot", str(log), *entry.plot, "-o", str(figure)])
    if code:
        raise RuntimeError(f"gallery {entry.key}: flexshell plot failed (exit {code})")
    pages = sorted(work.glob(f"{entry.name}-*.png")) or [figure]
    if figures is not None:
        Path(figures).mkdir(parents=True, exist_ok=True)
        shutil.copyfile(pages[0], Path(figures) / f"{entry.name}.png")
    return log, pages


def outcome(entry: Entry, log) -> dict:
    """The numbers the entry's page states, computed from its log."""
    from shell.commands.plot import attitude_error, commanded_attitude
    from shell.log_file import log_info, read_log

    data, info = read_log(log), log_info(log)
    scenario = str(info["attributes"]["scenario"])
    t = data["time"]
    result = {"status": info["attributes"]["status"], "t_end": float(t[-1])}

    def final_error_deg(signal):
        reference = commanded_attitude(scenario, signal)
        return float(np.degrees(attitude_error(data[signal][-1:], reference if reference is not None
                                               else (1.0, 0.0, 0.0, 0.0))[0]))

    for signal in ("multibody.acs.attitude", "multibody.bus_top.attitude"):
        if signal in data:
            result["final_attitude_error_deg"] = final_error_deg(signal)
            error = np.degrees(attitude_error(data[signal], commanded_attitude(scenario, signal)
                                              if commanded_attitude(scenario, signal) is not None else (1, 0, 0, 0)))
            outside = np.nonzero(error > 0.1)[0]
            result["settling_time_0p1deg_s"] = float(t[outside[-1] + 1]) if outside.size and outside[-1] + 1 < t.size \
                else (0.0 if not outside.size else float("inf"))
    if entry.key == "02":
        w = data["multibody.cm.angular_velocity"]
        inertia = np.array([100.0, 200.0, 300.0])
        energy = 0.5 * np.sum(inertia * w * w, axis=1)
        momentum = np.linalg.norm(inertia * w, axis=1)
        result["energy_drift"] = float(np.max(np.abs(energy / energy[0] - 1.0)))
        result["momentum_drift"] = float(np.max(np.abs(momentum / momentum[0] - 1.0)))
        result["flips"] = int(np.count_nonzero(np.diff(np.sign(w[:, 1])) != 0))
    if entry.key == "07":
        r = data["multibody.cg.position"]
        h = np.cross(r[:-1], r[1:])   # orbit normal from consecutive positions (10 s apart, 0.6 deg of arc)
        node = np.unwrap(np.arctan2(h[:, 0], -h[:, 1]))
        result["node_rate_rad_s"] = float(np.polyfit(0.5 * (t[:-1] + t[1:]), node, 1)[0])
        mu, radius, j2 = 3.986004418e14, 6378137.0, 1.08262668e-3
        a, inclination = 7.0e6, np.radians(45.0)
        n = np.sqrt(mu / a**3)
        result["node_rate_theory_rad_s"] = float(-1.5 * n * j2 * (radius / a) ** 2 * np.cos(inclination))
    if entry.key == "08":
        tip = data["multibody.array_tip.position"]
        q = data["multibody.q"]
        elastic = np.unwrap(np.arctan2(tip[:, 1], tip[:, 0])) - q[:, 0]   # tip angle seen from the bus axis
        elastic = elastic - np.polyval(np.polyfit(t, elastic, 2), t)
        spectrum = np.abs(np.fft.rfft(elastic * np.hanning(t.size)))
        frequencies = np.fft.rfftfreq(t.size, t[1] - t[0])
        k = int(np.argmax(spectrum[1:])) + 1
        # parabolic interpolation of the peak (log magnitude) between FFT bins
        a_, b_, c_ = np.log(spectrum[k - 1:k + 2])
        shift = 0.5 * (a_ - c_) / (a_ - 2 * b_ + c_)
        result["ring_frequency_hz"] = float(frequencies[k] + shift * (frequencies[1] - frequencies[0]))
        result["peak_modal_q"] = float(np.max(np.abs(q[:, 1:])))
    if entry.key == "09":
        result["final_bus_angle_deg"] = float(np.degrees(data["multibody.bus.q"][-1, 0]))
    if entry.key in ("10", "14"):
        eta = data["multibody.spacecraft.modal_q"]
        result["peak_modal_q"] = float(np.max(np.abs(eta)))
        result["final_modal_q"] = float(np.max(np.abs(eta[-1])))
    if entry.key == "11":
        mass = data["tanks.mass"]
        result["mass_used_kg"] = float(mass[0] - mass[-1])
        result["max_rate_deg_s"] = float(np.degrees(np.max(np.linalg.norm(data["multibody.nav.angular_velocity"],
                                                                          axis=1))))
        result["max_gimbal_deg"] = float(np.degrees(np.max(np.abs(data["multibody.engine.q"]))))
    if entry.key == "13":
        result["peak_command_n_m"] = float(np.max(np.abs(data["lqr.command"])))
    if entry.key == "12":
        result["max_imu_rate"] = float(np.max(np.abs(data["imu.angular_rate"])))
        result["finite"] = bool(all(np.isfinite(v).all() for v in data.values()))
    if entry.key in ("15", "16", "17"):
        changes = json.loads(str(info["attributes"]["scene_events"]))
        result["event_time_s"] = float(changes[0]["time"])
        bodies = {"15": ("lower", "upper"), "16": ("bus", "array"), "17": ("chaser", "target")}[entry.key]
        masses = {"lower": 1000.0, "upper": 300.0, "bus": 500.0, "array": 30.0, "chaser": 800.0, "target": 1200.0}
        momentum = sum(masses[b] * np.einsum("nij,nj->ni", data[f"multibody.{b}_cm.rotation"],
                                             data[f"multibody.{b}_cm.linear_velocity"]) for b in bodies)
        result["momentum_change_kg_m_s"] = float(np.abs(momentum - momentum[0]).max())
        result["momentum_kg_m_s"] = float(np.linalg.norm(momentum[0]))
        if "kinetic energy lost" in changes[0]["changes"]:
            result["energy_lost_j"] = float(changes[0]["changes"].split("kinetic energy lost ")[1].split(" J")[0])
    if entry.key == "15":
        v = data["multibody.upper_cm.linear_velocity"][-1, 0] - data["multibody.lower_cm.linear_velocity"][-1, 0]
        result["separation_speed_m_s"] = float(v)
    for key in ("rw1.wheel_speed", "wheels.rw1.wheel_speed"):
        if key in data:
            speeds = [data[k] for k in data if k.endswith("wheel_speed")]
            result["max_wheel_speed_rpm"] = float(np.max(np.abs(speeds)) * 30 / np.pi)
    return result


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description="run, plot and check the example gallery")
    parser.add_argument("keys", nargs="*", help="entries to run (01 .. 17; default all)")
    parser.add_argument("--output-directory", default="gallery_out", help="working directory (default gallery_out)")
    parser.add_argument("--figures", help="also copy each entry's figure into this folder (docs/gallery)")
    args = parser.parse_args(argv)
    chosen = [e for e in GALLERY if not args.keys or e.key in args.keys or e.name in args.keys]
    unknown = set(args.keys) - {e.key for e in GALLERY} - {e.name for e in GALLERY}
    if unknown:
        parser.error(f"no gallery entry {sorted(unknown)}; entries: {[e.key for e in GALLERY]}")
    failed = []
    for entry in chosen:
        try:
            log, pages = run_entry(entry, args.output_directory, args.figures)
        except RuntimeError as exc:
            print(exc, file=sys.stderr)
            failed.append(entry.key)
            continue
        numbers = ", ".join(f"{k} {v:.6g}" if isinstance(v, float) else f"{k} {v}"
                            for k, v in outcome(entry, log).items())
        print(f"{entry.key} {entry.name}: {numbers}; figure {pages[0]}", flush=True)
    if failed:
        print(f"gallery: entries {failed} failed", file=sys.stderr)
    return 1 if failed else 0


if __name__ == "__main__":
    sys.exit(main())

"""Work-precision of the observatory scene at the control rate: exponential RK4 against RK4 and mode cutoff.

Part A, the scene a user runs (configs/observatory.yaml: 60 modes from 11.5 Hz to 2.29 kHz, 1 kHz attitude hold
with the wheels, 20 Hz jet pulses), with the IMU's noise and quantization switched off so that the outputs are
smooth functions of the integration (everything else as in the file). Each run logs at 1 kHz:

* IMU rate ``imu.angular_rate`` (the sensor on the bench: the structure's vibration),
* attitude of the controller node (angle of ``q_ref^-1 q``),
* tip deflection: the bench tip (grid 101) relative to the centre node frame, minus its undeformed offset.

Errors are the largest difference over the run against the reference: RK4 at 25 and 50 us with all modes,
extrapolated to zero step (Richardson, fourth order; the distance of RK4 at 25 us from it is printed as the
reference's error scale). Runs: RK4 at 100 us (all modes: RK4 at 1 ms is unstable, h omega_max = 14.4 > 2.83),
the exponential RK4 ``etdrk4`` at 1 and 0.5 ms (all modes; a 2 ms step does not exist in this loop: the
1 kHz controller restarts the integrator every millisecond, see part B) and at 1 ms with the modes at or below
400 Hz, and RK4 at 1 ms with the cutoffs 400, 200 and 100 Hz (``max_frequency``). Cost: CPU seconds per
simulated second (process time of ``Simulation.run`` after the first millisecond, which holds the numba
compilation and the exponential's matrix functions, reported separately), one run each. Every run is in the
compiled loop (``etdrk4`` too, since issue 14's last step).

Then the real-time factor of the closed loop as a user runs it (the file as shipped, IMU noise on, logging to a
file) and with the IMU noise off: median and range of CPU and wall seconds per simulated second over 5 runs of
1 s, with the machine's load average before and after (a shared machine: read the CPU figure), and the same with
the modal integrals of order 2 (the file keeps order 0: ``order_check`` prints what orders 1 and 0 change in
the outputs against order 2, with RK4 at 50 us and with etdrk4 at 1 ms).

Part B, the 190-mode observatory of benchmarks/linearize_speed.py (modes up to 1943 Hz, order-0 modal data,
open loop): CPU per simulated second of etdrk4 at 2, 1 and 0.5 ms and of RK4 at 0.1 ms, and the etdrk4 state
error after 20 ms against RK4 at 25 us.

    python3 benchmarks/observatory.py [--duration 0.5] [--skip-b] [--real-time-only]
                                                      (writes docs/observatory_work_precision.png)
"""

from __future__ import annotations

import argparse
import gc
import sys
import tempfile
import time
from pathlib import Path

import h5py
import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from shell.scenario import build_simulation, load_scenario  # noqa: E402

CONFIG = ROOT / "configs" / "observatory.yaml"
SIGNALS = ["imu.angular_rate", "multibody.acs.attitude", "multibody.acs.position", "multibody.acs.rotation",
           "multibody.tip.position"]
QUIET_IMU = ["imu.gyro_lsb=0 rad", "imu.accel_lsb=0 m/s", "imu.gyro_random_walk=0 rad/s**0.5",
             "imu.gyro_bias_instability=0 rad/s", "imu.accel_random_walk=0 m/s**1.5"]
# (label, method, step in s, max_frequency in Hz or None)
REFERENCE = ("rk4 25 us", "rk4", 25e-6, None)
RUNS = [("rk4 50 us", "rk4", 50e-6, None), ("rk4 100 us", "rk4", 100e-6, None), ("etdrk4 1 ms", "etdrk4", 1e-3, None),
        ("etdrk4 0.5 ms", "etdrk4", 0.5e-3, None), ("etdrk4 1 ms, <= 400 Hz", "etdrk4", 1e-3, 400.0),
        ("rk4 1 ms, <= 400 Hz", "rk4", 1e-3, 400.0), ("rk4 1 ms, <= 200 Hz", "rk4", 1e-3, 200.0),
        ("rk4 1 ms, <= 100 Hz", "rk4", 1e-3, 100.0)]


def run_scene(method, step, max_frequency, duration, tmp, extra=()):
    overrides = QUIET_IMU + list(extra) + [f"integrator.method={method}", f"integrator.step={step!r} s", "log.rate=1 kHz",
                             "log.signals=[" + ", ".join(SIGNALS) + "]"]
    if max_frequency is not None:
        overrides.append(f"multibody.structure.max_frequency={max_frequency} Hz")
    simulation = build_simulation(load_scenario(str(CONFIG), overrides))
    log = Path(tmp) / f"{method}_{step}_{max_frequency}_{len(extra)}{'_'.join(extra)[-2:]}.h5"
    start = time.process_time()
    simulation.run(1e-3)
    setup = time.process_time() - start
    start = time.process_time()
    summary = simulation.run(duration, log_path=str(log))
    cpu = time.process_time() - start
    with h5py.File(log, "r") as f:
        group = f[next(iter(f.keys()))]
        data = {name: group[name][()] for name in SIGNALS} | {"time": group["time"][()]}
    return data, cpu / (duration - 1e-3), summary, setup


def outputs(data):
    """IMU rate (3), attitude angle from the command (identity) in rad, tip deflection in the centre frame (3)."""
    q = data["multibody.acs.attitude"]
    angle = 2.0 * np.arctan2(np.linalg.norm(q[:, 1:], axis=1), np.abs(q[:, 0]))
    R = data["multibody.acs.rotation"].reshape(-1, 3, 3)
    arm = data["multibody.tip.position"] - data["multibody.acs.position"]
    relative = np.einsum("kji,kj->ki", R, arm)
    deflection = relative - relative[0]
    return {"IMU rate": data["imu.angular_rate"], "attitude": angle[:, None], "tip deflection": deflection}


def errors(out, ref):
    return {k: float(np.abs(out[k] - ref[k]).max()) for k in ref}


def part_a(duration):
    results = {}
    with tempfile.TemporaryDirectory() as tmp:
        data, ref_cost, summary, _ = run_scene(*REFERENCE[1:], duration, tmp)
        fine = outputs(data)
        data, half_cost, _, _ = run_scene("rk4", 50e-6, None, duration, tmp)
        half = outputs(data)
        ref = {k: fine[k] + (fine[k] - half[k]) / 15.0 for k in fine}
        scale = {k: float(np.abs(v).max()) for k, v in ref.items()}
        print(f"reference {REFERENCE[0]} + 50 us extrapolated; RK4 at 25 us: {ref_cost:.1f} CPU s per simulated s "
              f"({summary.steps} steps, {summary.derivative_evaluations} evaluations), distance from the "
              "reference: " + ", ".join(f"{k} {v:.1e}" for k, v in errors(fine, ref).items()))
        print("peak values: " + ", ".join(f"{k} {v:.3e}" for k, v in scale.items()))
        results["rk4 50 us"] = (half_cost, errors(half, ref))  # 16x RK4 at 25 us's distance, by construction
        print(f"{'rk4 50 us':26s} {half_cost:8.2f} CPU s/s")
        for label, method, step, fmax in RUNS[1:]:
            gc.collect()
            data, cost, summary, setup = run_scene(method, step, fmax, duration, tmp)
            err = errors(outputs(data), ref)
            results[label] = (cost, err)
            print(f"{label:26s} {cost:8.2f} CPU s/s (first ms {setup:5.2f} s)  "
                  + "  ".join(f"{k} {v:.2e} ({v / scale[k]:.1e})" for k, v in err.items()), flush=True)
    return results, scale, ref_cost, errors(fine, ref)


def order_check(duration):
    """What the modal-integral order changes in this scene's outputs (the config keeps order 0): each order's
    run against order 2's, with RK4 at 50 us (the model alone) and etdrk4 at 1 ms (as configured)."""
    with tempfile.TemporaryDirectory() as tmp:
        for method, step in (("rk4", 50e-6), ("etdrk4", 1e-3)):
            out = {}
            for order in (2, 1, 0):
                data = run_scene(method, step, None, duration, tmp,
                                 [f"multibody.structure.modal_integrals_order={order}"])[0]
                out[order] = outputs(data)
            scale = {k: float(np.abs(v).max()) for k, v in out[2].items()}
            for order in (1, 0):
                print(f"{method} {step * 1e3:g} ms, modal integrals of order {order} against order 2: "
                      + "  ".join(f"{k} {v:.2e} ({v / scale[k]:.1e})" for k, v in errors(out[order], out[2]).items()),
                      flush=True)


def part_b():
    sys.path.insert(0, str(ROOT / "benchmarks"))
    from linearize_speed import observatory

    from shell.simulation import Simulation

    def build(method, step):
        with tempfile.TemporaryDirectory() as tmp:
            sim = observatory(190, Path(tmp))
        root = sim.root
        del sim
        gc.collect()
        simulation = Simulation(root, integrator=method, step=step)
        s = simulation.models[0].system
        simulation.x[s.nq:s.nq + 3] = np.radians([1.0, -0.5, 0.7])  # tumbling, five low modes deflected
        simulation.x[7:12] = 1e-3
        return simulation

    rows, final = {}, {}
    t0 = 2e-3  # a multiple of every step below; the first steps hold compilation and the matrix functions
    for method, step, duration in (("etdrk4", 2e-3, 0.02), ("etdrk4", 1e-3, 0.02), ("etdrk4", 0.5e-3, 0.02),
                                   ("rk4", 1e-4, 0.002), ("rk4", 25e-6, 0.02)):
        simulation = build(method, step)
        simulation.run(t0)
        start = time.process_time()
        simulation.run(t0 + duration)
        cpu = (time.process_time() - start) / duration
        rows[(method, step)] = cpu
        final[(method, step)] = simulation.x.copy()
        print(f"190 modes, {method} at {step * 1e3:g} ms: {cpu:.1f} CPU s per simulated s "
              f"(real-time factor {1 / cpu:.3g} on an idle core)", flush=True)
        del simulation
        gc.collect()
    for step in (2e-3, 1e-3, 0.5e-3):
        error = np.abs(final[("etdrk4", step)] - final[("rk4", 25e-6)]).max()
        print(f"190 modes: etdrk4 {step * 1e3:g} ms against rk4 25 us at 22 ms: largest state difference {error:.2e}")
    return rows


def real_time_factor(repeats=5, duration=1.0, overrides=()):
    """Closed loop as configured (etdrk4 at 1 ms in the compiled loop, IMU noise on, 100 Hz log to a file), wall
    and CPU per simulated second: medians and ranges over ``repeats`` runs of ``duration`` simulated seconds
    (after the first 2 ms, which hold the integrator's set-up)."""
    wall, cpu = [], []
    with tempfile.TemporaryDirectory() as tmp:
        for r in range(repeats):
            simulation = build_simulation(load_scenario(str(CONFIG), list(overrides)))
            simulation.run(0.002)
            assert simulation._compiled_loop_applies(), "etdrk4 should run in the compiled loop"
            w0, c0 = time.perf_counter(), time.process_time()
            simulation.run(0.002 + duration, log_path=str(Path(tmp) / f"rt{r}.h5"))
            wall.append((time.perf_counter() - w0) / duration)
            cpu.append((time.process_time() - c0) / duration)
            del simulation
            gc.collect()
    return np.median(wall), np.median(cpu), (min(cpu), max(cpu))


def plot(results, scale, ref_cost, ref_error, path):
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    style = {"rk4": ("o", "tab:blue"), "rk4 cut": ("o", "tab:orange"), "etdrk4": ("s", "tab:green"),
             "etdrk4 cut": ("s", "tab:olive")}
    fig, axes = plt.subplots(1, 3, figsize=(16, 5.2))
    for ax, key in zip(axes, scale):
        for label, (cost, err) in results.items():
            marker, color = style[label.split()[0] + (" cut" if "<=" in label else "")]
            fill = "none" if "0.5 ms" in label or "50 us" in label else color
            ax.loglog(cost, err[key] / scale[key], marker, ms=9, color=color, mfc=fill, label=label)
            if "<=" in label:
                ax.annotate(label.split("<= ")[1], (cost, err[key] / scale[key]), fontsize=7, xytext=(5, -9),
                            textcoords="offset points")
        ax.axhline(ref_error[key] / scale[key], color="0.5", ls="--", lw=1)
        ax.axvline(ref_cost, color="0.5", ls=":", lw=1)
        ax.set_xlabel("CPU seconds per simulated second")
        ax.set_ylabel("max |error| / peak")
        ax.set_title(f"{key} (peak {scale[key]:.2e})")
        ax.grid(True, which="both", alpha=0.3)
    axes[0].legend(fontsize=8, loc="center left")
    fig.suptitle("observatory (configs/observatory.yaml: 60 modes to 2.29 kHz, 1 kHz closed loop, 0.5 s) against RK4 "
                 "at 25 and 50 us extrapolated; dashed: RK4 at 25 us from it (the reference's error scale), "
                 "dotted: RK4 at 25 us's cost", fontsize=10)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    print(f"wrote {path}")


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--duration", type=float, default=0.5, help="simulated seconds of part A (default 0.5)")
    parser.add_argument("--skip-b", action="store_true", help="skip the 190-mode part")
    parser.add_argument("--real-time-only", action="store_true", help="only the closed loop's real-time factor")
    args = parser.parse_args()
    import os
    print(f"load average {os.getloadavg()}")
    if not args.real_time_only:
        results, scale, ref_cost, ref_error = part_a(args.duration)
        plot(results, scale, ref_cost, ref_error, ROOT / "docs" / "observatory_work_precision.png")
        order_check(args.duration)
    for label, overrides in (("as configured", ()), ("IMU noise off", QUIET_IMU),
                             ("modal integrals of order 2", ["multibody.structure.modal_integrals_order=2"])):
        load = os.getloadavg()
        wall, cpu, (low, high) = real_time_factor(overrides=overrides)
        print(f"closed loop {label} (etdrk4, 1 ms, 1 kHz controller, compiled loop): {wall:.2f} wall s and {cpu:.2f} "
              f"CPU s per simulated s (runs {low:.2f}-{high:.2f}; real-time factor {1 / wall:.3g} wall, {1 / cpu:.3g} "
              f"CPU); load {load} -> {os.getloadavg()}", flush=True)
    if not (args.skip_b or args.real_time_only):
        part_b()


if __name__ == "__main__":
    main()

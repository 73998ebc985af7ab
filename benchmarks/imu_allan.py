"""Long static IMU record: Allan deviation of every noise term against its IEEE Std 952 signature.

    python benchmarks/imu_allan.py [--samples 2000000] [--seed 1]

One record at 100 Hz with a tactical-grade datasheet (ARW, bias instability, RRW, quantization, angle
white noise) from the same kernel as a simulation (shell.models.imu.static_record); prints the measured
Allan deviation of the x gyro next to the sum of the analytic Allan variances of the terms, and the
ratio, over tau = 0.01 s .. samples/10 periods.
"""

from __future__ import annotations

import argparse
import time

import numpy as np

from shell.models.imu import (FLICKER_FLOOR, GAUSS_MARKOV_PEAK, Imu, allan_deviation,
                              gauss_markov_allan_variance, static_record)

DEG_H = np.pi / 180 / 3600


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--samples", type=int, default=2_000_000)
    parser.add_argument("--seed", type=int, default=1)
    args = parser.parse_args()
    period, tc = 0.01, 100.0
    arw, b, k = 0.15 * np.pi / 180 / 60, 0.5 * DEG_H, 0.01 * DEG_H / 60
    lsb = 0.05 / 3600 * np.pi / 180
    imu = Imu("imu", period=period, gyro_random_walk=arw, gyro_bias_instability=b, gyro_bias_correlation_time=tc,
              gyro_bias_random_walk=k, gyro_lsb=lsb)
    start = time.process_time()
    record = static_record(imu, args.samples, args.seed)[:, 0]
    elapsed = time.process_time() - start
    m = np.unique(np.geomspace(1, args.samples // 10, 30).astype(int))
    tau = m * period
    measured = allan_deviation(record, period, m)
    sigma_gm = FLICKER_FLOOR * b / GAUSS_MARKOV_PEAK
    model = np.sqrt(arw**2 / tau + gauss_markov_allan_variance(tau, sigma_gm, tc) + k**2 * tau / 3
                    + 3 * (lsb / np.sqrt(12)) ** 2 / tau**2)
    print(f"{args.samples} samples at {1 / period:g} Hz in {elapsed:.2f} s CPU")
    print(f"{'tau [s]':>10} {'measured [deg/h]':>18} {'model [deg/h]':>15} {'ratio':>7} {'1 sigma':>8}")
    for t, a, r, mm in zip(tau, measured, model, m):
        clusters = args.samples // mm
        print(f"{t:10.3g} {a / DEG_H:18.5g} {r / DEG_H:15.5g} {a / r:7.3f} {1 / np.sqrt(2 * (clusters - 1)):8.3f}")


if __name__ == "__main__":
    main()

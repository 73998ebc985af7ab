"""Does the observatory need a fourth-order exponential method? ETD2RK and ETD3RK against ``etdrk4`` (issue 28).

At order 1 the 196-mode observatory of benchmarks/flexible_observatory.py spends ~80 % of its 1 ms ``etdrk4`` step in
the four derivative evaluations Krogstad's scheme needs (the linear algebra ~15 %, the checks of the linear part
~1.5 %). A method with fewer stages evaluates the derivative less often; this study measures whether its accuracy
is enough for the scene (the must-show: the IMU's rate and the attitude within 5e-3 of their peaks).

Methods (Cox & Matthews, "Exponential time differencing for stiff systems", J. Comput. Phys. 176:430-455, 2002,
eqs. 22 and 25-26; Hochbruck & Ostermann, Acta Numerica 19, 2010, Sec. 2.3), with ``phi_{k,c} = phi_k(c h L)``,
``N = f - L y``, ``F = f(t, y)``, written as ``etdrk4`` writes its stages (``phi_0 y + c h phi_{1,c} N1 = y + c h
phi_{1,c} F``, shell/integrators/exponential.py):

* ETD2RK (2 derivative evaluations per step, classical and stiff order 2):
  ``Y2 = y + h phi_1 F``, ``y1 = Y2 + h phi_2 (N2 - N1)``;
* ETD3RK (3 evaluations, classical order 3; for ``L = 0`` Kutta's third-order method):
  ``a = y + h/2 phi_{1,1/2} F``, ``b = y + h phi_1 F + 2 h phi_1 (Na - N1)``,
  ``y1 = y + h phi_1 F + h phi_2 (-3 N1 + 4 Na - Nb) + 4 h phi_3 (N1 - 2 Na + Nb)``.

They are prototypes, registered only inside this script (Python loop, dense numpy products with the matrix functions
of ``LinearPart.real_functions``; the linear part, its driven rows and its checks are ``etdrk4``'s; no stiffness
monitor: ETD2RK has no two stages at the same time to estimate it from). Compared over ``--duration`` s at order 1
(and with ``--unbalanced`` the scene whose first wheel is unbalanced): RK4 at 0.05 ms (the figure of the must-show),
``etdrk4`` at 0.25 ms (a tighter reference: RK4 at 0.05 ms is 4.8e-5 of the IMU's peak away from it), ``etdrk4``,
ETD3RK and ETD2RK at 1 ms, ETD2RK at 0.5 ms (its order); largest differences relative to the reference's peaks, and
the derivative evaluations per step.

Measured 2026-12-07 (1 s, balanced wheels): against ``etdrk4`` at 0.25 ms, ``etdrk4`` 1 ms 5.3e-7 of the IMU rate's
peak and 1.6e-9 of the attitude's, ETD3RK 1 ms 5.3e-7 / 6.4e-9, ETD2RK 1 ms 1.4e-5 / 4.5e-8, ETD2RK 0.5 ms
3.6e-6 / 9.4e-9 (second order); against RK4 at 0.05 ms all of them 4.6-4.8e-5 / 3.6-3.7e-7 (that reference's own
error). Derivative evaluations per 1 ms step 4, 3, 2 (plus the m + 1 = 403 of the driven rows once).

    python3 benchmarks/etd_lower_order.py [--duration 1] [--unbalanced]
"""

from __future__ import annotations

import argparse
import os
import sys
import tempfile
import time
from pathlib import Path

for _var in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS", "NUMBA_NUM_THREADS"):
    os.environ.setdefault(_var, "1")

import numpy as np  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from benchmarks import flexible_observatory as FO  # noqa: E402
from benchmarks.flexible_scaling import beam_deck  # noqa: E402
from shell.cli import main as cli  # noqa: E402
from shell.integrators.exponential import PHI_AT_ZERO, ExponentialRK4  # noqa: E402
from shell.integrators.registry import register_integrator  # noqa: E402


class _LowerOrder(ExponentialRK4):
    """etdrk4's linear part, driven rows and checks; a step of fewer stages with dense numpy products (a prototype:
    the Python loop, no compiled stepper)."""

    compiled_stepping = None

    def _set_linear_part(self, t, y):
        super()._set_linear_part(t, y)
        self.phi_nominal = self.part.real_functions(self.h)

    def _begin(self):
        """(t, h) of this step, the matrix functions at h (recomputed for a shortened step), the drift check."""
        remaining = self.t_bound - self.t
        h = remaining if remaining <= self.h * (1.0 + 1e-9) else self.h
        self.phi = self.phi_nominal if abs(h - self.h) <= 1e-12 * self.h else self.part.real_functions(h)
        if callable(self.linear_part_option):
            self._check_drift(self.t, self.y, force=False)
        return self.t, h

    def _phi(self, f, v):
        """phi of FUNCTIONS[f] times v: the matrix on the linear components, phi_k(0) = 1/k! elsewhere."""
        out = v * PHI_AT_ZERO[f]
        out[self.part.indices] = self.phi[f] @ v[self.part.indices]
        return out

    def _N(self, t, y):
        f = np.asarray(self.fun(t, y), dtype=np.float64)
        self.nfev += 1
        out = np.empty_like(f)
        self._remainder(f, y, out)
        return out

    def _end(self, t, h, y_new):
        if self.normalize is not None:
            self.normalize(y_new)
        self.t_old, self.y_old, self.f_old = t, self.y, self._f
        self.t = self.t_bound if self.t_bound - t <= h * (1.0 + 1e-9) else t + h
        self.y, self._f = y_new, None
        return True


class ETD2RK(_LowerOrder):
    name = "etd2rk_study"
    order = 2

    def _step_impl(self):
        t, h = self._begin()
        y, F = self.y, self.f
        N1 = np.empty_like(F)
        self._remainder(F, y, N1)
        Y2 = y + h * self._phi(4, F)
        N2 = self._N(t + h, Y2)
        return self._end(t, h, Y2 + h * self._phi(5, N2 - N1))


class ETD3RK(_LowerOrder):
    name = "etd3rk_study"
    order = 3

    def _step_impl(self):
        t, h = self._begin()
        y, F = self.y, self.f
        N1 = np.empty_like(F)
        self._remainder(F, y, N1)
        a = y + 0.5 * h * self._phi(1, F)
        Na = self._N(t + 0.5 * h, a)
        base = y + h * self._phi(4, F)
        Nb = self._N(t + h, base + 2.0 * h * self._phi(4, Na - N1))
        return self._end(t, h, base + h * self._phi(5, -3.0 * N1 + 4.0 * Na - Nb)
                         + 4.0 * h * self._phi(6, N1 - 2.0 * Na + Nb))


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--duration", type=float, default=1.0)
    ap.add_argument("--unbalanced", action="store_true")
    args = ap.parse_args()
    register_integrator(ETD2RK)
    register_integrator(ETD3RK)
    runs = {}
    with tempfile.TemporaryDirectory() as tmp:
        (Path(tmp) / "beam.dat").write_text(beam_deck())
        assert cli(["fem2modal", str(Path(tmp) / "beam.dat"), "--modes", "196", "--modal-integrals", "-q",
                    "-o", str(Path(tmp) / "beam.h5")]) == 0
        for method, step in (("rk4", 5e-5), ("etdrk4", 2.5e-4), ("etdrk4", 1e-3), (ETD3RK.name, 1e-3),
                             (ETD2RK.name, 1e-3), (ETD2RK.name, 5e-4)):
            sim = FO.build(tmp, FO.scene("beam.h5", 1, method, step, args.duration, log_rate=1000,
                                         unbalanced=args.unbalanced), "study.yaml")
            c0 = time.process_time()
            runs[(method, step)] = FO.series(sim, args.duration)
            steps = sim.counters["steps"]
            part = getattr(sim._integrator, "part", None)
            setup = part.m + 1 if part is not None else 0  # the driven rows' forward differences, once
            print(f"{method} {step * 1e3:g} ms: {(sim.counters['nfev'] - setup) / steps:.2f} "
                  f"derivative evaluations per step, {time.process_time() - c0:.1f} CPU s", flush=True)
    for reference in (("rk4", 5e-5), ("etdrk4", 2.5e-4)):
        r_rate, r_att = runs[reference]
        for key, (rate, att) in runs.items():
            if key != reference:
                print(f"against {reference[0]} {reference[1] * 1e3:g} ms: {key[0]} {key[1] * 1e3:g} ms, IMU rate "
                      f"{np.abs(rate - r_rate).max() / np.abs(r_rate).max():.2e}, attitude "
                      f"{np.abs(att - r_att).max() / np.abs(r_att).max():.2e} of their peaks "
                      f"({np.abs(r_rate).max():.3e} rad/s, {np.abs(r_att).max():.3e} rad)", flush=True)


if __name__ == "__main__":
    main()

"""Stability study: how large a step each integrator can take on a flexible structure.

Part 1 - explicit stability limit. For the free-free beam's modal model
(shell.integrators.reference_problems.FreeFreeBeamModes, 0.5 % modal damping) truncated at a highest
retained frequency f_max, the largest stable fixed step of every explicit method is found by bisection
(a run of 4000 steps, 40000 for Euler and Heun, is stable when the energy of the highest mode has not
grown; the exact solution decays) and compared with linear
stability theory: ``h_max = r(zeta) / omega_max`` where ``r`` is the distance from the origin to the boundary
of the method's stability region along the ray of ``lambda = omega (-zeta + i sqrt(1 - zeta^2))``
(shell.integrators.stability; HW II Sec. IV.2). Each method is also run at 0.98 and 1.02 of its theoretical
limit to show it stable below and failing above, as theory says it must.

Part 2 - the implicit method. Radau IIA 5 with its step controller disabled (to isolate stability from
accuracy) runs the 100 Hz beam at steps up to 10^4 times 1/omega_max: the modal energy decays (L-stability)
instead of growing.

Part 3 - what this means for adaptive runs. The beam (modes up to f_max) is driven at its tip by a slow
sinusoidal force (0.05 Hz), so the high modes follow quasi-statically and carry no dynamics of interest.
At rtol = 1e-6, atol = 1e-7 (modal coordinates; the start-up ringing of the high modes is below it) the
explicit pairs need a number of steps proportional to f_max (their step is pinned at the stability limit),
Radau IIA 5 does not. Errors are measured against the closed-form forced response.

Outputs: docs/integrators_stability_limit.png, docs/integrators_stiff_steps.png and markdown tables on
stdout (copied into docs/integrators.md).

    python3 benchmarks/stability_study.py
"""
import pathlib
import time
import warnings

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

from shell.integrators import INTEGRATORS, Radau5, StiffnessWarning, integrate  # noqa: E402
from shell.integrators import stability  # noqa: E402
from shell.integrators.reference_problems import FreeFreeBeamModes, TipForcedBeam  # noqa: E402

ROOT = pathlib.Path(__file__).resolve().parents[1]
DOCS = ROOT / "docs"
ZETA = 0.005
EXPLICIT = ["euler", "heun", "rk4", "rk8"]
COLORS = {"euler": "tab:gray", "heun": "tab:brown", "rk4": "tab:blue", "rk8": "tab:purple", "bs32": "tab:olive",
          "dopri5": "tab:green", "dop853": "tab:red", "radau5": "tab:orange"}
# steps per stability run and bisection resolution (fraction of the theoretical limit): Euler's and Heun's
# stability boundaries meet the lightly damped ray almost tangentially, so the growth per step just past the
# limit is ~1e-7 and needs long runs to show above the within-period wobble of the modal energy
N_STEPS = {"euler": 40000, "heun": 40000, "rk4": 4000, "rk8": 4000}
RESOLUTION = {"euler": 1e-2, "heun": 1e-2, "rk4": 1e-3, "rk8": 1e-3}


class FixedStepRadau5(Radau5):
    """Radau IIA 5 with step control disabled: every step has the size given as ``step``."""

    def _error_norm(self, err, y_new):
        return 0.5

    def _accepted_step_factor(self, h, error_norm, safety, recompute_jac):
        return 1.0


def modal_energy(beam, y, modes):
    n = beam.n_modes
    eta, eta_dot = y[modes], y[n + modes]
    return 0.5 * float(np.sum(eta_dot ** 2 + beam.stiffness[modes] * eta ** 2))


def energy_ratio(method, beam, h, n_steps=None, top_mode_only=True, **options):
    """Energy after n_steps / initial energy, of the highest mode (which sets the explicit limit; the exact
    solution decays, so a ratio above 1 is numerical instability) or of all elastic modes; inf on blow-up."""
    modes = np.array([beam.n_modes - 1]) if top_mode_only else np.arange(2, beam.n_modes)
    n_steps = N_STEPS[method] if n_steps is None else n_steps
    r = integrate(method, beam.fun, 0.0, beam.y0, n_steps * h, step=h, **options)
    if r.status != "finished" or not np.all(np.isfinite(r.y[:, -1])):
        return np.inf
    return modal_energy(beam, r.y[:, -1], modes) / modal_energy(beam, beam.y0, modes)


def largest_stable_step(method, beam, h_theory):
    """Bisection on [0.5, 1.5] h_theory for the stable/unstable boundary (resolution RESOLUTION[method])."""
    lo, hi = 0.5 * h_theory, 1.5 * h_theory
    if energy_ratio(method, beam, lo) > 1.0:
        lo = 0.0
    if energy_ratio(method, beam, hi) <= 1.0:
        return hi
    while hi - lo > RESOLUTION[method] * h_theory:
        mid = 0.5 * (lo + hi)
        if energy_ratio(method, beam, mid) <= 1.0:
            lo = mid
        else:
            hi = mid
    return lo


def part1(f_max_values):
    rows = []
    measured = {m: [] for m in EXPLICIT}
    theory = {m: [] for m in EXPLICIT}
    for f_max in f_max_values:
        beam = FreeFreeBeamModes(f_max=f_max, zeta=ZETA)
        omega_max = beam.omega[-1]
        for method in EXPLICIT:
            tb = INTEGRATORS[method].tableau
            h_th = stability.max_stable_step(tb, omega_max, ZETA)
            h_me = largest_stable_step(method, beam, h_th)
            below = energy_ratio(method, beam, 0.98 * h_th)
            above = energy_ratio(method, beam, 1.02 * h_th)
            theory[method].append(h_th)
            measured[method].append(h_me)
            rows.append((f_max, omega_max / (2 * np.pi), method, h_th, h_me, below, above))
    return rows, measured, theory


def part2(f_max=100.0, factors=(1, 10, 100, 1000, 10000)):
    beam = FreeFreeBeamModes(f_max=f_max, zeta=ZETA)
    omega_max = beam.omega[-1]
    rows = []
    for factor in factors:
        h = factor / omega_max
        ratio = energy_ratio(FixedStepRadau5, beam, h, n_steps=400, top_mode_only=False, rtol=1e-9, atol=1e-12,
                             max_step=h, jac=beam.jacobian())
        rows.append((factor, h, ratio))
    return omega_max, rows


def part3(f_max_values, t_end=10.0, rtol=1e-6, atol=1e-7):
    rows = []
    for f_max in f_max_values:
        problem = TipForcedBeam(f_max, zeta=ZETA)
        y_ref = problem.exact(t_end)
        for method in ["bs32", "dopri5", "dop853", "radau5"]:
            options = {"jac": problem.beam.jacobian()} if method == "radau5" else {}
            t0 = time.process_time()  # CPU time: robust on a shared machine, the solvers are single-threaded
            r = integrate(method, problem.fun, 0.0, problem.y0, t_end, rtol=rtol, atol=atol, **options)
            cpu_time = time.process_time() - t0
            err = np.linalg.norm(r.y[:, -1] - y_ref) / np.linalg.norm(y_ref)
            rows.append((f_max, problem.beam.omega[-1] / (2 * np.pi), method, r.nsteps, r.nfev, cpu_time, err))
    return rows


def plot_limits(rows, measured, theory, radau_rows, omega_max_radau):
    fig, ax = plt.subplots(figsize=(8.5, 5.5))
    f = np.array([r[1] for r in rows if r[2] == EXPLICIT[0]])  # highest retained mode of each model (Hz)
    for method in EXPLICIT:
        ax.loglog(f, theory[method], "-", color=COLORS[method], label=f"{method}: theory r/omega_max")
        ax.loglog(f, measured[method], "o", color=COLORS[method], mfc="none", ms=8, label=f"{method}: measured")
    stable = [h for factor, h, ratio in radau_rows if ratio <= 1.0]
    ax.loglog(np.full(len(stable), omega_max_radau / (2 * np.pi)), stable, "^", color=COLORS["radau5"], ms=9,
              label="radau5: stable (every step tried)")
    ax.set_xlabel("highest retained modal frequency (Hz)")
    ax.set_ylabel("largest stable step (s)")
    ax.set_title(f"Explicit stability limit vs highest mode (modal damping {ZETA * 100:.1f} %)", fontsize=10)
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(fontsize=7, ncol=2)
    fig.tight_layout()
    path = DOCS / "integrators_stability_limit.png"
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path


def plot_stiff_steps(rows):
    fig, axes = plt.subplots(1, 2, figsize=(12, 4.8))
    for method in ["bs32", "dopri5", "dop853", "radau5"]:
        sel = [r for r in rows if r[2] == method]
        f = [r[1] for r in sel]
        axes[0].loglog(f, [r[3] for r in sel], "o-", color=COLORS[method], label=method)
        axes[1].loglog(f, [r[5] for r in sel], "o-", color=COLORS[method], label=method)
    axes[0].set_ylabel("accepted steps (10 s)")
    axes[1].set_ylabel("CPU time (s)")
    for ax in axes:
        ax.set_xlabel("highest retained modal frequency (Hz)")
        ax.grid(True, which="both", alpha=0.3)
        ax.legend(fontsize=8)
    fig.suptitle("Beam driven at the tip by a 0.05 Hz force (high modes quasi-static), rtol 1e-6, atol 1e-7",
                 fontsize=10)
    fig.tight_layout()
    path = DOCS / "integrators_stiff_steps.png"
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path


def main():
    DOCS.mkdir(exist_ok=True)
    warnings.simplefilter("ignore", RuntimeWarning)  # runs beyond the stability limit overflow on purpose
    warnings.simplefilter("ignore", StiffnessWarning)
    f_max_values = [10.0, 30.0, 100.0, 300.0]
    rows, measured, theory = part1(f_max_values)
    print("### Largest stable fixed step: measured against linear stability theory\n")
    print("| f_max (Hz) | highest mode (Hz) | method | theory h_max (s) | measured h_max (s) | measured/theory |"
          " energy ratio at 0.98 h_th | at 1.02 h_th |")
    print("| --- | --- | --- | --- | --- | --- | --- | --- |")
    for f_max, f_top, method, h_th, h_me, below, above in rows:
        print(f"| {f_max:g} | {f_top:.1f} | {method} | {h_th:.4g} | {h_me:.4g} | {h_me / h_th:.3f} | "
              f"{below:.3g} | {above:.3g} |")
    print("\n| method | stability radius r along the zeta = 0.5 % ray | undamped (imaginary axis) | real axis |")
    print("| --- | --- | --- | --- |")
    for method in EXPLICIT + ["bs32", "dopri5", "dop853"]:
        tb = INTEGRATORS[method].tableau
        print(f"| {method} | {stability.stability_radius(tb, stability.mode_angle(ZETA)):.4g} | "
              f"{stability.stability_radius(tb, np.pi / 2):.4g} | {stability.stability_radius(tb, np.pi):.4g} |")
    omega_max, radau_rows = part2()
    print(f"\n### Radau IIA 5 at fixed steps beyond the explicit limit (beam up to "
          f"{omega_max / 2 / np.pi:.1f} Hz, 400 steps)\n")
    print("| h * omega_max | step (s) | elastic modal energy ratio (end / start) |")
    print("| --- | --- | --- |")
    for factor, h, ratio in radau_rows:
        print(f"| {factor:g} | {h:.3g} | {ratio:.3g} |")
    stiff_rows = part3([10.0, 30.0, 100.0, 300.0, 1000.0])
    print("\n### Adaptive runs on the tip-forced beam (10 s, rtol 1e-6, atol 1e-7)\n")
    print("| f_max (Hz) | highest mode (Hz) | method | steps | derivative evals | CPU (s) | rel. error |")
    print("| --- | --- | --- | --- | --- | --- | --- |")
    for f_max, f_top, method, steps, nfev, cpu_time, err in stiff_rows:
        print(f"| {f_max:g} | {f_top:.1f} | {method} | {steps} | {nfev} | {cpu_time:.3f} | {err:.2e} |")
    print(f"\ncharts: {plot_limits(rows, measured, theory, radau_rows, omega_max).relative_to(ROOT)}, "
          f"{plot_stiff_steps(stiff_rows).relative_to(ROOT)}")


if __name__ == "__main__":
    main()

"""Work-precision study of flexshell's integrators (and scipy.integrate.solve_ivp in the same run).

For each scene, every method is run over a sweep of steps (fixed-step methods) or tolerances (adaptive
and implicit methods); the final-state relative error ``||y - y_ref|| / ||y_ref||`` is plotted against
CPU time and against derivative evaluations. Scenes:

(a) rigid spinning body: torque-free asymmetric body (Euler's equations), 100 s; reference = the
    Jacobi-elliptic closed form (shell.integrators.reference_problems.TorqueFreeRigidBody).
(b) free-free flexible beam: two rigid-body and 16 elastic modes up to 92.7 Hz (Euler-Bernoulli closed-form
    frequencies, 0.5 % modal damping), 1 s; reference = the closed-form modal response.
(c) closed-loop scene through shell.Simulation: a 500 kg bus on the engine's free hinge with two 20 kg
    solar panels on spring-loaded revolute hinges (appendage mode ~3.5 Hz) and the PD attitude controller of
    configs/demo_attitude_hold.yaml sampled at 10 Hz (every run restarts the integrator 10 times per
    second), 20 s; reference = DOP853 at rtol 1e-13 (no closed form; scipy cannot drive the sampled loop).

Each point is the best of ``--repeat`` timings (default 2) of the process CPU time (robust on a shared
machine; the solvers are single-threaded). Charts go to docs/integrators_wp_<scene>.png;
tables (markdown) go to stdout, including the CPU-time ratio against scipy's RK45 / DOP853 / Radau at the
same tolerance (same problem, same process).

    python3 benchmarks/work_precision.py            # all scenes (~5 min on one core)
    python3 benchmarks/work_precision.py --quick    # fewer points
"""
import argparse
import pathlib
import sys
import time
import warnings

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
from scipy.integrate import solve_ivp  # noqa: E402

from shell.integrators import StiffnessWarning, integrate  # noqa: E402
from shell.integrators.reference_problems import FreeFreeBeamModes, TorqueFreeRigidBody  # noqa: E402

ROOT = pathlib.Path(__file__).resolve().parents[1]
DOCS = ROOT / "docs"

FIXED = ["euler", "heun", "rk4", "rk8"]
ADAPTIVE = ["bs32", "dopri5", "dop853", "radau5"]
SCIPY_PEER = {"dopri5": "RK45", "dop853": "DOP853", "radau5": "Radau"}
# step * omega_max for the fixed-step sweeps (coarse to fine)
KAPPA = {"euler": [1e-2, 3e-3, 1e-3, 3e-4], "heun": [0.3, 0.1, 0.03, 0.01, 0.003],
         "rk4": [2.0, 1.0, 0.5, 0.25, 0.1, 0.05, 0.025], "rk8": [5.0, 3.0, 2.0, 1.0, 0.5, 0.25]}
RTOL = {"bs32": [1e-3, 1e-4, 1e-5, 1e-6, 1e-7, 1e-8], "dopri5": [1e-3, 1e-4, 1e-5, 1e-6, 1e-7, 1e-8, 1e-9, 1e-10],
        "dop853": [1e-3, 1e-5, 1e-7, 1e-9, 1e-11, 1e-12], "radau5": [1e-3, 1e-4, 1e-5, 1e-6, 1e-7, 1e-8, 1e-9]}
MAX_STEPS = 400_000  # skip fixed-step points that would take longer than this
STYLE = {"euler": ("tab:gray", "s"), "heun": ("tab:brown", "s"), "rk4": ("tab:blue", "s"), "rk8": ("tab:purple", "s"),
         "bs32": ("tab:olive", "o"), "dopri5": ("tab:green", "o"), "dop853": ("tab:red", "o"),
         "radau5": ("tab:orange", "^")}


def relative_error(y, y_ref):
    return float(np.linalg.norm(y - y_ref) / np.linalg.norm(y_ref))


def timed(run, repeat):
    """Best CPU time of this process over ``repeat`` runs: on a shared machine wall time also counts other
    jobs' work, CPU time does not (every solver here is single-threaded)."""
    best = np.inf
    result = None
    for _ in range(repeat):
        t0 = time.process_time()
        result = run()
        best = min(best, time.process_time() - t0)
    return best, result


class OdeScene:
    """A plain ODE scene with a closed-form reference final state."""

    def __init__(self, name, title, fun, y0, t_end, y_ref, omega_max, atol_scale, jac=None):
        self.name, self.title = name, title
        self.fun, self.y0, self.t_end, self.y_ref = fun, y0, t_end, y_ref
        self.omega_max, self.atol_scale, self.jac = omega_max, atol_scale, jac

    def run_ours(self, method, *, step=None, rtol=None):
        options = {"step": step} if step is not None else {"rtol": rtol, "atol": rtol * self.atol_scale}
        if method == "radau5" and self.jac is not None:
            options["jac"] = self.jac
        r = integrate(method, self.fun, 0.0, self.y0, self.t_end, **options)
        if r.status != "finished":
            return None
        return r.y[:, -1], r.nfev, r.nsteps

    def run_scipy(self, method, rtol):
        options = {"jac": self.jac} if (method == "Radau" and self.jac is not None) else {}
        r = solve_ivp(self.fun, (0.0, self.t_end), self.y0, method=method, rtol=rtol, atol=rtol * self.atol_scale,
                      **options)
        if r.status != 0:
            return None
        # scipy's nfev leaves out the evaluations spent on finite-difference Jacobians; add them back
        nfev = r.nfev + (r.njev * self.y0.size if (method == "Radau" and self.jac is None) else 0)
        return r.y[:, -1], nfev, r.t.size - 1


CLOSED_LOOP_SCENE = """\
name: wp_bus_with_panels
description: rigid bus with two hinged solar panels (torsional springs, ~3.5 Hz) under a 10 Hz PD attitude controller
multibody:
  gravity: "[0, 0, 0] m/s^2"
  bodies:
    - name: bus
      parent: world
      hinge: free
      mass: 500 kg
      inertia: "[[400, 5, 0], [5, 300, 0], [0, 0, 250]] kg*m^2"
      initial:
        attitude: [0.984807753012208, 0.10025582212029019, 0.10025582212029019, 0.10025582212029019]
        angular_velocity: "[2, -1, 3] deg/s"
    - name: panel_left
      parent: bus
      hinge: revolute
      axis: [1, 0, 0]
      inboard_position: "[0, 1.0, 0] m"
      mass: 20 kg
      com: "[0, 1.5, 0] m"
      inertia: "[15, 1, 15] kg*m^2"
      initial: {angle: "2 deg"}
    - name: panel_right
      parent: bus
      hinge: revolute
      axis: [1, 0, 0]
      inboard_position: "[0, -1.0, 0] m"
      mass: 20 kg
      com: "[0, -1.5, 0] m"
      inertia: "[15, 1, 15] kg*m^2"
      initial: {angle: "-1 deg"}
  nodes:
    - {name: acs, body: bus, position: "[0, 0, 0] m"}
models:
  controller:
    type: PdAttitudeController
    rate: 10 Hz
    attach: {node: acs}
    parameters:
      kp: "[10, 7.5, 6.25] N*m/rad"
      kd: "[90, 67.5, 56] N*m*s/rad"
      attitude_command: [1, 0, 0, 0]
  spring_left:
    type: Gain
    config: {unit: rad, output_unit: "N*m", shape: [1]}
    parameters: {k: "-60000 N*m/rad"}
  spring_right:
    type: Gain
    config: {unit: rad, output_unit: "N*m", shape: [1]}
    parameters: {k: "-60000 N*m/rad"}
connections:
  - multibody.panel_left.q -> spring_left.u
  - spring_left.y -> multibody.panel_left.torque
  - multibody.panel_right.q -> spring_right.u
  - spring_right.y -> multibody.panel_right.torque
"""


class ClosedLoopScene:
    """A closed-loop scene run through shell.Simulation (scenario text above, parsed like a YAML file)."""

    name = "closed_loop"
    title = ("(c) closed loop (shell.Simulation): bus on a free hinge + two spring-hinged panels (~3.5 Hz), "
             "PD controller at 10 Hz, 20 s")
    omega_max = 2 * np.pi * 3.5
    jac = None

    def __init__(self, t_end=20.0):
        self.t_end = t_end
        self.y_ref = self._simulate("dop853", None, {"rtol": 1e-13, "atol": 1e-15})[0]

    def _simulate(self, method, step, options):
        from shell.scenario import build_simulation, parse_scenario

        scenario = parse_scenario(CLOSED_LOOP_SCENE, "work_precision_closed_loop.yaml")
        scenario.integrator = method
        scenario.step = step
        scenario.integrator_options = dict(options)
        sim = build_simulation(scenario)
        summary = sim.run(self.t_end)
        return sim.x.copy(), summary.derivative_evaluations, summary.steps

    def run_ours(self, method, *, step=None, rtol=None):
        options = {} if step is not None else {"rtol": rtol, "atol": rtol * 1e-3}
        try:
            return self._simulate(method, step, options)
        except RuntimeError:
            return None

    def run_scipy(self, method, rtol):
        return None


def ode_scenes():
    body = TorqueFreeRigidBody((100.0, 200.0, 300.0), (0.3, -0.5, 1.0))
    beam = FreeFreeBeamModes(f_max=100.0)
    return [
        OdeScene("rigid_body", "(a) rigid spinning body: torque-free asymmetric body, 100 s (closed form)",
                 body.euler_equations(), np.array([0.3, -0.5, 1.0]), 100.0, body.omega(100.0), 1.0, 1e-3),
        OdeScene("beam", f"(b) free-free beam: 2 rigid + {beam.n_modes - 2} elastic modes up to "
                 f"{beam.omega[-1] / 2 / np.pi:.1f} Hz, zeta 0.5 %, 1 s (closed form)",
                 beam.fun, beam.y0, 1.0, beam.exact(1.0), beam.omega[-1], 1e-6, jac=beam.jacobian()),
    ]


def sweep(scene, repeat, quick):
    """Run every method over its sweep; returns {label: [(error, cpu_time, nfev, setting), ...]}."""
    results = {}
    for method in FIXED:
        kappas = KAPPA[method][::2] if quick else KAPPA[method]
        points = []
        for kappa in kappas:
            h = kappa / scene.omega_max
            if scene.t_end / h > MAX_STEPS:
                continue
            cpu_time, out = timed(lambda: scene.run_ours(method, step=h), repeat)
            if out is None or not np.all(np.isfinite(out[0])) or relative_error(out[0], scene.y_ref) > 1.0:
                print(f"  {method:7s} step {h:9.3g} s: unstable / failed")
                continue
            points.append((relative_error(out[0], scene.y_ref), cpu_time, out[1], h))
        results[method] = points
    for method in ADAPTIVE:
        tols = RTOL[method][::2] if quick else RTOL[method]
        points, peer_points = [], []
        for rtol in tols:
            cpu_time, out = timed(lambda: scene.run_ours(method, rtol=rtol), repeat)
            if out is not None:
                points.append((relative_error(out[0], scene.y_ref), cpu_time, out[1], rtol))
            peer = SCIPY_PEER.get(method)
            if peer is not None:
                cpu_p, out_p = timed(lambda: scene.run_scipy(peer, rtol), repeat)
                if out_p is not None:
                    peer_points.append((relative_error(out_p[0], scene.y_ref), cpu_p, out_p[1], rtol))
        results[method] = points
        if peer_points:
            results["scipy " + SCIPY_PEER[method]] = peer_points
    return results


def plot(scene, results):
    fig, axes = plt.subplots(1, 2, figsize=(13, 5.2), sharey=True)
    for label, points in results.items():
        if not points:
            continue
        err = np.array([p[0] for p in points])
        cpu_time = np.array([p[1] for p in points])
        nfev = np.array([p[2] for p in points])
        if label.startswith("scipy"):
            ours = next(m for m, s in SCIPY_PEER.items() if "scipy " + s == label)
            color, marker = STYLE[ours][0], "x"
            kw = dict(ls="--", lw=1.0, alpha=0.8)
        else:
            color, marker = STYLE[label]
            kw = dict(ls="-", lw=1.6)
        axes[0].loglog(cpu_time, err, marker=marker, color=color, label=label, **kw)
        axes[1].loglog(nfev, err, marker=marker, color=color, label=label, **kw)
    axes[0].set_xlabel("CPU time (s)")
    axes[1].set_xlabel("derivative evaluations")
    axes[0].set_ylabel("final-state relative error")
    for ax in axes:
        ax.grid(True, which="both", alpha=0.3)
    axes[1].legend(fontsize=8, ncol=2, loc="lower left")
    fig.suptitle(scene.title, fontsize=10)
    fig.tight_layout()
    path = DOCS / f"integrators_wp_{scene.name}.png"
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path


def print_tables(scene, results):
    print(f"\n### {scene.title}\n")
    print("| method | setting | rel. error | CPU (ms) | derivative evals |")
    print("| --- | --- | --- | --- | --- |")
    for label, points in results.items():
        for err, cpu_time, nfev, setting in points:
            kind = "step" if label in FIXED else "rtol"
            print(f"| {label} | {kind} {setting:.3g} | {err:.2e} | {cpu_time * 1e3:.1f} | {nfev} |")
    ratios = []
    for ours, peer in SCIPY_PEER.items():
        a = {p[3]: p for p in results.get(ours, [])}
        b = {p[3]: p for p in results.get("scipy " + peer, [])}
        for rtol in sorted(set(a) & set(b)):
            ratios.append((ours, peer, rtol, b[rtol][1] / a[rtol][1], a[rtol][0], b[rtol][0]))
    if ratios:
        print("\nSpeed against solve_ivp (same rtol/atol, same process): CPU(scipy) / CPU(flexshell)\n")
        print("| flexshell | scipy | rtol | speed-up | error flexshell | error scipy |")
        print("| --- | --- | --- | --- | --- | --- |")
        for ours, peer, rtol, ratio, e_a, e_b in ratios:
            print(f"| {ours} | {peer} | {rtol:.0e} | {ratio:.2f} | {e_a:.2e} | {e_b:.2e} |")
        by_method = {}
        for ours, _, _, ratio, _, _ in ratios:
            by_method.setdefault(ours, []).append(ratio)
        summary = ", ".join(f"{m} {np.exp(np.mean(np.log(v))):.2f}x" for m, v in by_method.items())
        print(f"\nGeometric-mean speed-up: {summary}")


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--quick", action="store_true", help="every other point of each sweep")
    parser.add_argument("--repeat", type=int, default=2, help="timings per point (best is kept)")
    parser.add_argument("--scenes", nargs="*", default=["rigid_body", "beam", "closed_loop"])
    args = parser.parse_args(argv)
    DOCS.mkdir(exist_ok=True)
    warnings.simplefilter("ignore", StiffnessWarning)
    warnings.simplefilter("ignore", RuntimeWarning)  # diverging explicit runs overflow on purpose
    # compile every numba kernel once before timing anything
    for scene in ode_scenes()[:1]:
        for method in FIXED + ADAPTIVE:
            integrate(method, scene.fun, 0.0, scene.y0, 0.1, step=0.01, rtol=1e-3, atol=1e-6)
    scenes = [s for s in ode_scenes() if s.name in args.scenes]
    if "closed_loop" in args.scenes:
        scenes.append(ClosedLoopScene())
    for scene in scenes:
        print(f"running {scene.name} ...", file=sys.stderr)
        results = sweep(scene, args.repeat, args.quick)
        path = plot(scene, results)
        print_tables(scene, results)
        print(f"\nchart: {path.relative_to(ROOT)}")


if __name__ == "__main__":
    main()

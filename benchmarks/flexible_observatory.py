"""The observatory-size flexible scene of issue 28, general mass: cost, accuracy and linearization at order 1.

The structure is a real deck's kind of body: a 9 m aluminium tube (100 CBAR, PARAM COUPMASS -1) with a CONM2
carrying rotary inertia on every grid (0.5 kg, I = [0.002, 0.01, 0.01] kg m^2: every grid has rotary inertia,
so its modal mass depends on the deformation at order 1), through ``flexshell fem2modal --modes 196
--modal-integrals``: 196 free-free modes, 3.56 Hz to 2.13 kHz (the scene's system modes, wheels included:
to 2.13 kHz as well). The scene (YAML, the user's path): the structure on
a free hinge, four reaction wheels as engine bodies on revolute hinges at its middle grid (a deforming node; axes
x, y, z and (1, 1, 1)/sqrt(3), spin inertia 0.1 kg m^2, transverse 0.06, 50 rad/s), an IMU on grid 30, a 10 Hz
PD attitude controller at the middle grid (bandwidth about 0.01 Hz: a rate gain at that node, whose rotation
the 196 modes resolve with a large compliance, destabilizes a loop sampled at 1 kHz once kd h sum(lambda^2)
exceeds about 2), ``etdrk4`` at 1 ms, modal-integral order 1 (the must-show; ``auto``
chooses order 0 at this scene's rates and says so), IMU noise off (the outputs are then smooth functions of the
integration).

Reported:

* cost: CPU seconds per simulated second of ``flexshell run`` (process time of ``Simulation.run``, compilation
  excluded: a first short run compiles), real-time factor = 1 / that, median of ``--repeat`` runs of
  ``--duration`` s, at orders 0, 1 and 2 and at 1 and 2 without the terms of the nodes' rotary inertia, with the
  machine's load average; for orders 0, 1, 2 where the last run's step went (:func:`profile`: the derivative
  evaluations, the integrator's linear algebra, what the two cost more for sharing the caches, the checks of its
  linear part as counted in the run, the rest: updates, log, loop; alone with ``--profile-only``); and order 1 without the
  sixteen nodes that only the linearization uses (before the engine model computed only the nodes a scene reads,
  their kinematics were about 40 % of the order-1 derivative; now what is left of their cost is this difference);
* the node mask before/after (:func:`node_mask`, first; alone with ``--nodes-only``): per order, interleaved, every
  node's kinematics computed in every evaluation (what the engine model did first), the nodes something reads
  computed in every evaluation (what it did next), and those nodes per evaluation kind (now: a derivative evaluation
  computes only the IMU's node, which the IMU's integrals read; the bus and tip nodes only at the controller's
  samples and the log's instants);
* accuracy at order 1 (:func:`accuracy`), balanced and unbalanced wheel: the IMU's rate and the controller node's
  attitude (angle from the command) over the run, etdrk4 at 1 ms and RK4 at 0.05 ms against RK4 at 6.25 us
  (:data:`REFERENCE_STEP`), largest difference relative to the peak of the reference, with the reference's own
  error (Richardson, from RK4 at 12.5 us). RK4 at 0.05 ms is not a reference here: the structure is undamped, and
  the modes above 1 kHz that the wheels' imbalance (a rotating force and torque at the middle grid, released at
  t = 0 on an undeformed structure) and the controller's first torque step excite keep ringing; at 0.05 ms
  (h |lambda| = 0.67 for the top mode) RK4's phase error on them is O(1) rad after 0.2 s (its propagator
  ``R(h lambda)^n`` against ``exp(n h lambda)``: error factors 0.29 / 0.62 / 1.2 for the modes at 1-1.25 /
  1.25-1.5 / 1.5-2.2 kHz after 0.2 s; 1.2e-3 / 2.8e-3 / 1.8e-2 at 12.5 us; 7.5e-5 / 1.8e-4 / 1.1e-3 at 6.25 us).
  Measured on 0.2 s with the unbalanced wheel (2026-12-07): successive RK4 differences at 0.1 / 0.05 / 0.025 /
  0.0125 ms of 1.25e-2 / 4.2e-3 / 2.9e-4 of the IMU rate's peak (ratios 3.0 and 14.7, what the propagators of the
  1-1.5 kHz modes predict: 1.6-4.0 and 13.8-15.2; fourth order is 16); the balanced scene has the same ratios at
  1.5e-4 / 5.4e-5 / 3.6e-6 of its peak (its modes are excited less); with 1 % modal damping the ratios are 13.8 and
  13.7 from 0.1 ms on. Against RK4 at 6.25 us: RK4 at 0.1 / 0.05 / 0.025 / 0.0125 ms 1.5e-2 / 4.5e-3 / 3.0e-4 /
  1.8e-5, etdrk4 at 1 / 0.5 / 0.25 / 0.125 ms 3.4e-3 / 3.3e-4 / 5.4e-6 / 1.3e-6 (two independent methods meeting).
  Orders 0 and 1 behave alike, the PD loop and the IMU play no part (the same without them), the products of
  inertia excite the modes more than the centre-of-mass offset (node torque against node force), and without
  torques the scene conserves energy and angular momentum at RK4's fourth order (4.1e-10 / 5.4e-14 relative at
  0.05 ms): the dynamics is smooth and consistent (tests/flexible/test_unbalanced_rotor.py), the reference was
  not converged;
* the same scene with an unbalanced wheel (products of inertia 0.005 kg m^2, centre of mass 1 mm off the axis):
  how many times the exponential integrator rebuilt its linear part (it counts ``_set_linear_part`` calls: 1 is
  the build at the start), and its cost;
* linearization: 20 inputs (the four wheels' torques and sixteen node forces along z at grids 5, 11, ..., 95)
  by 5 outputs (IMU rate, the controller node's angular velocity and attitude, the tip position, the wheels'
  rates), 4-point central differences with Richardson (``shell.analysis.linearize``), wall time.

    python3 benchmarks/flexible_observatory.py [--duration 1] [--repeat 3] [--skip-reference] [--nodes-only]
        [--profile-only] [--accuracy-only] [--reference-step 6.25e-6]
"""

from __future__ import annotations

import argparse
import contextlib
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

from benchmarks.flexible_scaling import beam_deck  # noqa: E402
from numba import njit  # noqa: E402

from shell.cli import main as cli  # noqa: E402
from shell.compiled_loop import derivative_of  # noqa: E402
from shell.integrators import exponential as EX  # noqa: E402
from shell.integrators.exponential_stepper import exponential_stepper  # noqa: E402
from shell.integrators.exponential import ExponentialRK4  # noqa: E402
from shell.log_file import MemoryLog  # noqa: E402
from shell.scenario import build_simulation, load_scenario  # noqa: E402

WHEEL_AXES = [(1.0, 0.0, 0.0), (0.0, 1.0, 0.0), (0.0, 0.0, 1.0), tuple(float(a) for a in np.ones(3) / np.sqrt(3.0))]
THRUSTER_GRIDS = list(range(5, 100, 6))[:16]
REFERENCE_STEP = 6.25e-6
"""RK4 step of the accuracy reference: the scene's top system mode is at 2.13 kHz (|lambda| h = 0.084; at 0.05 ms
it is 0.67, and RK4's phase error on the undamped top modes reaches a radian in 0.2 s: module docstring)."""
COMMAND = [float(c) for c in np.array([1.0, 5e-4, 5e-4, 0.0]) / np.linalg.norm([1.0, 5e-4, 5e-4, 0.0])]


def wheel_inertia(axis, spin=0.1, transverse=0.06):
    a = np.asarray(axis)
    return transverse * np.eye(3) + (spin - transverse) * np.outer(a, a)


def scene(body_file, order, method, step, duration, unbalanced=False, log_rate=1000, omit=(), thrusters=True):
    wheels = []
    for k, axis in enumerate(WHEEL_AXES):
        J = wheel_inertia(axis)
        com = [0.0, 0.0, 0.0]
        if unbalanced and k == 0:
            J = J + 0.005 * (np.ones((3, 3)) - np.eye(3))
            com = [0.0, 0.001, 0.0]
        wheels.append(f"    - {{name: w{k + 1}, parent: structure, parent_node: bus, hinge: revolute, "
                      f"axis: {list(axis)}, mass: 5 kg, com: '{com} m', inertia: '{J.tolist()} kg*m^2', "
                      f"initial: {{angle_rate: 50 rad/s}}}}")
    thruster_nodes = "\n".join(f"    - {{name: t{k + 1}, body: structure, grid: {g}}}"
                                for k, g in enumerate(THRUSTER_GRIDS if thrusters else ()))
    return f"""name: flexible_observatory
multibody:
  bodies:
    - name: structure
      hinge: free
      body_file: {body_file}
      modal_integrals_order: {order}
      omit_terms: {list(omit)}
      initial: {{angular_velocity: "[0.002, -0.001, 0.003] deg/s"}}
{chr(10).join(wheels)}
  nodes:
    - {{name: bus, body: structure, grid: 51}}
    - {{name: imu, body: structure, grid: 30}}
    - {{name: tip, body: structure, grid: 101}}
{thruster_nodes}
models:
  imu:
    type: Imu
    rate: 1 kHz
    attach: {{node: imu}}
  controller:
    type: PdAttitudeController
    rate: 10 Hz
    attach: {{node: bus}}
    parameters: {{kp: "[0.001, 2, 2] N*m/rad", kd: "[0.03, 40, 40] N*m*s/rad",
                  attitude_command: {COMMAND}}}
integrator: {{method: {method}, step: {step} s}}
stop: {{time: {duration} s}}
log:
  rate: {log_rate} Hz
  signals: [imu.angular_rate, multibody.bus.attitude, multibody.tip.position]
"""


def build(tmp, text, name):
    path = Path(tmp) / name
    path.write_text(text)
    return build_simulation(load_scenario(str(path)))


@contextlib.contextmanager
def timed_checks():
    """A list of the CPU seconds of each check of the exponential integrator's linear part made inside (the compiled
    loop asks ``ExponentialRK4.check_linear_part`` for them)."""
    times = []
    original = ExponentialRK4.check_linear_part

    def timed(self, t, y):
        c0 = time.process_time()
        try:
            return original(self, t, y)
        finally:
            times.append(time.process_time() - c0)

    ExponentialRK4.check_linear_part = timed
    try:
        yield times
    finally:
        ExponentialRK4.check_linear_part = original


def timed_run(sim, duration, checks=None, counts=None):
    """CPU seconds of Simulation.run for ``duration`` s after a 2 ms run (compilation, matrix functions); ``checks``
    (a :func:`timed_checks` list) keeps the checks of the timed part only, ``counts`` (a dict) receives its steps and
    derivative evaluations."""
    sim.run(2e-3)
    if checks is not None:
        checks.clear()
    steps, nfev = sim.counters["steps"], sim.counters["nfev"]
    c0 = time.process_time()
    result = sim.run(2e-3 + duration)
    cpu = time.process_time() - c0
    if counts is not None:
        counts.update(steps=sim.counters["steps"] - steps, nfev=sim.counters["nfev"] - nfev)
    return cpu, result


def order_costs(tmp, args, orders=((0, ()), (1, ()), (2, ()), (1, ("G1",)), (2, ("G1", "F2", "G2")))):
    """The cost at each order (median of ``--repeat`` runs) and, for the orders with every term, the profile of the
    last run (:func:`profile`)."""
    for order, omit in orders:
        costs = []
        counts = {}
        with timed_checks() as checks:
            for r in range(args.repeat):
                sim = build(tmp, scene("beam.h5", order, "etdrk4", 1e-3, args.duration + 0.01, omit=omit),
                            f"o{order}.yaml")
                cpu, _ = timed_run(sim, args.duration, checks, counts)
                costs.append(cpu / args.duration)
        print(f"order {order}{' without ' + ', '.join(omit) if omit else ''}: etdrk4 1 ms, {np.median(costs):.3f} "
              f"CPU s per simulated s (real-time factor {1 / np.median(costs):.2f}; runs "
              f"{', '.join(f'{c:.3f}' for c in costs)})", flush=True)
        if not omit:
            print(f"  last run, {profile(sim, cpu, args.duration, checks, counts['steps'], counts['nfev'])}",
                  flush=True)


@njit(cache=True)
def step_work(k, b, st, t, y, reps, evaluate, algebra):
    """``reps`` times the work of a nominal step's four stages without its logic, compiled (no Python between the
    kernels, as in the loop): with ``evaluate`` the derivative at (t, y), with ``algebra`` the remainder and the stage
    product (exponential.remainder and exponential.stage_real on the stepper's arrays, as ExponentialStepper's step)."""
    for _ in range(reps):
        for j in range(4):
            if evaluate:
                derivative_of(k, t, y, b)
            if algebra:
                EX.remainder(st.F, y if j == 0 else st.S[j - 1], st.nonzero_components, st.L_other,
                             st.other_components, st.copy_components, st.copied_components, st.y_lin, st.product,
                             st.N[j])
                n = st.stage_terms[j]
                base = y if st.stage_base[j] < 0 else st.S[st.stage_base[j]]
                EX.stage_real(st.Phi[j], st.Phi_copies, st.phi_at_zero, st.stage_functions[j, :n],
                              st.stage_coefficients[j, :n], st.F, st.N, st.h, base, st.indices,
                              st.dense_other_components, st.dense_copy_components, st.zero_components, st.is_linear,
                              st.S[j], st.W[:n], st.w_stack, st.w_copies, st.product)


def profile(sim, cpu, duration, checks, steps, nfev, reps=50, rounds=7):
    """Where a nominal 1 ms step of the last timed run went, as a table (after the run, at its final state): the
    derivative evaluations (how many per step, timed alone), the integrator's linear algebra (the four remainders and
    four stage products; the matrix entries they read per step in units of m^2), what the two cost more when they
    alternate as in a step (each evicts the other's data from the caches), all three from :func:`step_work`
    (medians of ``rounds`` of ``reps`` steps), the checks of the linear part (counted and timed in the run) and the
    rest (the models' updates, the log, the loop)."""
    integ = sim._integrator
    st = exponential_stepper(integ)
    k, b = sim.plan.kernels, sim.plan.buffers
    y = st.Y.copy()

    def timed(evaluate, algebra):
        step_work(k, b, st, integ.t, y, 1, evaluate, algebra)
        samples = []
        for _ in range(rounds):
            c0 = time.process_time()
            step_work(k, b, st, integ.t, y, reps, evaluate, algebra)
            samples.append((time.process_time() - c0) / reps)
        return float(np.median(samples))

    per_step = cpu / steps
    derivatives, kernels = timed(True, False), timed(False, True)
    caches = timed(True, True) - derivatives - kernels
    part = integ.part
    # the copy columns are read for the terms on the slope F (stages 2 and 4), every other column once per term
    read = (sum(P.size for P in integ.Phi_other) + 2 * integ.Phi_copies[0].size + 4 * part.L_other.size) / part.m ** 2
    check = float(np.median(checks)) if checks else 0.0
    rows = [("derivative evaluations", f"{nfev / steps:.2f} x {1e6 * derivatives / 4:.0f} us",
             nfev / steps * derivatives / 4),
            ("linear algebra (4 remainders, 4 stage products)", f"{read:.1f} m^2 entries read", kernels),
            ("the two alternating, less each alone (caches)", "", caches),
            ("checks of the linear part", f"{len(checks)} in {duration:g} s, {1e3 * check:.1f} ms each",
             sum(checks) / steps)]
    rows.append(("the rest (updates, log, loop)", "", per_step - sum(r[2] for r in rows)))
    lines = [f"per 1 ms step {1e6 * per_step:.0f} us (m = {part.m}, load {os.getloadavg()[0]:.2f}):"]
    lines += [f"    {name:48s} {what:30s} {1e6 * cost:6.0f} us {cost / per_step:6.1%}" for name, what, cost in rows]
    return "\n".join(lines)


def series(sim, duration):
    log = MemoryLog(sim.log_groups())
    sim.run(duration, log_path=log)
    signals = log.signals()
    rate = np.asarray(signals["imu.angular_rate"][1])
    q = np.asarray(signals["multibody.bus.attitude"][1])
    w = np.abs(q @ np.array(COMMAND))
    return rate, 2.0 * np.arccos(np.clip(w, -1.0, 1.0))


def accuracy(tmp, duration, reference_step=REFERENCE_STEP):
    """Order 1, balanced and unbalanced wheel: etdrk4 at 1 ms and RK4 at 0.05 ms against RK4 at ``reference_step``
    (the converged reference, :data:`REFERENCE_STEP`), with the reference's own error estimated by Richardson from
    RK4 at twice its step (``|x_2h - x_h| / 15``: RK4 is in its asymptotic range there, the ratio of successive
    differences measured 16.6 between 25, 12.5 and 6.25 us over 0.2 s with the unbalanced wheel)."""
    for unbalanced in (False, True):
        def run(method, step):
            text = scene("beam.h5", 1, method, step, duration, unbalanced=unbalanced, log_rate=1000)
            return series(build(tmp, text, "acc.yaml"), duration)

        (r_rate, r_att), (c_rate, c_att) = run("rk4", reference_step), run("rk4", 2.0 * reference_step)
        peak_rate, peak_att = np.abs(r_rate).max(), np.abs(r_att).max()

        def error(rate, att):
            return np.abs(rate - r_rate).max() / peak_rate, np.abs(att - r_att).max() / peak_att

        name = "unbalanced wheel" if unbalanced else "balanced wheels"
        ref_rate, ref_att = error(c_rate, c_att)
        print(f"order 1, {name}, over {duration} s, against RK4 at {1e6 * reference_step:g} us (its own error "
              f"~{ref_rate / 15:.1e} / {ref_att / 15:.1e} of the IMU rate / attitude peaks, {peak_rate:.3e} rad/s / "
              f"{peak_att:.3e} rad; RK4 at {2e6 * reference_step:g} us: {ref_rate:.2e} / {ref_att:.2e}):", flush=True)
        runs = {(method, step): run(method, step) for method, step in (("etdrk4", 1e-3), ("rk4", 5e-5))}
        for (method, step), (rate, att) in runs.items():
            e_rate, e_att = error(rate, att)
            print(f"  {method} at {1e3 * step:g} ms: IMU rate {e_rate:.2e}, attitude {e_att:.2e} of their peaks",
                  flush=True)
        (e_rate, e_att), (o_rate, o_att) = runs[("etdrk4", 1e-3)], runs[("rk4", 5e-5)]
        print(f"  (the must-show's figure, etdrk4 at 1 ms against RK4 at 0.05 ms: IMU rate "
              f"{np.abs(e_rate - o_rate).max() / np.abs(o_rate).max():.2e}, attitude "
              f"{np.abs(e_att - o_att).max() / np.abs(o_att).max():.2e} of RK4's peaks)", flush=True)


def node_mask(tmp, args):
    """Before/after of computing only the nodes a scene reads (the engine model's node masks), interleaved in one
    process, per order: "every node" sets both masks to every node (what the model computed first: the kinematics of
    all 19 nodes in its outputs and after the forward dynamics, in every evaluation), "read" computes the nodes
    something reads (the IMU's, the controller's and the logged tip node; not the sixteen thruster nodes) in every
    evaluation (the derivatives' mask set to the read nodes), "per kind" leaves the masks as the diagram built them
    (the derivative evaluations compute only the IMU's node; the others at the samples and log instants)."""
    for order in (0, 1, 2):
        costs = {"every node": [], "read": [], "per kind": []}
        for r in range(args.repeat):
            for variant in costs:
                sim = build(tmp, scene("beam.h5", order, "etdrk4", 1e-3, args.duration + 0.01), f"m{order}.yaml")
                model = next(m for m in sim.models if m.path == "multibody")
                if variant == "every node":
                    model.ports.node_read[:] = 1
                if variant != "per kind":
                    model.ports.node_read_in_derivatives[:] = model.ports.node_read
                cpu, _ = timed_run(sim, args.duration)
                costs[variant].append(cpu / args.duration)
        every, read, kind = (np.median(costs[v]) for v in costs)
        print(f"order {order}, node masks: every node {every:.3f}, nodes read ({', '.join(model.nodes_read)}) "
              f"{read:.3f}, in derivatives only {', '.join(model.nodes_read_in_derivatives)} {kind:.3f} CPU s per "
              f"simulated s: {every / read:.2f}x, then {read / kind:.2f}x (real-time factor {1 / kind:.2f}; runs "
              + " / ".join(', '.join(f'{c:.3f}' for c in costs[v]) for v in costs)
              + f"; load {os.getloadavg()[0]:.2f})", flush=True)


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--duration", type=float, default=1.0)
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--skip-reference", action="store_true")
    ap.add_argument("--reference-step", type=float, default=REFERENCE_STEP,
                    help="RK4 step of the accuracy reference (s; its Richardson check runs at twice it)")
    ap.add_argument("--accuracy-only", action="store_true", help="only the accuracy against the reference")
    ap.add_argument("--profile-only", action="store_true",
                    help="only the cost at orders 0, 1, 2 and where a step goes (the profile of the last run)")
    ap.add_argument("--nodes-only", action="store_true",
                    help="only the before/after of the node masks (every node computed, the nodes read in every "
                         "evaluation, the nodes read per evaluation kind)")
    args = ap.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        (Path(tmp) / "beam.dat").write_text(beam_deck())
        assert cli(["fem2modal", str(Path(tmp) / "beam.dat"), "--modes", "196", "--modal-integrals", "-q",
                    "-o", str(Path(tmp) / "beam.h5")]) == 0
        print(f"load average {os.getloadavg()[0]:.2f}")
        if args.accuracy_only:
            accuracy(tmp, args.duration, args.reference_step)
            return
        if args.profile_only:
            order_costs(tmp, args, ((0, ()), (1, ()), (2, ())))
            return
        node_mask(tmp, args)
        if args.nodes_only:
            return
        order_costs(tmp, args)
        costs = []
        for r in range(args.repeat):  # the sixteen nodes are the linearization's inputs; the run reads none of them
            sim = build(tmp, scene("beam.h5", 1, "etdrk4", 1e-3, args.duration + 0.01, thrusters=False), "o1n.yaml")
            cpu, _ = timed_run(sim, args.duration)
            costs.append(cpu / args.duration)
        print(f"order 1 without the sixteen thruster nodes: etdrk4 1 ms, {np.median(costs):.3f} CPU s per simulated s "
              f"(real-time factor {1 / np.median(costs):.2f}; runs {', '.join(f'{c:.3f}' for c in costs)})", flush=True)
        sim = build(tmp, scene("beam.h5", "auto", "etdrk4", 1e-3, 0.01), "auto.yaml")
        print("auto: " + "; ".join(next(m for m in sim.models if m.path == "multibody").notes))
        if not args.skip_reference:
            accuracy(tmp, args.duration, args.reference_step)
        builds = []
        original = ExponentialRK4._set_linear_part

        def counting(self, *a, **k):
            builds.append(1)
            return original(self, *a, **k)

        ExponentialRK4._set_linear_part = counting
        try:
            sim = build(tmp, scene("beam.h5", 1, "etdrk4", 1e-3, args.duration + 0.01, unbalanced=True), "unb.yaml")
            cpu, _ = timed_run(sim, args.duration)
        finally:
            ExponentialRK4._set_linear_part = original
        print(f"unbalanced wheel, order 1: {len(builds)} build(s) of the linear part in {args.duration} s, "
              f"{cpu / args.duration:.3f} CPU s per simulated s", flush=True)
        from shell.analysis.linearize import linearize

        sim = build(tmp, scene("beam.h5", 1, "etdrk4", 1e-3, 0.01), "lin.yaml")
        inputs = [f"multibody.w{k + 1}.torque" for k in range(4)] + [f"multibody.t{k + 1}.force[2]" for k in range(16)]
        outputs = ["imu.angular_rate", "multibody.bus.angular_velocity", "multibody.bus.attitude",
                   "multibody.tip.position", "multibody.u"]
        linearize(sim, inputs[:1], outputs[:1])  # compiles what the evaluations need
        t0 = time.perf_counter()
        model = linearize(sim, inputs, outputs)
        print(f"linearization 20 x 5 at order 1: {time.perf_counter() - t0:.2f} s wall, A {model.A.shape}, "
              f"load average {os.getloadavg()[0]:.2f}", flush=True)


if __name__ == "__main__":
    main()

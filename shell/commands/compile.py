"""``flexshell compile``: compile now what a first ``flexshell run`` would compile, with a progress bar.

numba compiles flexshell's kernels on their first use and keeps them in the on-disk cache
(:mod:`dynamics.compile_cache`); a first run therefore waits for the compilation of what its scene needs. This verb
compiles the common set instead, once, for users who want every first run to start at once: the simulation loop for
each integrator family (fixed-step Runge-Kutta, the exponential ``etdrk4``, the adaptive embedded methods and
``radau5``, each through a two-step run of a small scene), the multibody engine's kernel, and the kernels of every
registered model. Whatever is cached already loads in milliseconds, so running it again costs seconds.

:func:`describe` names what a compilation is part of (the engine, the loop, a model's kernels) and how long such a
compilation took here on an empty cache: ``flexshell run``'s compile notice and this verb's progress say it.
"""

from __future__ import annotations

import sys
import time
import warnings

#: seconds each part takes to compile on an empty cache, one core of this 2-core machine without other load: the
#: engine per solver path (the single-body kernel 6 s in the demo, benchmarks/compile_time.py --profile,
#: 2026-11-28 at load 3; the articulated-body and dense paths from the 2026-11-27 profile of the whole engine, 424 s
#: of 505 s compiling at load 7.7, scaled to the 106 s the demo then compiled on a quiet machine), the loop of one
#: stepper family (~15 s CPU in the 2026-11-28 02:20 profile at load 4: one loop per stepper for every scene, the
#: evaluation compiled once and called by reference; 40 s when it was inlined into the stepper); model kernels 1-3 s
#: each. The constrained path (a scene with closure constraints; not in the common set `flexshell compile`
#: compiles): the first run of configs/four_bar.yaml compiled engine and loop in 104 s at load 2 (2026-11-28), ~40 s
#: of it the loop, which such scenes now share with the others
ENGINE_SECONDS = {"single_body": 10, "articulated": 60, "dense": 60, "constrained": 70}
LOOP_SECONDS = 20
MODEL_SECONDS = 3

#: a model's numba kernels (the two ``*_for_derivatives`` are optional, :mod:`shell.model`; compiled where present)
_MODEL_KERNELS = ("state_outputs", "feedthrough_outputs", "state_outputs_for_derivatives",
                  "feedthrough_outputs_for_derivatives", "derivatives", "zero_crossing_values", "update")

#: integrator families whose loop code differs (the fixed-step methods share one loop, the adaptive ones one driver)
FAMILIES = (("rk4", "fixed-step Runge-Kutta: euler, heun, rk4, rk8"), ("etdrk4", "exponential RK4: etdrk4"),
            ("dopri5", "adaptive: bs32, dopri5, dop853"), ("radau5", "implicit: radau5"))


def register(subparsers) -> None:
    parser = subparsers.add_parser(
        "compile", help="compile the simulation kernels now, so that a first run starts at once",
        description="Compile (into numba's on-disk cache) what first runs need: the simulation loop for each "
                    "integrator family, the multibody engine, and every registered model's kernels. Kernels "
                    "already cached load at once. The FEM pipeline (fem2modal) compiles on its first use.")
    parser.add_argument("--quiet", action="store_true", help="no progress bar; only the summary")
    parser.set_defaults(func=compile_kernels)


def describe(dispatcher) -> tuple[str, float]:
    """(what the compilation of ``dispatcher`` is part of, wall seconds that part took on an empty cache: an upper
    bound when some of its functions are cached already)."""
    module = getattr(getattr(dispatcher, "py_func", None), "__module__", "") or ""
    if module.startswith("dynamics.flex."):
        return "the FEM-to-modal pipeline", MODEL_SECONDS
    if module == "shell.kernel_protocol":  # an op kernel's by-reference form (a few lines around the kernel's call)
        return "an op kernel's by-reference form", MODEL_SECONDS
    if module == "shell.models.multibody" or module.startswith("dynamics"):
        name = getattr(dispatcher.py_func, "__name__", "")
        path = next((p for p in ENGINE_SECONDS if name == f"engine_kernel_{p}"), None)
        if path is None:  # a function of the engine compiled on its own (the system's set-up): small
            return "the multibody engine's set-up", MODEL_SECONDS
        return f"the multibody engine ({path.replace('_', ' ')} path)", ENGINE_SECONDS[path]
    if module.startswith(("shell.compiled_loop", "shell.integrators")):
        return "the simulation loop", LOOP_SECONDS
    return "model kernels", MODEL_SECONDS


def work_items() -> list[tuple[str, object]]:
    """(label, function compiling it) for the common set, in the order a progress bar shows them."""
    items = [(f"simulation loop, {text}", _loop(method)) for method, text in FAMILIES[:1]]
    items.append(("multibody engine", _engine))
    items += [(f"simulation loop, {text}", _loop(method)) for method, text in FAMILIES[1:]]
    items += [(f"model {name}", _model(name, cls)) for name, cls in _model_classes()]
    return items


def engine_data():
    """The data of an engine model without closure constraints (a one-body probe's: every such model's have its
    numba type)."""
    from dynamics import Multibody
    from shell.models.multibody import MultibodyModel

    builder = Multibody()
    builder.add_body("probe", None, mass=1.0, inertia=[1.0, 1.0, 1.0], hinge="free")
    builder.add_node("probe_node", "probe")
    return MultibodyModel("probe", builder.compile()).create_data()[1]


def engine_signature():
    """The op-kernel signature of the engine model (:mod:`shell.kernel_protocol`) for the numba type of its data."""
    from numba import typeof

    from shell.kernel_protocol import op_kernel_signature

    return op_kernel_signature(typeof(engine_data()))


def _engine() -> None:
    from numba import typeof

    from shell.kernel_protocol import REFERENCE_KERNEL_SIGNATURE, by_reference, op_kernel_signature, reference
    from shell.models.multibody import ENGINE_KERNELS

    data = engine_data()
    data_type = typeof(data)
    reference(data)  # how a run hands the data to the compiled loop
    for kernel in ENGINE_KERNELS.values():  # single body, articulated-body recursion, dense solve
        kernel.compile(op_kernel_signature(data_type))
        by_reference(kernel, data_type).compile(REFERENCE_KERNEL_SIGNATURE)  # as the compiled loop calls it


def _loop(method: str):
    def compile_loop() -> None:
        """A first-order lag x' = -x run for two steps: the loop (or driver) of ``method`` and its kernels."""
        import numpy as np

        from shell.assembly import Assembly
        from shell.kernel_protocol import reference
        from shell.models.blocks import Gain, Integrator
        from shell.simulation import Simulation

        root = Assembly("compile")
        lag = root.add(Integrator("x", unit="m"))
        lag.set_initial("x", "1 m")
        root.add(Gain("k", unit="m", output_unit="m/s", k="-1 1/s"))
        root.connect("x.y", "k.u")
        root.connect("k.y", "x.u")
        with warnings.catch_warnings():  # etdrk4 says that this scene has no linear part: expected here
            warnings.filterwarnings("ignore", "etdrk4: the linear part is empty", UserWarning)
            Simulation(root, integrator=method, step=1e-3).run(2e-3)
        reference(np.random.default_rng(0))  # how a run hands a noisy model's generator to the loop

    return compile_loop


def _model_classes() -> list[tuple[str, type]]:
    from shell.model import Model
    from shell.registry import registered

    return [(name, cls) for name, cls in registered().items()
            if isinstance(cls, type) and issubclass(cls, Model) and _kernels(cls)]


def _kernels(cls) -> list[tuple[str, object]]:
    from numba.core.registry import CPUDispatcher

    return [(name, getattr(cls, name)) for name in _MODEL_KERNELS
            if isinstance(getattr(cls, name, None), CPUDispatcher)]


def _model(name: str, cls):
    def compile_model() -> None:
        """Each numba kernel of ``cls`` for the compiled loop's signature of its arity (:mod:`shell.kernel_protocol`:
        an update without noise of five arguments, a kernel of six, a kernel of a model with a data slot of seven)."""
        from shell.kernel_protocol import DATA_KERNEL_SIGNATURE, KERNEL_SIGNATURE, UPDATE_SIGNATURE

        by_arity = {5: UPDATE_SIGNATURE, 6: KERNEL_SIGNATURE, 7: DATA_KERNEL_SIGNATURE}
        for _, kernel in _kernels(cls):
            kernel.compile(by_arity[kernel.py_func.__code__.co_argcount])

    return compile_model


def compile_kernels(args) -> int:
    from dynamics.compile_cache import CompileClock, cache_directory

    items = work_items()
    compiled: list = []
    clock = CompileClock(on_start=compiled.append).start()
    started = time.perf_counter()
    failures = []
    bar = None
    if not args.quiet and sys.stderr.isatty():
        from tqdm import tqdm

        bar = tqdm(total=len(items), file=sys.stderr, unit="part", dynamic_ncols=True,
                   bar_format="{desc}: {n}/{total} [{elapsed}]")
    try:
        for number, (label, compile_item) in enumerate(items, 1):
            item_started = time.perf_counter()
            if bar is not None:
                bar.set_description_str(f"flexshell compile: {label}")
            try:
                compile_item()
            except Exception as exc:  # a shipped kernel that does not compile is a defect: name it, go on
                failures.append(f"{label}: {type(exc).__name__}: {str(exc).splitlines()[0][:300]}")
            if bar is not None:
                bar.update(1)
            elif not args.quiet:
                print(f"flexshell compile: [{number}/{len(items)}] {label}: {time.perf_counter() - item_started:.1f} s",
                      file=sys.stderr, flush=True)
    finally:
        clock.stop()
        if bar is not None:
            bar.close()
    for failure in failures:
        print(f"flexshell compile: {failure}", file=sys.stderr)
    print(f"flexshell compile: {len(items)} parts in {time.perf_counter() - started:.0f} s; {len(compiled)} "
          f"functions compiled ({clock.seconds:.0f} s), the rest loaded from the cache {cache_directory()}")
    return 1 if failures else 0

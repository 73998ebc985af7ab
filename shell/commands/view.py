"""``flexshell view LOG.h5 | SCENE.yaml | LIN.h5 --mode K -o scene.html``: the scene in 3D, in a browser.

Writes one self-contained HTML file (three.js inlined, no server, no network) that draws the bodies
from their geometry (flexible bodies' FE grids and elements deformed by their modal coordinates, rigid
bodies as equivalent-inertia boxes or user meshes), node and body frames, spinning wheels, firing
thrusters and the track, with play / pause / time slider / speed and a panel of signals (shell/view/,
docs/view.md).

* a log: the motion it holds (``<engine>.q`` logged, or per-body coordinates); the scene is rebuilt from
  the scenario text the log keeps;
* a scenario: its initial configuration, or with ``--t-final`` a run of that length (a user asking to
  *view* a scenario gets what it looks like at once; running it is asked for explicitly, since a first run
  compiles for minutes);
* a linear model (``flexshell linearize``): system mode ``--mode K`` (1 = lowest frequency) animated.
"""

from __future__ import annotations

import sys
import time
from pathlib import Path

from shell.outputs import OVERWRITE_HELP


def register(subparsers) -> None:
    parser = subparsers.add_parser(
        "view", help="3D view of a log, a scenario or a linear model's mode, as one HTML file",
        description="Write a self-contained HTML page (opens offline in any browser) that animates a log "
                    "(LOG.h5), shows a scenario (SCENE.yaml: initial configuration, or a run with --t-final) "
                    "or animates a system mode of a linear model (LIN.h5 --mode K).")
    parser.add_argument("input", help="log (HDF5 from flexshell run), scenario (YAML) or linear model (HDF5 from "
                                      "flexshell linearize)")
    parser.add_argument("-o", "--output", help="HTML file to write (default: the input's name with .html)")
    parser.add_argument("--mode", type=int, metavar="K", help="linear model: the system mode to animate "
                                                             "(1 = lowest-frequency oscillatory mode)")
    parser.add_argument("--signals", nargs="+", metavar="SIGNAL",
                        help="signals of the log for the panel (full name or unique suffix; default: a few small ones)")
    parser.add_argument("--scale", default="auto",
                        help="deformation scale of flexible bodies (default auto: the largest displacement drawn "
                             "as about 8%% of the scene; 1 = true size)")
    parser.add_argument("--mesh", action="append", default=[], metavar="BODY=FILE",
                        help="draw BODY with a mesh file (any format trimesh reads; metres, body axes)")
    parser.add_argument("--scenario", help="the scenario of a log or linear model, when its recorded path is not "
                                           "valid from here")
    parser.add_argument("--set", dest="overrides", action="append", default=[], metavar="KEY=VALUE",
                        help="scenario override, as for flexshell run (a log keeps the scenario without them)")
    parser.add_argument("--t-final", help="scenario: run it this long (e.g. 20 s) and view the run")
    parser.add_argument("--rate", help="scenario run: frame rate of the view (default the scenario's log rate, "
                                       "else 10 Hz)")
    parser.add_argument("--max-frames", type=int, default=6000,
                        help="most frames kept from a log (evenly decimated; default 6000)")
    parser.add_argument("--overwrite", action="store_true", help=OVERWRITE_HELP)
    parser.set_defaults(func=view)


def _kind(path: Path) -> str:
    if path.suffix.lower() in (".yaml", ".yml"):
        return "scenario"
    import h5py

    try:
        with h5py.File(path, "r", locking=False) as f:
            found = f.attrs.get("format")
    except (OSError, RuntimeError):
        return "scenario"  # not HDF5: read as a scenario, which names what is wrong with it
    found = found.decode() if isinstance(found, bytes) else found
    if found == "flexshell-log":
        return "log"
    if found == "flexshell-linear-model":
        return "linear"
    what = "an HDF5 file without a format attribute (a body file? view a scenario that uses it)" if found is None \
        else f"an HDF5 file of format {found!r}"
    raise ValueError(f"{path}: {what}; flexshell view reads a log (flexshell run), a linear model (flexshell "
                     "linearize) or a scenario (YAML)")


def _meshes(items) -> dict:
    out = {}
    for item in items:
        name, sep, file = item.partition("=")
        if not sep or not name or not file:
            raise ValueError(f"--mesh {item!r}: expected BODY=FILE")
        if not Path(file).is_file():
            raise ValueError(f"--mesh {item}: no file {file!r}")
        out[name] = file
    return out


def _scale(value: str):
    if value == "auto":
        return value
    try:
        scale = float(value)
    except ValueError:
        raise ValueError(f"--scale: expected auto or a number, given {value!r}") from None
    if not scale >= 0 or scale == float("inf"):
        raise ValueError(f"--scale: expected a finite number >= 0, given {value!r}")
    return scale


def view(args) -> int:
    from shell.log_file import LogError
    from shell.model import ModelError
    from shell.outputs import HTML, guard_output
    from shell.scenario import ScenarioError
    from shell.units import UnitError
    from shell.view.page import write_html
    from shell.view.scene import ViewError, from_linear_model, from_log, from_scenario

    source = Path(args.input)
    output = Path(args.output) if args.output else source.with_suffix(".html")
    start = time.perf_counter()
    try:
        if not source.is_file():
            raise ValueError(f"{source}: no such file")
        kind = _kind(source)
        guard_output(output, HTML, inputs=((source, "the input itself"), (args.scenario, "the scenario of --scenario"),
                                           *((item.partition("=")[2], "a mesh of --mesh") for item in args.mesh)),
                     overwrite=args.overwrite)
        scale, meshes = _scale(args.scale), _meshes(args.mesh)
        if args.max_frames < 2:
            raise ValueError(f"--max-frames: expected at least 2, given {args.max_frames}")
        if args.mode is not None and kind != "linear":
            raise ValueError(f"--mode: {source} is a {kind}; --mode animates a system mode of a linear model "
                             "(flexshell linearize)")
        if args.t_final is not None and kind != "scenario":
            raise ValueError(f"--t-final: {source} is a {kind}; --t-final runs a scenario")
        if kind == "log":
            scene = from_log(source, signals=args.signals, scenario=args.scenario, overrides=args.overrides,
                             meshes=meshes, scale=scale, max_frames=args.max_frames)
        elif kind == "linear":
            if args.mode is None:
                raise ValueError(f"{source}: a linear model; say which system mode to animate with --mode K "
                                 "(1 = lowest frequency)")
            scene = from_linear_model(source, args.mode, scenario=args.scenario,
                                      overrides=args.overrides or None, meshes=meshes, scale=scale)
        else:
            t_final = None
            if args.t_final is not None:
                from shell.commands.run import stop_time

                t_final = stop_time(args.t_final, str(source))
            scene = from_scenario(source, overrides=args.overrides, meshes=meshes, scale=scale, t_final=t_final,
                                  rate=args.rate, signals=args.signals, max_frames=args.max_frames,
                                  say=lambda text: print(f"flexshell view: {text}", flush=True))
        size = write_html(scene, output)
    except (ViewError, ScenarioError, LogError, ModelError, UnitError, ValueError, KeyError, OSError) as exc:
        print(f"flexshell view: {exc.args[0] if isinstance(exc, KeyError) else exc}", file=sys.stderr)
        return 1
    for note in scene.notes:
        print(f"  note: {note}")
    print(f"view: {output} ({size / 1e6:.2f} MB, {len(scene.time)} frames, {len(scene.bodies)} bodies; "
          f"{time.perf_counter() - start:.1f} s)")
    return 0

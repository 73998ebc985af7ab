"""``flexshell bode MODEL``: Bode, Nichols and Nyquist plots, the frequency response as CSV and the stability
margins (gain, phase, delay, distance to -1) of a linear model, SISO or per channel of a MIMO loop.

A verb of its own rather than a ``linearize`` option: it reads a model already written (``flexshell linearize``'s
HDF5 file or its .mat export, or A, B, C, D in an .npz, .mat or HDF5 file of a design script:
:func:`shell.linear.matrix_files.read_state_space`), so one linearization (minutes for a large scene) serves any
number of looks at other channels, frequency ranges and loop conventions, each in about a second; the model file
is the contract between the two verbs.

Which loop (:mod:`shell.analysis.margins`): ``--feedback negative`` (default) takes the model as the loop
transfer function L closed by ``u = -y`` (python-control's ``stability_margins`` and MATLAB's ``margin``);
``--feedback positive`` takes it as a loop broken at a port, ``linearize --inputs PORT --outputs SIGNAL`` with
SIGNAL the signal wired into PORT, so ``u = +y`` and ``L = -G``. ``--others open`` (default) treats every
(output, input) pair as a SISO loop with the other channels open; ``--others closed`` pairs output k with input k
and breaks one channel at a time with the others closed (loop-at-a-time margins). Plots and CSV show L in the
negative-feedback convention, so the critical point is always -1 (0 dB, -180 deg).

Outputs (``-o PREFIX``, default the model's path without its suffix): ``PREFIX_bode.png``,
``PREFIX_nichols.png``, ``PREFIX_nyquist.png``, ``PREFIX_response.csv`` (one row per channel and frequency:
frequency in Hz and rad/s, real and imaginary parts, magnitude in dB, phase in degrees unwrapped along
frequency) and ``PREFIX_margins.csv`` (one row per channel); the margins are printed too. Frequencies: ``--points``
log-spaced over ``--frequencies FMIN,FMAX`` Hz (default: a decade beyond the slowest and fastest pole, up to the
Nyquist frequency of a sampled model), plus each damped pole's frequency and each crossover, so that no resonance
peak or crossing falls between the points.
"""

from __future__ import annotations

import csv
import math
import sys
import warnings
from pathlib import Path

import numpy as np

from shell.outputs import OVERWRITE_HELP

PLOTS = ("bode", "nichols", "nyquist")
RESPONSE_HEADER = ("output", "input", "frequency_hz", "frequency_rad_s", "real", "imag", "magnitude_db", "phase_deg")
MARGIN_HEADER = ("output", "input", "feedback", "others", "closed_loop_stable", "gain_margin", "gain_margin_db",
                 "phase_crossover_hz", "phase_margin_deg", "gain_crossover_hz", "delay_margin_s",
                 "delay_margin_samples", "stability_margin", "stability_margin_hz")
#: more channels than this make unreadable plots: the user selects some
MAX_CHANNELS = 16


def register(subparsers) -> None:
    parser = subparsers.add_parser(
        "bode", help="Bode, Nichols and Nyquist plots, frequency-response CSV and stability margins of a linear model",
        description="Frequency response and stability margins (gain, phase, delay, distance to -1) of a linear "
                    "model file (flexshell linearize's HDF5 or .mat; A, B, C, D in .npz, .mat or HDF5), SISO or "
                    "per channel of a MIMO loop. Writes PREFIX_bode.png, PREFIX_nichols.png, PREFIX_nyquist.png, "
                    "PREFIX_response.csv and PREFIX_margins.csv.")
    parser.add_argument("model", help="linear-model file (.h5, .mat, .npz)")
    parser.add_argument("--inputs", action="append", default=[], metavar="NAME[,NAME...]",
                        help="input channels by name (a port name selects all its elements; default all)")
    parser.add_argument("--outputs", action="append", default=[], metavar="NAME[,NAME...]",
                        help="output channels by name (default all)")
    parser.add_argument("--feedback", choices=("negative", "positive"), default="negative",
                        help="negative (default): the model is the loop transfer function L, closed by u = -y; "
                             "positive: a loop broken at a port (u = +y, so L = -G)")
    parser.add_argument("--others", choices=("open", "closed"), default="open",
                        help="open (default): every (output, input) pair a SISO loop, the others open; closed: "
                             "output k fed back to input k, margins one channel at a time with the others closed")
    parser.add_argument("--frequencies", metavar="FMIN,FMAX",
                        help="frequency range in Hz (default: from the poles)")
    parser.add_argument("--points", type=int, default=1000, help="log-spaced frequencies (default 1000)")
    parser.add_argument("-o", "--output", metavar="PREFIX",
                        help="prefix of the files written (default: the model's path without its suffix)")
    parser.add_argument("--overwrite", action="store_true", help=OVERWRITE_HELP)
    parser.set_defaults(func=bode_command)


def _names(values) -> list[str]:
    return [name.strip() for value in values for name in value.split(",") if name.strip()]


def select(names, wanted, what: str) -> list[int]:
    """Indices of the ``wanted`` signals among ``names``: a full name, or a port naming its elements ``port[k]``."""
    import difflib

    if not wanted:
        return list(range(len(names)))
    chosen = []
    for token in wanted:
        found = [k for k, name in enumerate(names) if name == token or name.startswith(token + "[")]
        if not found:
            close = difflib.get_close_matches(token, names, n=3)
            hint = f"; did you mean {', '.join(close)}?" if close else f"; the model's {what}s: {', '.join(names)}"
            raise ValueError(f"--{what}s {token}: no such {what}{hint}")
        chosen += [k for k in found if k not in chosen]
    return chosen


def _frequency_range(text, channels, points: int) -> np.ndarray:
    """The frequencies (rad/s) of the plots and the CSV (module docstring)."""
    system = channels[0].loop
    nyquist = math.pi / system.sample_time if system.discrete else math.inf
    extra = []
    for channel in channels:
        m = channel.margins
        extra += [*m.gain_crossovers, *m.phase_crossovers, m.stability_margin_frequency]
        poles = channel.loop.poles()
        if system.discrete:
            poles = np.log(poles[np.abs(poles) > 0]) / system.sample_time
        extra += list(np.abs(poles[poles.real < 0].imag))
    if text:
        try:
            low, high = (float(v) * 2 * math.pi for v in text.split(","))
        except ValueError:
            raise ValueError(f"--frequencies {text}: expected FMIN,FMAX in Hz, e.g. 0.01,100") from None
        if not (0 < low < high and math.isfinite(high)):
            raise ValueError(f"--frequencies {text}: expected 0 < FMIN < FMAX (Hz)")
    else:
        poles = np.concatenate([c.loop.poles() for c in channels])
        if system.discrete:
            poles = np.log(poles[np.abs(poles) > 0]) / system.sample_time
        features = np.abs(poles)
        features = features[features > 1e-9 * max(float(np.max(features, initial=0.0)), 1.0)]
        if not features.size:
            features = np.array([1.0])
        low = 10.0 ** math.floor(math.log10(features.min()) - 1.0)
        high = 10.0 ** math.ceil(math.log10(features.max()) + 1.0)
    high = min(high, nyquist)
    grid = np.geomspace(low, high, points)
    extra = [w for w in extra if math.isfinite(w) and low < w < high]
    return np.unique(np.concatenate([grid, extra]))


def _response(channels, omega) -> np.ndarray:
    from shell.linear.response import frequency_response

    return np.array([frequency_response(c.loop, omega)[0, 0] for c in channels])


def _write_response(path, channels, omega, response) -> None:
    with open(path, "w", newline="") as f:
        out = csv.writer(f)
        out.writerow(RESPONSE_HEADER)
        for channel, G in zip(channels, response):
            phase = np.degrees(np.unwrap(np.angle(G)))
            for w, g, p in zip(omega, G, phase):
                magnitude = 20 * math.log10(abs(g)) if g != 0 else -math.inf
                out.writerow([channel.output, channel.input, *map(_number, (w / (2 * math.pi), w, g.real, g.imag,
                                                                            magnitude, p))])


def _number(value) -> str:
    """Shortest text that reads back as the same float."""
    return repr(float(value))


def _hz(omega: float) -> float:
    return omega / (2 * math.pi)


def _margin_row(channel, feedback: str, others: str) -> list:
    m = channel.margins
    samples = m.delay_margin / m.sample_time if m.sample_time else math.nan
    return [channel.output, channel.input, feedback, others, channel.closed_loop_stable,
            *map(_number, (m.gain_margin, m.gain_margin_db, _hz(m.phase_crossover), m.phase_margin,
                           _hz(m.gain_crossover), m.delay_margin, samples, m.stability_margin,
                           _hz(m.stability_margin_frequency)))]


def _describe(channel) -> str:
    m = channel.margins
    gm = "none (no phase crossover)" if math.isinf(m.gain_margin) else \
        f"{m.gain_margin:.6g} ({m.gain_margin_db:+.4g} dB) at {_hz(m.phase_crossover):.6g} Hz"
    if math.isinf(m.phase_margin):
        pm = dm = "none (no gain crossover)"
    else:
        pm = f"{m.phase_margin:.6g} deg at {_hz(m.gain_crossover):.6g} Hz"
        samples = f" = {m.delay_margin / m.sample_time:.4g} samples" if m.sample_time else ""
        dm = f"{m.delay_margin:.6g} s{samples} (crossover {_hz(m.delay_margin_frequency):.6g} Hz)"
    sm = f"{m.stability_margin:.6g} at {_hz(m.stability_margin_frequency):.6g} Hz"
    return (f"  {channel.output} <- {channel.input}:\n    gain margin {gm}\n    phase margin {pm}\n"
            f"    delay margin {dm}\n    stability margin (min |1 + L|) {sm}")


def _label(channel) -> str:
    return f"{channel.output} \u2190 {channel.input}"


def _draw(kind: str, channels, omega, response, title: str):
    import matplotlib.pyplot as plt

    if kind == "bode":
        figure, (top, bottom) = plt.subplots(2, 1, sharex=True, figsize=(9.0, 7.0))
        for channel, G in zip(channels, response):
            m = channel.margins
            summary = (f"GM {m.gain_margin_db:.3g} dB, PM {m.phase_margin:.3g} deg, DM {m.delay_margin:.3g} s, "
                       f"min|1+L| {m.stability_margin:.3g}")
            top.semilogx(omega / (2 * math.pi), 20 * np.log10(np.abs(G)), label=f"{_label(channel)}: {summary}")
            bottom.semilogx(omega / (2 * math.pi), np.degrees(np.unwrap(np.angle(G))))
            for w in channel.margins.gain_crossovers:
                top.plot(_hz(w), 0.0, "o", mfc="none", color="k", ms=5)
            for w in channel.margins.phase_crossovers:
                top.plot(_hz(w), 20 * np.log10(abs(G[np.argmin(abs(omega - w))]) or 1e-300), "s", mfc="none",
                         color="k", ms=5)
        top.axhline(0.0, color="0.5", lw=0.8)
        top.set_ylabel("|L| (dB)")
        bottom.set_ylabel("phase of L (deg)")
        bottom.set_xlabel("frequency (Hz)")
        low, high = bottom.get_ylim()
        for k in range(math.ceil((low + 180) / 360), math.floor((high + 180) / 360) + 1):
            bottom.axhline(-180.0 + 360.0 * k, color="0.5", lw=0.8)
        top.legend(fontsize=7)
        axes = (top, bottom)
    elif kind == "nichols":
        figure, ax = plt.subplots(figsize=(8.0, 6.5))
        for channel, G in zip(channels, response):
            ax.plot(np.degrees(np.unwrap(np.angle(G))), 20 * np.log10(np.abs(G)), label=_label(channel))
        low, high = ax.get_xlim()
        for k in range(math.ceil((low + 180) / 360), math.floor((high + 180) / 360) + 1):
            ax.plot(-180.0 + 360.0 * k, 0.0, "r+", ms=12)
        ax.set_xlabel("phase of L (deg)")
        ax.set_ylabel("|L| (dB)")
        ax.legend(fontsize=7)
        axes = (ax,)
    else:
        figure, ax = plt.subplots(figsize=(7.0, 7.0))
        for channel, G in zip(channels, response):
            line, = ax.plot(G.real, G.imag, label=_label(channel))
            ax.plot(G.real, -G.imag, "--", color=line.get_color(), lw=0.8)
        circle = np.exp(1j * np.linspace(0, 2 * math.pi, 361))
        ax.plot(circle.real, circle.imag, ":", color="0.5", lw=0.8)
        ax.plot(-1.0, 0.0, "r+", ms=14)
        for channel in channels:
            disc = -1.0 + channel.margins.stability_margin * circle
            ax.plot(disc.real, disc.imag, "-", color="0.7", lw=0.6)
        largest = float(np.max(np.abs(response[np.isfinite(response)]), initial=0.0))
        reach = min(max(1.2, largest), 3.0) * 1.1  # the neighbourhood of -1; the whole curve is in the CSV
        ax.set_xlim(-reach, reach)
        ax.set_ylim(-reach, reach)
        ax.set_aspect("equal")
        ax.set_xlabel("Re L")
        ax.set_ylabel("Im L")
        ax.legend(fontsize=7)
        title += f"\n(view |L| <= {reach:.3g}; negative frequencies dashed; grey: the disc min |1 + L| about -1)"
        axes = (ax,)
    for ax in axes:
        ax.grid(True, which="both", lw=0.3)
    axes[0].set_title(title, fontsize=9)
    figure.subplots_adjust(left=0.1, right=0.97, bottom=0.08, top=0.92, hspace=0.08)
    return figure


def _outputs(args) -> dict:
    prefix = args.output or str(Path(args.model).with_suffix(""))
    files = {kind: f"{prefix}_{kind}.png" for kind in PLOTS}
    files["response"], files["margins"] = f"{prefix}_response.csv", f"{prefix}_margins.csv"
    return files


def bode_command(args) -> int:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from shell.analysis.margins import channel_loops
    from shell.linear.matrix_files import read_state_space
    from shell.linear.system import LinearSystemError
    from shell.outputs import figure_kind, guard_output, text_kind

    files = _outputs(args)
    kinds = {kind: figure_kind(files[kind]) for kind in PLOTS}
    kinds["response"] = text_kind("frequency-response table (CSV) of flexshell bode", ",".join(RESPONSE_HEADER))
    kinds["margins"] = text_kind("margin table (CSV) of flexshell bode", ",".join(MARGIN_HEADER))
    try:
        for key, path in files.items():
            guard_output(path, kinds[key], inputs=((args.model, "the model itself"),), overwrite=args.overwrite,
                         others=[other for name, other in files.items() if name != key])
        if args.points < 2:
            raise ValueError(f"--points: expected at least 2 frequencies, given {args.points}")
        system = read_state_space(args.model)
        system = system.select(select(system.input_names, _names(args.inputs), "input"),
                               select(system.output_names, _names(args.outputs), "output"))
        count = system.B.shape[1] if args.others == "closed" else system.B.shape[1] * system.C.shape[0]
        if count > MAX_CHANNELS:
            raise ValueError(f"{args.model}: {count} channels ({system.C.shape[0]} outputs x {system.B.shape[1]} "
                             f"inputs) make unreadable plots; select at most {MAX_CHANNELS} with --inputs/--outputs")
        channels = channel_loops(system, args.feedback, args.others)
        omega = _frequency_range(args.frequencies, channels, args.points)
    except (LinearSystemError, ValueError, OSError) as exc:
        print(f"flexshell bode: {exc}", file=sys.stderr)
        return 1
    response = _response(channels, omega)
    loop = "L = G" if args.feedback == "negative" else "L = -G"
    timing = f"sampled every {system.sample_time:g} s" if system.discrete else "continuous"
    print(f"{args.model}: {system.shape[0]} states, {timing}; {loop} ({args.feedback} feedback), other channels "
          f"{args.others}")
    for channel in channels:
        if not channel.closed_loop_stable:
            warnings.warn(f"{args.model}: {channel.output} <- {channel.input}: the loop closed as described "
                          f"({args.feedback} feedback, others {args.others}) is unstable; its margins say how far "
                          "it is from stability, not how far from instability")
        print(_describe(channel))
    _write_response(files["response"], channels, omega, response)
    with open(files["margins"], "w", newline="") as f:
        out = csv.writer(f)
        out.writerow(MARGIN_HEADER)
        out.writerows(_margin_row(c, args.feedback, args.others) for c in channels)
    title = f"{Path(args.model).name}: {loop}, {args.feedback} feedback, others {args.others}"
    for kind in PLOTS:
        figure = _draw(kind, channels, omega, response, title)
        figure.savefig(files[kind], dpi=110)
        plt.close(figure)
    print("  written " + ", ".join(files.values()))
    return 0

"""Size and load time of a ``flexshell view`` page for a large flexible body (docs/view.md).

The case of issue 18: one flexible body of 1,000 grids (a 40 x 25 plate of CQUAD4) with 200 modes, over
600 s of log at 10 Hz (6,000 frames, the default --max-frames), plus smaller and larger variants to show
how it scales. The page is built from a :class:`shell.view.scene.ViewScene` made here directly (plate
grids, smooth mode shapes, modal coordinates as decaying sines): the page's size and the browser's work
depend only on these array sizes; the Python side (poses per frame from the engine) is timed separately
on a real scene in docs/view.md.

Load time: headless Chromium (SwiftShader, software WebGL) opens the file and the viewer reports
``performance.now()`` (from navigation start: reading and parsing the HTML, decoding the arrays,
building the scene, the first deformed frame drawn) into its probe; wall time of the whole browser
process is given too (its start-up included).

    python3 benchmarks/view_size.py            # writes its pages to a temporary directory
"""

from __future__ import annotations

import json
import re
import shutil
import subprocess
import tempfile
import time
from pathlib import Path

import numpy as np

from shell.view.page import write_html
from shell.view.scene import ViewBody, ViewScene, element_drawing


def plate_scene(nx: int, ny: int, n_modes: int, seconds: float, rate: float) -> ViewScene:
    x, y = np.meshgrid(np.linspace(0, 4.0, nx), np.linspace(0, 2.5, ny), indexing="ij")
    grids = np.stack([x.ravel(), y.ravel(), np.zeros(x.size)], 1)
    ids = np.arange(1, len(grids) + 1)
    quads = [[ids[i * ny + j], ids[(i + 1) * ny + j], ids[(i + 1) * ny + j + 1], ids[i * ny + j + 1]]
             for i in range(nx - 1) for j in range(ny - 1)]
    edges, faces, _ = element_drawing(["CQUAD4"] * len(quads), np.array(quads), ids)
    shapes = np.zeros((n_modes, len(grids), 3))
    for k in range(n_modes):
        a, b = 1 + k % 14, 1 + k // 14
        shapes[k, :, 2] = 0.01 * np.sin(a * np.pi * x.ravel() / 4.0) * np.sin(b * np.pi * y.ravel() / 2.5)
    t = np.arange(0.0, seconds, 1.0 / rate)
    frequencies = 1.0 + 0.5 * np.arange(n_modes)
    eta = np.exp(-0.01 * t)[:, None] * np.sin(2 * np.pi * frequencies[None, :] * t[:, None]) / (1 + np.arange(n_modes))
    F = len(t)
    quaternion = np.tile([0.0, 0.0, 0.0, 1.0], (F, 1)).astype(np.float32)
    body = ViewBody("plate", "flexible", np.zeros((F, 3)), quaternion, vertices=grids, faces=faces, edges=edges,
                    shapes=shapes.reshape(n_modes, -1), eta=eta, mode_frequencies_hz=frequencies)
    node = {"name": "centre", "body": "plate", "position": np.tile(grids[len(grids) // 2], (F, 1)),
            "quaternion": quaternion}
    return ViewScene(title=f"plate {len(grids)} grids, {n_modes} modes, {F} frames", source="benchmark", time=t,
                     bodies=[body], nodes=[node], length=4.0, deformation_scale=5.0)


def load(html: Path) -> tuple[float, dict, float]:
    """(page-reported load ms, its marks, wall s of the browser process)."""
    chromium = shutil.which("chromium")
    start = time.perf_counter()
    out = subprocess.run([chromium, "--headless", "--no-sandbox", "--disable-gpu-sandbox", "--use-angle=swiftshader",
                          "--enable-unsafe-swiftshader", "--window-size=1200,700", "--virtual-time-budget=5000",
                          "--dump-dom", html.resolve().as_uri() + "?t=300&probe=1"],
                         capture_output=True, text=True, timeout=300).stdout
    wall = time.perf_counter() - start
    probe = json.loads(re.search(r'<pre id="probe">(.*?)</pre>', out, re.S).group(1).replace("&quot;", '"'))
    return float(probe["load_ms"]), probe["marks"], wall


def main() -> None:
    cases = [(40, 25, 2, 6.0, 10.0), (40, 25, 200, 600.0, 10.0), (40, 25, 100, 600.0, 10.0),
             (40, 25, 200, 300.0, 10.0), (80, 50, 200, 600.0, 10.0)]
    print("| grids | modes | frames | HTML MB | predicted MB | HTML read, script start ms | decode ms | WebGL "
          "start ms | first frame ms | load ms (page) | browser wall s |")
    print("| ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: |")
    with tempfile.TemporaryDirectory() as tmp:
        for nx, ny, n, seconds, rate in cases:
            scene = plate_scene(nx, ny, n, seconds, rate)
            html = Path(tmp) / "plate.html"
            size = write_html(scene, html)
            G, F = nx * ny, len(scene.time)
            predicted = (0.9e6 + 4 / 3 * 4 * (3 * G * n + F * n + 3 * G + 2 * 2 * G)
                         + 4 / 3 * (8 * F * 4 + 4 * F * 2)) / 1e6
            ms, marks, wall = min((load(html) for _ in range(2)), key=lambda r: r[0])
            webgl = marks["renderer"] - marks["parsed"]
            print(f"| {G} | {n} | {F} | {size / 1e6:.2f} | {predicted:.2f} | {marks['start']:.0f} | "
                  f"{marks['decoding']:.0f} | {webgl:.0f} | {marks['drawn'] - marks['built']:.0f} | {ms:.0f} | "
                  f"{wall:.1f} |", flush=True)


if __name__ == "__main__":
    main()

"""Where numba caches flexshell's compiled code: a directory keyed on the sources of the whole package.

numba's on-disk cache (``cache=True``) invalidates a function when *its own* file changes, not when a
function it calls from another file does: after an update of ``dynamics/kernels/kinematics.py`` a cached caller
(the engine entry points, the shell's compiled loop) would keep linking the old machine code and run
outdated physics (seen during development). :func:`configure` therefore points numba at
``~/.cache/flexshell/numba/<hash of every .py file of dynamics and shell>`` (``$XDG_CACHE_HOME`` is
honoured) before any kernel is compiled: any change of the sources starts a fresh cache, an unchanged
installation reuses its cache across processes (Monte Carlo workers, later runs). Directories unused for
a week are removed, except the four most recently used. A ``NUMBA_CACHE_DIR`` set by the user is left alone.
"""

from __future__ import annotations

import hashlib
import os
import shutil
import time
from pathlib import Path

KEEP = 4
STALE_AFTER_S = 7 * 24 * 3600.0


def source_key(root: Path) -> str:
    """sha256 (16 hex digits) of the package sources under ``root`` (paths and contents)."""
    digest = hashlib.sha256()
    for package in ("dynamics", "shell"):
        for path in sorted((root / package).rglob("*.py")):
            digest.update(path.relative_to(root).as_posix().encode())
            digest.update(path.read_bytes())
    return digest.hexdigest()[:16]


def configure() -> str | None:
    """Set numba's cache directory for this process (see the module docstring); returns it, or None when
    the user chose one with ``NUMBA_CACHE_DIR``."""
    import numba

    if os.environ.get("NUMBA_CACHE_DIR"):
        return None
    base = Path(os.environ.get("XDG_CACHE_HOME") or Path.home() / ".cache") / "flexshell" / "numba"
    directory = base / source_key(Path(__file__).resolve().parent.parent)
    try:
        directory.mkdir(parents=True, exist_ok=True)
        os.utime(directory)  # most recently used
        _prune(base, directory)
    except OSError:  # an unwritable home: numba's default (__pycache__ next to the sources)
        return None
    numba.config.CACHE_DIR = str(directory)
    return str(directory)


def _prune(base: Path, current: Path) -> None:
    older = sorted((p for p in base.iterdir() if p.is_dir() and p != current), key=lambda p: p.stat().st_mtime,
                   reverse=True)
    now = time.time()
    for stale in older[KEEP - 1:]:
        if now - stale.stat().st_mtime > STALE_AFTER_S:  # never a directory another process may be using
            shutil.rmtree(stale, ignore_errors=True)


class CompileClock:
    """numba's compilations in this process, followed through its ``numba:compile`` event (raised when a kernel is
    compiled, not when it is loaded from the on-disk cache): ``seconds`` spent compiling (a compilation and the
    callees it compiles counted once), and ``on_start(dispatcher)`` called as each compilation, outer or nested,
    starts. Listens from :meth:`start` to :meth:`stop` (`flexshell run`'s compile notice, the Monte Carlo runs'
    compile counter and timeout)."""

    def __init__(self, on_start=None):
        self.seconds = 0.0
        self._on_start, self._depth, self._started, self._listener = on_start, 0, 0.0, None

    @property
    def running(self) -> bool:
        return self._listener is not None

    def start(self) -> "CompileClock":
        from numba.core import event

        clock = self

        class _Listener(event.Listener):
            def on_start(self, ev) -> None:
                if clock._depth == 0:
                    clock._started = time.perf_counter()
                clock._depth += 1
                if clock._on_start is not None:
                    clock._on_start((ev.data or {}).get("dispatcher"))

            def on_end(self, ev) -> None:
                clock._depth -= 1
                if clock._depth == 0:
                    clock.seconds += time.perf_counter() - clock._started

        self._listener = _Listener()
        event.register("numba:compile", self._listener)
        return self

    def stop(self) -> None:
        if self._listener is not None:
            from numba.core import event

            event.unregister("numba:compile", self._listener)
            self._listener = None

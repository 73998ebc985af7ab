"""The first run after installing (or changing) flexshell says that it compiles, instead of a silent minute.

`shell.compiled_plan.loop_is_cached` decides it from numba's index file of the compiled loop. A defect found
on 2026-11-23: it read an attribute numba's cache object does not have, fell into its "numba internals
moved" branch and always answered True, so the notice never appeared (a cold demo run was silent for 7
minutes). Checked: False with an empty cache directory (a fresh process, nothing compiled), True once the
loop has been compiled into the cache, and the notice printed when it is False.
"""

from __future__ import annotations

import os
import subprocess
import sys

from shell.compiled_plan import loop_is_cached

_COLD = """
import shell.compiled_plan as plan
import shell.commands.run as run
print("cached", plan.loop_is_cached())
plan.prepare = lambda: 0.0          # the compilation itself is not what is tested (minutes)
run.announce_compilation(quiet=False)
"""


def test_cold_cache_is_detected_and_announced(tmp_path):
    env = dict(os.environ, NUMBA_CACHE_DIR=str(tmp_path / "empty_numba_cache"))
    done = subprocess.run([sys.executable, "-c", _COLD], capture_output=True, text=True, env=env, timeout=300)
    assert done.returncode == 0, done.stderr
    assert "cached False" in done.stdout
    assert "compiling the simulation loop" in done.stderr
    assert "compiled in" in done.stderr


def test_warm_cache_is_detected():
    from shell.compiled_plan import prepare

    prepare()                           # compiles (cold suite) or loads the loop: its index is on disk
    assert loop_is_cached()

"""Where the runs of a campaign execute: serially, on a local process pool, or on a Dask cluster.

Every executor calls the same function, :func:`run_campaign_member` (``Campaign.run(i)``), and yields
:class:`~shell.montecarlo.campaign.RunRecord` objects as runs complete (in completion order; the
results file stores row i at index i, so the table does not depend on the order). A run's result
depends only on (campaign, i), hence serial, pool and Dask give identical tables.

Workers start warm (:func:`start_worker`, in the coordinator before it forks a process pool or a Dask
LocalCluster, in the pool's initializer and through ``Client.run`` on every Dask worker): each caps
its BLAS/OpenMP threads at one (threadpoolctl; the runs are the parallelism, and more threads per
worker oversubscribe the cores), loads the compiled loop from numba's on-disk cache and builds the
campaign's scene once (:mod:`shell.montecarlo.reuse`); a run is then a new context of that scene. The
coordinator compiles (or loads) every kernel when the campaign is validated, which writes numba's
cache; each record counts the kernels its worker had to compile (0 when the cache was used; on other
machines of a cluster the cache directory must be shared, or each machine compiles once).

Pool workers die with their coordinator (:func:`start_pool_worker`: Linux ``PR_SET_PDEATHSIG``, and a
watchdog thread where that is missing): a coordinator killed with ``kill -9`` leaves no worker running
on, holding files or cores.

Dask: ``--scheduler ADDRESS`` connects to a running ``dask scheduler`` (workers started with
``dask worker ADDRESS`` where flexshell is installed and the campaign's files are readable);
without it a ``LocalCluster`` of one single-threaded worker process per core is started and closed.
"""

from __future__ import annotations

import ctypes
import ctypes.util
import multiprocessing
import os
import signal
import socket
import threading
import time
from concurrent.futures import FIRST_COMPLETED, ProcessPoolExecutor, wait
from urllib.parse import urlsplit

from shell.montecarlo.campaign import Campaign, RunRecord
from shell.montecarlo.results import open_results

EXECUTORS = ("serial", "pool", "dask")


def run_campaign_member(campaign: Campaign, run: int) -> RunRecord:
    """Run ``run`` of ``campaign`` (top-level so that process pools and Dask can pickle it)."""
    return campaign.run(run)


def run_campaign_chunk(campaign: Campaign, runs: list) -> list:
    """Runs ``runs`` of ``campaign`` one after another in one task (fewer, larger Dask tasks: each task
    costs the scheduler a few milliseconds, a run of a short campaign about fifty)."""
    return [campaign.run(i) for i in runs]


def start_worker(campaign: Campaign) -> str:
    """Make a worker process ready before its first run: one BLAS/OpenMP thread (the runs are the
    parallelism; more threads per worker oversubscribe the cores), the campaign's scene built
    (:mod:`shell.montecarlo.reuse`) and its kernels loaded. Once per process and campaign: a worker forked
    from a warm coordinator inherits all of it and returns at once. Returns the worker's name."""
    import socket

    global _THREAD_LIMIT
    if _THREAD_LIMIT is None:
        from threadpoolctl import threadpool_limits

        _THREAD_LIMIT = threadpool_limits(1)
    if campaign.fingerprint not in _WARM:
        warm_up(campaign)
        _WARM.add(campaign.fingerprint)
    return f"{socket.gethostname()}:{os.getpid()}"


def warm_up(campaign: Campaign) -> None:
    """Load the kernels the campaign's runs use, and nothing else: run 0's scene, as a run gets it (a new
    context of the reused scene, or the scene rebuilt from run 0's overrides), advanced by one step (0.01 s
    for an adaptive integrator) without a log; nothing is stored. A scene that fails here fails in its own
    run, which says why in its record."""
    try:
        scenario, simulation, _ = campaign._scene(0, campaign.draws(0), None)
        span = float(scenario.step or 0.01)
        simulation.run(min(span, float(scenario.t_final or span)))
    except Exception:  # noqa: BLE001 - see above: the run reports it
        pass


_WARM: set = set()  # campaigns this process is warm for (a forked worker inherits its coordinator's)
_THREAD_LIMIT = None
PR_SET_PDEATHSIG = 1  # <linux/prctl.h>


class SchedulerUnreachable(ConnectionError):
    """The Dask scheduler named by --scheduler does not answer; the message says where it was looked for."""


def start_pool_worker(campaign: Campaign, coordinator: int) -> str:
    """The pool's initializer: tie this worker's life to the coordinator's (pid ``coordinator``), then
    :func:`start_worker`."""
    die_with_parent(coordinator)
    return start_worker(campaign)


def die_with_parent(parent: int) -> None:
    """End this process when ``parent`` ends, even by ``kill -9``: the kernel sends SIGKILL on the parent's
    death (Linux ``prctl(PR_SET_PDEATHSIG)``); elsewhere a daemon thread polls the parent's pid."""
    libc_name = ctypes.util.find_library("c")
    armed = False
    if libc_name and os.uname().sysname == "Linux":
        libc = ctypes.CDLL(libc_name, use_errno=True)
        armed = libc.prctl(PR_SET_PDEATHSIG, signal.SIGKILL, 0, 0, 0) == 0
    if os.getppid() != parent:  # the parent died before the request took effect
        os._exit(1)
    if not armed:
        def watch() -> None:
            while os.getppid() == parent:
                time.sleep(0.5)
            os._exit(1)
        threading.Thread(target=watch, name="flexshell-parent-watch", daemon=True).start()


def check_scheduler(address: str, timeout: float = 5.0) -> None:
    """Fail fast (``timeout`` seconds) when nothing listens at a Dask scheduler ``address``
    (``tcp://host:port``, ``host:port``)."""
    parts = urlsplit(address if "://" in address else f"tcp://{address}")
    try:
        host, port = parts.hostname, parts.port
    except ValueError:
        host, port = None, None
    if parts.scheme not in ("tcp", "tls") or not host or port is None:
        raise SchedulerUnreachable(f"--scheduler {address!r}: expected an address such as tcp://host:8786")
    try:
        with socket.create_connection((host, port), timeout=timeout):
            pass
    except OSError as exc:
        reason = exc.strerror or type(exc).__name__
        raise SchedulerUnreachable(f"--scheduler {address}: no Dask scheduler answers at {host}:{port} "
                                   f"({reason}); start one with `dask scheduler` or check the address") from None


def guided_chunks(runs: list, workers: int, largest: int = 8) -> list:
    """Runs grouped into tasks of decreasing size ("guided" scheduling): at most ``largest`` runs, and at most
    1/4 of the remaining runs per worker, down to single runs at the end, so the workers finish within about
    one run of each other (equal chunks of 8 left one of two workers 12 runs behind on 100 runs: 10 % of
    the wall time) while the per-task overhead stays on few tasks."""
    chunks, k = [], 0
    while k < len(runs):
        size = max(1, min(largest, (len(runs) - k) // (4 * max(workers, 1))))
        chunks.append(runs[k:k + size])
        k += size
    return chunks


def run_serial(campaign: Campaign, runs):
    from threadpoolctl import threadpool_limits

    with threadpool_limits(1):  # as in the workers: the same arithmetic, the same speed per run
        for i in runs:
            yield campaign.run(i)


def run_pool(campaign: Campaign, runs, workers: int | None = None):
    """A process pool of ``workers`` (default: all cores); at most 2 runs queued per worker."""
    workers = workers or os.cpu_count() or 1
    method = "fork" if "fork" in multiprocessing.get_all_start_methods() else "spawn"
    if method == "fork":
        start_worker(campaign)  # forked workers inherit the loaded loop and the built scene
    pending_runs = list(runs)
    with ProcessPoolExecutor(max_workers=workers, mp_context=multiprocessing.get_context(method),
                             initializer=start_pool_worker, initargs=(campaign, os.getpid())) as pool:
        in_flight = set()
        try:
            while pending_runs or in_flight:
                while pending_runs and len(in_flight) < 2 * workers:
                    in_flight.add(pool.submit(run_campaign_member, campaign, pending_runs.pop(0)))
                done, in_flight = wait(in_flight, return_when=FIRST_COMPLETED)
                for future in done:
                    yield future.result()
        except BaseException:
            for future in in_flight:
                future.cancel()
            raise


#: The LocalCluster's housekeeping, slowed to what a campaign of short runs needs: each worker's profiler
#: (stack samples every 10 ms), the event-loop watchdog of every scheduler, nanny and worker (every 20 ms),
#: the system monitor (500 ms) and the nannies' memory checks (100 ms) took CPU from the runs on a machine with
#: as many workers as cores. Measured (CPU of all processes for 300 runs of the attitude-hold campaign, medians
#: of 1-4 interleaved campaigns, four sittings): 9.96 / 7.92 / 9.16 s with Dask's defaults against 9.16 / 7.92 /
#: 8.56 s with these (the same runs serially: 7.70 / 6.86 / 7.45 s); 100 runs: 3.41 against 2.89 s.
#: A cluster started by the user (``--scheduler``) keeps its own configuration.
QUIET_CLUSTER = {
    "distributed.worker.profile.enabled": False,
    "distributed.admin.tick.interval": "1s",
    "distributed.admin.system-monitor.interval": "5s",
    "distributed.worker.memory.monitor-interval": "1s",
}


def run_dask(campaign: Campaign, runs, scheduler: str | None = None, workers: int | None = None,
             timeout: float = 60.0):
    """Runs as Dask futures on ``scheduler`` (an address) or on a LocalCluster of worker processes."""
    from dask.distributed import Client, LocalCluster, as_completed

    import dask

    cluster = None
    if scheduler is None:
        # forked workers start with the coordinator's loaded loop and built scene (measured: 0.4 s to a
        # warm 2-worker cluster, against 9 s for spawned workers that import and load everything)
        fork = "fork" in multiprocessing.get_all_start_methods()
        if fork:
            start_worker(campaign)
        with dask.config.set({"distributed.worker.multiprocessing-method": "fork" if fork else "spawn",
                              **QUIET_CLUSTER}):
            cluster = LocalCluster(n_workers=workers or os.cpu_count() or 1, threads_per_worker=1, processes=True,
                                   dashboard_address=None)
        client = Client(cluster, timeout=timeout)
    else:
        check_scheduler(scheduler)
        client = Client(scheduler, timeout=timeout)
    try:
        client.run(start_worker, campaign)  # every worker warm before the first run is submitted
        shipped = client.scatter(campaign, broadcast=True)
        runs = list(runs)
        n_workers = max(len(client.scheduler_info().get("workers", {})), 1)
        chunks = guided_chunks(runs, n_workers)
        futures = [client.submit(run_campaign_chunk, shipped, chunk, pure=False,
                                 key=f"{campaign.name}-{campaign.fingerprint[:12]}-runs-{chunk[0]}-{chunk[-1]}")
                   for chunk in chunks]
        try:
            for future in as_completed(futures):
                yield from future.result()
        except BaseException:
            client.cancel(futures)
            raise
    finally:
        client.close()
        if cluster is not None:
            cluster.close()


def execute(campaign: Campaign, runs, executor: str = "serial", workers: int | None = None,
            scheduler: str | None = None):
    """Records of ``runs`` (indices) as they complete, on the chosen executor."""
    if executor == "serial":
        return run_serial(campaign, runs)
    if executor == "pool":
        return run_pool(campaign, runs, workers)
    if executor == "dask":
        return run_dask(campaign, runs, scheduler, workers)
    raise ValueError(f"executor {executor!r}: expected one of {EXECUTORS}")


def run_campaign(campaign: Campaign, output, executor: str = "serial", workers: int | None = None,
                 scheduler: str | None = None, resume: bool = False, overwrite: bool = False, progress=None,
                 runs=None) -> dict:
    """Run the campaign's runs not yet in ``output`` and store each as it completes.

    ``progress(record, done, total)`` is called after each stored run. Returns counts by status.
    ``runs`` restricts the campaign to those indices (default: all).
    An interrupted campaign (Ctrl-C) keeps its completed runs and marks the file "interrupted".
    """
    results = open_results(output, campaign, resume=resume, overwrite=overwrite)
    status = "interrupted"
    try:
        done = results.done()
        selected = range(campaign.runs) if runs is None else runs
        todo = [i for i in selected if i not in done]
        total, count = len(done) + len(todo), len(done)
        for record in execute(campaign, todo, executor, workers, scheduler):
            results.write(record)
            count += 1
            if progress is not None:
                progress(record, count, total)
        results.flush()
        finished = results.done()
        status = "completed" if len(finished) == campaign.runs else "partial"
        counts = {}
        for s in results.table["status"]:
            counts[s.decode()] = counts.get(s.decode(), 0) + 1
        return counts
    finally:
        results.close(status)

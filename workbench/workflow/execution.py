"""Dask distributed, the one execution layer: ``--workers N`` (a local cluster) or ``--scheduler ADDRESS``.

`mapper` opens the place where tasks run and yields a `workbench.tasks.Mapper`: one process (the
serial path) for ``workers == 1`` without a scheduler; otherwise a Dask client, either on a local
cluster of ``workers`` single-threaded worker processes, or on the running scheduler at ``scheduler``
(``tcp://host:8786``; start one with ``dask scheduler`` and workers with ``dask worker ADDRESS``).
What every task shares (a model, its nominal modes) is scattered to the workers once; each task is
retried on another worker when its worker dies; results come back in the tasks' order, so for one
seed the numbers are the same whichever path ran them.
"""

from __future__ import annotations

import contextlib
import logging
import re
import sys
import warnings
from collections.abc import Callable, Iterator, Sequence
from contextlib import contextmanager
from typing import Any

from workbench.progress import Progress, report
from workbench.tasks import Mapper, serial_mapper

__all__ = ["SCHEDULER_TIMEOUT_S", "mapper"]

SCHEDULER_TIMEOUT_S = 10  # an unreachable --scheduler is said within this time
RETRIES = 3  # a task whose worker died is run again, up to this many times
_ADDRESS = re.compile(r"(?:(?:tcp|tls|ws|wss|ucx)://)?(?:\[[0-9A-Fa-f:]+\]|[A-Za-z0-9._-]+):\d{1,5}")


@contextmanager
def mapper(workers: int = 1, scheduler: str | None = None, progress: Progress | None = None) -> Iterator[Mapper]:
    """The `Mapper` of ``workers`` local processes or of the Dask scheduler at ``scheduler``.

    The local cluster starts at the first call that hands out more than one task: a command that finds nothing
    to hand out (bad input, an identification of a modes.csv campaign) does not pay for it, and a single task
    before then runs here (``diagnose`` always hands out its candidates' grids). The mapper is for use inside the
    ``with`` block only.

    Raises
    ------
    ValueError
        One line naming the address when no scheduler answers there within `SCHEDULER_TIMEOUT_S`.
    """
    if scheduler is None and workers <= 1:
        yield serial_mapper(progress)
        return
    opened: list[Any] = []  # the client, then the local cluster it runs on, once started

    def run(function: Callable[[Any, Any], Any], tasks: Sequence[Any], label: str, shared: Any) -> list[Any]:
        if not opened and len(tasks) <= 1:
            return serial_mapper(progress)(function, tasks, label, shared)
        if not opened:
            opened.extend(_local_cluster(workers))
        return _dask_mapper(opened[0], progress)(function, tasks, label, shared)

    if scheduler is not None:
        opened.append(_scheduler_client(scheduler))
    try:
        yield run
    finally:
        try:
            if len(opened) > 1:  # our local cluster (never a user's scheduler's workers)
                _quiet_workers(opened[0])
            if opened:
                opened[0].close()  # the client, then (`_local_cluster`) its cluster, even if the client's close fails
        finally:
            for part in opened[1:]:
                part.close()


def _scheduler_client(scheduler: str) -> Any:
    """A client of the running scheduler at ``scheduler`` (`mapper`'s ValueError where none answers)."""
    from distributed import Client  # only when work is handed out: its import takes a second

    if not _ADDRESS.fullmatch(scheduler):  # refused here: a Client built on it hangs 20 s at exit
        raise ValueError(f"--scheduler {scheduler}: not a Dask scheduler address; expected tcp://host:8786 "
                         "(what `dask scheduler` prints)")
    try:
        return Client(scheduler, timeout=f"{SCHEDULER_TIMEOUT_S}s", set_as_default=False)
    except (OSError, TimeoutError, ValueError) as exc:
        raise ValueError(f"--scheduler {scheduler}: no Dask scheduler answered within {SCHEDULER_TIMEOUT_S} s "
                         f"({' '.join(str(exc).split())[:160]})") from None


def _local_cluster(workers: int) -> tuple[Any, Any]:
    """``(client, cluster)``: a local cluster of ``workers`` single-threaded processes, forked on Linux."""
    import dask
    from distributed import Client, LocalCluster

    # Dask's nannies set MALLOC_TRIM_THRESHOLD_=65536 in their workers, which makes glibc hand
    # memory back on nearly every numpy free: measured 30 % slower circle fits (16.2 s against
    # 12.4 s for campaigns/four_bolt_table6); the workers keep one BLAS thread each
    environ = {k: v for k, v in dask.config.get("distributed.nanny.pre-spawn-environ").items()
               if k != "MALLOC_TRIM_THRESHOLD_"}
    settings: dict[str, object] = {"distributed.nanny.pre-spawn-environ": environ}
    if sys.platform.startswith("linux"):
        # forked from this loaded process, a worker starts in a tenth of a second; spawned, it imports the
        # package again (1-2 s). Its one BLAS thread is then `_one_blas_thread`'s, not the environment's
        settings["distributed.worker.multiprocessing-method"] = "fork"
    # dashboard on a free port: with None the scheduler's HTTP server still takes 8787, and a second
    # workbench run beside the first warns (an error under pytest) and moves
    with dask.config.set(settings), warnings.catch_warnings():
        # the nannies fork from a helper thread; Python 3.12+ warns of any fork of a threaded process, but
        # the forked worker runs only its own event loop (Dask supports "fork")
        warnings.filterwarnings("ignore", message=r".*multi-threaded, use of fork\(\)", category=DeprecationWarning)
        cluster = LocalCluster(n_workers=workers, threads_per_worker=1, processes=True, dashboard_address=":0",
                               silence_logs=logging.ERROR)
    # the client closes first (`mapper` closes in order), then its cluster
    return Client(cluster, set_as_default=False), cluster


def _quiet_workers(client: Any) -> None:
    """Silence the local workers' logs once their work is done: a worker whose heartbeat meets the closing
    scheduler logs an ERROR and its traceback (dask/distributed issue 7105), after a run that succeeded (seen once
    in about 15 ``diagnose --workers 2`` runs). Best effort: a worker that is already gone has nothing to say, and
    no failure here may hide the run's own result.
    """
    with contextlib.suppress(Exception):
        client.run(_silence_worker_logs)


def _silence_worker_logs() -> None:
    for name in ("distributed", "distributed.worker", "distributed.nanny", "distributed.core"):
        logging.getLogger(name).setLevel(logging.CRITICAL)


def _one_blas_thread(function: Callable[[Any, Any], Any], shared: Any, task: Any) -> Any:
    """Run a task with one BLAS thread: each worker is one process, and several multithreaded BLAS
    on a machine's cores contend (as in the Monte Carlo chunks of `workbench.uq.stochastic`).
    """
    from threadpoolctl import threadpool_limits

    with threadpool_limits(1):
        return function(shared, task)


def _dask_mapper(client: Any, progress: Progress | None) -> Mapper:
    import dask
    from distributed import as_completed

    def run(function: Callable[[Any, Any], Any], tasks: Sequence[Any], label: str, shared: Any) -> list[Any]:
        # one future for the whole shared object (scattering a tuple would scatter its items one by one)
        common = client.scatter([shared], broadcast=True)[0] if shared is not None else None
        # a task may carry a whole campaign (tens of MB) inside the graph on purpose: a task whose worker died
        # is then rerun elsewhere, which scattered data (lost with its worker) would not allow. Set here, with
        # distributed loaded: a "distributed.*" key set before its import is dropped, with all of distributed's
        # configuration, when the setting ends, and the cluster then fails as it closes
        with dask.config.set({"distributed.admin.large-graph-warning-threshold": "500MB"}):
            futures = [client.submit(_one_blas_thread, function, common, task, pure=False, retries=RETRIES)
                       for task in tasks]
        index = {future.key: i for i, future in enumerate(futures)}
        results: list[Any] = [None] * len(futures)
        # as tasks end, in any order (the loop named: this client is not the process's default one)
        for done, future in enumerate(as_completed(futures, loop=client.loop), start=1):
            results[index[future.key]] = future.result()
            report(progress, label, done, len(futures))
        return results

    return run

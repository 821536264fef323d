"""The one way independent work is handed out: a ``Mapper`` the caller passes in.

Numerical code that has many independent tasks (Monte Carlo chunks, circle fits of many tests,
validation cases) never starts processes itself and imports no scheduler: it builds its tasks and
calls ``mapper(function, tasks, label, shared)``, which returns ``[function(shared, task) for task
in tasks]`` in the tasks' order (``shared``, the model say, is sent to each worker once). `serial`
does exactly that in this process; `workbench.workflow.execution` gives
the Dask mapper (a local cluster, or a running scheduler at ``--scheduler ADDRESS``). Each task
carries its own inputs and seeds, so the results do not depend on the mapper or the worker count.
"""

from __future__ import annotations

import os
from collections.abc import Callable, Sequence
from typing import Any

from workbench.progress import Progress, report

__all__ = ["Mapper", "local_cores", "serial", "serial_mapper"]

Mapper = Callable[[Callable[[Any, Any], Any], Sequence[Any], str, Any], list[Any]]
"""``mapper(function, tasks, label, shared) -> [function(shared, task) for task in tasks]``, in order."""


def serial(function: Callable[[Any, Any], Any], tasks: Sequence[Any], label: str = "tasks", shared: Any = None,
           progress: Progress | None = None) -> list[Any]:
    """Run ``tasks`` one after the other in this process, reporting ``progress`` after each."""
    out = []
    for done, task in enumerate(tasks, start=1):
        out.append(function(shared, task))
        report(progress, label, done, len(tasks))
    return out


def serial_mapper(progress: Progress | None = None) -> Mapper:
    """`serial` as a `Mapper` reporting to ``progress``."""
    return lambda function, tasks, label, shared: serial(function, tasks, label, shared, progress)


def local_cores(most: int = 8) -> int:
    """The cores this process may use (its CPU affinity where the system tells it), at least 1, at most ``most``:
    a campaign's dozen circle-fit tasks keep no more than a few workers busy.
    """
    try:
        count = len(os.sched_getaffinity(0))
    except AttributeError:  # macOS and Windows do not tell a process its affinity
        count = os.cpu_count() or 1
    return max(1, min(count, most))

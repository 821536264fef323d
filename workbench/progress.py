"""The one progress mechanism: long loops report through a callback the command line passes in.

Numerical code never draws a bar (it imports no tqdm); it calls ``progress(label, done, total)``
after each unit of work, with ``done`` counting from 1 to ``total``. The command line turns the calls
into tqdm bars (`workbench.cli`); a library user passes any callable, or nothing.
"""

from __future__ import annotations

from collections.abc import Callable

__all__ = ["Progress", "report"]

Progress = Callable[[str, int, int], None]
"""``progress(label, done, total)``: ``done`` of ``total`` units of the task ``label`` are finished."""


def report(progress: Progress | None, label: str, done: int, total: int) -> None:
    """Call ``progress`` when one was given."""
    if progress is not None:
        progress(label, done, total)

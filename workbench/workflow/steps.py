"""The steps of a run, timed for the report's "what was done" (`workbench.workflow.study`)."""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass

__all__ = ["Notify", "Step", "Steps", "step_line", "tell"]

Notify = Callable[[str], None] | None
"""Called with one line per finished step (the command line prints it), or None."""


@dataclass(frozen=True)
class Step:
    """One step of the run, for the report's "what was done": wall time (s), seed where random."""

    name: str
    wall_time_s: float
    detail: str = ""
    seed: int | None = None


def step_line(prefix: str, step: Step) -> str:
    """The line told of a finished step."""
    return f"{prefix}{step.name}: {step.detail} ({step.wall_time_s:.1f} s)"


def tell(notify: Notify, prefix: str, steps: tuple[Step, ...] | list[Step]) -> None:
    """Tell ``notify`` the lines of steps that ran elsewhere (another process), in their order."""
    for step in steps:
        if notify is not None:
            notify(step_line(prefix, step))


class Steps:
    """Times the steps and tells ``notify`` one line as each ends."""

    def __init__(self, notify: Notify, prefix: str):
        self.items: list[Step] = []
        self.notify, self.prefix = notify, prefix

    def add(self, name: str, start: float | None, detail: str = "", seed: int | None = None,
            wall_time_s: float | None = None) -> None:
        if wall_time_s is None:
            if start is None:
                raise ValueError(f"step {name!r}: give its start time or its wall time")
            wall_time_s = time.perf_counter() - start
        step = Step(name, wall_time_s, detail, seed)
        self.items.append(step)
        tell(self.notify, self.prefix, [step])

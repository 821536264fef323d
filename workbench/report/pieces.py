"""Small HTML pieces shared by the report's pages: escaped text, numbers, figures, absent parts.

Drawing the figures is most of a page's time (matplotlib's text layout and rasterising: 10 s of the
demo's 12 s page). Inside ``with figure_pool(workers) as pool:`` `html_figure` hands each figure,
pickled, to ``workers`` processes and returns a placeholder at once, so that the figures are drawn
while the page is built; ``pool.resolve(page)`` then puts the images in. Outside a pool it draws
in place. The PNG bytes are the same either way.
"""

from __future__ import annotations

import base64
import html
import math
import multiprocessing
import pickle
from collections.abc import Iterator
from concurrent.futures import Future, ProcessPoolExecutor
from contextlib import contextmanager

from workbench.report.plots import figure_png, plt

__all__ = ["escape", "number", "html_figure", "absent", "FigurePool", "figure_pool"]


def _draw(pickled: bytes) -> bytes:
    """PNG bytes of a pickled figure (run in a pool process)."""
    return figure_png(pickle.loads(pickled))


class FigurePool:
    """Figures drawn in other processes (module docstring); ``resolve`` puts them in the page."""

    def __init__(self, executor: ProcessPoolExecutor):
        self.executor = executor
        self.pending: list[Future] = []

    def submit(self, fig) -> str:
        """A placeholder for the PNG of ``fig`` (closed here), drawn in the pool."""
        pickled = pickle.dumps(fig)
        plt.close(fig)
        self.pending.append(self.executor.submit(_draw, pickled))
        return f"\x00figure {len(self.pending) - 1}\x00"

    def resolve(self, text: str) -> str:
        """``text`` with every placeholder replaced by its figure's base64 PNG."""
        for i, future in enumerate(self.pending):
            text = text.replace(f"\x00figure {i}\x00", base64.b64encode(future.result()).decode("ascii"))
        return text


_POOL: FigurePool | None = None


@contextmanager
def figure_pool(workers: int) -> Iterator[FigurePool | None]:
    """A `FigurePool` of ``workers`` processes for the figures of the pages built inside it; None
    (figures drawn in place) for one worker.
    """
    global _POOL
    if workers <= 1:
        yield None
        return
    # forkserver: the pool's processes do not inherit this process's threads (a Dask client's)
    with ProcessPoolExecutor(workers, mp_context=multiprocessing.get_context("forkserver")) as executor:
        _POOL = FigurePool(executor)
        try:
            yield _POOL
        finally:
            _POOL = None


def escape(value: object) -> str:
    """``value`` as text safe in HTML (quotes too)."""
    return html.escape(str(value), quote=True)


def number(value: float | None, fmt: str = ".4g") -> str:
    """A number formatted with ``fmt``; "-" for None, NaN or infinity."""
    if value is None or not math.isfinite(float(value)):
        return "-"
    return format(float(value), fmt)


def html_figure(fig, caption: str, alt: str) -> str:
    """A matplotlib figure as an embedded PNG with its caption (the figure is closed); inside a
    `figure_pool`, a placeholder that the pool resolves.
    """
    data = _POOL.submit(fig) if _POOL is not None else base64.b64encode(figure_png(fig)).decode("ascii")
    return (f'<figure><img src="data:image/png;base64,{data}" alt="{escape(alt)}">'
            f"<figcaption>{escape(caption)}</figcaption></figure>")


def absent(reason: str) -> str:
    """A part not shown, and why."""
    return f'<p class="absent">Not shown: {escape(reason)}</p>'

"""Small HTML pieces shared by the report's pages: escaped text, numbers, figures, absent parts."""

from __future__ import annotations

import base64
import html
import math

from workbench.report.plots import figure_png

__all__ = ["escape", "number", "html_figure", "absent"]


def escape(value: object) -> str:
    """``value`` as text safe in HTML (quotes too)."""
    return html.escape(str(value), quote=True)


def number(value: float | None, fmt: str = ".4g") -> str:
    """A number formatted with ``fmt``; "-" for None, NaN or infinity."""
    if value is None or not math.isfinite(float(value)):
        return "-"
    return format(float(value), fmt)


def html_figure(fig, caption: str, alt: str) -> str:
    """A matplotlib figure as an embedded PNG with its caption (the figure is closed)."""
    data = base64.b64encode(figure_png(fig)).decode("ascii")
    return (f'<figure><img src="data:image/png;base64,{data}" alt="{escape(alt)}">'
            f"<figcaption>{escape(caption)}</figcaption></figure>")


def absent(reason: str) -> str:
    """A part not shown, and why."""
    return f'<p class="absent">Not shown: {escape(reason)}</p>'

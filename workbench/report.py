"""Figures (and later the HTML reports): the only module that imports matplotlib.

Plot functions take an ``ax`` and return it; the numbers they draw are computed elsewhere.
"""

from __future__ import annotations

from collections.abc import Mapping
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

__all__ = ["plot_moment_errors", "save_figure", "moment_error_figure"]

_COLOURS = {"smr1": "tab:orange", "smr2": "tab:blue", "adaptive": "tab:green", "pert2": "tab:purple",
            "mc": "tab:gray"}


def plot_moment_errors(ax, errors_percent: Mapping[str, np.ndarray], title: str = "",
                       band_percent: np.ndarray | None = None, ylabel: str = "relative error (%)"):
    """Grouped bars of relative errors per mode for several methods (paper Figure 11 style).

    Parameters
    ----------
    ax : matplotlib axes.
    errors_percent : method name -> (n_modes,) signed relative errors in percent.
    band_percent : optional (n_modes,) half-width of the reference's own uncertainty, shaded.
    """
    methods = list(errors_percent)
    n = len(next(iter(errors_percent.values())))
    modes = np.arange(1, n + 1)
    width = 0.8 / max(len(methods), 1)
    for i, method in enumerate(methods):
        ax.bar(modes - 0.4 + width * (i + 0.5), errors_percent[method], width, label=method,
               color=_COLOURS.get(method))
    if band_percent is not None:
        ax.fill_between(np.r_[0.5, modes + 0.5], np.r_[band_percent[0], band_percent],
                        -np.r_[band_percent[0], band_percent], step="pre", color="0.85", zorder=0,
                        label="reference 3 SE")
    ax.axhline(0.0, color="k", lw=0.6)
    for level in (-1.0, 1.0):
        ax.axhline(level, color="k", lw=0.6, ls=":")
    ax.set_xticks(modes)
    ax.set_xlabel("mode")
    ax.set_ylabel(ylabel)
    if title:
        ax.set_title(title, fontsize=10)
    return ax


def moment_error_figure(panels: Mapping[str, tuple[Mapping[str, np.ndarray], Mapping[str, np.ndarray]]],
                        bands: Mapping[str, tuple[np.ndarray, np.ndarray]] | None = None):
    """One row per case, two columns (mean, std): ``panels[case] = (mean_errors, std_errors)``."""
    fig, axes = plt.subplots(len(panels), 2, figsize=(11, 3.2 * len(panels)), squeeze=False)
    for row, (case, (mean_err, std_err)) in enumerate(panels.items()):
        band = (bands or {}).get(case, (None, None))
        plot_moment_errors(axes[row, 0], mean_err, f"{case}: mean", band[0])
        plot_moment_errors(axes[row, 1], std_err, f"{case}: standard deviation", band[1])
    axes[0, 1].legend(fontsize=8, ncol=3)
    fig.tight_layout()
    return fig


def save_figure(fig, path: str | Path) -> Path:
    """Write ``fig`` as PNG (whole or not at all) and close it."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.with_name(f".{path.name}.tmp.png")
    fig.savefig(tmp, dpi=120)
    plt.close(fig)
    tmp.replace(path)
    return path

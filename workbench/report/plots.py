"""Figures of the benchmarks and of the identification report: the only module that imports matplotlib.

Plot functions take an ``ax`` and return it; figure functions return the figure. The numbers they
draw are computed elsewhere (`workbench.workflow.study`, `workbench.uq.smr`, `workbench.uq.prediction`);
`figure_png` and `save_figure` encode a figure and close it. Agg backend, never ``plt.show()``.
"""

from __future__ import annotations

import io
import warnings
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
from matplotlib.axes import Axes  # noqa: E402
from matplotlib.figure import Figure  # noqa: E402

from workbench.io.outputs import write_file  # noqa: E402
from workbench.model.modal import FRFSet  # noqa: E402
from workbench.uq.prediction import FRFBand  # noqa: E402
from workbench.workflow.measured import NyquistData  # noqa: E402
from workbench.workflow.report_inputs import ShapeComparison  # noqa: E402

__all__ = ["plt", "plot_moment_errors", "moment_error_figure", "save_figure", "figure_png", "frf_overlay_figure",
           "plot_frf_band", "band_figure", "band_zoom_figure", "nyquist_figure", "forest_figure", "posterior_figure",
           "plot_frequency_spread", "prediction_figure", "shape_figure", "mac_figure"]

_COLOURS = {"smr1": "tab:orange", "smr2": "tab:blue", "adaptive": "tab:green", "pert2": "tab:purple",
            "mc": "tab:gray", "moments": "tab:blue", "bayes": "tab:red"}
_BAND = "tab:blue"
_MEASURED = "0.35"


# ------------------------------------------------------------------------------ Figure 11 style

def plot_moment_errors(ax: Axes, errors_percent: Mapping[str, np.ndarray], title: str = "",
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


def save_figure(fig: Figure, path: str | Path) -> Path:
    """Write ``fig`` as PNG (whole or not at all, `write_file`) and close it."""
    buffer = io.BytesIO()
    fig.savefig(buffer, format="png", dpi=120)
    plt.close(fig)
    return write_file(path, buffer.getvalue())


def figure_png(fig: Figure, dpi: int = 90) -> bytes:
    """The figure as PNG bytes (for embedding in a report); the figure is closed."""
    buffer = io.BytesIO()
    try:
        fig.savefig(buffer, format="png", dpi=dpi)
    finally:
        plt.close(fig)
    return buffer.getvalue()


def _grid(count: int, ncols: int, panel: tuple[float, float]):
    nrows = -(-count // ncols)
    fig, axes = plt.subplots(nrows, ncols, figsize=(panel[0] * ncols, panel[1] * nrows), squeeze=False,
                             layout="constrained")
    for ax in axes.flat[count:]:
        ax.set_visible(False)
    return fig, axes.flat[:count]


_UNITS = {"accelerance": "m/s$^2$/N", "mobility": "m/s/N", "receptance": "m/N"}


def _frf_axes(ax: Axes, quantity: str, title: str = "", log: bool = True):
    if log:
        ax.set_yscale("log")
    ax.set_xlabel("frequency (Hz)")
    ax.set_ylabel(f"|{quantity}| ({_UNITS.get(quantity, '')})")
    ax.grid(True, which="major", lw=0.3, alpha=0.6)
    if title:
        ax.set_title(title, fontsize=10)
    return ax


def _positive(frequency_hz: np.ndarray, values: np.ndarray):
    keep = np.asarray(frequency_hz) > 0  # |H| is 0 at 0 Hz for mobility and accelerance: no log
    return np.asarray(frequency_hz)[keep], np.abs(np.asarray(values))[..., keep]


# ---------------------------------------------------------------------------- measured FRFs

def frf_overlay_figure(sets: Mapping[object, FRFSet], ncols: int = 2) -> Figure:
    """Measured ``|H|`` of every test overlaid, one panel per sensor (log scale against Hz).

    Parameters
    ----------
    sets : test id -> `workbench.model.modal.FRFSet` (sensors in the same order in every test).
    """
    tests = list(sets)
    first = sets[tests[0]]
    colours = plt.cm.viridis(np.linspace(0.0, 0.9, len(tests)))
    fig, axes = _grid(len(first.responses), ncols, (6.2, 2.8))
    for s, ax in enumerate(axes):
        for test, colour in zip(tests, colours):
            f, mag = _positive(sets[test].frequency_hz, sets[test].values[s])
            ax.plot(f, mag, lw=0.5, color=colour, label=str(test))
        _frf_axes(ax, first.quantity, f"sensor {first.responses[s]}")
    if len(tests) <= 12:
        axes[0].legend(title="test", fontsize=7, ncol=3, title_fontsize=7)
    else:
        axes[0].text(0.01, 0.02, f"{len(tests)} tests, colour by test order", transform=axes[0].transAxes,
                     fontsize=7)
    return fig


# ------------------------------------------------------------------------------ circle fits

def nyquist_figure(panels: Sequence[NyquistData], ncols: int = 5) -> Figure:
    """Nyquist plots (mobility) of one circle fit per mode: measured points and the fitted circle.

    Parameters
    ----------
    panels : `workbench.workflow.study.NyquistData`, one per mode.
    """
    fig, axes = _grid(len(panels), ncols, (2.5, 2.5))
    for p, ax in zip(panels, axes):
        ax.plot(p.measured.real, p.measured.imag, ".", ms=2.5, color="0.3")
        ax.plot(p.fitted.real, p.fitted.imag, color="tab:red", lw=0.9)  # on top: the dots crowd the band's ends
        ax.set_aspect("equal", adjustable="datalim")
        ax.tick_params(labelsize=6)
        ax.ticklabel_format(style="sci", scilimits=(-2, 2))
        ax.xaxis.get_offset_text().set_fontsize(6)
        ax.yaxis.get_offset_text().set_fontsize(6)
        flags = f"\n{', '.join(p.flags)}" if p.flags else ""
        ax.set_title(f"mode {p.mode}: {p.frequency_hz:.2f} Hz, {100 * p.damping_ratio:.2f} %\n"
                     f"{p.sensor}, error {p.circle_error:.1e}{flags}", fontsize=7,
                     color="tab:red" if p.flags else "k")
    return fig


# -------------------------------------------------------------------------------- joint models

def forest_figure(rows: Sequence[Mapping[str, Any]]) -> Figure:
    """Joint models of several estimators with their 95 % intervals (forest plot).

    Parameters
    ----------
    rows : one per (group, estimator): ``label``, ``method`` (colour), ``modulus_gpa``,
        ``modulus_ci`` ((lo, hi) or None), ``cov``, ``cov_ci`` ((lo, hi) or None).
    """
    fig, axes = plt.subplots(1, 2, figsize=(10, 0.55 * len(rows) + 1.4), squeeze=False, layout="constrained")
    y = np.arange(len(rows))[::-1]
    for ax, key, label in ((axes[0, 0], "modulus", "mean joint modulus E (GPa)"),
                           (axes[0, 1], "cov", "CoV of E (%)")):
        scale = 1.0 if key == "modulus" else 100.0  # CoV drawn in %
        for yi, row in zip(y, rows):
            value = scale * row["modulus_gpa" if key == "modulus" else "cov"]
            ci = None if row[f"{key}_ci"] is None else scale * np.asarray(row[f"{key}_ci"], float)
            colour = _COLOURS.get(str(row["method"]), "k")
            if ci is not None:
                ax.errorbar(value, yi, xerr=[[value - ci[0]], [ci[1] - value]], fmt="o", color=colour, capsize=4)
            else:
                ax.plot(value, yi, "o", mfc="white", color=colour)
        ax.set_yticks(y)
        ax.set_yticklabels([str(r["label"]) for r in rows] if key == "modulus" else [])
        ax.set_xlabel(label)
        ax.grid(True, axis="x", lw=0.3)
        ax.set_ylim(-0.7, len(rows) - 0.3)
    return fig


def posterior_figure(posterior, az) -> object:
    """Arviz posterior densities of each group's E (GPa) and CoV, and their pair plot.

    Parameters
    ----------
    posterior : `workbench.identify.bayes.Posterior` with its ``idata``.
    az : the arviz module (imported quietly by `workbench.identify.bayes`).
    """
    post = posterior.idata.posterior
    groups = posterior.groups
    values = {}
    for g in groups:
        values[f"E_{g} (GPa)"] = post[f"youngs_modulus_{g}"].values / 1e9
        values[f"CoV_{g} (%)"] = 100 * post[f"cov_{g}"].values
    scaled = az.from_dict(posterior=values)
    fig, axes = plt.subplots(len(groups), 3, figsize=(11, 3.0 * len(groups)), squeeze=False, layout="constrained")
    with warnings.catch_warnings():
        # arviz 0.x calls a matplotlib helper that matplotlib 3.11 deprecates: theirs to fix, not a fault here
        warnings.filterwarnings("ignore", category=matplotlib.MatplotlibDeprecationWarning)
        for row, g in enumerate(groups):
            names = [f"E_{g} (GPa)", f"CoV_{g} (%)"]
            az.plot_posterior(scaled, var_names=names, ax=axes[row, :2], hdi_prob=0.95, point_estimate="median",
                              textsize=8)
            az.plot_pair(scaled, var_names=names, kind="hexbin", ax=axes[row, 2], textsize=8)
    return fig


# ---------------------------------------------------------------------------- stochastic FRF

def plot_frf_band(ax: Axes, band: FRFBand, sensor: int, measured: Mapping[object, FRFSet] | None = None,
                  title: str = "", window: tuple[float, float] | None = None, log: bool = True) -> Axes:
    """One sensor's stochastic FRF (Figures 12, 14, 16): envelope, 5-95 % band and mean of ``|H|``
    over the joint samples, over the measured ``|H|`` of every test (grey).

    Parameters
    ----------
    band : `workbench.uq.prediction.FRFBand`.
    sensor : row of ``band`` (frame order).
    measured : test id -> measured `FRFSet` with the same sensors, or None.
    window : (f_lo, f_hi) Hz to zoom on, or None for the whole band.
    log : logarithmic ``|H|`` axis (linear suits a zoom on one peak).
    """
    lo, hi = window or (0.0, float(band.frequency_hz.max()))
    inside = (band.frequency_hz >= lo) & (band.frequency_hz <= hi)
    # only the lines in view (and one beyond each edge): drawing clipped points costs as much as shown ones
    inside |= np.convolve(inside, np.ones(3), "same") > 0
    f = band.frequency_hz[inside]
    ax.fill_between(f, band.lower[sensor, inside], band.upper[sensor, inside], color=_BAND, alpha=0.15, lw=0,
                    label=f"envelope ({band.samples} samples)")
    ax.fill_between(f, band.p05[sensor, inside], band.p95[sensor, inside], color=_BAND, alpha=0.35, lw=0,
                    label="5-95 %")
    tops = [band.upper[sensor, inside].max()]
    for i, frfs in enumerate((measured or {}).values()):
        fm, mag = _positive(frfs.frequency_hz, frfs.values[sensor])
        seen = (fm >= f[0]) & (fm <= f[-1])
        ax.plot(fm[seen], mag[seen], color=_MEASURED, lw=0.4, alpha=0.7,
                label="measured (each test)" if i == 0 else None)
        tops.append(mag[seen].max(initial=0.0))
    ax.plot(f, band.mean[sensor, inside], color="navy", lw=0.9, label="mean")
    top = float(max(tops))
    floor = float(np.percentile(band.lower[sensor, inside], 1.0))
    ax.set_xlim(lo, hi)
    ax.set_ylim(*((max(floor, 1e-6 * top) / 1.5, 1.5 * top) if log else (0.0, 1.05 * top)))
    return _frf_axes(ax, band.quantity, title or f"sensor {band.sensors[sensor]}", log)


def band_figure(band: FRFBand, measured: Mapping[object, FRFSet] | None = None, ncols: int = 2) -> Figure:
    """`plot_frf_band` for every sensor of the band, one panel each."""
    fig, axes = _grid(len(band.sensors), ncols, (6.2, 2.9))
    for s, ax in enumerate(axes):
        plot_frf_band(ax, band, s, measured)
    axes[0].legend(fontsize=7, loc="lower right")
    return fig


def band_zoom_figure(band: FRFBand, measured: Mapping[object, FRFSet] | None,
                     windows: Sequence[tuple[float, float, int]],
                     ncols: int = 5):
    """The band around each mode (`workbench.workflow.study.mode_windows`: window and sensor), one panel each."""
    fig, axes = _grid(len(windows), ncols, (2.6, 2.3))
    for k, (ax, (lo, hi, sensor)) in enumerate(zip(axes, windows)):
        plot_frf_band(ax, band, sensor, measured, f"mode {k + 1}, {band.sensors[sensor]}", (lo, hi), log=False)
        ax.set_title(ax.get_title(), fontsize=8)
        ax.set_xlabel("Hz", fontsize=7)
        ax.set_ylabel("")
        ax.tick_params(labelsize=6)
        ax.xaxis.set_major_locator(matplotlib.ticker.MaxNLocator(3))
    return fig


def plot_frequency_spread(ax: Axes, predicted_samples_pct: np.ndarray, predicted_std_pct: np.ndarray,
                          measured_pct: np.ndarray, title: str = ""):
    """Per mode, the predicted and the measured frequency spread, in % of the predicted mean.

    Parameters
    ----------
    predicted_samples_pct : (samples, n_modes) Monte Carlo frequencies of the prediction (5-95 % bar).
    predicted_std_pct : (n_modes,) the SMR standard deviation (the +-1 std bar about 0).
    measured_pct : (n_tests, n_modes) measured frequencies (dots, NaN skipped) and their mean (diamond).
    """
    n = measured_pct.shape[1]
    modes = np.arange(1, n + 1)
    lo, hi = np.percentile(predicted_samples_pct[:, :n], [5.0, 95.0], axis=0)
    ax.bar(modes - 0.17, hi - lo, 0.28, bottom=lo, color=_BAND, alpha=0.35, label="predicted 5-95 %")
    ax.errorbar(modes - 0.17, np.zeros(n), yerr=predicted_std_pct[:n], fmt="_", color="navy", capsize=3,
                label="predicted mean +- std (SMR)")
    jitter = np.linspace(-0.07, 0.07, measured_pct.shape[0]) if measured_pct.shape[0] > 1 else np.zeros(1)
    for k in range(n):
        ax.plot(modes[k] + 0.17 + jitter, measured_pct[:, k], ".", ms=3, color=_MEASURED,
                label="measured (each test)" if k == 0 else None)
    with np.errstate(invalid="ignore"):
        ax.plot(modes + 0.17, np.nanmean(measured_pct, axis=0), "D", ms=4, color="tab:red", label="measured mean")
    ax.axhline(0.0, color="k", lw=0.5)
    ax.set_xticks(modes)
    ax.set_xlabel("mode")
    ax.set_ylabel("frequency - predicted mean (%)")
    ax.grid(True, axis="y", lw=0.3)
    if title:
        ax.set_title(title, fontsize=10)
    return ax


def prediction_figure(band: FRFBand, measured: Mapping[object, FRFSet], sensor: int, predicted_samples_pct: np.ndarray,
                      predicted_std_pct: np.ndarray, measured_pct: np.ndarray):
    """Section 5 side by side: the predicted band at one sensor over the measured FRFs (left),
    and the predicted against the measured frequency spread per mode (right).
    """
    fig, axes = plt.subplots(1, 2, figsize=(13, 4.3), gridspec_kw={"width_ratios": [1.5, 1.0]}, layout="constrained")
    plot_frf_band(axes[0], band, sensor, measured, f"predicted band and measured FRFs, sensor {band.sensors[sensor]}")
    axes[0].legend(fontsize=7, loc="lower right")
    plot_frequency_spread(axes[1], predicted_samples_pct, predicted_std_pct, measured_pct,
                          "eigenfrequencies: predicted and measured spread")
    axes[1].legend(fontsize=7, loc="best")
    return fig


# ------------------------------------------------------------------------- mode shapes and MAC

def shape_figure(shapes: ShapeComparison, ncols: int = 3) -> Figure:
    """Measured against model mode shapes at the sensors, one panel per measured mode.

    Each shape is scaled to a peak of 1 (the model's paired mode signed as the measured one), so that
    the panel compares forms; both are receptance modal constants ``phi(s) phi(exc)`` (1/kg) before scaling.
    """
    fig, axes = _grid(len(shapes.modes), ncols, (3.6, 2.5))
    x = np.arange(len(shapes.sensors))
    for k, ax in enumerate(axes):
        measured = shapes.measured[k]
        model = shapes.model[shapes.paired[k]]
        peak = np.nanmax(np.abs(measured)) if np.isfinite(measured).any() else 1.0
        sign = np.sign(np.nansum(measured * model)) or 1.0
        ax.plot(x, sign * model / np.max(np.abs(model)), "s--", color=_BAND, label="model (nominal)")
        ax.plot(x, measured / (peak or 1.0), "o-", color="k", label="measured (mean of tests)")
        ax.axhline(0.0, color="0.6", lw=0.6)
        ax.set_xticks(x)
        ax.set_xticklabels(shapes.sensors, fontsize=7, rotation=45 if len(x) > 4 else 0)
        ax.set_ylim(-1.15, 1.15)
        ax.set_title(f"mode {shapes.modes[k]} / model {shapes.model_modes[shapes.paired[k]]} "
                     f"({shapes.model_hz[shapes.paired[k]]:.1f} Hz)", fontsize=9)
        if k == 0:
            ax.legend(fontsize=7)
            ax.set_ylabel("shape / peak (-)")
    return fig


def mac_figure(shapes: ShapeComparison) -> Figure:
    """The MAC matrix of the measured shapes (rows) against the model's (columns), values written in."""
    fig, ax = plt.subplots(figsize=(1.0 + 0.55 * shapes.model_modes.size, 0.9 + 0.45 * shapes.modes.size),
                           layout="constrained")
    image = ax.imshow(shapes.mac, vmin=0.0, vmax=1.0, cmap="Blues", aspect="auto")
    for (i, j), value in np.ndenumerate(shapes.mac):
        if np.isfinite(value):
            ax.text(j, i, f"{value:.2f}", ha="center", va="center", fontsize=7,
                    color="white" if value > 0.6 else "k")
    ax.set_xticks(np.arange(shapes.model_modes.size), [str(m) for m in shapes.model_modes])
    ax.set_yticks(np.arange(shapes.modes.size), [str(m) for m in shapes.modes])
    ax.set_xlabel("model mode (nominal, elastic)")
    ax.set_ylabel("measured mode")
    fig.colorbar(image, ax=ax, label="MAC (-)")
    return fig


def design_width_figure(curves: Mapping[str, Mapping[str, tuple[np.ndarray, np.ndarray]]], target: float,
                        chosen: tuple[int, Mapping[str, float]] | None = None) -> Figure:
    """Predicted 95 % interval width (%) of each group's CoV against the number of tests, one line per family.

    Parameters
    ----------
    curves : group -> family -> (tests, width in %), sorted by tests.
    target : the target width, %, drawn as a line.  chosen : (tests, group -> width %) of the recommended design.
    """
    fig, axes = plt.subplots(1, len(curves), figsize=(5.2 * len(curves), 3.6), squeeze=False, layout="constrained")
    for ax, (group, families) in zip(axes[0], curves.items()):
        for family, (tests, width) in families.items():
            ax.plot(tests, width, "o-", ms=3, lw=1, label=family)
        ax.axhline(target, color="k", ls="--", lw=0.8, label="target")
        if chosen is not None:
            ax.plot(chosen[0], chosen[1][group], "*", ms=14, color="crimson", label="recommended")
        ax.set_yscale("log")
        ax.set_xlabel("tests")
        ax.set_ylabel("predicted 95 % width of the CoV (% of its value)")
        ax.set_title(f"group {group}")
        ax.grid(True, which="both", lw=0.3)
    axes[0, 0].legend(fontsize=7)
    return fig

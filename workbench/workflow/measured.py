"""What the tests measured: the circle-fit modes of every test of a campaign, read for the report.

`extract_campaign` is the one place a campaign's FRFs go through the circle fit
(`workbench.extraction.modes.extract_tests`; `workbench extract`, the report and the demo all call it);
`load_campaigns` runs it for several campaigns in worker processes. `Extraction` gives the
per-test frequencies and damping as arrays (NaN where a fit is unusable), the identification's
`MeasuredModes`, and the measured mean damping that the FRF synthesis uses (paper 2.2.2);
`nyquist_data` and `mode_windows` prepare what the report draws of them. `measured_modes` turns a
campaign (modes.csv, FRFs or published moments) into the one `MeasuredModes` record. No matplotlib here.
"""

from __future__ import annotations

import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np
import pandas as pd

from workbench.extraction.circlefit import to_mobility
from workbench.extraction.modes import ModeEstimate, extract_tests
from workbench.extraction.records import MeasuredModes
from workbench.io.campaign import (
    MODES_COLUMNS,
    MODES_OPTIONAL,
    Campaign,
    CampaignError,
    amplitude_of_tests,
    frf_set,
    load_campaign,
)
from workbench.model.modal import modal_superposition
from workbench.progress import Progress
from workbench.tasks import Mapper, serial_mapper
from workbench.uq.prediction import FRFBand

__all__ = ["UNUSABLE_FLAGS", "Extraction", "extract_campaign", "load_and_extract", "load_campaigns",
           "campaign_label", "frequency_axis", "extraction_rows", "MODES_HEADER", "SHAPES_HEADER",
           "QUALITY_HEADER", "NyquistData", "nyquist_data", "mode_windows", "measured_modes"]

# A mode whose combined fit carries one of these flags is left out of that test, as in
# `measured_modes`: the circle is lost in noise, is not a circle, or is narrower than a line and not one mode's.
UNUSABLE_FLAGS = ("weak", "poor_circle", "unresolved")


@dataclass(frozen=True)
class Extraction:
    """Circle-fit modes of every test of a campaign (`workbench.extraction.modes.extract_tests`).

    Attributes
    ----------
    sets : test id -> the test's measured FRFs (`FRFSet`, sensors in frame order).
    bands : (n_modes,) pairs (f_lo, f_hi), Hz; band k is mode k + 1 in every test.
    estimates : test id -> one `ModeEstimate` per band (sensors combined by fit quality).
    wall_time_s : s, the circle fits only.
    """

    sets: dict
    bands: tuple[tuple[float, float], ...]
    estimates: dict
    wall_time_s: float = 0.0

    @property
    def tests(self) -> list:
        return list(self.estimates)

    @property
    def modes(self) -> np.ndarray:
        """(n_modes,) mode numbers, 1 = lowest."""
        return np.arange(1, len(self.bands) + 1)

    def _usable(self, e: ModeEstimate, k: int) -> bool:
        """Not flagged unusable, and its frequency within its band widened by the band's width each side: a fit
        that put the pole far outside the data it fitted (once 2e15 Hz) estimates nothing.
        """
        lo, hi = self.bands[k]
        inside = bool(np.isfinite(e.frequency_hz) and lo - (hi - lo) <= e.frequency_hz <= hi + (hi - lo))
        return inside and not set(UNUSABLE_FLAGS) & set(e.flags)

    def _table(self, value: Callable[[ModeEstimate], float], usable: bool) -> np.ndarray:
        return np.array([[value(e) if not usable or self._usable(e, k) else np.nan
                          for k, e in enumerate(self.estimates[t])] for t in self.tests], float)

    def frequency_hz(self, usable: bool = True) -> np.ndarray:
        """(n_tests, n_modes) natural frequencies, Hz; NaN where the fit is unusable (`UNUSABLE_FLAGS`)."""
        return self._table(lambda e: e.frequency_hz, usable)

    def damping_ratio(self, usable: bool = True) -> np.ndarray:
        """(n_tests, n_modes) viscous modal damping ratios; NaN where the fit is unusable."""
        return self._table(lambda e: e.damping_ratio, usable)

    def flag_counts(self) -> np.ndarray:
        """(n_modes,) number of tests whose estimate of the mode carries any flag."""
        return np.array([sum(bool(self.estimates[t][k].flags) for t in self.tests) for k in range(len(self.bands))])

    def mean_damping(self) -> np.ndarray:
        """(n_modes,) mean measured damping ratio of each mode over the tests (the paper's FRF
        synthesis uses the measured modal damping, 2.2.2); a mode never usable takes all its fits.
        """
        usable, every = self.damping_ratio(True), self.damping_ratio(False)
        found = np.isfinite(usable).any(axis=0)
        return np.where(found, np.nanmean(np.where(found, usable, 0.0), axis=0), every.mean(axis=0))

    def measured_modes(self, source: str) -> MeasuredModes:
        """The identification's input: every test's usable frequencies and damping (NaN where the fit is
        unusable, `UNUSABLE_FLAGS`), with the fits' scatter over the sensors (NaN there too) and flags.
        """
        return MeasuredModes(self.frequency_hz(), modes=self.modes, damping_ratio=self.damping_ratio(),
                             tests=tuple(self.tests),
                             frequency_scatter_hz=self._table(lambda e: e.frequency_scatter, True),
                             damping_scatter=self._table(lambda e: e.damping_scatter, True),
                             flags=tuple(tuple(e.flags for e in self.estimates[t]) for t in self.tests),
                             modal_constants=self._modal_constants(), sensors=self._sensors(), source=source)

    def _sensors(self) -> tuple[str, ...]:
        """The sensors of the modal constants: the tests' FRF responses, when every test has the same."""
        names = {tuple(self.sets[t].responses) for t in self.tests}
        return names.pop() if len(names) == 1 else ()

    def _modal_constants(self) -> np.ndarray | None:
        """(n_tests, n_modes, n_sensors) complex receptance modal constants of every fit, 1/kg (NaN where
        the fit is unusable, `UNUSABLE_FLAGS`), or None when the tests were not measured at the same
        number of sensors.
        """
        # a curve whose circle is lost in noise or is no circle gives no constant: NaN there
        values = [[[np.nan if set(UNUSABLE_FLAGS) & set(f.flags) else f.modal_constant for f in e.fits]
                   for e in self.estimates[t]] for t in self.tests]
        sizes = {len(fits) for per_test in values for fits in per_test}
        return np.array(values, complex) if len(sizes) == 1 else None


MODES_HEADER = MODES_COLUMNS + MODES_OPTIONAL
SHAPES_HEADER = ("test_id", "mode", "sensor", "modal_constant_re", "modal_constant_im")
QUALITY_HEADER = ("test_id", "mode", "curve", "frequency_hz", "damping_ratio", "damping_scatter", "circle_error",
                  "points_used", "weight", "flags")


def extraction_rows(extraction: Extraction) -> dict[str, list[tuple]]:
    """The rows of ``modes.csv``, ``shapes.csv`` and ``quality.csv`` (CONTRACTS.md section 2), headers above.

    modes.csv: the combined estimate of every test and mode with its 95 % intervals and ``;``-separated
    flags; shapes.csv: every sensor's receptance modal constant (1/kg) of the mode, from that sensor's fit;
    quality.csv: the combined estimate and each curve's fit, with the weights they were combined with.
    """
    modes, shapes, quality = [], [], []
    for t, per_mode in extraction.estimates.items():
        sensors = extraction.sets[t].responses
        for k, est in enumerate(per_mode, start=1):
            modes.append((t, k, est.frequency_hz, est.damping_ratio, *est.frequency_ci95_hz, *est.damping_ci95,
                          ";".join(est.flags)))
            quality.append((t, k, "combined", est.frequency_hz, est.damping_ratio, est.damping_scatter, "", "",
                            est.curves_used, ";".join(est.flags)))
            for sensor, fit, weight in zip(sensors, est.fits, est.weights):
                shapes.append((t, k, sensor, fit.modal_constant.real, fit.modal_constant.imag))
                quality.append((t, k, sensor, fit.frequency_hz, fit.damping_ratio, fit.damping_scatter,
                                fit.circle_error, fit.points_used, weight, ";".join(fit.flags)))
    return {"modes.csv": modes, "shapes.csv": shapes, "quality.csv": quality}


def extract_campaign(campaign, bands=None, count: int | None = None, mapper: Mapper | None = None) -> Extraction:
    """Circle-fit modes of every test of ``campaign`` (`workbench.io.campaign.Campaign` with FRFs).

    Parameters
    ----------
    campaign : a loaded campaign.
    bands : (f_lo, f_hi) Hz per mode, or None to find them across every test and sensor.
    count : keep the ``count`` lowest modes found.

    Raises
    ------
    ValueError
        The campaign has no FRFs.
    """
    if campaign.frf is None:
        raise ValueError(f"{campaign.path or campaign.name}: frf.csv: the campaign has no FRFs to extract modes from")
    start = time.perf_counter()
    sets = {t: frf_set(campaign, t) for t in campaign.test_ids}
    found, estimates = extract_tests({t: s.frequency_hz for t, s in sets.items()},
                                     {t: s.values for t, s in sets.items()}, campaign.quantity, bands, count,
                                     mapper)
    return Extraction(sets, tuple(found), estimates, time.perf_counter() - start)


Loaded = tuple[Campaign, Extraction | None]
"""A loaded campaign and its circle-fit modes (None without FRFs)."""


def load_and_extract(path: str | Path) -> Loaded:
    """``(campaign, extraction or None)`` of a campaign directory; None when it has no FRFs."""
    campaign = load_campaign(path)
    return campaign, (extract_campaign(campaign) if campaign.frf is not None else None)


def _load(_: None, path: str) -> Loaded:
    return load_and_extract(path)


def load_campaigns(paths: Sequence[str | Path], mapper: Mapper | None = None,
                   progress: Progress | None = None) -> dict[str, Loaded]:
    """`load_and_extract` of several campaigns, run by ``mapper`` (`workbench.workflow.execution`; the
    circle fits of a campaign take 5-15 s); returns ``{path: (campaign, extraction)}`` in the order given.
    """
    names = list(dict.fromkeys(str(p) for p in paths))
    run = mapper or serial_mapper(progress)
    return dict(zip(names, run(_load, names, "circle fits", None)))


@dataclass(frozen=True)
class NyquistData:
    """One mode's circle fit on one curve, in mobility (m/s/N), for a Nyquist plot.

    Attributes
    ----------
    test, sensor, mode : where it comes from (mode 1 = lowest).
    measured : (n,) complex measured mobility in the fit's band.
    fitted : (m,) complex modal circle plus residual terms on a fine axis over the band.
    frequency_hz, damping_ratio, circle_error : the fit's values; flags : its flags.
    """

    test: object
    sensor: str
    mode: int
    measured: np.ndarray
    fitted: np.ndarray
    frequency_hz: float
    damping_ratio: float
    circle_error: float
    flags: tuple[str, ...]


def nyquist_data(extraction: Extraction, test=None) -> list[NyquistData]:
    """The circle fit of every mode on the best curve (largest combination weight) of one test
    (default the first): the measured mobility points of the band and the fitted
    ``i w (A / (w_r^2 - w^2 + 2 i zeta w_r w) + U - L / w^2)`` (Ewins 4.3; `workbench.extraction.circlefit`).
    """
    test = extraction.tests[0] if test is None else test
    frfs = extraction.sets[test]
    out = []
    for k, estimate in enumerate(extraction.estimates[test]):
        c = int(np.argmax(estimate.weights))
        fit = estimate.fits[c]
        f = frfs.frequency_hz
        inside = (f >= fit.band[0]) & (f <= fit.band[1]) & (f > 0)
        measured = to_mobility(f[inside], frfs.values[c, inside], frfs.quantity)
        fine = np.linspace(max(fit.band[0], 1e-3), fit.band[1], 400)
        omega = 2.0 * np.pi * fine
        modal = modal_superposition(fine, np.array([fit.frequency_hz]), np.array([fit.damping_ratio]),
                                    np.array([[fit.modal_constant]]), "mobility")[0]
        fitted = modal + 1j * omega * (fit.residual_upper - fit.residual_lower / omega**2)
        out.append(NyquistData(test, frfs.responses[c], k + 1, measured, fitted, fit.frequency_hz,
                               fit.damping_ratio, fit.circle_error, fit.flags))
    return out


def mode_windows(band: FRFBand, measured_hz: np.ndarray, damping_ratio: np.ndarray,
                 pad: float = 3.0) -> list[tuple[float, float, int]]:
    """Frequency windows around each measured mode, for zooms on a band (Figures 12, 14, 16 in detail).

    Window k spans the band's 1-99 % frequencies of mode k and every test's measured frequency
    (NaN skipped), widened by ``pad`` half-power half-widths ``zeta_k f_k`` each side; its sensor
    is the one where the band's mean ``|H|`` peaks highest inside it.

    Parameters
    ----------
    band : the FRF band (its ``natural_hz`` samples).
    measured_hz : (n_tests, n_modes) measured frequencies, Hz.
    damping_ratio : (n_modes,) modal damping ratios.

    Returns
    -------
    list of ``(f_lo, f_hi, sensor_row)``, one per measured mode, Hz.
    """
    n = min(measured_hz.shape[1], band.natural_hz.shape[1])
    lo, hi = np.percentile(band.natural_hz[:, :n], [1.0, 99.0], axis=0)
    found = np.isfinite(measured_hz[:, :n])
    lo = np.where(found.any(axis=0), np.fmin(lo, np.nanmin(np.where(found, measured_hz[:, :n], np.inf), axis=0)), lo)
    hi = np.where(found.any(axis=0), np.fmax(hi, np.nanmax(np.where(found, measured_hz[:, :n], -np.inf), axis=0)), hi)
    half = pad * np.asarray(damping_ratio, float)[:n] * 0.5 * (lo + hi)
    windows = []
    for k in range(n):
        inside = (band.frequency_hz >= lo[k] - half[k]) & (band.frequency_hz <= hi[k] + half[k])
        sensor = int(np.argmax(band.mean[:, inside].max(axis=1))) if inside.any() else 0
        windows.append((float(lo[k] - half[k]), float(hi[k] + half[k]), sensor))
    return windows


def campaign_label(campaign) -> str:
    """A campaign's short name: its directory's name, else its ``name``."""
    return Path(str(campaign.path)).name if campaign.path else str(campaign.name)


def frequency_axis(extraction: Extraction) -> np.ndarray:
    """The campaign's frequency axis without 0 Hz (where an accelerance or mobility is 0: no log)."""
    f = next(iter(extraction.sets.values())).frequency_hz
    return f[f > 0]


def _wide(campaign: Campaign, table: pd.DataFrame, column: str, count: int | None) -> pd.DataFrame:
    wide = table.pivot(index="test_id", columns="mode", values=column).sort_index(axis=1)
    if count is not None:
        wide = wide[[mode for mode in wide.columns if int(mode) <= count]]
    return wide.reindex(campaign.test_ids)


def measured_modes(campaign: Campaign, count: int | None = None, purpose: str = "identify",
                   mapper: Mapper | None = None) -> MeasuredModes:
    """The campaign's measured modes: ``modes.csv``, else the circle fit of its FRFs, else its published moments.

    Parameters
    ----------
    count : use at most the first ``count`` modes.
    purpose : what the modes are for, in the error message when the campaign has none.
    mapper : runs the bands' votes and the tests' circle fits (`workbench.tasks.Mapper`); default, one after the
        other.

    Raises
    ------
    CampaignError
        The campaign holds no modes, FRFs or moments.
    """
    source = str(campaign.path or campaign.name)
    if campaign.modes is None and campaign.frf is not None:
        # every test's circle fits (bands shared across tests; weak or poor circles left out), less
        # the modes found usable in no test
        fitted = extract_campaign(campaign, count=count, mapper=mapper).measured_modes(
            source + " (modes by circle fit of its FRFs)")
        fitted = fitted.select(np.isfinite(fitted.frequency_hz).any(axis=0))
        return replace(fitted, amplitude=amplitude_of_tests(campaign), design=_design_columns(campaign))
    if campaign.modes is None and campaign.moments is not None:
        m = campaign.moments.sort_values("mode")
        if count is not None:
            m = m[m["mode"] <= count]
        return MeasuredModes(m["mean_hz"].to_numpy()[None, :], modes=m["mode"].to_numpy(),
                             published_std_hz=m["std_hz"].to_numpy(), tests_count=len(campaign.test_ids) or 9,
                             source=source + "/moments.csv")
    if campaign.modes is None:
        raise CampaignError(f"{source}: holds no modes, FRFs or moments to {purpose}")
    table, source = campaign.modes, source + "/modes.csv"
    wide = _wide(campaign, table, "frequency_hz", count)
    damping = _wide(campaign, table, "damping_ratio", count).to_numpy(float) if "damping_ratio" in table else None
    return MeasuredModes(wide.to_numpy(float), modes=wide.columns.to_numpy(), damping_ratio=damping,
                         tests=tuple(wide.index), amplitude=amplitude_of_tests(campaign), source=source,
                         design=_design_columns(campaign))


def _design_columns(campaign: Campaign) -> np.ndarray | None:
    """(n_tests, n_columns) the campaign's designed factors other than the amplitude, in test order: each
    factor's levels but its first as 0/1 columns (`MeasuredModes.design`); None without such factors.
    """
    factors = [f for f in campaign.factors if f.kind != "amplitude"]
    if not factors or campaign.design is None:
        return None
    table = campaign.design.set_index("test_id").reindex(campaign.test_ids)
    columns = np.hstack([pd.get_dummies(table[f.name].astype(str), drop_first=True).to_numpy(float)
                         for f in factors])
    return columns if columns.shape[1] else None


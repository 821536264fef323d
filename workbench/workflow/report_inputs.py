"""What the report reads beyond the studies: the campaign's measured modes as the report takes them
(modes.csv when the campaign has one, else a circle fit with the bands asked for), and the mode
shapes at the sensors set against the model's (MAC).

Numbers only, no figure and no HTML (`workbench.report` draws them); no matplotlib here.

Mode shapes at the sensors: the circle fit's modal constants ``A_r(s)`` (receptance form, 1/kg,
`workbench.extraction.records.MeasuredModes.modal_constants`) are the product of the
mass-normalised shape at sensor ``s`` and at the excitation; the model's counterpart is
``phi_r(s) phi_r(exc)`` of the nominal modes (joints at their mean, `workbench.model.structure.structure_modes`),
as `workbench.uq.prediction.frf_band` builds its constants. A measured constant is complex (damping,
noise): each test's vector of a mode is turned to its dominant phase (the angle maximising the
energy of its real part, ``theta = arg(sum A^2) / 2``) and its real part kept; the tests' vectors,
signed alike, are then averaged. A sensor's fit flagged `SHAPE_UNUSABLE` (too few points in its band,
or a band cut by the axis' edge: its constant can be off by orders of magnitude) is left out (NaN).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from workbench.extraction.records import MeasuredModes
from workbench.io.campaign import Campaign, load_campaign
from workbench.model.modal import RIGID_HZ, dominant_real, mac
from workbench.model.structure import receptance_constants, structure_modes, structure_of
from workbench.tasks import Mapper
from workbench.workflow.measured import Extraction, extract_campaign

__all__ = ["ShapeComparison", "shape_comparison", "usable_constants", "parse_bands",
           "load_for_report", "SHAPE_UNUSABLE"]

SHAPE_UNUSABLE = ("few_points", "edge_of_band", "unresolved")


def parse_bands(text: str | None) -> list[tuple[float, float]] | None:
    """``'lo:hi,lo:hi'`` (Hz) -> ``[(lo, hi), ...]``, as ``workbench extract --bands`` reads it; None for none.

    Raises
    ------
    ValueError
        A band is not two numbers ``lo:hi`` with ``0 <= lo < hi``.
    """
    if not text:
        return None
    bands = []
    for item in text.split(","):
        parts = item.split(":")
        try:
            lo, hi = (float(v) for v in parts) if len(parts) == 2 else (np.nan, np.nan)
        except ValueError:
            lo = hi = np.nan
        if not (np.isfinite(lo) and np.isfinite(hi) and 0 <= lo < hi):
            raise ValueError(f"--bands: {item!r} is not a band 'lo:hi' in Hz with 0 <= lo < hi")
        bands.append((lo, hi))
    return bands


def load_for_report(path: str | Path, bands: Sequence[tuple[float, float]] | None = None,
                    mapper: Mapper | None = None) -> tuple[Campaign, Extraction | None, str]:
    """The campaign the report studies, with its circle fit where the report needs one.

    A campaign with ``modes.csv`` is identified from it (no circle fit redone) unless ``bands`` are
    given, which ask for a circle fit with those bands; a campaign with FRFs and no modes.csv is
    circle-fitted (with ``bands`` when given).

    Returns
    -------
    (campaign, extraction or None, note)
        ``note`` says why a campaign with FRFs has no extraction (its modes.csv is used); empty otherwise.

    Raises
    ------
    ValueError
        ``bands`` are given for a campaign without FRFs.
    """
    campaign = load_campaign(path)
    if bands is not None and campaign.frf is None:
        raise ValueError(f"{path}: --bands: the campaign has no FRFs to circle-fit")
    if campaign.modes is not None and bands is None and campaign.frf is not None:
        return campaign, None, (f"{path}/modes.csv: the campaign's extracted modes are identified as they are; "
                                "the circle fit is not redone (pass --bands to redo it), so its FRFs, fits and "
                                "the FRF band are not shown.")
    if campaign.frf is None:
        return campaign, None, ""
    return campaign, extract_campaign(campaign, bands, mapper=mapper), ""


@dataclass(frozen=True)
class ShapeComparison:
    """Measured mode shapes at the sensors against the nominal model's, and their MAC.

    Attributes
    ----------
    sensors : sensor names, in the order of the columns.
    modes : (n_measured,) measured mode numbers.
    measured : (n_measured, n_sensors) mean over the tests of the modal constants turned real
        (module notes), 1/kg; NaN where no test has the mode.
    tests : (n_measured,) number of tests averaged per mode.
    model_modes : (n_model,) elastic model mode numbers (1 = lowest elastic mode).
    model_hz : (n_model,) their frequencies, Hz.
    model : (n_model, n_sensors) the model's ``phi(s) phi(exc)``, 1/kg.
    mac : (n_measured, n_model) MAC of each measured shape with each model shape, on the sensors where
        the measured shape is known (NaN with fewer than two).
    paired : (n_measured,) index into ``model_modes`` paired with each measured mode (by order, as
        the identification pairs them).
    """

    sensors: tuple[str, ...]
    modes: np.ndarray
    measured: np.ndarray
    tests: np.ndarray
    model_modes: np.ndarray
    model_hz: np.ndarray
    model: np.ndarray
    mac: np.ndarray
    paired: np.ndarray


def usable_constants(extraction: Extraction) -> np.ndarray | None:
    """(n_tests, n_modes, n_sensors) complex modal constants of every sensor's fit, 1/kg, NaN where the
    fit is flagged `SHAPE_UNUSABLE`; None when the tests were not measured at the same number of sensors.
    """
    values = [[[np.nan if set(SHAPE_UNUSABLE) & set(f.flags) else f.modal_constant for f in e.fits]
               for e in extraction.estimates[t]] for t in extraction.tests]
    sizes = {len(fits) for per_test in values for fits in per_test}
    return np.array(values, complex) if len(sizes) == 1 else None


def _mean_shape(constants: np.ndarray, reference: np.ndarray) -> tuple[np.ndarray, int]:
    """(n_tests, n_sensors) complex constants of one mode -> their mean real shape, signed as ``reference``."""
    real = dominant_real(constants)
    keep = (np.isfinite(real).sum(axis=1) >= 2) & (np.nansum(np.abs(real), axis=1) > 0)
    if not keep.any():
        return np.full(real.shape[1], np.nan), 0
    real = real[keep]
    signs = np.sign(np.nansum(real * reference[None, :], axis=1))
    signs[signs == 0] = 1.0
    with np.errstate(invalid="ignore"):
        signed = real * signs[:, None]
        seen = np.isfinite(signed).any(axis=0)
        mean = np.full(real.shape[1], np.nan)
        mean[seen] = np.nanmean(signed[:, seen], axis=0)
    return mean, int(keep.sum())


def shape_comparison(campaign: Campaign, data: MeasuredModes, sensors: Sequence[str], extra: int = 2,
                     constants: np.ndarray | None = None) -> ShapeComparison | None:
    """The measured shapes of ``data`` against the nominal model's at ``sensors`` (module notes).

    Parameters
    ----------
    campaign : its frame gives the model, the sensors' points and the excitation.
    data : measured modes with ``modal_constants`` (n_tests, n_modes, n_sensors).
    sensors : the names of the constants' sensors, in their order.
    extra : model modes compared beyond the measured count.
    constants : (n_tests, n_modes, n_sensors) complex constants to use instead of ``data.modal_constants``
        (`usable_constants`: the unusable fits left out).

    Returns
    -------
    ShapeComparison, or None when ``data`` holds no modal constants, the frame has no excitation,
    or fewer than two sensors (a MAC of one number says nothing).
    """
    constants = data.modal_constants if constants is None else constants
    if constants is None or campaign.frame.excitation is None or len(sensors) < 2 or constants.shape[2] != len(sensors):
        return None
    model = structure_of(campaign.frame)
    n_measured = constants.shape[1]
    solved = structure_modes(model, min(n_measured + extra + 3, model.size - 1))
    elastic = np.flatnonzero(solved.frequency_hz >= RIGID_HZ)[: n_measured + extra]
    model_constants = receptance_constants(model, solved.shapes[:, elastic], sensors)  # (n_model, n_sensors)
    paired = np.minimum(np.asarray(data.modes, int) - 1, elastic.size - 1)
    measured, counts = [], []
    for k in range(n_measured):
        shape, count = _mean_shape(constants[:, k, :], model_constants[paired[k]])
        measured.append(shape)
        counts.append(count)
    measured_arr = np.array(measured)
    table = np.full((n_measured, elastic.size), np.nan)
    for k, shape in enumerate(measured_arr):  # each on the sensors where some test's fit of it is usable
        seen = np.isfinite(shape)
        if seen.sum() >= 2:
            table[k] = mac(shape[seen][:, None], model_constants[:, seen].T)[0]
    return ShapeComparison(tuple(sensors), np.asarray(data.modes), measured_arr, np.array(counts),
                           np.arange(1, elastic.size + 1), solved.frequency_hz[elastic], model_constants, table,
                           paired)

"""Modal extraction from many FRFs: mode bands, a circle fit per curve, quality-weighted combination.

Builds on `workbench.extraction.circlefit` (one curve, one band) and `workbench.extraction.bands` (re-exported
here): `find_mode_bands` finds the modes across sensors and tests (peak detection, with a user override),
`split_bands` lists a band twice where a two-pole fit (`workbench.extraction.multimode`) finds two modes
under one peak, `fit_modes` fits
every curve in every band (a band listed twice: both modes at once, poles common to the curves),
`combine` merges the curves of one mode with weights from their fit quality, with a 95 % interval,
and `error_vs_snr` measures the accuracy of the whole chain against synthetic FRFs.
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace

import numpy as np

from workbench.extraction.bands import find_mode_bands, peak_start, split_bands, track_bands
from workbench.extraction.circlefit import (
    CLOSE_BANDWIDTHS,
    FLAGS,
    MIN_BAND_POINTS,
    POOR_CIRCLE,
    WEAK_FACTOR,
    WEIGHT_FLOOR,
    ModalFit,
    _check_band,
    _check_frequency,
    _check_frfs,
    _check_quantity,
    _circle_fit,
    _second_mode_near,
    circle_fit,
    noise_level,
)
from workbench.extraction.multimode import PoleFit, pole_fit, second_mode
from workbench.model.modal import add_noise, modal_superposition
from workbench.tasks import Mapper, serial_mapper

__all__ = ["ModeEstimate", "find_mode_bands", "split_bands", "fit_modes", "combine", "extract_tests", "error_vs_snr"]

# The tiers of fits `combine` uses, cleanest first: a fit may carry the flags of its tier. ``close_mode`` marks the
# structure (a whole band's row carries it), not a sensor; ``few_points`` a coarse grid, for which a fit's intervals
# widen already. Counted as flagged alike with ``weak`` and ``poor_circle``, they made every fit of a close pair
# or of a mode under a line wide "flagged": every fit was then used, the estimate carried the ``weak`` or
# ``poor_circle`` of the sensors that do not see the mode, and the diagnosis left the mode out (proving-ground
# seed 9001, case 40: the two-bay's 210/216 Hz pair; case 20: a 28 Hz sway mode at 0.25 % damping, 0.14 Hz wide
# on a 0.25 Hz grid, 600 noise levels high on two sensors).
TOLERATED_FLAGS = (frozenset({"close_mode"}), frozenset({"close_mode", "few_points"}))


@dataclass(frozen=True)
class ModeEstimate:
    """One mode combined over several curves (`combine`).

    Attributes
    ----------
    frequency_hz, damping_ratio : quality-weighted means over the curves used (Hz, ratio).
    frequency_scatter, damping_scatter : weighted standard deviations over those curves.
    curves_used : number of curves with a non-zero weight.
    weights : (n_curves,) normalised weights, 0 for the curves outside the tier used (`TOLERATED_FLAGS`).
    flags : flags of the curves used, plus ``"close_mode"`` if a curve raised it alone.
    fits : the per-curve fits.
    frequency_ci95_hz : (low, high) 95 % interval of ``frequency_hz``, Hz (`combine`).
    damping_ci95 : (low, high) 95 % interval of ``damping_ratio`` (`combine`).
    """

    frequency_hz: float
    damping_ratio: float
    frequency_scatter: float
    damping_scatter: float
    curves_used: int
    weights: tuple[float, ...]
    flags: tuple[str, ...]
    fits: tuple[ModalFit, ...] = field(repr=False, default=())
    frequency_ci95_hz: tuple[float, float] = (float("nan"), float("nan"))
    damping_ci95: tuple[float, float] = (float("nan"), float("nan"))

    @property
    def ok(self) -> bool:
        return not self.flags


def fit_modes(frequency_hz, frfs, quantity: str, bands=None, count: int | None = None) -> list[list[ModalFit]]:
    """Circle fit of every band on every curve; a multi-mode fit where a band is listed more than once.

    Parameters
    ----------
    frequency_hz : (n_freq,) Hz.
    frfs : (n_curves, n_freq) complex FRFs in the unit of ``quantity``.
    quantity : receptance, mobility or accelerance.
    bands : list of (f_lo, f_hi) Hz; ``None`` finds them with `find_mode_bands` (``count``) and
        `split_bands`. A band listed ``m`` times in a row holds ``m`` modes: they are fitted at once
        (`workbench.extraction.multimode.pole_fit`, poles common to the curves), and every fit of
        theirs carries ``"close_mode"``.

    Returns
    -------
    ``fits[mode][curve]``, one row per entry of ``bands``. Besides `circle_fit`'s own flags: where a
    band's circle misfit is systematic on some curve, ``"close_mode"`` only when a two-pole fit over
    all the curves finds a second mode (`circlefit._second_mode_near`); and both modes of two
    neighbouring bands whose frequencies (median over their unflagged curves) are closer than
    `CLOSE_BANDWIDTHS` half-power bandwidths ``2 zeta f`` get ``"close_mode"``.
    """
    f = _check_frequency(frequency_hz)
    h = _check_frfs(frfs, f.size)
    _check_quantity(quantity)
    if bands is None:
        bands = split_bands([f], [h], quantity, find_mode_bands(f, h, count=count))
    bands = [_check_band(f, band) for band in bands]
    fits: list[list[ModalFit]] = []
    noise = noise_level(h)  # each curve's, once: not once per band
    k = 0
    while k < len(bands):
        m = 1
        while k + m < len(bands) and bands[k + m] == bands[k]:
            m += 1
        if m > 1:
            fits.extend(_multimode_rows(f, h, noise, bands[k], quantity, m))
        else:
            row, triggered = zip(*[_circle_fit(f, curve, bands[k], quantity, float(sigma))
                                   for curve, sigma in zip(h, noise)])
            best = row[int(np.argmin([x.circle_error for x in row]))]
            pair = any(triggered) and _second_mode_near(f, h, best, quantity, noise)
            fits.append([_with_flag(x, "close_mode") if pair else x for x in row])
        k += m
    # neighbours, from the bands with at least one unflagged fit (the others are flagged already)
    centres = {i: (float(np.median([x.frequency_hz for x in row if x.ok])),
                   float(np.median([x.damping_ratio for x in row if x.ok])))
               for i, row in enumerate(fits) if any(x.ok for x in row)}
    close = [False] * len(fits)
    order = sorted(centres, key=lambda i: centres[i][0])
    for a, b in zip(order[:-1], order[1:]):
        (fa, za), (fb, zb) = centres[a], centres[b]
        if abs(fb - fa) < CLOSE_BANDWIDTHS * 2.0 * max(za * fa, zb * fb):
            close[a] = close[b] = True
    return [[_with_flag(x, "close_mode") if close[i] else x for x in row] for i, row in enumerate(fits)]


def _multimode_rows(f: np.ndarray, h: np.ndarray, noise: np.ndarray, band: tuple[float, float], quantity: str,
                    m: int) -> list[list[ModalFit]]:
    """``m`` modes of one band fitted at once, as `ModalFit` rows (one per mode, lowest first; ``noise``: the
    curves' `noise_level`).
    """
    inside = (f >= band[0]) & (f <= band[1])
    start = peak_start(f[inside], h[:, inside])
    if m == 2:
        fit = second_mode(f, h, band, quantity, noise, start, screen=False)[1]
    else:  # spread the starts over the middle half of the band
        lo, hi = 0.75 * band[0] + 0.25 * band[1], 0.25 * band[0] + 0.75 * band[1]
        fit = pole_fit(f, h, band, quantity, noise, [[(x, start[1] / m) for x in np.linspace(lo, hi, m)]])
    return [[_pole_mode(fit, r, c, noise[c], quantity, int(inside.sum())) for c in range(h.shape[0])]
            for r in range(m)]


def _pole_mode(fit: PoleFit, r: int, c: int, noise: float, quantity: str, points: int) -> ModalFit:
    """Pole ``r`` of a multi-mode fit on curve ``c`` as a `ModalFit` (mobility units at resonance)."""
    fr, zeta = float(fit.frequency_hz[r]), float(fit.damping_ratio[r])
    to_mob = (2.0 * np.pi * fr) ** (1 - {"receptance": 0, "mobility": 1, "accelerance": 2}[quantity])
    peak = float(fit.peak_noise[c, r])
    # circle error: the curve's RMS misfit over the mode's radius, both in noise levels
    error = float(fit.misfit_noise[c] / (0.5 * peak)) if peak > 0 else np.inf
    flags = {"close_mode"}
    if peak < WEAK_FACTOR:
        flags.add("weak")
    if error > POOR_CIRCLE:
        flags.add("poor_circle")
    if not fit.band[0] + zeta * fr <= fr <= fit.band[1] - zeta * fr:
        flags.add("edge_of_band")
    return ModalFit(
        frequency_hz=fr, damping_ratio=zeta, damping_scatter=0.0,
        modal_constant=complex(fit.modal_constants[c, r]), residual_lower=complex(fit.residual_lower[c]),
        residual_upper=complex(fit.residual_upper[c]), circle_error=error, noise=noise * to_mob,
        diameter=peak * noise * to_mob, points_used=points, pairs_used=0, band=fit.band,
        flags=tuple(x for x in FLAGS if x in flags),
        frequency_ci95_hz=(float(fit.frequency_ci95_hz[r, 0]), float(fit.frequency_ci95_hz[r, 1])),
        damping_ci95=(float(fit.damping_ci95[r, 0]), float(fit.damping_ci95[r, 1])))


def _with_flag(fit: ModalFit, flag: str) -> ModalFit:
    if flag in fit.flags:
        return fit
    return replace(fit, flags=tuple(x for x in FLAGS if x in fit.flags or x == flag))


def combine(fits) -> ModeEstimate:
    """Combine one mode's fits on several curves.

    Weights ``w = points_used / (circle_error^2 + WEIGHT_FLOOR^2)``, normalised, over the fits of the cleanest
    tier of `TOLERATED_FLAGS` any fit reaches (when none does, every fit, its flags carried). Frequency
    and damping are weighted means, with weighted standard deviations as scatter. The result's
    flags are those of the fits used, plus ``"close_mode"`` if any fit raised it and nothing else
    (two close modes are a property of the structure, not of a sensor; a fit that failed for
    other reasons as well is no evidence of them).

    95 % intervals (`_combined_interval`, `_combined_damping`): the per-curve intervals (damping:
    their statistical part, the model-form part added back in the end) combined as independent
    (``sqrt(sum w^2 h^2)``, ``h`` each side's half-width; damping in log), times the Birge ratio
    ``sqrt(chi^2 / (n - 1))`` when above 1 (``chi^2`` of the curves' estimates about the mean, in
    their own standard deviations ``h / 1.96``): curves that scatter more than their intervals say
    widen the interval. Fits that share one estimate (a multi-mode fit's common pole) count once.
    """
    fits = tuple(fits)
    if not fits:
        raise ValueError("fits: nothing to combine")
    tiers = (np.array([not set(x.flags) - tolerated for x in fits]) for tolerated in TOLERATED_FLAGS)
    use = next((u for u in tiers if u.any()), np.ones(len(fits), bool))  # the cleanest tier any fit reaches
    w = np.array([x.points_used / (x.circle_error**2 + WEIGHT_FLOOR**2) for x in fits]) * use
    w = np.where(np.isfinite(w), w, 0.0)
    if w.sum() <= 0.0:
        w = use.astype(float)
    w = w / w.sum()
    fr = np.array([x.frequency_hz for x in fits])
    ze = np.array([x.damping_ratio for x in fits])
    f_mean, z_mean = float(w @ fr), float(w @ ze)
    flags = {flag for x, u in zip(fits, use) if u for flag in x.flags}
    if any(x.flags == ("close_mode",) for x in fits):  # a clean fit but for its neighbour
        flags.add("close_mode")
    f_lo, f_hi = _combined_interval(w, fr, np.array([x.frequency_ci95_hz for x in fits]))
    z_lo, z_hi = _combined_damping(w, fits)
    return ModeEstimate(
        frequency_hz=f_mean, damping_ratio=z_mean,
        frequency_scatter=float(np.sqrt(w @ (fr - f_mean) ** 2)),
        damping_scatter=float(np.sqrt(w @ (ze - z_mean) ** 2)),
        curves_used=int(np.count_nonzero(w)), weights=tuple(float(v) for v in w),
        flags=tuple(flag for flag in FLAGS if flag in flags), fits=fits,
        frequency_ci95_hz=(f_mean - f_lo, f_mean + f_hi),
        damping_ci95=(z_mean * float(np.exp(-z_lo)), z_mean * float(np.exp(z_hi))))


def _combined_damping(w: np.ndarray, fits: tuple[ModalFit, ...]) -> tuple[float, float]:
    """Half-widths in log (below, above) of the combined damping (`combine`): the curves' statistical
    parts combined by `_combined_interval`, their common model-form part
    (`ModalFit.damping_model_form`) averaged, not reduced, then both in quadrature.
    """
    ze = np.array([x.damping_ratio for x in fits])
    ci = np.log(np.array([x.damping_ci95 for x in fits]) / ze[:, None]) * [-1.0, 1.0]
    ratio = np.array([x.damping_model_form for x in fits]) / ze
    common = np.column_stack([-np.log(1.0 - np.minimum(ratio, 0.99)), np.log(1.0 + ratio)])
    own = np.sqrt(np.maximum(ci**2 - common**2, 0.0))
    low, high = _combined_interval(w, np.log(ze), np.column_stack([np.log(ze) - own[:, 0], np.log(ze) + own[:, 1]]))
    return min(float(np.hypot(low, w @ common[:, 0])), 50.0), min(float(np.hypot(high, w @ common[:, 1])), 50.0)


def _combined_interval(w: np.ndarray, x: np.ndarray, ci: np.ndarray) -> tuple[float, float]:
    """Half-widths (below, above) of the weighted mean ``w @ x`` (`combine`); ``ci`` (n, 2)."""
    keep = w > 0
    w, x, ci = w[keep], x[keep], ci[keep]
    _, first, groups = np.unique(np.column_stack([x, ci]), axis=0, return_index=True, return_inverse=True)
    if first.size < x.size:  # fits sharing one estimate (a multi-mode fit's pole): counted once
        w = np.bincount(groups.ravel(), weights=w)
        x, ci = x[first], ci[first]
    below, above = x - ci[:, 0], ci[:, 1] - x
    if not (np.all(np.isfinite(below)) and np.all(np.isfinite(above))):
        return np.inf, np.inf
    half = np.array([np.sqrt(w**2 @ below**2), np.sqrt(w**2 @ above**2)])
    if x.size > 1:
        # Birge ratio: curves that disagree beyond their own intervals widen the combined one
        sd = np.maximum(0.5 * (below + above), 1e-12 * np.abs(x).max() + 1e-300) / 1.96
        mean = float(w @ x)
        half = half * max(1.0, float(np.sqrt(np.sum(((x - mean) / sd) ** 2) / (x.size - 1))))
    return float(half[0]), float(half[1])


def _fit_test(shared: tuple, task: tuple) -> list[ModeEstimate]:
    """One test's modes: ``shared = (quantity,)``, ``task = (frequency_hz, frfs, the test's bands)``."""
    (quantity,) = shared
    f, h, bands = task
    return [combine(row) for row in fit_modes(f, np.atleast_2d(h), quantity, bands)]


def extract_tests(frequency_hz: dict, frfs: dict, quantity: str, bands=None, count: int | None = None,
                  mapper: Mapper | None = None) -> tuple[list[tuple[float, float]], dict[object, list[ModeEstimate]]]:
    """Modes of every test of a campaign: bands found across all tests and sensors, each followed per test.

    Parameters
    ----------
    frequency_hz : test id -> (n_freq,) Hz.
    frfs : test id -> (n_sensors, n_freq) complex FRFs in the unit of ``quantity``.
    bands : (f_lo, f_hi) Hz per mode, or None to find them (`find_mode_bands` on all the curves
        of all the tests when they share one frequency axis, else on the first test's curves; then
        `split_bands`: a band that holds two modes in most tests is listed twice; then `track_bands`: each
        test fits each mode in its own band, centred on its own peak, and a mode the tests hold at two
        places is one mode). A band listed twice is fitted with two poles at once (`fit_modes`). Bands
        given are used as they are, in every test.
    count : keep the ``count`` lowest modes found.
    mapper : runs the bands' votes (`split_bands`) and the tests' fits (`workbench.tasks.Mapper`); default, one
        after the other here.

    Returns
    -------
    bands : the modes' bands, increasing (a band that `track_bands` merged spans its places; each test's
        own band lies inside it, or inside its search window); band k is mode k + 1 in every test (a band
        listed twice gives its lower mode, then its upper one).
    estimates : test id -> one `ModeEstimate` per band (its flags say where not to trust it).
    """
    tests = list(frfs)
    if not tests:
        raise ValueError("extract_tests: no test to extract")
    run = mapper or serial_mapper()
    if bands is None:
        axis = np.asarray(frequency_hz[tests[0]], float)
        shared = all(np.array_equal(np.asarray(frequency_hz[t], float), axis) for t in tests)
        curves = np.concatenate([np.atleast_2d(frfs[t]) for t in tests]) if shared else np.atleast_2d(frfs[tests[0]])
        bands = split_bands([frequency_hz[t] for t in tests], [frfs[t] for t in tests], quantity,
                            find_mode_bands(axis, curves), run)
        # the lowest modes, not the most prominent: mode k must be the k-th mode in every use
        bands, own = track_bands([frequency_hz[t] for t in tests], [frfs[t] for t in tests], sorted(bands))
        bands, own = bands[:count], [b[:count] for b in own]
    else:  # the user's bands, as given
        bands = sorted((float(lo), float(hi)) for lo, hi in bands)[:count]
        own = [bands] * len(tests)
    fitted = run(_fit_test, [(frequency_hz[t], frfs[t], b) for t, b in zip(tests, own)], "circle fits", (quantity,))
    return bands, dict(zip(tests, fitted))


def error_vs_snr(snr_db_values, seeds, *, natural_hz=(100.0, 250.0, 600.0), damping_ratios=(0.03, 0.01, 0.001),
                 constants=((1.0, 0.6, 0.2),), quantity: str = "accelerance", resolution_hz: float = 0.25,
                 f_max: float = 1250.0, band_halfwidths: float = 6.0) -> dict:
    """Relative errors of the circle fit versus SNR on a well-separated synthetic mode set.

    For each SNR (dB, `add_noise`) and seed (``numpy.random.default_rng(seed)``), noise is added
    to the exact FRF on 0..``f_max`` Hz at ``resolution_hz``, and each mode is fitted in the band
    ``f_r +- band_halfwidths * zeta_r f_r`` (at least `MIN_BAND_POINTS` lines).

    Returns
    -------
    dict with ``snr_db`` (n_snr,), ``seeds``, ``natural_hz`` and ``damping_ratios`` (n_modes,),
    ``frequency_median``, ``frequency_p90``, ``damping_median``, ``damping_p90`` (n_snr, n_modes):
    median and 90th percentile of ``|estimate / truth - 1|`` over the seeds and curves,
    ``ok_fraction`` (n_snr, n_modes), the share of fits without flags, and ``frequency_coverage``,
    ``damping_coverage`` (n_snr, n_modes), the share of fits whose 95 % interval holds the truth.
    """
    f = np.arange(0.0, f_max + resolution_hz / 2, resolution_hz)
    fr, zr = np.asarray(natural_hz, float), np.asarray(damping_ratios, float)
    clean = modal_superposition(f, fr, zr, np.asarray(constants, float), quantity)
    half = np.maximum(band_halfwidths * zr * fr, MIN_BAND_POINTS / 2 * resolution_hz)
    snr = np.asarray(snr_db_values, float)
    shape = (snr.size, fr.size)
    out = {k: np.zeros(shape) for k in ("frequency_median", "frequency_p90", "damping_median",
                                        "damping_p90", "ok_fraction", "frequency_coverage",
                                        "damping_coverage")}
    for i, level in enumerate(snr):
        ef: list[list[float]] = [[] for _ in fr]
        ez: list[list[float]] = [[] for _ in fr]
        ok: list[list[bool]] = [[] for _ in fr]
        covered: list[list[tuple[bool, bool]]] = [[] for _ in fr]
        for seed in seeds:
            noisy = add_noise(clean, level, np.random.default_rng(seed))
            for r in range(fr.size):
                for curve in noisy:
                    fit = circle_fit(f, curve, (fr[r] - half[r], fr[r] + half[r]), quantity)
                    ef[r].append(abs(fit.frequency_hz / fr[r] - 1.0))
                    ez[r].append(abs(fit.damping_ratio / zr[r] - 1.0))
                    ok[r].append(fit.ok)
                    covered[r].append((fit.frequency_ci95_hz[0] <= fr[r] <= fit.frequency_ci95_hz[1],
                                       fit.damping_ci95[0] <= zr[r] <= fit.damping_ci95[1]))
        for r in range(fr.size):
            out["frequency_median"][i, r], out["frequency_p90"][i, r] = np.percentile(ef[r], [50, 90])
            out["damping_median"][i, r], out["damping_p90"][i, r] = np.percentile(ez[r], [50, 90])
            out["ok_fraction"][i, r] = np.mean(ok[r])
            out["frequency_coverage"][i, r], out["damping_coverage"][i, r] = np.mean(covered[r], axis=0)
    return {"snr_db": snr, "seeds": tuple(seeds), "natural_hz": fr, "damping_ratios": zr, **out}

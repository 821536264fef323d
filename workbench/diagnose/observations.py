"""What the diagnosis fits: condition means of the measured modes, their standard errors and chi-squares.

The tests are grouped by excitation amplitude (one condition when the campaign has no amplitude
factor). For each condition ``c`` and measured mode ``i``: the mean frequency and, when measured,
the mean damping ratio. Their standard errors come from the scatter of the tests about a straight
line in amplitude (a mean when there is one condition), divided by the square root of the
condition's test count, with a relative floor (`RELATIVE_FLOOR`, 1e-4 for circle-fit frequencies:
the extraction's bias at 40 dB is 3e-5; `DAMPING_FLOOR` for damping). Published means with a
published std use ``std / sqrt(tests)``.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from workbench.extraction.records import MeasuredModes

__all__ = ["RELATIVE_FLOOR", "DAMPING_FLOOR", "Observations", "observations", "frequency_chi2", "chi2", "rms"]

RELATIVE_FLOOR = 1e-4  # floor of the relative standard error of a mean frequency
DAMPING_FLOOR = 0.02  # floor of the relative standard error of a mean damping ratio


@dataclass(frozen=True)
class Observations:
    """Condition means and their standard errors (module docstring).

    ``amplitude`` (n_cond,); ``frequency_hz``, ``frequency_se`` (n_cond, n_modes), Hz;
    ``frequency_cov`` (n_cond, n_modes, n_modes) of the relative errors of the means; ``damping``,
    ``damping_se`` likewise (damping ratios) or None; NaN marks a missing mean.
    """

    amplitude: np.ndarray
    frequency_hz: np.ndarray
    frequency_se: np.ndarray
    frequency_cov: np.ndarray  # (n_cond, n_modes, n_modes) of the relative errors of the means
    damping: np.ndarray | None
    damping_se: np.ndarray | None


def _test_covariance(values: np.ndarray, amplitude: np.ndarray, levels: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Covariance across modes of one test's relative deviation from the amplitude line, and which
    modes have a degree of freedom left to estimate it.
    """
    design = np.stack([np.ones_like(amplitude), amplitude], axis=1) if levels.size > 1 else np.ones((amplitude.size, 1))
    deviation = np.zeros_like(values)
    dof = np.zeros(values.shape[1])
    for k in range(values.shape[1]):
        ok = ~np.isnan(values[:, k])
        if not ok.any():
            continue
        dof[k] = ok.sum() - np.linalg.matrix_rank(design[ok])
        if dof[k] >= 1:
            coef = np.linalg.lstsq(design[ok], values[ok, k], rcond=None)[0]
            deviation[ok, k] = (values[ok, k] - design[ok] @ coef) / np.nanmean(values[ok, k])
    usable = dof >= 1
    covariance = np.zeros((values.shape[1],) * 2)
    if usable.any():
        d = np.where(usable, deviation, 0.0)
        covariance = d.T @ d / np.sqrt(np.outer(np.maximum(dof, 1), np.maximum(dof, 1)))
    return covariance, usable


def _condition_means(values: np.ndarray, amplitude: np.ndarray, floor_rel: float, published_std: np.ndarray | None,
                     tests_count: int | None) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Condition means, their standard errors and the relative covariance of each condition's means.

    The tests' deviations from a straight line in amplitude (a mean with one condition) give the
    covariance across modes of one test: a joint whose modulus scatters from test to test moves
    every mode at once, so the errors of the means are correlated, and a chi-square that ignored
    it would read a chance joint scatter as a gap.

    Returns
    -------
    levels (n_cond,), means and standard errors (n_cond, n_modes) in the unit of ``values``, and
    the covariances (n_cond, n_modes, n_modes) of the relative errors of the means.
    """
    levels = np.unique(amplitude)
    means = np.array([np.nanmean(np.where((amplitude == a)[:, None], values, np.nan), axis=0) for a in levels])
    counts = np.array([np.sum(~np.isnan(values[amplitude == a]), axis=0) for a in levels])
    covariance, usable = _test_covariance(values, amplitude, levels)
    if published_std is not None:  # published means: their std, no correlation known
        rel = np.asarray(published_std, float) / np.nanmean(values, axis=0)
        covariance = np.where(np.diag(usable), covariance, np.diag(rel ** 2))
        counts = np.maximum(counts, tests_count or 1)
    n = np.maximum(counts, 1)
    cov_means = np.array([covariance / np.sqrt(np.outer(n[c], n[c])) + np.diag(np.full(values.shape[1], floor_rel ** 2))
                          for c in range(levels.size)])
    se = np.sqrt(np.array([np.diag(c) for c in cov_means])) * np.abs(means)
    return levels, means, se, cov_means


def observations(measured: MeasuredModes, relative_floor: float = RELATIVE_FLOOR,
                 damping_floor: float = DAMPING_FLOOR) -> Observations:
    """Condition means, standard errors and covariances of a campaign's modes (module docstring).

    Parameters
    ----------
    measured : the measured modes (per test, or one row of published means with their std).
    relative_floor, damping_floor : floors of the relative standard errors of the mean frequencies
        and mean damping ratios.
    """
    n_tests = measured.frequency_hz.shape[0]
    amplitude = measured.amplitude if measured.amplitude is not None else np.ones(n_tests)
    levels = np.unique(amplitude)
    if measured.published_std_hz is None and not _test_covariance(measured.frequency_hz, amplitude, levels)[1].any():
        # with the floor alone as the error, any model error reads as a gap far beyond scatter
        raise ValueError(f"{measured.source}: tests: {n_tests} test(s) over {levels.size} excitation level(s) leave "
                         "no degree of freedom to measure the test-to-test scatter, so a gap cannot be told from "
                         "chance; diagnose needs a repeated test (or std_hz in moments.csv)")
    levels, f, f_se, f_cov = _condition_means(measured.frequency_hz, amplitude, relative_floor,
                                              measured.published_std_hz, measured.tests_count)
    d = d_se = None
    if measured.damping_ratio is not None:
        _, d, d_se, _ = _condition_means(measured.damping_ratio, amplitude, damping_floor, None, None)
    return Observations(levels, f, f_se, f_cov, d, d_se)


def frequency_chi2(obs: Observations, predicted_hz: np.ndarray, mask: np.ndarray | None = None,
                   cache: dict | None = None) -> float:
    """``sum_c r_c^T C_c^-1 r_c`` of the relative residuals over the modes in ``mask``.

    ``predicted_hz`` (n_cond, n_modes), Hz. ``cache`` keeps the inverted covariances between calls
    with the same missing means.
    """
    r = predicted_hz / obs.frequency_hz - 1.0
    mask = np.ones(r.shape[1], bool) if mask is None else mask
    total = 0.0
    for c in range(r.shape[0]):
        idx = mask & ~np.isnan(r[c])
        key = (c, idx.tobytes())
        if cache is None or key not in cache:
            w = np.linalg.inv(obs.frequency_cov[c][np.ix_(idx, idx)])
            if cache is not None:
                cache[key] = w
        else:
            w = cache[key]
        total += float(r[c, idx] @ w @ r[c, idx])
    return total


def chi2(residual: np.ndarray, se: np.ndarray) -> float:
    """Sum of the squared residuals over their standard errors, NaN skipped."""
    z = residual / se
    return float(np.nansum(z * z))


def rms(x: np.ndarray) -> float:
    """Root mean square, NaN skipped (NaN when nothing is left)."""
    return float(np.sqrt(np.nanmean(x * x))) if np.any(~np.isnan(x)) else float("nan")

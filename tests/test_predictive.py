"""The leave-one-mode-out predictive density (`workbench.diagnose.predictive`) against an explicit Gaussian
conditioning, the independent-modes case and its expectation under the model."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from workbench.diagnose.observations import FORM_SD, Discrepancy, Observations, frequency_chi2
from workbench.diagnose.predictive import frequency_score


def _observations(n_modes: int = 5, n_cond: int = 2, seed: int = 3, correlated: bool = True) -> Observations:
    rng = np.random.default_rng(seed)
    f = np.tile(np.linspace(50.0, 600.0, n_modes), (n_cond, 1)) * (1.0 + 0.002 * rng.standard_normal((n_cond, n_modes)))
    if correlated:
        a = rng.standard_normal((n_cond, n_modes, n_modes)) * 1e-4
        cov = a @ a.transpose(0, 2, 1) + np.eye(n_modes) * 1e-8
        discrepancy = Discrepancy(0.001, 0.004, 0.2, geometry=rng.standard_normal((n_modes, 3)) * 0.002)
    else:
        cov = np.tile(np.eye(n_modes) * 1e-8, (n_cond, 1, 1))
        discrepancy = Discrepancy(0.001, 0.0, 0.2)
    f[0, 1] = np.nan  # a missing mean
    return Observations(np.arange(1.0, n_cond + 1.0), f, f * 1e-4, cov, None, None, discrepancy)


def _explicit(obs: Observations, rows: np.ndarray, reference: np.ndarray) -> tuple[float, float]:
    """The same score by conditioning each left-out mode's block on the rest (covariance blocks, no precision)."""
    present, cov = obs.joint_covariance(np.ones(obs.frequency_hz.shape[1], bool))
    mode = np.nonzero(present)[1]
    chi2, log_det = 0.0, 0.0
    for k in range(rows.shape[0]):
        a, b = mode == k, mode != k
        r = (rows[k] / obs.frequency_hz - 1.0)[present]
        extra = (FORM_SD * (rows[k] / reference - 1.0))[present]
        w = cov + np.outer(extra, extra) * (mode[:, None] == mode[None, :])

        def conditional(c: np.ndarray, a: np.ndarray = a, b: np.ndarray = b) -> np.ndarray:
            return c[np.ix_(a, a)] - c[np.ix_(a, b)] @ np.linalg.solve(c[np.ix_(b, b)], c[np.ix_(b, a)])

        e = r[a] - w[np.ix_(a, b)] @ np.linalg.solve(w[np.ix_(b, b)], r[b])
        s = conditional(w)
        chi2 += float(e @ np.linalg.solve(s, e))
        log_det += np.linalg.slogdet(s)[1] - np.linalg.slogdet(conditional(cov))[1]
    return chi2, log_det


def test_the_score_is_the_gaussian_conditional_of_each_left_out_mode():
    obs = _observations()
    rng = np.random.default_rng(8)
    reference = obs.frequency_hz * 1.01
    reference[np.isnan(reference)] = 100.0
    n_modes = obs.frequency_hz.shape[1]
    rows = obs.frequency_hz[None] * (1.0 + 0.003 * rng.standard_normal((n_modes, *obs.frequency_hz.shape)))
    rows[np.isnan(rows)] = 100.0
    chi2, log_det = frequency_score(obs, rows, reference)
    want_chi2, want_log_det = _explicit(obs, rows, reference)
    assert chi2 == pytest.approx(want_chi2, rel=1e-8)
    assert log_det == pytest.approx(want_log_det, rel=1e-8, abs=1e-10)
    assert log_det > 0.0  # the form's error widens each conditional


def test_with_independent_modes_it_is_the_joint_chi_square():
    # with no error shared between modes, what the other modes did says nothing about the left-out one
    obs = _observations(correlated=False)
    predicted = np.where(np.isnan(obs.frequency_hz), 100.0, obs.frequency_hz * 1.002)
    chi2, log_det = frequency_score(obs, predicted, predicted)
    assert chi2 == pytest.approx(frequency_chi2(obs, predicted), rel=1e-9)
    assert log_det == pytest.approx(0.0, abs=1e-12)


def test_under_the_model_the_score_averages_one_per_mean():
    # r ~ N(0, C) about the true means: each standardised conditional residual has unit variance, so the summed
    # chi-square averages the number of means (its law is not chi-square: the residuals are correlated)
    obs = _observations(n_modes=4)
    present, cov = obs.joint_covariance(np.ones(4, bool))
    truth = np.where(np.isnan(obs.frequency_hz), 100.0, obs.frequency_hz)
    chol = np.linalg.cholesky(cov)
    rng = np.random.default_rng(11)
    draws = 1500
    values = []
    for _ in range(draws):
        measured = truth.copy()
        measured[present] = truth[present] / (1.0 + chol @ rng.standard_normal(cov.shape[0]))
        measured[~present] = np.nan
        values.append(frequency_score(replace(obs, frequency_hz=measured), truth, truth)[0])
    values = np.array(values)
    n = int(present.sum())
    # measured = truth / (1 + e) makes the residual predicted / measured - 1 exactly e
    assert abs(values.mean() - n) < 4.0 * values.std(ddof=1) / np.sqrt(draws)

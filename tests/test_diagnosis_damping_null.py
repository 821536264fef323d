"""The damping channel's chi-square under no effect: one model error per mode, whatever the number of levels.

Independent of the diagnosis's fits: the null is drawn here directly (a shared model error per mode of
``DAMPING_MODEL_SD`` of the typical ratio, a measurement error per level), and the chi-square's law is checked
against the chi-square law with one degree of freedom per mean (its variance ``2 k``). The former per-level
chi-square counted the shared error once per level, and its variance was 2.5 times the law's at two levels
(`benchmarks/damping_null_calibration.py` prints the rejection rates). The whitening is checked against the
quadratic form of the dense covariance it stands for.
"""

from __future__ import annotations

import numpy as np
import pytest
from scipy.stats import chi2 as chi2_law

from workbench.diagnose.family import damping_null
from workbench.diagnose.fitting import damping_columns, damping_fit
from workbench.diagnose.observations import (
    DAMPING_MODEL_SD,
    Discrepancy,
    Observations,
    damping_chi2,
    damping_levels_chi2,
    damping_whiten,
)

ZETA, SE_REL, MODES = 0.006, 0.02, 10


def _observations(damping: np.ndarray) -> Observations:
    n_cond, n_modes = damping.shape
    f = np.tile(np.linspace(50.0, 900.0, n_modes), (n_cond, 1))
    se = np.full_like(damping, SE_REL * ZETA)
    return Observations(np.arange(1.0, n_cond + 1.0), f, f * 1e-4, np.zeros((n_cond, n_modes, n_modes)), damping, se,
                        Discrepancy())


def _null_chi2(n_cond: int, draws: int, seed: int) -> tuple[np.ndarray, np.ndarray, int]:
    """The whole chi-square and its levels' part, and that part's degrees of freedom, over ``draws`` nulls."""
    rng = np.random.default_rng(seed)
    whole, levels = np.empty(draws), np.empty(draws)
    q = 0
    for i in range(draws):
        shared = DAMPING_MODEL_SD * ZETA * rng.standard_normal(MODES)
        measured = ZETA + shared[None, :] + SE_REL * ZETA * rng.standard_normal((n_cond, MODES))
        obs, base = _observations(measured), np.full_like(measured, ZETA)
        whole[i] = damping_chi2(obs, base)
        levels[i], q = damping_levels_chi2(obs, base)
    return whole, levels, q


@pytest.mark.parametrize("n_cond", [1, 2, 4])
def test_damping_chi2_follows_the_law_of_its_means(n_cond: int) -> None:
    whole, levels, q = _null_chi2(n_cond, 3000, 21 + n_cond)
    k = n_cond * MODES
    # chi-square law with one degree of freedom per mean: mean k, variance 2 k; the model error's scale taken
    # from the measured median widens it (about 1.25 times here). The per-level formula had 2.5 times its
    # law's variance at two levels; the bound 1.6 separates the two.
    assert abs(whole.mean() / k - 1.0) < 0.08
    assert 0.8 < whole.var() / (2 * k) < 1.6
    assert q == (MODES if n_cond > 1 else 0)
    if q:  # the levels' line: the model error cancels, chi-square with q degrees of freedom exactly
        assert abs(levels.mean() / q - 1.0) < 0.05
        assert 0.85 < levels.var() / (2 * q) < 1.15


def test_damping_chi2_is_the_quadratic_form_of_its_covariance() -> None:
    rng = np.random.default_rng(8)
    measured = ZETA * (1.0 + 0.2 * rng.standard_normal((3, MODES)))
    measured[1, 4] = np.nan  # a mean the second level did not measure
    obs = _observations(measured)
    obs = Observations(obs.amplitude, obs.frequency_hz, obs.frequency_se, obs.frequency_cov, measured,
                       obs.damping_se * rng.uniform(0.5, 2.0, measured.shape), obs.discrepancy)
    predicted = ZETA * (1.0 + 0.1 * rng.standard_normal(measured.shape))
    assert obs.damping_se is not None
    model = DAMPING_MODEL_SD * float(np.nanmedian(measured))
    expected = 0.0
    for i in range(MODES):
        ok = ~np.isnan(measured[:, i])
        r = (predicted - measured)[ok, i]
        cov = np.diag(obs.damping_se[ok, i] ** 2) + model**2
        expected += float(r @ np.linalg.solve(cov, r))
    assert damping_chi2(obs, predicted) == pytest.approx(expected, rel=1e-10)


def test_damping_fit_on_repeated_levels_is_the_one_level_fit() -> None:
    rng = np.random.default_rng(5)
    one = ZETA * (1.0 + 0.2 * rng.standard_normal((1, MODES)))
    share = rng.uniform(0.0, 1.0, MODES)
    mask = np.ones(MODES, bool)
    fit_one, p_one = damping_fit(_observations(one), share, mask)
    fit_two, p_two = damping_fit(_observations(np.vstack([one, one])), share, mask)
    np.testing.assert_allclose(fit_two, np.vstack([fit_one, fit_one]), rtol=1e-10)
    assert p_two == pytest.approx(p_one, rel=1e-10)


def test_damping_fit_is_the_same_at_every_level() -> None:
    """A linear damping model damps a mode alike at every level: the fit's prediction may not follow the levels'
    own frequencies (a viscous form read at each level's frequency followed a damping that rose with the level).
    """
    rng = np.random.default_rng(9)
    rising = ZETA * np.linspace(1.0, 3.0, 4)[:, None] * np.ones((1, MODES))
    obs = _observations(rising)
    softened = obs.frequency_hz * (1.0 - 0.01 * np.arange(4))[:, None]  # the frequencies fall with the level
    obs = Observations(obs.amplitude, softened, obs.frequency_se, obs.frequency_cov, rising, obs.damping_se,
                       obs.discrepancy)
    share = rng.uniform(0.0, 1.0, MODES) * softened / softened.mean()
    fit, _ = damping_fit(obs, share.mean(axis=0), np.ones(MODES, bool))
    np.testing.assert_allclose(fit, np.broadcast_to(fit[0], fit.shape), rtol=1e-12)


def family_tangents(obs: Observations, shares: list[np.ndarray]) -> list[np.ndarray]:
    """Each share's whitened column less its projection on the baseline's columns, written out here."""
    base = np.stack([damping_whiten(obs, c).ravel() for c in damping_columns(obs, np.ones(MODES, bool))], axis=1)
    out = []
    for share in shares:
        g = damping_whiten(obs, np.broadcast_to(share, obs.frequency_hz.shape)).ravel()
        out.append((g - base @ np.linalg.lstsq(base, g, rcond=None)[0])[:, None])
    return out


def test_damping_null_draws_the_drops_the_fits_make() -> None:
    """The damping family's draws stand for the candidates' fits exactly: for any measured damping, the drop a
    candidate's fit makes is ``max(0, -g.z)^2 / |g|^2`` of its column ``g`` (the share, whitened, less its
    projection on the baseline's columns) and the baseline's whitened residual ``z``; and the family-wise
    p-value is never above Bonferroni's bound (but for the draws' resolution).
    """
    rng = np.random.default_rng(12)
    f = np.linspace(50.0, 900.0, MODES)
    hysteretic = [rng.uniform(0.0, 1.0, MODES) for _ in range(3)]
    shares = [s for h in hysteretic for s in (h, h * f / f.mean())]

    def law(drop: np.ndarray) -> np.ndarray:
        return chi2_law.sf(drop, 1)

    mask = np.ones(MODES, bool)
    for _ in range(20):
        measured = ZETA * (1.0 + 0.2 * rng.standard_normal((2, MODES)))
        obs = _observations(measured)
        base_fit = damping_fit(obs, None, mask)[0]
        z = damping_whiten(obs, base_fit - measured).ravel()
        family = damping_null(obs, shares, law, draws=2000)
        drops = []
        for share, t in zip(shares, family_tangents(obs, shares)):
            drop = damping_chi2(obs, base_fit) - damping_chi2(obs, damping_fit(obs, share, mask)[0])
            g = t[:, 0]
            assert drop == pytest.approx(max(0.0, -float(g @ z)) ** 2 / float(g @ g), rel=1e-8, abs=1e-10)
            drops.append(drop)
        p_one = float(law(np.array(max(drops))))
        assert family.adjusted(p_one) <= min(1.0, len(shares) * p_one) + 2.0 / 2001

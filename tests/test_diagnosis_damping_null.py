"""The damping channel's chi-square under no effect: one model error per mode, whatever the number of levels.

Independent of the diagnosis's fits: the null is drawn here directly (a shared model error per mode of
``DAMPING_MODEL_SD`` of the typical ratio, a measurement error per level), and the chi-square's law is checked
against the chi-square law with one degree of freedom per mode (its variance ``2 k``). The former per-level
chi-square counted the shared error once per level, and its variance was twice the law's at two levels
(`benchmarks/damping_null_calibration.py` prints the rejection rates).
"""

from __future__ import annotations

import numpy as np
import pytest

from workbench.diagnose.fitting import damping_fit
from workbench.diagnose.observations import DAMPING_MODEL_SD, Discrepancy, Observations, damping_chi2

ZETA, SE_REL, MODES = 0.006, 0.02, 10


def _observations(damping: np.ndarray) -> Observations:
    n_cond, n_modes = damping.shape
    f = np.tile(np.linspace(50.0, 900.0, n_modes), (n_cond, 1))
    se = np.full_like(damping, SE_REL * ZETA)
    return Observations(np.arange(1.0, n_cond + 1.0), f, f * 1e-4, np.zeros((n_cond, n_modes, n_modes)), damping, se,
                        Discrepancy())


def _null_chi2(n_cond: int, draws: int, seed: int) -> np.ndarray:
    rng = np.random.default_rng(seed)
    out = np.empty(draws)
    for i in range(draws):
        shared = DAMPING_MODEL_SD * ZETA * rng.standard_normal(MODES)
        measured = ZETA + shared[None, :] + SE_REL * ZETA * rng.standard_normal((n_cond, MODES))
        out[i] = damping_chi2(_observations(measured), np.full_like(measured, ZETA))
    return out


@pytest.mark.parametrize("n_cond", [1, 2, 4])
def test_damping_chi2_follows_one_degree_of_freedom_per_mode(n_cond: int) -> None:
    chi2 = _null_chi2(n_cond, 3000, 21 + n_cond)
    # chi-square law with MODES degrees of freedom: mean MODES, variance 2 MODES; the scale taken from the
    # measured median widens it (about 1.25 times here, at any level count). The per-level formula, read
    # against its own law (2 n_cond MODES), had 2.5 times that law's variance at two levels.
    assert abs(chi2.mean() / MODES - 1.0) < 0.08
    assert 0.8 < chi2.var() / (2 * MODES) < 1.6


def test_damping_fit_on_repeated_levels_is_the_one_level_fit() -> None:
    rng = np.random.default_rng(5)
    one = ZETA * (1.0 + 0.2 * rng.standard_normal((1, MODES)))
    share = rng.uniform(0.0, 1.0, MODES)
    mask = np.ones(MODES, bool)
    fit_one, p_one = damping_fit(_observations(one), share, mask)
    fit_two, p_two = damping_fit(_observations(np.vstack([one, one])), share, mask)
    np.testing.assert_allclose(fit_two, np.vstack([fit_one, fit_one]), rtol=1e-10)
    assert p_two == pytest.approx(p_one, rel=1e-10)

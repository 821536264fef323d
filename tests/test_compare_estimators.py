"""benchmarks/compare_estimators.py: one tiny campaign through both estimators, and the summary."""

from __future__ import annotations

import importlib.util
import math

import numpy as np
import pytest
from conftest import REPO

SCRIPT = REPO / "benchmarks" / "compare_estimators.py"


@pytest.fixture(scope="module")
def study():
    spec = importlib.util.spec_from_file_location("compare_estimators", SCRIPT)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def test_campaign_is_seeded_and_drawn_from_the_truth(study):
    data, moduli = study.synthetic_campaign(9, seed=5)
    again, moduli_again = study.synthetic_campaign(9, seed=5)
    assert data.frequency_hz.shape == (9, study.N_MODES)
    np.testing.assert_array_equal(data.frequency_hz, again.frequency_hz)
    np.testing.assert_array_equal(moduli, moduli_again)
    other, _ = study.synthetic_campaign(40, seed=5)  # the designs' campaigns are independent
    assert not np.allclose(other.frequency_hz[:9], data.frequency_hz)
    assert 0.7 * study.TRUE_E_PA < moduli.mean() < 1.3 * study.TRUE_E_PA


def test_reference_posterior_matches_the_normal_theory(study):
    rng = np.random.default_rng(3)
    y = 24e9 * rng.gamma(1 / 0.09**2, 0.09**2, 400)
    (e_lo, e_med, e_hi), (c_lo, c_med, c_hi) = study.reference_posterior(y)
    cov = y.std(ddof=1) / y.mean()
    assert e_med == pytest.approx(y.mean(), rel=1e-3)
    assert math.log(e_hi / e_lo) == pytest.approx(2 * 1.96 * cov / math.sqrt(400), rel=0.05)
    assert c_med == pytest.approx(cov, rel=0.02)
    assert math.log(c_hi / c_lo) == pytest.approx(2 * 1.96 / math.sqrt(2 * 399), rel=0.1)


def test_one_tiny_campaign_through_both_estimators(study):
    rows, kept = study.run_campaign(9, 1, base_seed=7, steps=60, burn=20, walkers=24, keep_posterior=True)
    assert [r["estimator"] for r in rows] == list(study.ESTIMATORS)
    for r in rows:
        assert set(study.RUN_FIELDS) <= set(r)
        assert r["design"] == 9 and r["campaign"] == 1 and r["seed"] == 8
        assert r["start_pa"] == 0.5 * study.TRUE_E_PA  # odd campaigns start 2x low
        assert abs(r["E_pa"] / r["sample_mean_pa"] - 1) < 0.05  # far from the 12 GPa start
        assert 0.005 < r["cov"] < 0.6 and r["wall_time_s"] > 0
    bayes = rows[1]
    assert bayes["E_lo_pa"] < bayes["E_pa"] < bayes["E_hi_pa"]
    assert bayes["cov_lo"] < bayes["cov"] < bayes["cov_hi"]
    assert math.isfinite(bayes["max_rhat"]) and bayes["ess_E"] > 0
    assert set(kept.data_vars) == {"E_GPa", "cov"}
    assert bayes["ref_E_lo_pa"] < bayes["sample_mean_pa"] < bayes["ref_E_hi_pa"]
    assert bayes["ref_cov_lo"] < bayes["sample_cov"] < bayes["ref_cov_hi"]

    summary = study.summarise(rows)
    assert [(r["estimator"], r["quantity"]) for r in summary] == [
        ("moment_matching", "E"), ("moment_matching", "CoV"), ("bayes", "E"), ("bayes", "CoV")]
    assert "bias%" in study.format_summary(summary)
    targets = study.check_targets(summary, design=9)
    assert len(targets) == 4 and all(isinstance(held, bool) for _, _, held in targets)

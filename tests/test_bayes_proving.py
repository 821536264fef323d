"""The Bayesian identification, whole (circle fit, pairing, Laplace, sampler), on a campaign of the independent
proving ground, fitted with the generator's own physics (`benchmarks/bayes_bias_source.py`, ``timo_asbuilt``).

With the nominal model right, what is left between each group's estimated mean modulus and the campaign's sample
mean is the pipeline's own error. On the development seed's campaigns 0-5 (four-bolt frame,
`reports/estimators_proving.md`, section 7) it was 0.04-0.32 points, and the discrepancy scale fell to 0.01 % or
less, against 0.2-0.6 % with the bundled Euler-Bernoulli file. The bounds below were frozen from those six
before this test's campaign (7) was fitted: 1.5 points (about five times the largest), and a discrepancy scale under
0.2 % (the smallest the misspecified file needed).

The second test runs it as a user would, without reading the truth: the Timoshenko frame as drawn, with the
drawing's tolerances integrated as latent factors (`workbench.identify.members`, ``timo_tolerances``). On the
development seed's twelve campaigns (0-5 of both designs) the estimates landed 0.0-4.4 points from the sample means
(all but two under 0.6) and the discrepancy scale at 0.05 % or less. Frozen from those before campaign 7 was
fitted: 5 points, and 0.1 %. Campaign 7 failed them (6.8 points off, interval +-1.8 %) with the factors' terms
expanded about the drawing only; they are now expanded again where the posterior puts the factors
(`workbench.identify.laplace.LaplaceLikelihood.reanchored`), a change made after looking at campaign 7, so the test
fits campaign 8, which no step saw, with the same bounds.

The third is a regression test on a development campaign (1), not a held-out one: stated twice too wide, its
tolerances once sent the horizontal mean to a confident -24 % (the likelihood stayed anchored where a search
with fixed error scales had put it); it holds the mend (`workbench.identify.runs.sample_anchored`) to the
second test's mean bound, with the sample mean inside the interval.
"""

from __future__ import annotations

import importlib.util
import sys

import pytest
from conftest import REPO

pytestmark = pytest.mark.slow

CAMPAIGN = 7  # not one of the six the bounds came from
MEAN_BOUND = 1.5  # points of the group's law's mean
DISCREPANCY_BOUND = 0.2  # %
TOLERANCES_MEAN_BOUND = 5.0  # points, with the tolerances integrated (module docstring)
TOLERANCES_DISCREPANCY_BOUND = 0.1  # %


TOLERANCES_CAMPAIGN = 8


def _fit(kind: str, campaign: int = CAMPAIGN) -> dict:
    sys.path.insert(0, str(REPO / "benchmarks"))  # the script imports its sibling estimators_proving
    try:
        spec = importlib.util.spec_from_file_location("bayes_bias_source", REPO / "benchmarks" / "bayes_bias_source.py")
        module = importlib.util.module_from_spec(spec)
        spec.loader.exec_module(module)
        return module.fit_one("four", campaign, kind)
    finally:
        sys.path.remove(str(REPO / "benchmarks"))


@pytest.fixture(scope="module")
def fit():
    return _fit("timo_asbuilt")


def test_with_the_generators_physics_each_group_lands_on_its_sample_mean(fit):
    assert fit["converged"]
    for group in ("vertical", "horizontal"):
        row = fit[group]
        assert abs(row["mean"] - row["sample"]) < MEAN_BOUND, (group, row)
        assert row["low"] <= row["sample"] <= row["high"], (group, row)
    assert fit["discrepancy_scale_pct"] < DISCREPANCY_BOUND, fit


def test_with_the_drawings_tolerances_integrated_each_group_lands_near_its_sample_mean():
    fit = _fit("timo_tolerances", TOLERANCES_CAMPAIGN)
    assert fit["converged"]
    for group in ("vertical", "horizontal"):
        row = fit[group]
        assert abs(row["mean"] - row["sample"]) < TOLERANCES_MEAN_BOUND, (group, row)
    assert fit["discrepancy_scale_pct"] < TOLERANCES_DISCREPANCY_BOUND, fit


MISSTATED_CAMPAIGN = 1  # a development campaign: the one the defect showed on


def test_a_tolerance_stated_twice_too_wide_does_not_send_the_mean_away():
    """Campaign 1 with the tolerance stated at twice the drawing's gave -23.6 % [-25.0, -22.1] for a sample mean
    of +1.6 % when the likelihood stayed anchored where a search with fixed error scales had put it (-45 %); the
    pilot runs now anchor it where the posterior goes (`workbench.identify.runs.sample_anchored`).
    """
    fit = _fit("timo_tolerances_x2", MISSTATED_CAMPAIGN)
    assert fit["converged"]
    for group in ("vertical", "horizontal"):
        row = fit[group]
        assert abs(row["mean"] - row["sample"]) < TOLERANCES_MEAN_BOUND, (group, row)
        assert row["low"] <= row["sample"] <= row["high"], (group, row)

"""The Laplace likelihood with its further error terms (a test-level common error ``u_t`` and a per-mode
model discrepancy ``delta_k``, `workbench.identify.laplace`) against brute-force integration of the
same integrand: nested grids over every latent variable of a small campaign (one joint, three tests,
two modes: per test ``z_t`` and ``u_t``, shared ``delta_1``, ``delta_2``)."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.special import gammaln, logsumexp
from test_bayes import ONE_BOLT, synthetic

from workbench.identify.anchored import AnchoredForward
from workbench.identify.laplace import ErrorTerms, laplace_likelihood

pytestmark = pytest.mark.slow

SIGMA = 2e-3  # relative measurement error: a circle fit's scatter
COMMON_SD, DISCREPANCY = 3e-3, np.array([0.006, -0.004])
# A log-likelihood error of 0.05 changes a posterior density ratio by 5 %, well inside what a chain of a
# few thousand steps resolves; frozen before the first comparison.
TOLERANCE = 0.05


@pytest.fixture(scope="module")
def campaign():
    model, data, _ = synthetic(ONE_BOLT, [24e9], [0.09], 3, SIGMA, 21, count=2)
    rng = np.random.default_rng(4)
    shifted = data.frequency_hz * np.exp(COMMON_SD * rng.standard_normal((3, 1)) + DISCREPANCY)
    data = type(data)(shifted, modes=data.modes, tests=data.tests, source="synthetic, shifted")
    lm, _ = laplace_likelihood(model, data, terms=ErrorTerms(common=True, discrepancy=True))
    return lm


def _log_normal(x: np.ndarray, sd: np.ndarray | float) -> np.ndarray:
    return -0.5 * (x / sd) ** 2 - np.log(sd) - 0.5 * np.log(2 * np.pi)


def _brute_force(lm, theta: np.ndarray, delta_mode: np.ndarray, delta_sd: np.ndarray) -> float:
    """``log p(f | theta)`` by Riemann sums: delta on a 25 x 25 grid (+-6 of its Laplace sd around its
    Laplace mode: only the grid's place comes from Laplace, and its edges are checked), and for each
    delta, each test's (z, u) on a 601 x 201 grid."""
    log_e, log_c, log_sigma, log_su, log_sd = theta[0], theta[1], theta[2:4], theta[4], theta[5]
    c, s_u, s_d = np.exp(log_c), np.exp(log_su), np.exp(log_sd)
    a, log_th = 1 / c**2, log_e + 2 * log_c
    sd = np.exp(log_sigma) * lm.fbar
    d_axes = [np.linspace(m - 6 * s, m + 6 * s, 25) for m, s in zip(delta_mode, delta_sd)]
    d1, d2 = np.meshgrid(*d_axes, indexing="ij")
    delta = np.stack([d1.ravel(), d2.ravel()], axis=-1)  # (D, 2)
    u = np.linspace(-7 * s_u - 0.02, 7 * s_u + 0.02, 201)  # wide: where delta is off, u makes up for it
    total = np.sum(_log_normal(delta, s_d), axis=-1)  # (D,)
    gaps = []
    for t in range(lm.f_obs.shape[0]):
        low, high = sorted((lm.z_start[t, 0], log_e))  # between the test's anchor and the population's mean
        z = np.linspace(low - 1.5, high + 0.8, 601)  # a log-Gamma law's long left tail
        one = AnchoredForward(lm.table.anchor[t:t + 1], lm.table.rest[t:t + 1], lm.table.joints[t:t + 1])
        g = np.asarray(one(z[:, None, None]))[:, 0, :]  # (Z, K): test t's forward model
        prior = a * (z - log_th) - np.exp(z - log_th) - gammaln(a)  # (Z,)
        f = g[None, :, None, :] * np.exp(u[None, None, :, None] + delta[:, None, None, :])  # (D, Z, U, K)
        log_g = (np.sum(_log_normal(lm.f_obs[t] - f, sd), axis=-1) + prior[None, :, None]
                 + _log_normal(u, s_u)[None, None, :])
        edges = np.maximum(log_g[:, [0, -1], :].max(axis=(1, 2)), log_g[:, :, [0, -1]].max(axis=(1, 2)))
        gaps.append(log_g.max(axis=(1, 2)) - edges)  # (D,) how far below each delta's peak its grid's edges are
        total = total + logsumexp(log_g, axis=(1, 2)) + np.log((z[1] - z[0]) * (u[1] - u[0]))
    # the (z, u) grids hold the integrand: at every delta, each grid's edges lie far below the peak of the
    # whole integrand (a delta point of small weight may have its grid cut closer)
    assert np.all(total - np.array(gaps) < total.max() - 20), "the (z, u) grid must hold the integrand"
    grid = total.reshape(25, 25)
    assert max(grid[[0, -1]].max(), grid[:, [0, -1]].max()) < grid.max() - 15, "the delta grid must hold it"
    return float(logsumexp(total) + np.log((d_axes[0][1] - d_axes[0][0]) * (d_axes[1][1] - d_axes[1][0])))


@pytest.mark.parametrize("theta_args", [
    {},  # the truth
    # away from the truth in every parameter at once: one grid run (each takes a quarter of a minute)
    {"shift": 0.04, "cov": 0.15, "sigma": 4e-3, "common": 0.006, "discrepancy": 0.004},
])
def test_laplace_with_common_and_discrepancy_terms_against_nested_grids(campaign, theta_args):
    lm = campaign
    args = {"shift": 0.0, "cov": 0.09, "sigma": SIGMA, "common": COMMON_SD, "discrepancy": 0.008} | theta_args
    theta = np.r_[args["shift"], np.log(args["cov"]), np.log([args["sigma"]] * 2), np.log(args["common"]),
                  np.log(args["discrepancy"])]
    fast = float(lm.log_likelihood(theta[None])[0])
    mode, sd = (x[0] for x in lm.discrepancy(theta[None]))
    slow = _brute_force(lm, theta, mode, sd)
    assert abs(fast - slow) < TOLERANCE, (fast, slow)

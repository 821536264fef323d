"""The Laplace likelihood with its further error terms (a test-level common error ``u_t``, a per-mode
model discrepancy ``delta_k`` and sensitivity error ``eps_k``, `workbench.identify.laplace`) against
brute-force integration of the same integrand on a small campaign (one joint, three tests, two modes):
per test ``z_t`` and ``u_t`` on fine grids; the shared latents on a grid (``delta_1``, ``delta_2``) or,
with ``eps_1``, ``eps_2`` too, by importance sampling (a four-dimensional grid of that fineness is
out of reach)."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.special import gammaln, logsumexp
from test_bayes import ONE_BOLT, synthetic

from workbench.identify.laplace import SENSITIVITY_SD, ErrorTerms, laplace_likelihood

pytestmark = pytest.mark.slow

SIGMA = 2e-3  # relative measurement error: a circle fit's scatter
COMMON_SD, DISCREPANCY = 3e-3, np.array([0.006, -0.004])
# A log-likelihood error of 0.05 changes a posterior density ratio by 5 %, well inside what a chain of a
# few thousand steps resolves; frozen before the first comparison.
TOLERANCE = 0.05
DRAWS = 4000  # importance draws of the shared latents; the estimate's standard error is checked below
IS_LINES = (301, 101)  # each draw's (z, u) grids: a smooth integrand's Riemann sums need no more


@pytest.fixture(scope="module")
def data():
    model, data, _ = synthetic(ONE_BOLT, [24e9], [0.09], 3, SIGMA, 21, count=2)
    rng = np.random.default_rng(4)
    shifted = data.frequency_hz * np.exp(COMMON_SD * rng.standard_normal((3, 1)) + DISCREPANCY)
    return model, type(data)(shifted, modes=data.modes, tests=data.tests, source="synthetic, shifted")


def _log_normal(x: np.ndarray, sd: np.ndarray | float) -> np.ndarray:
    return -0.5 * (x / sd) ** 2 - np.log(sd) - 0.5 * np.log(2 * np.pi)


def _tests_integral(lm, theta: np.ndarray, delta: np.ndarray, eps: np.ndarray, lines: tuple[int, int] = (601, 201)
                    ) -> np.ndarray:
    """``sum_t log`` of each test's integral over its ``(z, u)`` (Riemann sums on ``lines`` points) at each
    row of the shared latents ``delta``, ``eps`` (D, K) each, (D,); its grids' edges checked."""
    log_e, log_c, log_sigma, log_su = theta[0], theta[1], theta[2:4], theta[4]
    c, s_u = np.exp(log_c), np.exp(log_su)
    a, log_th = 1 / c**2, log_e + 2 * log_c
    sd = np.exp(log_sigma) * lm.fbar
    u = np.linspace(-7 * s_u - 0.02, 7 * s_u + 0.02, lines[1])  # wide: where delta is off, u makes up for it
    total, gaps = np.zeros(delta.shape[0]), []
    for t in range(lm.f_obs.shape[0]):
        low, high = sorted((lm.z_start[t, 0], log_e))  # between the test's anchor and the population's mean
        z = np.linspace(low - 1.5, high + 0.8, lines[0])  # a log-Gamma law's long left tail
        joint = lm.table.joints[t, :, 0] * np.exp(z[:, None] - lm.table.anchor[t, 0])  # (Z, K)
        lam = lm.table.rest[t] + np.exp(eps)[:, None, :] * joint[None]  # (D, Z, K): joint energies x exp(eps)
        g = np.sqrt(lam) / (2 * np.pi)
        prior = a * (z - log_th) - np.exp(z - log_th) - gammaln(a)  # (Z,)
        f = g[:, :, None, :] * np.exp(u[None, None, :, None] + delta[:, None, None, :])  # (D, Z, U, K)
        log_g = (np.sum(_log_normal(lm.f_obs[t] - f, sd), axis=-1) + prior[None, :, None]
                 + _log_normal(u, s_u)[None, None, :])
        edges = np.maximum(log_g[:, [0, -1], :].max(axis=(1, 2)), log_g[:, :, [0, -1]].max(axis=(1, 2)))
        gaps.append(log_g.max(axis=(1, 2)) - edges)  # (D,) how far below each row's peak its grid's edges are
        total = total + logsumexp(log_g, axis=(1, 2)) + np.log((z[1] - z[0]) * (u[1] - u[0]))
    # the (z, u) grids hold the integrand: at every row, each grid's edges lie far below the peak of the
    # whole integrand (a row of small weight may have its grid cut closer)
    assert np.all(total - np.array(gaps) < total.max() - 20), "the (z, u) grid must hold the integrand"
    return total


def _theta(args: dict) -> np.ndarray:
    return np.r_[args["shift"], np.log(args["cov"]), np.log([args["sigma"]] * 2), np.log(args["common"]),
                 np.log(args["discrepancy"])]


THETAS = [
    {},  # the truth
    # away from the truth in every parameter at once: one grid run (each takes a quarter of a minute)
    {"shift": 0.04, "cov": 0.15, "sigma": 4e-3, "common": 0.006, "discrepancy": 0.004},
]
TRUTH = {"shift": 0.0, "cov": 0.09, "sigma": SIGMA, "common": COMMON_SD, "discrepancy": 0.008}


@pytest.mark.parametrize("theta_args", THETAS)
def test_laplace_with_common_and_discrepancy_terms_against_nested_grids(data, theta_args):
    # delta on a 25 x 25 grid (+-6 of its Laplace sd around its Laplace mode: only the grid's place comes
    # from Laplace, and its edges are checked)
    lm, _ = laplace_likelihood(*data, terms=ErrorTerms(common=True, discrepancy=True, sensitivity=False))
    theta = _theta(TRUTH | theta_args)
    fast = float(lm.log_likelihood(theta[None])[0])
    mode, sd = (x[0] for x in lm.discrepancy(theta[None]))
    axes = [np.linspace(m - 6 * s, m + 6 * s, 25) for m, s in zip(mode, sd)]
    delta = np.stack([g.ravel() for g in np.meshgrid(*axes, indexing="ij")], axis=-1)  # (D, 2)
    total = _tests_integral(lm, theta, delta, np.zeros_like(delta)) + np.sum(_log_normal(delta, np.exp(theta[5])), -1)
    grid = total.reshape(25, 25)
    assert max(grid[[0, -1]].max(), grid[:, [0, -1]].max()) < grid.max() - 15, "the delta grid must hold it"
    slow = float(logsumexp(total) + np.log((axes[0][1] - axes[0][0]) * (axes[1][1] - axes[1][0])))
    assert abs(fast - slow) < TOLERANCE, (fast, slow)


@pytest.mark.parametrize("theta_args", THETAS)
def test_laplace_with_the_sensitivity_error_against_importance_sampling(data, theta_args):
    # the shared latents (delta_1, delta_2, eps_1, eps_2) drawn from a Student t (10 degrees of freedom,
    # 1.2 times the Laplace covariance: heavier tails than the integrand), each draw's tests integrated
    # on grids; the estimate is trusted only with a standard error a fifth of the tolerance
    lm, _ = laplace_likelihood(*data, terms=ErrorTerms(common=True, discrepancy=True, sensitivity=True))
    theta = _theta(TRUTH | theta_args)
    fast = float(lm.log_likelihood(theta[None])[0])
    law = lm._mode(theta[None])
    mode, cov = law.shared_mode[0], 1.2 ** 2 * law.shared_cov[0]
    rng, nu, dim = np.random.default_rng(11), 10.0, mode.size
    root = np.linalg.cholesky(cov)
    chi = rng.chisquare(nu, DRAWS)
    draws = mode + (rng.standard_normal((DRAWS, dim)) @ root.T) / np.sqrt(chi / nu)[:, None]
    maha = np.einsum("di,ij,dj->d", draws - mode, np.linalg.inv(cov), draws - mode)
    log_q = (gammaln((nu + dim) / 2) - gammaln(nu / 2) - 0.5 * dim * np.log(nu * np.pi)
             - 0.5 * np.linalg.slogdet(cov)[1] - 0.5 * (nu + dim) * np.log1p(maha / nu))
    prior = (np.sum(_log_normal(draws[:, :2], np.exp(theta[5])), -1)
             + np.sum(_log_normal(draws[:, 2:], SENSITIVITY_SD), -1))
    log_w = np.concatenate([_tests_integral(lm, theta, d[:, :2], d[:, 2:], IS_LINES)
                            for d in np.array_split(draws, 80)]) + prior - log_q
    weights = np.exp(log_w - log_w.max())
    standard_error = float(np.std(weights) / np.mean(weights) / np.sqrt(DRAWS))  # of the log estimate
    assert standard_error < 0.01, "the importance estimate must be far finer than the tolerance"
    slow = float(logsumexp(log_w) - np.log(DRAWS))
    assert abs(fast - slow) < TOLERANCE, (fast, slow, standard_error)

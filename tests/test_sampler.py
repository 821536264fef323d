"""The ensemble sampler with its fitted independence move (`workbench.identify.sampler`) against closed
forms: a correlated Gaussian and the log of half-normal scales, whose moments are known exactly."""

from __future__ import annotations

import math

import numpy as np

from workbench.identify.sampler import StudentProposal, run_ensemble

EULER_GAMMA = 0.5772156649015329
# s = log(sigma), sigma ~ half-normal(1): E[s] = -(gamma + log 2) / 2, Var[s] = pi^2 / 8
LOG_HALF_NORMAL_MEAN = -(EULER_GAMMA + math.log(2.0)) / 2.0
LOG_HALF_NORMAL_VAR = math.pi**2 / 8.0
COV = np.array([[1.0, 0.6, 0.0], [0.6, 2.0, -0.3], [0.0, -0.3, 0.25]])
MEAN = np.array([1.0, -2.0, 0.5])


def _target(theta: np.ndarray) -> np.ndarray:
    """Three correlated normal parameters and three logs of half-normal scales (as the error scales are sampled)."""
    d = theta[:, :3] - MEAN
    gauss = -0.5 * np.einsum("ni,ij,nj->n", d, np.linalg.inv(COV), d)
    s = theta[:, 3:]
    return gauss + np.sum(s - 0.5 * np.exp(2.0 * s), axis=1)


def test_the_independence_move_keeps_every_moment_of_a_skewed_target():
    rng = np.random.default_rng(7)
    sampler = run_ensemble(_target, rng.standard_normal((24, 6)) * 0.3, 3000, 400, seed=3, independence=True)
    flat = sampler.get_chain(flat=True)
    tau = sampler.get_autocorr_time(quiet=True)
    ess = flat.shape[0] / tau
    mean = np.r_[MEAN, [LOG_HALF_NORMAL_MEAN] * 3]
    var = np.r_[np.diag(COV), [LOG_HALF_NORMAL_VAR] * 3]
    z = (flat.mean(axis=0) - mean) / np.sqrt(var / ess)
    assert np.all(np.abs(z) < 4.5), z
    np.testing.assert_allclose(flat.var(axis=0), var, rtol=0.1)
    np.testing.assert_allclose(np.corrcoef(flat[:, :2].T)[0, 1], 0.6 / math.sqrt(2.0), atol=0.05)
    assert tau.max() < 15, tau  # differential evolution alone: about 20 steps in 6 dimensions


def test_the_independence_move_keeps_the_spread_of_a_12d_gaussian():
    rng = np.random.default_rng(3)

    def log_prob(theta):
        return -0.5 * np.sum(theta**2, axis=1)

    chain = run_ensemble(log_prob, rng.standard_normal((48, 12)), 2000, 400, seed=4,
                         independence=True).get_chain(flat=True)
    assert abs(chain.std(axis=0).mean() - 1.0) < 0.03
    assert np.all(np.abs(chain.mean(axis=0)) < 0.1)


def test_same_seed_same_chain_with_the_independence_move():
    start = np.random.default_rng(0).standard_normal((16, 6)) * 0.3
    a = run_ensemble(_target, start, 50, 40, seed=5, independence=True).get_chain()
    b = run_ensemble(_target, start, 50, 40, seed=5, independence=True).get_chain()
    np.testing.assert_array_equal(a, b)


def test_the_proposal_density_ratio_is_the_t_law_s_with_its_jacobian():
    """Importance weights of the proposal's own draws against its stated density: flat when the density
    (with the Jacobian of the exponentiated coordinates) is right."""
    rng = np.random.default_rng(2)
    points = np.column_stack([rng.normal(0.0, 1.0, 4000), np.log(np.abs(rng.normal(0.0, 1.0, 4000)))])
    proposal = StudentProposal().fit(points)
    draws, ratio = proposal(np.zeros((40000, 2)), np.random.RandomState(1))
    draws = draws[np.isfinite(ratio)]  # a scale drawn below zero is refused: the density covers the rest
    kept = (np.abs(draws[:, 0]) < 1.0) & (draws[:, 1] > -1.5) & (draws[:, 1] < 0.5)
    # the fraction of draws in a box against the stated density integrated over it (a 200 x 200 grid)
    x, y = np.meshgrid(np.linspace(-1, 1, 201)[:-1] + 0.005, np.linspace(-1.5, 0.5, 201)[:-1] + 0.005)
    grid = np.column_stack([x.ravel(), y.ravel()])
    wide = np.meshgrid(np.linspace(-12, 12, 601), np.linspace(-12, 4, 601))
    wide_grid = np.column_stack([wide[0].ravel(), wide[1].ravel()])
    norm = np.sum(np.exp(proposal.log_density(wide_grid))) * (24 / 600) * (16 / 600)
    mass = np.sum(np.exp(proposal.log_density(grid))) * 0.01 * 0.01 / norm
    assert abs(kept.mean() - mass) < 0.01, (kept.mean(), mass)

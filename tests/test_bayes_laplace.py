"""The Laplace integration of each test's latent joint moduli (workbench.identify.laplace), for any
number of joints: its error against brute-force integration where that is possible (two joints),
its anchored forward model against exact solves, and four joints identified one by one."""

from __future__ import annotations

import numpy as np
import pytest
from conftest import REPO
from scipy.special import gammaln
from test_bayes import TWO_BOLT, synthetic

from workbench.identify.anchored import AnchoredForward
from workbench.identify.bayes import bayes_identify
from workbench.identify.data import JointGroups
from workbench.identify.laplace import ErrorTerms, laplace_likelihood
from workbench.identify.likelihood import likelihood_model

FOUR_BOLT = REPO / "frames" / "four_bolt.toml"


@pytest.fixture(scope="module")
def two_joints():
    model, data, _ = synthetic(TWO_BOLT, [24e9, 73.5e9], [0.09, 0.22], 4, 5e-4, 12)
    # the integration of the latent moduli alone: no further error terms
    plain = laplace_likelihood(model, data, terms=ErrorTerms(False, False))[0]
    return model, data, plain, likelihood_model(model, data)[0]


def _theta(lm, shift=(0.0, 0.0), covs=(0.09, 0.22), sigma=5e-4):
    return np.r_[shift, np.log(covs), np.full(lm.fbar.size, np.log(sigma))]


def _grid_log_likelihood(lm, theta, t, half=(0.2, 0.45), points=601):
    """``log p(f_t | theta)`` by a fine 2-D grid over z with the Laplace likelihood's own forward model."""
    c = np.exp(theta[2:4])
    a, log_th = 1 / c**2, theta[:2] + 2 * theta[2:4]
    sd = np.exp(theta[4:]) * lm.fbar
    z0 = lm.z_start[t]
    g0 = np.linspace(z0[0] - half[0], z0[0] + half[0], points)
    g1 = np.linspace(z0[1] - half[1], z0[1] + half[1], points)
    z = np.stack(np.meshgrid(g0, g1, indexing="ij"), axis=-1)
    one = AnchoredForward(lm.table.anchor[t:t + 1], lm.table.rest[t:t + 1], lm.table.joints[t:t + 1])
    f = one(z[..., None, :])[..., 0, :]  # test t's forward model at every grid point
    log_g = np.sum(-0.5 * ((lm.f_obs[t] - f) / sd) ** 2 - np.log(sd) - 0.5 * np.log(2 * np.pi), axis=-1)
    log_g += np.sum(a * (z - log_th) - np.exp(z - log_th) - gammaln(a), axis=-1)
    edge = max(log_g[0].max(), log_g[-1].max(), log_g[:, 0].max(), log_g[:, -1].max())
    assert edge < log_g.max() - 30  # the grid holds the whole integrand
    peak = log_g.max()
    return peak + np.log(np.exp(log_g - peak).sum() * (g0[1] - g0[0]) * (g1[1] - g1[0]))


@pytest.mark.parametrize("theta_args", [{}, {"shift": (0.03, -0.05)}, {"covs": (0.15, 0.3), "sigma": 1e-3}])
def test_laplace_against_brute_force_integration_on_two_joints(two_joints, theta_args):
    _, _, lm, _ = two_joints
    theta = _theta(lm, **theta_args)
    fast = lm.test_log_likelihood(theta[None])[0]
    for t in range(lm.f_obs.shape[0]):
        # the integrand is near-Gaussian in log-moduli where the data pin them: Laplace is off by
        # about a thousandth of a unit of log-likelihood per test (measured 1e-4 to 1.2e-3 here)
        assert fast[t] == pytest.approx(_grid_log_likelihood(lm, theta, t), abs=5e-3)


def test_laplace_with_its_anchored_forward_against_the_exact_tensor_rule(two_joints):
    # forward model and integration together against the exact forward table and adaptive
    # Gauss-Hermite (1e-6 per test): within a few hundredths per test, and, what the posterior
    # sees, nearly constant across parameters (the differences' spread below 0.05 in the sum)
    _, _, lm, exact = two_joints
    rng = np.random.default_rng(0)
    sums = []
    for _ in range(6):
        theta = _theta(lm, 0.04 * rng.standard_normal(2), np.exp(np.log([0.09, 0.22]) + 0.3 * rng.standard_normal(2)))
        gap = exact.test_log_likelihood(theta[None])[0] - lm.test_log_likelihood(theta[None])[0]
        assert np.max(np.abs(gap)) < 0.1
        sums.append(gap.sum())
    assert np.ptp(sums) < 0.05


@pytest.mark.slow
def test_four_joints_each_its_own_group_are_identified():
    means, covs = [24e9, 73.5e9, 73.5e9, 24e9], [0.09, 0.22, 0.22, 0.09]
    model, data, moduli = synthetic(FOUR_BOLT, means, covs, 24, 5e-4, 7)
    groups = JointGroups(("L1", "L2", "L3", "L4"), ((0,), (1,), (2,), (3,)),
                         tuple(j.youngs_modulus for j in model.joints))
    post = bayes_identify(model, data, groups, seed=1, steps=1000)  # its time: benchmarks/bayes_many_joints.py
    sample_mean = moduli.mean(axis=0)
    sample_cov = moduli.std(axis=0, ddof=1) / sample_mean
    assert post.forward == "anchored"
    np.testing.assert_allclose(post.youngs_modulus, sample_mean, rtol=0.08)
    np.testing.assert_allclose(post.cov, sample_cov, rtol=0.35)
    assert np.all(np.isfinite(post.youngs_modulus_ci95)) and np.all(np.isfinite(post.cov_ci95))


def test_a_fit_listed_group_by_group_is_written_in_the_frame_order():
    from workbench.identify.record import identification_record
    from workbench.model.frame_file import read_frame

    frame = read_frame(FOUR_BOLT)  # groups: vertical (L1, L4), horizontal (L2, L3)

    class GroupOrdered:
        def joint_records(self):
            entry = {"youngs_modulus": 1e10, "cov": 0.1, "youngs_modulus_ci95": None, "cov_ci95": None}
            return {name: dict(entry) for name in ("L1", "L4", "L2", "L3")}

    record = identification_record("four-bolt", "bayes", frame, GroupOrdered(), [1, 2], 1.0)
    assert list(record["joints"]) == ["L1", "L2", "L3", "L4"]


def test_sampler_diagnostics_flag_an_unconverged_posterior():
    from types import SimpleNamespace

    from workbench.identify.record import ESS_LIMIT, RHAT_LIMIT, sampler_diagnostics

    good = sampler_diagnostics(SimpleNamespace(rhat=np.array([1.002, 1.009]), ess=np.array([900.0, 450.0])))
    assert good is not None and good["converged"] and good["limits"] == {"rhat_max": RHAT_LIMIT, "ess_min": ESS_LIMIT}
    for rhat, ess in (([1.002, 1.02], [900.0, 900.0]), ([1.0, 1.0], [900.0, 399.0])):
        bad = sampler_diagnostics(SimpleNamespace(rhat=np.array(rhat), ess=np.array(ess)))
        assert bad is not None and not bad["converged"]
    assert sampler_diagnostics(SimpleNamespace()) is None  # moment matching has no chains


@pytest.mark.slow
def test_the_log_likelihood_is_smooth_between_posterior_points_and_its_newton_settled():
    """Between two points of the four-bolt posterior (error terms on, small measurement errors), the
    log-likelihood must be finite and smooth, and equal to a far stricter Newton iteration's. Four
    exact-Hessian Newton steps from the anchors, as before, left holes of 100 to 1000 along such a line
    (a walker proposing into one is always refused)."""
    from workbench.identify import laplace

    model, data, _ = synthetic(FOUR_BOLT, [24e9, 73.5e9, 73.5e9, 24e9], [0.09, 0.22, 0.22, 0.09], 24, 5e-4, 7)
    groups = JointGroups(("L1", "L2", "L3", "L4"), ((0,), (1,), (2,), (3,)),
                         tuple(j.youngs_modulus for j in model.joints))
    lm, _ = laplace_likelihood(model, data, groups, terms=ErrorTerms(True, True))
    k = lm.fbar.size
    a = np.r_[[0.0] * 4, np.log([0.08, 0.2, 0.24, 0.05]), np.full(k, -7.5), -8.0, -10.0]
    b = np.r_[[0.05, -0.1, 0.12, -0.03], np.log([0.06, 0.17, 0.17, 0.06]), np.linspace(-9.5, -6.8, k), -6.8, -9.0]
    line = a + np.linspace(0.0, 1.0, 201)[:, None] * (b - a)
    values = lm.log_likelihood(line)
    assert np.all(np.isfinite(values))
    # smooth: second differences at a step of 1/200 are those of a curve, not of a jump
    assert np.max(np.abs(np.diff(values, 2))) < 1e-3 * (values.max() - values.min() + 1.0)
    strict = {"NEWTON_TOLERANCE": 1e-13, "TRUSTED_DECREMENT": 0.0, "NEWTON_ITERATIONS": 100}
    saved = {name: getattr(laplace, name) for name in strict}
    try:
        for name, value in strict.items():
            setattr(laplace, name, value)
        np.testing.assert_allclose(values, lm.log_likelihood(line), atol=1e-5, rtol=0)
    finally:
        for name, value in saved.items():
            setattr(laplace, name, value)


@pytest.mark.parametrize("shape", [(6, 4), (2, 5)])
@pytest.mark.parametrize("terms,factors", [(ErrorTerms(True, True, True), 0), (ErrorTerms(True, True), 0),
                                           (ErrorTerms(True, False), 0), (ErrorTerms(False, True, True), 0),
                                           (ErrorTerms(False, False), 0), (ErrorTerms(True, True), 3),
                                           (ErrorTerms(False, True), 3)])
def test_both_gauss_newton_solvers_give_the_step_of_the_dense_system(terms, factors, shape):
    # More joints than modes (the Woodbury path) and fewer (the direct path), one mode missing in one
    # test: both steps against the whole latent system assembled densely, its Jacobian by finite
    # differences of the forward model written out here (the joint energies scaled by exp(eps_k) with
    # the sensitivity term; rest and joint energies linear in the manufacturing factors m with them)
    # and its gradient by finite differences of the log integrand
    from workbench.identify.laplace import LaplaceLikelihood, _Latent
    from workbench.identify.laplace_hessian import hessian_blocks
    from workbench.identify.laplace_steps import direct_step, gauss_newton_step

    rng = np.random.default_rng(3)
    (r, k), tests, p = shape, 3, shape[0] + terms.common
    shared = k * (1 + (terms.discrepancy and terms.sensitivity)) + factors if terms.discrepancy else 0
    rest, joints = rng.uniform(1e6, 4e6, (tests, k)), rng.uniform(1e4, 2e5, (tests, k, r))
    forward = AnchoredForward(0.1 * rng.standard_normal((tests, r)), rest, joints,
                              *((rest[..., None] * rng.uniform(-1, 2, (tests, k, factors)),
                                 joints[..., None] * rng.uniform(-1, 3, (tests, k, r, factors))) if factors else ()))
    f_obs = forward(forward.anchor) * (1 + 0.003 * rng.standard_normal((tests, k)))
    mask = np.ones((tests, k), bool)
    mask[1, 0] = False
    lm = LaplaceLikelihood(forward, np.where(mask, f_obs, 0.0), mask, f_obs.mean(axis=0), np.arange(r) % 2,
                           np.array([1.0, 1.0]), forward.anchor, terms, factor_sd=np.full(factors, 0.004))
    scales = {"common_error": 4e-3, "discrepancy_scale": 6e-3}
    theta = np.r_[0.02, -0.03, np.log([0.1, 0.2]), np.full(k, np.log(2e-3)), np.log([scales[n] for n in terms.names])]
    pop, _ = lm._population(theta[None])
    x = _Latent(forward.anchor[None] + 0.05 * rng.standard_normal((1, tests, r)),
                0.002 * rng.standard_normal((1, tests)) * terms.common,
                np.r_[0.02 * rng.standard_normal(max(shared - factors, k)),
                      0.005 * rng.standard_normal(factors)][None] * terms.discrepancy)
    local = lm._evaluate(pop, x, grad=True)
    diagonal = np.concatenate([local.e, np.full(local.e.shape[:-1] + (1,), pop.inv_u[0, 0])], axis=-1) \
        if terms.common else local.e
    fast = gauss_newton_step(local, pop.w, diagonal, pop.inv_d)
    direct = direct_step(local, *hessian_blocks(local, pop.w, pop.inv_u, r, exact=False), pop.inv_d)

    def unpack(xi):  # the dense system's latents: (z_t, u_t) per test, then delta (and eps)
        blocks = xi[:tests * p].reshape(tests, p)
        u = blocks[:, r] if terms.common else np.zeros(tests)
        s = xi[tests * p:] if terms.discrepancy else np.zeros(k)
        return _Latent(blocks[None, :, :r], u[None], s[None])

    def model_f(xi):
        at = unpack(xi)
        s = at.delta[0]
        eps = s[k:2 * k] if s.size - factors > k else np.zeros(k)
        m = s[s.size - factors:]
        joints_m = forward.joints + (forward.joints_grad @ m if factors else 0.0)
        lam = forward.rest + (forward.rest_grad @ m if factors else 0.0) + np.exp(eps) * np.sum(
            joints_m * np.exp(at.z[0] - forward.anchor)[:, None, :], -1)
        return (np.sqrt(lam) / (2 * np.pi) * np.exp(at.u[0][:, None] + at.delta[0][None, :k])).ravel()

    def objective(xi):
        return lm._evaluate(pop, unpack(xi), grad=False).objective[0]

    xi0 = np.r_[np.concatenate([x.z[0], x.u[0][:, None]], axis=1).ravel() if terms.common else x.z[0].ravel(),
                x.delta[0] if terms.discrepancy else []]
    h, n = 1e-6, xi0.size
    jac = np.stack([(model_f(xi0 + h * e) - model_f(xi0 - h * e)) / (2 * h) for e in np.eye(n)], axis=1)
    grad = np.array([(objective(xi0 + h * e) - objective(xi0 - h * e)) / (2 * h) for e in np.eye(n)])
    assert np.allclose(np.r_[local.grad[0].ravel(), local.grad_d[0] if terms.discrepancy else []], grad,
                       rtol=1e-5, atol=1e-6 * np.abs(grad).max())
    prior = np.concatenate([np.c_[local.e[0], np.full((tests, 1), pop.inv_u[0, 0])].ravel() if terms.common
                            else local.e[0].ravel(), pop.inv_d[0] if terms.discrepancy else []])
    dense = jac.T @ (np.where(mask, pop.w[0], 0.0).ravel()[:, None] * jac) + np.diag(prior)
    step = np.linalg.solve(dense, grad)
    for got in (fast, direct):
        flat = np.r_[got[0][0].ravel(), got[1][0] if terms.discrepancy else []]
        assert np.allclose(flat, step, rtol=1e-4, atol=1e-6 * np.max(np.abs(step)))

    # the exact Hessian (the Laplace determinant's) against finite differences of the gradient
    def gradient(xi):
        at = lm._evaluate(pop, unpack(xi), grad=True)
        return np.r_[at.grad[0].ravel(), at.grad_d[0] if terms.discrepancy else []]

    numeric = -np.stack([(gradient(xi0 + h * e) - gradient(xi0 - h * e)) / (2 * h) for e in np.eye(n)], axis=1)
    hess, coupling, block = hessian_blocks(local, pop.w, pop.inv_u, r, exact=True)
    exact = np.zeros((n, n))
    for t in range(tests):
        exact[t * p:(t + 1) * p, t * p:(t + 1) * p] = hess[0, t]
        if terms.discrepancy:
            exact[tests * p:, t * p:(t + 1) * p] = coupling[0, t]
            exact[t * p:(t + 1) * p, tests * p:] = coupling[0, t].T
    if terms.discrepancy:
        exact[tests * p:, tests * p:] = block[0] + np.diag(pop.inv_d[0])
    assert np.allclose(exact, numeric, rtol=1e-4, atol=1e-6 * np.abs(numeric).max())


def test_the_group_means_stay_where_the_anchored_forward_model_holds(two_joints):
    # the trust region: TRUST_RADIUS about the anchors' mean per group, then about where it was re-anchored
    from workbench.identify.laplace import TRUST_RADIUS

    _, _, lm, _ = two_joints
    centre = np.array([lm.z_start[:, lm.joint_group == g].mean() for g in range(lm.n_groups)])
    for shift, finite in [(0.9 * TRUST_RADIUS, True), (1.1 * TRUST_RADIUS, False), (-1.1 * TRUST_RADIUS, False)]:
        theta = _theta(lm, shift=tuple(centre + np.array([shift, 0.0])))
        assert np.isfinite(lm.log_posterior(theta[None])[0]) == finite
    moved = _theta(lm, shift=tuple(centre + 0.2))
    again, _ = lm.reanchored(moved)
    assert np.allclose(again.mean_bounds.mean(axis=1), centre + 0.2)
    beyond = _theta(lm, shift=tuple(centre + 0.2 + 0.9 * TRUST_RADIUS))
    assert np.isfinite(again.log_posterior(beyond[None])[0]) and not np.isfinite(lm.log_posterior(beyond[None])[0])


def test_a_group_at_its_trust_edge_is_a_failed_identification():
    from types import SimpleNamespace

    from workbench.identify.bayes import Posterior
    from workbench.identify.likelihood import COV_BOUNDS, MODULUS_BOUNDS_PA
    from workbench.identify.record import TRUST_EDGE_FAILURE, bound_failures, identification_record
    from workbench.model.frame_file import read_frame

    frame = read_frame(TWO_BOLT)
    groups = ("vertical", "horizontal")
    members = tuple(tuple(j.name for j in frame.joints if j.group == g) for g in groups)
    fit = SimpleNamespace(joints=members, groups=groups, youngs_modulus=np.array([2.4e10, 7e10]),
                          youngs_modulus_ci95=np.array([[2.2e10, 2.6e10], [6e10, 8e10]]), cov=np.array([0.09, 0.2]),
                          cov_ci95=np.array([[0.05, 0.14], [0.1, 0.3]]), trust_reached=("horizontal",),
                          mean_box_pa=MODULUS_BOUNDS_PA, cov_box=COV_BOUNDS)
    fit.joint_records = lambda: Posterior.joint_records(fit)
    record = identification_record("c", "bayes", frame, fit, [1, 2], 1.0)
    assert all(record["joints"][name].get("at_bound") for name in members[1])
    assert not any(record["joints"][name].get("at_bound") for name in members[0])
    failures = bound_failures(record, fit)
    assert len(failures) == len(members[1]) and all(TRUST_EDGE_FAILURE in f for f in failures)

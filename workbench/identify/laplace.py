"""The full likelihood for any number of joints, with the error terms a real campaign needs.

`workbench.identify.likelihood` integrates one or two latent joint moduli per test on a tensor rule
over a tensor forward table; both grow exponentially with the number of joints. Here, for any
number ``r`` of random joints, per joint group g a mean ``E_g`` and CoV ``c_g`` (the same Gamma laws
and priors), and three error terms:

    Y_tj ~ Gamma(1 / c_g^2, E_g c_g^2)                       (eq. 8-9)
    f_tk = f_k(Y_t) exp(u_t + delta_k) + e_tk,  e_tk ~ Normal(0, (sigma_k fbar_k)^2)
    u_t ~ Normal(0, s_u^2)          a test-level common error: temperature, mounting, all modes of
                                    test t move together (``ErrorTerms.common``)
    delta_k ~ Normal(0, s_delta^2)  the model's discrepancy: mode k's systematic relative error, the
                                    same in every test (``ErrorTerms.discrepancy``)

``sigma_k`` is each mode's measurement error; ``s_u`` and ``s_delta`` are sampled too, each with a
half-normal prior as the sigmas' (`workbench.identify.likelihood`: scales `COMMON_SCALE`,
`DISCREPANCY_SCALE`, within `COMMON_BOUNDS`, `DISCREPANCY_BOUNDS`). What keeps the
discrepancy identifiable: it is one number per mode for all tests, so it cannot take up the tests'
scatter (the CoVs' evidence), and its zero-mean prior of sampled width lets a joint's mean move only
in the pattern of its energy shares across modes (eq. 5); a discrepancy pattern that the joints
cannot produce is the discrepancy's, and it widens the means' intervals by what it could absorb.

**Integration.** Every latent variable is integrated out by Laplace: the tests' ``z_t = log(Y_t /
Y0)`` and ``u_t``, and the shared ``delta``. Newton's method finds the joint mode of the integrand;
its Hessian is block-arrow (each test's block couples to ``delta`` only), so each step solves the
tests' small blocks and a K x K Schur complement for ``delta``, and

    log p(f | theta) ~ log p(f, x*, delta* | theta) + (n / 2) log 2 pi - (1 / 2) log det H,

``n`` the latent count, ``H`` minus the Hessian (the data term's exact Hessian, with the forward
model's curvature, plus the priors'), ``log det H = sum_t log det H_t + log det S``. Against
brute-force integration of the same integrand (two joints, 0.05 % noise, CoVs 0.09-0.3, fine grid):
1e-4 to 1.2e-3 per test; with the common and discrepancy terms on, against nested grids on a small
campaign: `tests/test_bayes_errors.py`. The forward model ``f_k(Y)`` is anchored per test
(`workbench.identify.anchored`).
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, field, replace

import numpy as np

from workbench.extraction.records import MeasuredModes
from workbench.identify.anchored import AnchoredForward, anchored_forward, forward_at, forward_error, tracked_nominal
from workbench.identify.data import JointGroups, Values
from workbench.identify.likelihood import LOG_2PI, PopulationModel, gamma_log_density, prepare
from workbench.model.structure import Structure, structure_at_moduli

__all__ = ["ErrorTerms", "ERROR_TERMS", "COMMON_BOUNDS", "DISCREPANCY_BOUNDS", "COMMON_SCALE", "DISCREPANCY_SCALE",
           "NEWTON_STEPS", "LaplaceLikelihood", "laplace_likelihood"]

NEWTON_STEPS = 4  # Newton steps from the anchor per evaluation: 3 reach 1e-11 in the log-likelihood (four-bolt frame)
COMMON_BOUNDS = (1e-5, 0.02)  # s_u: a test's common relative shift; 0.02 is 60 K of steel, or a remounting
DISCREPANCY_BOUNDS = (1e-5, 0.05)  # s_delta: a model off by more than 5 % per mode needs updating, not a term
COMMON_SCALE = 0.005  # half-normal scales: a test shifting all its modes by 0.5 %, a model off by 1 % per mode
DISCREPANCY_SCALE = 0.01
MAX_Z_STEP = 0.5  # largest Newton step in log-modulus
MAX_SHIFT_STEP = 0.05  # largest Newton step in u and delta (relative frequency)


@dataclass(frozen=True)
class ErrorTerms:
    """The error terms beside each mode's measurement error (module docstring)."""

    common: bool = True
    discrepancy: bool = True

    @property
    def names(self) -> tuple[str, ...]:
        """The sampled scales, in ``theta``'s order after the sigmas."""
        return (("common_error",) if self.common else ()) + (("discrepancy_scale",) if self.discrepancy else ())


ERROR_TERMS = {"full": ErrorTerms(True, True), "common": ErrorTerms(True, False),
               "discrepancy": ErrorTerms(False, True), "none": ErrorTerms(False, False)}  # by their command-line names


@dataclass(frozen=True)
class _Mode:
    """The integrand's mode and the Laplace terms at given ``theta`` (N rows)."""

    z: np.ndarray  # (N, T, r) the tests' latent log-moduli at the mode
    per_test: np.ndarray  # (N, T) each test's terms
    shared: np.ndarray  # (N,) the discrepancy's terms
    delta: np.ndarray  # (N, K) delta at the mode
    delta_sd: np.ndarray  # (N, K) its Laplace standard deviation


@dataclass(frozen=True)
class LaplaceLikelihood(PopulationModel):
    """The log-posterior with every latent variable integrated by Laplace; ``theta`` (..., 2 G + K + E)
    is ``log(E_g / Y0_g)``, ``log c_g``, ``log sigma_k`` (as `workbench.identify.likelihood.LikelihoodModel`),
    then ``log s_u`` and ``log s_delta`` for the terms switched on.

    Attributes
    ----------
    table : the anchored forward model (``table(z)`` frequencies at ``z``, (T, r)).
    f_obs, mask, fbar, joint_group, reference_pa : as in `LikelihoodModel`.
    z_start : (T, r) the anchors, Newton's starting points.
    terms : the error terms beside the measurement error.
    refit : the forward model and its error at new anchors (T, r) (`reanchored`).
    """

    table: AnchoredForward
    f_obs: np.ndarray
    mask: np.ndarray
    fbar: np.ndarray
    joint_group: np.ndarray
    reference_pa: np.ndarray
    z_start: np.ndarray
    terms: ErrorTerms = field(default_factory=ErrorTerms)
    refit: Callable[[np.ndarray], tuple[AnchoredForward, float]] | None = field(default=None, compare=False,
                                                                               repr=False)

    @property
    def extra_bounds(self) -> tuple[tuple[float, float], ...]:
        common = (COMMON_BOUNDS,) if self.terms.common else ()
        return common + ((DISCREPANCY_BOUNDS,) if self.terms.discrepancy else ())

    @property
    def extra_scales(self) -> tuple[float, ...]:
        return ((COMMON_SCALE,) if self.terms.common else ()) + ((DISCREPANCY_SCALE,) if self.terms.discrepancy else ())

    def log_likelihood(self, theta: np.ndarray) -> np.ndarray:
        """``log p(f | theta)``, every latent variable integrated out, (N,)."""
        mode = self._mode(np.atleast_2d(np.asarray(theta, float)))
        return mode.per_test.sum(axis=1) + mode.shared

    def test_log_likelihood(self, theta: np.ndarray) -> np.ndarray:
        """Each test's terms of the log-likelihood, (N, T); they sum to it without the discrepancy term
        (with it, the shared terms are `log_likelihood`'s).
        """
        return self._mode(np.atleast_2d(np.asarray(theta, float))).per_test

    def discrepancy(self, theta: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Each mode's discrepancy ``delta_k`` at the integrand's mode and its Laplace sd, (N, K) each (0 if off)."""
        mode = self._mode(np.atleast_2d(np.asarray(theta, float)))
        return mode.delta, mode.delta_sd

    def reanchored(self, theta: np.ndarray) -> tuple[LaplaceLikelihood, float]:
        """The likelihood with every test's forward model anchored at its latent mode under ``theta`` (D,),
        and the new forward model's error (`workbench.identify.anchored`).
        """
        if self.refit is None:
            raise ValueError("reanchored: this likelihood was built without its model (laplace_likelihood builds it)")
        forward, error = self.refit(self._mode(np.atleast_2d(np.asarray(theta, float))[:1]).z[0])
        return replace(self, table=forward, z_start=forward.anchor), error

    def _scales(self, theta: np.ndarray) -> tuple[np.ndarray | None, np.ndarray | None]:
        """``1 / s_u^2`` (N, 1) and ``1 / s_delta^2`` (N, 1), None for a term switched off."""
        extra = theta[:, 2 * self.n_groups + self.fbar.size:]
        common = np.exp(-2.0 * extra[:, :1]) if self.terms.common else None
        shared = np.exp(-2.0 * extra[:, -1:]) if self.terms.discrepancy else None
        return common, shared

    def _mode(self, theta: np.ndarray) -> _Mode:
        """Newton on the integrand in (z_t, u_t) per test and the shared delta; the Laplace terms there."""
        a, log_th, w, const, norm = self.population(theta)
        inv_u, inv_d = self._scales(theta)
        n, (tests, k), r = theta.shape[0], self.f_obs.shape, self.joint_group.size
        z = np.broadcast_to(self.z_start, (n,) + self.z_start.shape).copy()
        u = np.zeros((n, tests))
        delta = np.zeros((n, k))
        eye = np.eye(r)
        for it in range(NEWTON_STEPS + 1):
            g, d = self.table(z, grad=True)  # (N, T, K), (N, T, K, r)
            lam = (2.0 * math.pi * g) ** 2
            m = np.exp(u[..., None] + delta[:, None, :])
            f = g * m
            jz = f[..., None] * d / (2.0 * lam[..., None])  # df/dz
            res = self.f_obs - f
            wr = w * res
            _, e = gamma_log_density(z, a, log_th)  # (N, T, r)
            pull = (wr[..., None, :] @ jz)[..., 0, :]  # the data's gradient in z, (N, T, r)
            # minus the Hessian in z: the Gauss-Newton term, minus the residual times f's curvature
            # (d2f/dz_i dz_j = delta_ij df_j - df_i d_j / (2 lambda)), plus the Gamma law's
            hess = (np.swapaxes(jz * w[..., None], -1, -2) @ jz
                    + np.swapaxes(jz * (wr / (2.0 * lam))[..., None], -1, -2) @ d + (e - pull)[..., None] * eye)
            grad = pull + a - e
            q = w * (f - res)  # d2f/du2 = d2f/ddelta2 = f: the cross terms' weight
            jac = jz
            if inv_u is not None:
                h_zu = np.sum(q[..., None] * jz, axis=-2)  # (N, T, r)
                h_uu = np.sum(q * f, axis=-1) + inv_u  # (N, T)
                hess = np.concatenate([np.concatenate([hess, h_zu[..., None]], axis=-1),
                                       np.concatenate([h_zu, h_uu[..., None]], axis=-1)[..., None, :]], axis=-2)
                grad = np.concatenate([grad, (np.sum(wr * f, axis=-1) - u * inv_u)[..., None]], axis=-1)
                jac = np.concatenate([jz, f[..., None]], axis=-1)
            if it == NEWTON_STEPS:
                break
            if inv_d is None:
                step = np.linalg.solve(hess, grad[..., None])[..., 0]
            else:
                coupling = q[..., None] * jac  # (N, T, K, p): d2/dx_i ddelta_k of minus the log integrand
                grad_d = np.sum(wr * f, axis=1) - delta * inv_d
                right = np.concatenate([np.swapaxes(coupling, -1, -2), grad[..., None]], axis=-1)
                solved = np.linalg.solve(hess, right)  # H_t^-1 [C_t, g_t]
                schur = _schur(q, f, inv_d, coupling, solved[..., :k])
                reduced = grad_d - _over_tests(coupling, solved[..., k:])[..., 0]
                step_d = np.linalg.solve(schur, reduced[..., None])
                step = solved[..., k] - (solved[..., :k] @ step_d[:, None])[..., 0]
                delta = delta + np.clip(step_d[..., 0], -MAX_SHIFT_STEP, MAX_SHIFT_STEP)
            z = z + np.clip(step[..., :r], -MAX_Z_STEP, MAX_Z_STEP)
            if inv_u is not None:
                u = u + np.clip(step[..., r], -MAX_SHIFT_STEP, MAX_SHIFT_STEP)
        per_test = (-0.5 * np.sum(w * res * res, axis=-1) + np.sum(gamma_log_density(z, a, log_th)[0], axis=-1)
                    + const + norm)
        sign, log_det = np.linalg.slogdet(hess)
        per_test = per_test + np.where(sign > 0, 0.5 * hess.shape[-1] * LOG_2PI - 0.5 * log_det, -np.inf)
        if inv_u is not None:
            per_test = per_test - 0.5 * u * u * inv_u + 0.5 * np.log(inv_u) - 0.5 * LOG_2PI
        if inv_d is None:
            return _Mode(z, per_test, np.zeros(n), delta, np.zeros((n, k)))
        # the discrepancy's marginal precision is the Schur complement of the tests' blocks
        coupling = q[..., None] * jac
        schur = _schur(q, f, inv_d, coupling, np.linalg.solve(hess, np.swapaxes(coupling, -1, -2)))
        sign_s, log_det_s = np.linalg.slogdet(schur)
        shared = (np.sum(-0.5 * delta * delta * inv_d + 0.5 * np.log(inv_d), axis=-1)
                  + np.where(sign_s > 0, -0.5 * log_det_s, -np.inf))  # the K (1/2) log 2 pi cancel
        sd = np.sqrt(np.clip(np.diagonal(np.linalg.inv(schur), axis1=-2, axis2=-1), 0.0, None))
        return _Mode(z, per_test, shared, delta, sd)


def _schur(q: np.ndarray, f: np.ndarray, inv_d: np.ndarray, coupling: np.ndarray, solved: np.ndarray) -> np.ndarray:
    """``S = D - sum_t C_t^T H_t^-1 C_t``, (N, K, K): the discrepancy block of minus the Hessian, its
    diagonal ``D_k = sum_t q_tk f_tk + 1 / s_delta^2``, less what the tests' blocks take up.
    """
    diagonal = np.sum(q * f, axis=1) + inv_d
    return diagonal[..., None] * np.eye(q.shape[-1]) - _over_tests(coupling, solved)


def _over_tests(coupling: np.ndarray, right: np.ndarray) -> np.ndarray:
    """``sum_t C_t^T X_t`` (N, K, L) of ``coupling`` (N, T, K, p) and ``right`` (N, T, p, L): one batched
    product over the tests' stacked rows (an einsum here took a fifth of the likelihood's time).
    """
    n, t, k, p = coupling.shape
    return coupling.transpose(0, 2, 1, 3).reshape(n, k, t * p) @ right.reshape(n, t * p, right.shape[-1])


def laplace_likelihood(model: Structure, measured: MeasuredModes, groups: JointGroups | None = None,
                       start: Values | None = None, terms: ErrorTerms | None = None) -> tuple[LaplaceLikelihood, float]:
    """The `LaplaceLikelihood` of a campaign, for any number of joints, and its forward model's error.

    ``terms``: the error terms beside the measurement error (default both, `ErrorTerms`).

    Raises
    ------
    ValueError
        As `workbench.identify.likelihood.prepare`.
    """
    p = prepare(model, measured, groups, start)
    at = structure_at_moduli(model, p.reference_pa[p.joint_group])
    nominal = tracked_nominal(at, p.modes)  # one solve serves the anchors and the error check
    forward = anchored_forward(at, nominal, p.f_obs, p.mask, p.modes)

    def refit(anchors: np.ndarray) -> tuple[AnchoredForward, float]:
        moved = forward_at(at, nominal, p.modes, anchors)
        return moved, forward_error(at, nominal, moved, p.modes)

    lm = LaplaceLikelihood(forward, p.f_obs, p.mask, np.asarray(measured.mean_hz, float), p.joint_group,
                           p.reference_pa, forward.anchor, terms or ErrorTerms(), refit)
    return lm, forward_error(at, nominal, forward, p.modes)

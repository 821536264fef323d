"""The full likelihood for any number of joints, with the error terms a real campaign needs.

`workbench.identify.likelihood` integrates one or two latent joint moduli per test on a tensor rule
over a tensor forward table; both grow exponentially with the number of joints. Here, for any
number ``r`` of random joints, per joint group g a mean ``E_g`` and CoV ``c_g`` (the same Gamma laws
and priors), and three error terms:

    Y_tj ~ Gamma(1 / c_g^2, E_g c_g^2)                       (eq. 8-9)
    f_tk = f_k(Y_t; eps_k) exp(u_t + delta_k) + e_tk,  e_tk ~ Normal(0, (sigma_k fbar_k)^2)
    u_t ~ Normal(0, s_u^2)          a test-level common error: temperature, mounting, all modes of
                                    test t move together (``ErrorTerms.common``)
    delta_k ~ Normal(0, s_delta^2)  the model's discrepancy: mode k's systematic relative error, the
                                    same in every test (``ErrorTerms.discrepancy``)
    eps_k ~ Normal(0, 0.1^2)        and its sensitivity error: mode k's joint energies are
                                    ``exp(eps_k)`` times the model's (``ErrorTerms.sensitivity``; on
                                    request, ``--errors sensitivity``: see below)
    m_p ~ Normal(0, tol_p^2)        with ``--tolerances``, the frame's manufacturing factors (each member's b and
                                    t, each material's E and rho) in every test's energies (`identify.members`)

``sigma_k`` is each mode's measurement error; ``s_u`` and ``s_delta`` are sampled too, each with a
half-normal prior as the sigmas' (`workbench.identify.likelihood`: scales `COMMON_SCALE`,
`DISCREPANCY_SCALE`, within `COMMON_BOUNDS`, `DISCREPANCY_BOUNDS`). What keeps the
discrepancy identifiable: it is one number per mode for all tests, so it cannot take up the tests'
scatter (the CoVs' evidence), and its zero-mean prior of sampled width lets a joint's mean move only
in the pattern of its energy shares across modes (eq. 5); a discrepancy pattern that the joints
cannot produce is the discrepancy's, and it widens the means' intervals by what it could absorb.

**Why the sensitivity error.** A mode's sensitivity to a joint, ``0.5 L_kj Y / (c_k + sum L Y)`` (eq. 5),
saturates with the modulus at the mode's own rate, so the pattern of the tests' scatter across the modes
tells the joints' level even when ``delta`` takes every mean frequency (`benchmarks/bayes_bias_source.py`).
That information is only as good as the model's energy shares; ``eps_k`` (sd `SENSITIVITY_SD`: a beam
zone's share of a mode's strain energy stands for a bolted lap to about 10 %) was meant to price it. It
does not (`reports/estimators_proving.md`, step 6): the errors' mean over the modes is a change of every
modulus, which the data cannot see, so it only widens the means' intervals by ``SENSITIVITY_SD /
sqrt(K)``; their zero-sum pattern moves the estimates away from the truth. So it is on request only; the
members' tolerances (``m``) are what the report's section 8 found to price the energy shares.

**Integration.** Every latent variable is integrated out by Laplace: the tests' ``z_t = log(Y_t /
Y0)`` and ``u_t``, and the shared ``delta``, ``eps`` and ``m``. Gauss-Newton with a line search finds the
joint mode of the integrand (`LaplaceLikelihood._mode`); its Hessian is block-arrow (each test's block
couples to the shared latents only), so each step solves the tests' small blocks (through their K x K
capacitance when there are more joints than modes) and one Schur complement for the shared latents
(`workbench.identify.laplace_hessian` builds the blocks, `workbench.identify.laplace_steps` solves), and

    log p(f | theta) ~ log p(f, x*, s* | theta) + (n / 2) log 2 pi - (1 / 2) log det H,

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
from typing import Any

import numpy as np

from workbench.extraction.records import MeasuredModes
from workbench.identify.anchored import AnchoredForward, anchored_forward, forward_at, forward_error, tracked_nominal
from workbench.identify.data import JointGroups, Values
from workbench.identify.laplace_hessian import hessian_blocks
from workbench.identify.laplace_steps import direct_step, gauss_newton_step, schur, shared_design
from workbench.identify.likelihood import LOG_2PI, PopulationModel, gamma_log_density, prepare
from workbench.identify.members import member_factors, with_member_derivatives
from workbench.model.structure import Structure, structure_at_moduli
from workbench.model.tolerance import Tolerances

__all__ = ["ErrorTerms", "ERROR_TERMS", "COMMON_BOUNDS", "DISCREPANCY_BOUNDS", "COMMON_SCALE", "DISCREPANCY_SCALE",
           "TRUST_RADIUS", "SENSITIVITY_SD", "shared_summary",
           "NEWTON_ITERATIONS", "NEWTON_TOLERANCE", "LaplaceLikelihood", "laplace_likelihood"]

NEWTON_ITERATIONS = 30  # at most; the four-bolt frame's rows settle in 3 to 6
NEWTON_TOLERANCE = 1e-5  # Newton's decrement after which one more step finds a row's mode (to ~1e-10)
TRUSTED_DECREMENT = 1e-2  # below it a full Gauss-Newton step is taken without checking its gain
LINE_SEARCH_HALVINGS = 8
ARMIJO = 1e-4  # the fraction of the decrement a step must gain
COMMON_BOUNDS = (1e-5, 0.02)  # s_u: a test's common relative shift; 0.02 is 60 K of steel, or a remounting
DISCREPANCY_BOUNDS = (1e-5, 0.05)  # s_delta: a model off by more than 5 % per mode needs updating, not a term
COMMON_SCALE = 0.005  # half-normal scales: a test shifting all its modes by 0.5 %, a model off by 1 % per mode
DISCREPANCY_SCALE = 0.01
TRUST_RADIUS = 0.5  # how far a group's log mean modulus may go from the anchors' population (mean_bounds)
MAX_Z_STEP = 0.5  # largest Newton step in log-modulus
MAX_SHIFT_STEP = 0.05  # largest Newton step in u, delta (relative frequency) and eps
SENSITIVITY_SD = 0.1  # eps_k's prior sd: a mode's joint energy known to 10 % (module docstring)


Refit = Callable[[np.ndarray, np.ndarray | None], tuple[AnchoredForward, float]]  # (anchors, factors' centre)


@dataclass(frozen=True)
class ErrorTerms:
    """The error terms beside each mode's measurement error (module docstring)."""

    common: bool = True
    discrepancy: bool = True
    sensitivity: bool = False  # with the discrepancy: each mode's joint energies uncertain too (eps_k)

    @property
    def names(self) -> tuple[str, ...]:
        """The sampled scales, in ``theta``'s order after the sigmas."""
        return (("common_error",) if self.common else ()) + (("discrepancy_scale",) if self.discrepancy else ())


# by their command-line names; "sensitivity" is "full" with each mode's sensitivity error
ERROR_TERMS = {"full": ErrorTerms(True, True), "common": ErrorTerms(True, False),
               "discrepancy": ErrorTerms(False, True), "none": ErrorTerms(False, False),
               "sensitivity": ErrorTerms(True, True, True)}


@dataclass(frozen=True)
class _Mode:
    """The integrand's mode and the Laplace terms at given ``theta`` (N rows)."""

    z: np.ndarray  # (N, T, r) the tests' latent log-moduli at the mode
    per_test: np.ndarray  # (N, T) each test's terms
    shared: np.ndarray  # (N,) the shared latents' terms
    shared_mode: np.ndarray  # (N, S) every shared latent at the mode (delta, eps, m from its centre); (N, 0) without
    shared_cov: np.ndarray  # (N, S, S) their Laplace covariance


@dataclass(frozen=True)
class _Population:
    """What ``theta`` sets in the integrand, per row: the Gamma laws' shape ``a`` and log scale (N, 1, r),
    the data weights ``w`` (N, T, K), ``1 / s_u^2`` (N, 1) and the shared latents' prior precisions (N, S)
    (``1 / s_delta^2`` for delta, ``1 / SENSITIVITY_SD^2`` for eps, the tolerances' for m), or None for a term off.
    """

    a: np.ndarray
    log_th: np.ndarray
    w: np.ndarray
    inv_u: np.ndarray | None
    inv_d: np.ndarray | None

    def take(self, rows: np.ndarray) -> _Population:
        return _Population(self.a[rows], self.log_th[rows], self.w[rows],
                           None if self.inv_u is None else self.inv_u[rows],
                           None if self.inv_d is None else self.inv_d[rows])


@dataclass(frozen=True)
class _Latent:
    """The latent variables of N rows: ``z`` (N, T, r), ``u`` (N, T), the shared ``delta`` (N, S): each
    mode's shift, then with the sensitivity term each mode's ``eps``, then the factors ``m`` from their centre.
    """

    z: np.ndarray
    u: np.ndarray
    delta: np.ndarray

    def take(self, rows: np.ndarray) -> _Latent:
        return _Latent(self.z[rows], self.u[rows], self.delta[rows])

    def moved(self, step: _Latent, alpha: np.ndarray) -> _Latent:
        return _Latent(self.z + alpha[:, None, None] * step.z, self.u + alpha[:, None] * step.u,
                       self.delta + alpha[:, None] * step.delta)

    def put(self, rows: np.ndarray, value: _Latent) -> None:
        self.z[rows], self.u[rows], self.delta[rows] = value.z, value.u, value.delta


@dataclass(frozen=True)
class _Local:
    """The log integrand at a point and its derivatives (N rows): each test's terms (N, T), the
    shared latents' prior (N,); ascent directions ``grad`` (N, T, p) in each test's ``(z_t, u_t)`` and
    ``grad_d`` (N, S) in the shared latents; what the Hessians are built from.
    """

    per_test: np.ndarray
    shared: np.ndarray
    f: np.ndarray
    res: np.ndarray
    lam: np.ndarray
    d: np.ndarray
    jac: np.ndarray
    e: np.ndarray
    grad: np.ndarray
    grad_d: np.ndarray
    share: np.ndarray | None = None  # (N, T, K) dlog f / deps_k, with the sensitivity term
    design: np.ndarray = field(default_factory=lambda: np.zeros(0))  # (N, T, K, S) df/ds
    factors: tuple[np.ndarray, np.ndarray] | None = None  # dlambda/dm and its joints' part (`factor_terms`)

    @property
    def objective(self) -> np.ndarray:
        return self.per_test.sum(axis=1) + self.shared


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
    refit : the forward model and its error at new anchors (T, r) and factors' centre (`reanchored`).
    """

    table: AnchoredForward
    f_obs: np.ndarray
    mask: np.ndarray
    fbar: np.ndarray
    joint_group: np.ndarray
    reference_pa: np.ndarray
    z_start: np.ndarray
    terms: ErrorTerms = field(default_factory=ErrorTerms)
    refit: Refit | None = field(default=None, compare=False, repr=False)
    trust_centre: np.ndarray | None = None
    factor_sd: np.ndarray = field(default_factory=lambda: np.zeros(0))  # the manufacturing factors' prior sds (P,)
    factor_centre: np.ndarray = field(default_factory=lambda: np.zeros(0))  # their expansion point (`reanchored`)
    factor_names: tuple[str, ...] = ()

    @property
    def mean_bounds(self) -> np.ndarray:
        """(G, 2) the prior's support of ``log(E_g / Y0_g)`` within `TRUST_RADIUS` of ``trust_centre`` (the
        population the anchors were placed for; by default the anchors' mean per group).

        Why: the anchored forward model holds near its anchors (second order in the distance). Far
        from them it is wrong by far more than the measurement error, and the discrepancy term then
        absorbs that error: on the 20-joint frame of `benchmarks/bayes_many_joints.py` (10 modes), with
        the group means at a quarter of their values the forward model was off by 7.6 %, the
        discrepancy took 4-6 % per mode, and that point's log-posterior exceeded the truth's by 80;
        anchored there, its log-posterior fell by 350. The radius is the anchors' own broad prior's
        sd (`workbench.identify.anchored.ANCHOR_PRIOR_SD`): a factor of 1.65 either way. A radius of
        0.3 cut the horizontal mean's posterior of ordinary two- and four-bolt campaigns, whose first
        anchors' MAP search then stopped where it started (0.25 from the posterior; since mended,
        `workbench.identify.runs.map_search`).
        """
        box = self.support_mean_bounds
        centre = self.trust_centre if self.trust_centre is not None else np.array(
            [self.z_start[:, self.joint_group == g].mean() for g in range(self.n_groups)])
        return np.stack([np.maximum(box[:, 0], centre - TRUST_RADIUS), np.minimum(box[:, 1], centre + TRUST_RADIUS)],
                        axis=1)

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
        delta, sd = self.shared_latents(theta)
        k = self.fbar.size
        return (delta[:, :k], sd[:, :k]) if delta.shape[1] else (np.zeros((delta.shape[0], k)),) * 2

    def shared_latents(self, theta: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Every shared latent at the integrand's mode and its Laplace sd, (N, S) each: each mode's discrepancy
        ``delta_k``, with the sensitivity term each mode's ``eps_k``, with tolerances the factors ``m`` last (logs
        from the drawing); (N, 0) without the discrepancy.
        """
        mode = self._mode(np.atleast_2d(np.asarray(theta, float)))
        return (mode.shared_mode + self._offset(mode.shared_mode.shape[1]),
                np.sqrt(np.clip(np.diagonal(mode.shared_cov, axis1=-2, axis2=-1), 0.0, None)))

    def _offset(self, count: int) -> np.ndarray:
        """(S,) each shared latent's expansion point: the factors' ``factor_centre``, 0 for the rest."""
        return np.concatenate([np.zeros(count - self.factor_centre.size), self.factor_centre])

    def reanchored(self, theta: np.ndarray) -> tuple[LaplaceLikelihood, float]:
        """The likelihood with every test's forward model anchored at its latent mode under ``theta`` (D,),
        and the new forward model's error (`workbench.identify.anchored`); the manufacturing factors'
        terms expanded again about their mode (`workbench.identify.members.member_factors`).
        """
        if self.refit is None:
            raise ValueError("reanchored: this likelihood was built without its model (laplace_likelihood builds it)")
        theta = np.atleast_2d(np.asarray(theta, float))[:1]
        mode = self._mode(theta)
        centre = self.factor_centre + mode.shared_mode[0, mode.shared_mode.shape[1] - self.factor_centre.size:]
        forward, error = self.refit(mode.z[0], centre if centre.size else None)
        return replace(self, table=forward, z_start=forward.anchor, trust_centre=theta[0, :self.n_groups],
                       factor_centre=centre), error

    def _population(self, theta: np.ndarray) -> tuple[_Population, np.ndarray]:
        """The integrand's population terms of ``theta`` (N, D), and the normalising constants (N, T)."""
        a, log_th, w, const, norm = self.population(theta)
        extra = theta[:, 2 * self.n_groups + self.fbar.size:]
        inv_u = np.exp(-2.0 * extra[:, :1]) if self.terms.common else None
        inv_d = None
        if self.terms.discrepancy:
            k = self.fbar.size
            inv_d = np.repeat(np.exp(-2.0 * extra[:, -1:]), k, axis=1)
            if self.terms.sensitivity:
                inv_d = np.concatenate([inv_d, np.full((theta.shape[0], k), SENSITIVITY_SD ** -2)], axis=1)
            factors = np.broadcast_to(self.factor_sd ** -2, (theta.shape[0], self.factor_sd.size))
            inv_d = np.concatenate([inv_d, factors], axis=1)
        return _Population(a, log_th, w, inv_u, inv_d), const + norm

    @property
    def _sensitive(self) -> bool:
        return self.terms.discrepancy and self.terms.sensitivity

    def _evaluate(self, pop: _Population, x: _Latent, grad: bool) -> _Local:
        """The log integrand at ``x`` without its constants; with ``grad`` its ascent directions too.

        With the sensitivity term, mode k's joint energies are scaled by ``exp(eps_k)``:
        ``lambda_tk = c_tk + exp(eps_k) sum_j L_tkj exp(z_tj - zbar_tj)``.
        """
        k, n_m = self.fbar.size, self.factor_sd.size
        m = x.delta[:, x.delta.shape[1] - n_m:] if n_m else None
        if grad or self._sensitive:
            g, d = self.table(x.z, grad=True, m=m)
        else:
            g, d = self.table(x.z, m=m), None
        lam, share = (2.0 * math.pi * g) ** 2, None
        if self._sensitive and d is not None:
            scale = np.exp(x.delta[:, None, k:])  # (N, 1, K)
            joint = d.sum(axis=-1)
            lam = lam + (scale - 1.0) * joint
            d = d * scale[..., None]
            share = 0.5 * scale * joint / lam
            g = np.sqrt(np.maximum(lam, 0.0)) / (2.0 * math.pi)
        f = g * np.exp(x.u[..., None] + x.delta[:, None, :k])
        res = self.f_obs - f
        log_gamma, e = gamma_log_density(x.z, pop.a, pop.log_th)
        per_test = -0.5 * np.sum(pop.w * res * res, axis=-1) + np.sum(log_gamma, axis=-1)
        shared = np.zeros(f.shape[0])
        if pop.inv_u is not None:
            per_test = per_test - 0.5 * x.u * x.u * pop.inv_u
        prior_at = x.delta + self._offset(x.delta.shape[1])  # the factors from the drawing, not their centre
        if pop.inv_d is not None:
            shared = -0.5 * np.sum(prior_at * prior_at * pop.inv_d, axis=-1)
        if not grad or d is None:
            return _Local(per_test, shared, f, res, np.zeros(0), np.zeros(0), np.zeros(0), e, np.zeros(0), np.zeros(0))
        wr = pop.w * res
        jac = f[..., None] * d / (2.0 * lam[..., None])  # df/dz
        grad_x = (wr[..., None, :] @ jac)[..., 0, :] + pop.a - e
        if pop.inv_u is not None:  # df/du = f
            grad_x = np.concatenate([grad_x, (np.sum(wr * f, axis=-1) - x.u * pop.inv_u)[..., None]], axis=-1)
            jac = np.concatenate([jac, f[..., None]], axis=-1)
        on_delta = np.sum(wr * f, axis=1)  # df/ddelta = f, df/deps = f share
        grad_d = on_delta if share is None else np.concatenate([on_delta, np.sum(wr * f * share, axis=1)], axis=1)
        design, factors = shared_design(f, share), None
        if n_m:  # df/dm = f (dlambda/dm) / (2 lambda)
            factors = self.table.factor_terms(x.z)
            on_m = f[..., None] * factors[0] / (2.0 * lam[..., None])
            design = np.concatenate([design, on_m], axis=-1)
            grad_d = np.concatenate([grad_d, np.einsum("ntk,ntkp->np", wr, on_m)], axis=1)
        if pop.inv_d is not None:
            grad_d = grad_d - prior_at * pop.inv_d
        return _Local(per_test, shared, f, res, lam, d, jac, e, grad_x, grad_d, share, design, factors)

    def _mode(self, theta: np.ndarray) -> _Mode:
        """The integrand's mode in every test's ``(z_t, u_t)`` and the shared delta, and the Laplace terms there.

        Gauss-Newton directions (positive definite, so each is an ascent direction), a backtracking
        line search (Armijo) per row unless Newton's decrement ``grad . step`` is below
        `TRUSTED_DECREMENT`, until the step taken from a decrement below `NEWTON_TOLERANCE`
        (Gauss-Newton converges fast on small residuals: the next decrement is about its square). A fixed number of
        exact-Hessian Newton steps, as before, left some rows short of the mode or at a saddle: holes
        of 100 to 1000 in the log-posterior between neighbouring walkers (rows that gain nothing stay
        where they are and leave the iteration: the loop keeps the best point found).
        """
        pop, constants = self._population(theta)
        n, (tests, k), r = theta.shape[0], self.f_obs.shape, self.joint_group.size
        shared_count = k * (2 if self._sensitive else 1) + self.factor_sd.size
        x = _Latent(np.broadcast_to(self.z_start, (n,) + self.z_start.shape).copy(), np.zeros((n, tests)),
                    np.zeros((n, shared_count)))
        active = np.arange(n)
        for _ in range(NEWTON_ITERATIONS):
            p, here = pop.take(active), x.take(active)
            local = self._evaluate(p, here, grad=True)
            if k < r + (p.inv_u is not None):  # the data's rank is below each test's block: Woodbury
                diagonal = local.e if p.inv_u is None else np.concatenate(
                    [local.e, np.broadcast_to(p.inv_u[:, :, None], local.e.shape[:-1] + (1,))], axis=-1)
                step_x, step_d = gauss_newton_step(local, p.w, diagonal, p.inv_d)
            else:
                step_x, step_d = direct_step(local, *hessian_blocks(local, p.w, p.inv_u, r, exact=False), p.inv_d)
            decrement = np.sum(local.grad * step_x, axis=(1, 2)) + np.sum(local.grad_d * step_d, axis=1)
            step = _Latent(step_x[..., :r], step_x[..., r] if p.inv_u is not None else np.zeros(here.u.shape), step_d)
            largest_z = np.max(np.abs(step.z), axis=(1, 2))
            largest_shift = np.maximum(np.max(np.abs(step.u), axis=1, initial=0.0), np.max(np.abs(step.delta), axis=1,
                                                                                         initial=0.0))
            alpha = np.minimum(1.0, np.minimum(MAX_Z_STEP / np.maximum(largest_z, 1e-300),
                                               MAX_SHIFT_STEP / np.maximum(largest_shift, 1e-300)))
            sure = (decrement < TRUSTED_DECREMENT) & (alpha == 1.0)  # the quadratic model holds: no check
            x.put(active[sure], here.take(sure).moved(step.take(sure), alpha[sure]))
            moving = np.flatnonzero(~sure)
            for _ in range(LINE_SEARCH_HALVINGS):
                if moving.size == 0:
                    break
                trial = here.take(moving).moved(step.take(moving), alpha[moving])
                gain = self._evaluate(p.take(moving), trial, grad=False).objective - local.objective[moving]
                good = gain >= ARMIJO * alpha[moving] * decrement[moving]  # NaN (a negative eigenvalue) is not good
                x.put(active[moving[good]], trial.take(np.flatnonzero(good)))
                moving = moving[~good]
                alpha[moving] *= 0.5
            # after a step from a decrement below the tolerance, the next one is of its square: settled
            active = active[(decrement >= NEWTON_TOLERANCE) & ~np.isin(np.arange(active.size), moving)]
            if active.size == 0:
                break
        return self._laplace(pop, x, constants)

    def _laplace(self, pop: _Population, x: _Latent, constants: np.ndarray) -> _Mode:
        """The Laplace terms (module docstring) at the integrand's mode ``x`` (`_mode`), with the exact Hessian."""
        n = x.delta.shape[0]
        local = self._evaluate(pop, x, grad=True)
        hess, coupling, block = hessian_blocks(local, pop.w, pop.inv_u, self.joint_group.size, exact=True)
        sign, log_det = np.linalg.slogdet(hess)
        per_test = (local.per_test + constants
                    + np.where(sign > 0, 0.5 * hess.shape[-1] * LOG_2PI - 0.5 * log_det, -np.inf))
        if pop.inv_u is not None:  # u's normal law's constant
            per_test = per_test + 0.5 * np.log(pop.inv_u) - 0.5 * LOG_2PI
        if pop.inv_d is None:
            return _Mode(x.z, per_test, np.zeros(n), np.zeros((n, 0)), np.zeros((n, 0, 0)))
        # the shared latents' marginal precision is the Schur complement of the tests' blocks
        matrix = schur(block, pop.inv_d, coupling, np.linalg.solve(hess, np.swapaxes(coupling, -1, -2)))
        sign_s, log_det_s = np.linalg.slogdet(matrix)
        shared = (local.shared + 0.5 * np.sum(np.log(pop.inv_d), axis=1)
                  + np.where(sign_s > 0, -0.5 * log_det_s, -np.inf))  # the S (1/2) log 2 pi cancel
        return _Mode(x.z, per_test, shared, x.delta, np.linalg.inv(matrix))


def laplace_likelihood(model: Structure, measured: MeasuredModes, groups: JointGroups | None = None,
                       start: Values | None = None, terms: ErrorTerms | None = None,
                       tolerances: Tolerances | None = None) -> tuple[LaplaceLikelihood, float]:
    """The `LaplaceLikelihood` of a campaign, for any number of joints, and its forward model's error.

    ``terms``: the error terms beside the measurement error (default both, `ErrorTerms`).
    ``tolerances``: the frame's manufacturing tolerances, its factors then shared latents of the forward
    model (`workbench.identify.members`); with the discrepancy term, without the sensitivity term.

    Raises
    ------
    ValueError
        As `workbench.identify.likelihood.prepare`; tolerances on a matrix model or with those terms.
    """
    terms = terms or ErrorTerms()
    if tolerances is not None and (not terms.discrepancy or terms.sensitivity):
        raise ValueError(f"{measured.source}: tolerances: they need the discrepancy term, without the sensitivity term")
    p = prepare(model, measured, groups, start)
    at = structure_at_moduli(model, p.reference_pa[p.joint_group])
    factors = member_factors(at, tolerances) if tolerances is not None else None
    nominal = tracked_nominal(at, p.modes)  # one solve serves the anchors and the error check

    forward = anchored_forward(at, nominal, p.f_obs, p.mask, p.modes)
    forward = forward if factors is None else with_member_derivatives(forward, factors, nominal, p.modes)

    def refit(anchors: np.ndarray, centre: np.ndarray | None) -> tuple[AnchoredForward, float]:
        there = factors if centre is None or tolerances is None else member_factors(at, tolerances, centre)
        base = at if there is None else there.base
        moved = forward_at(base, nominal, p.modes, anchors)
        moved = moved if there is None else with_member_derivatives(moved, there, nominal, p.modes)
        return moved, forward_error(base, nominal, moved, p.modes)

    lm = LaplaceLikelihood(forward, p.f_obs, p.mask, np.asarray(measured.mean_hz, float), p.joint_group,
                           p.reference_pa, forward.anchor, terms, refit,
                           factor_sd=np.zeros(0) if factors is None else factors.prior_sd,
                           factor_centre=np.zeros(0) if factors is None else factors.centre,
                           factor_names=() if factors is None else factors.names)
    return lm, forward_error(at, nominal, forward, p.modes)


SUMMARY_DRAWS = 400  # posterior draws whose shared latents' Laplace law is evaluated for their summary


def shared_summary(lm: LaplaceLikelihood, chain: np.ndarray, rng: np.random.Generator) -> dict[str, Any]:
    """`workbench.identify.bayes.Posterior`'s ``discrepancy``, ``sensitivity`` and ``factors`` (and ``_ci95``):
    the median and 95 % interval of each over the posterior, from their Laplace law (mode and sd) at
    `SUMMARY_DRAWS` draws of ``chain`` (..., D), with the factors' names and prior sds; nothing for a term off.
    """
    out: dict[str, Any] = {}
    if not lm.terms.discrepancy:
        return out
    flat = chain.reshape(-1, chain.shape[-1])
    draws = flat[rng.choice(flat.shape[0], min(SUMMARY_DRAWS, flat.shape[0]), replace=False)]
    mode, sd = lm.shared_latents(draws)
    q = np.percentile(mode + sd * rng.standard_normal(mode.shape), [2.5, 50.0, 97.5], axis=0)
    k, n_m = lm.fbar.size, lm.factor_sd.size
    parts = [("discrepancy", slice(0, k))] + ([("sensitivity", slice(k, 2 * k))] if lm.terms.sensitivity else [])
    for name, part in parts + [("factors", slice(q.shape[1] - n_m, q.shape[1]))]:
        if q[1, part].size:
            out[name], out[f"{name}_ci95"] = q[1, part], q[[0, 2]][:, part].T
    if n_m:  # the factors' names and priors travel with their summary
        out.update(factor_names=lm.factor_names, factor_prior_sd=lm.factor_sd)
    return out

"""The full likelihood of the Bayesian identification, its priors and its forward model.

Every test's extracted frequencies enter the likelihood (not their moments). The model, per joint
group g (`workbench.identify.data.JointGroups`) with mean modulus ``E_g`` and CoV ``c_g``, and per
mode k with a relative model/measurement error ``sigma_k``:

    Y_tj ~ Gamma(shape = 1 / c_g^2, scale = E_g c_g^2)   independent over tests t and joints j
                                                         (eq. 8-9: gamma = Y / E[Y], mean 1)
    f_tk | Y_t ~ Normal(f_k(Y_t), (sigma_k fbar_k)^2)      independent over modes; NaN skipped

``fbar_k`` is mode k's mean over the tests, a fixed scale (the frequencies move by < 1 % from test
to test, so "relative to f_k(Y_t)" and "relative to fbar_k" differ by < 1 % of sigma_k).

**Parameters** (sampled): ``log E_g``, ``log c_g``, ``log sigma_k`` (one per mode: the modes that
hardly load a joint still scatter, from temperature and extraction, and a weak mode's circle fit
scatters more than a strong one's; their prior pools them, below).

**Priors** (independent, all proper):

- ``E_g`` log-uniform on [1e8, 1e12] Pa (`MODULUS_BOUNDS_PA`): four decades, so the frame file's
  value is never needed;
- ``c_g`` uniform on (0.005, 0.6) (`COV_BOUNDS`; sampled as ``log c`` with the Jacobian);
- ``sigma_k``, each mode's random measurement error, within [1e-6, 0.05] (`SIGMA_BOUNDS`): their
  geometric mean ``sigma_bar`` half-normal of scale 1 % (`SIGMA_SCALE`), and each ``log sigma_k``
  normal about ``log sigma_bar`` with sd 0.5 (`SIGMA_SPREAD`): the modes of one campaign are measured
  by the same sensors and the same circle fit, so their random errors differ by a factor of 2.7 at
  most either way (95 %); what one mode's model gets wrong in every test is the discrepancy term's
  (`workbench.identify.laplace`). Why pooled: with independent half-normal priors, a mode whose
  scatter a test's latent moduli can absorb (three latent variables per test fit any three of eight
  modes) had a posterior ``sigma_k`` reaching towards zero, traded against the other modes'
  (correlations to -0.75), over 2-3 units of ``log sigma``; the chains of a proving-ground campaign
  (two-bolt frame, circle fit, 14 parameters) had not converged after 8000 steps (R-hat 1.08). With
  the pooled prior the same campaign has R-hat 1.003 after 3000 steps (autocorrelation time 7 steps
  against 40-117). The half-normal (not log-uniform) ``sigma_bar``: where the data cannot tell a
  small error from a smaller one, a log-uniform prior leaves a posterior flat in ``log sigma`` over
  decades; the half-normal's density in ``log sigma`` falls as ``sigma`` towards zero (Gelman 2006,
  "Prior distributions for variance parameters in hierarchical models").

**Latent moduli, integrated out.** Each test's ``Y_t`` (one per random joint, ``r`` of them) is
integrated out numerically, per test, by an *adaptive* Gauss-Hermite rule in ``z = log(Y / Y0)``:
a few Gauss-Newton steps find the mode of ``log p(f_t | z) + log p(z | E, c)`` from the test's own
data-only estimate, and the rule (`GH_POINTS[r]` points per dimension) is centred there and scaled
by the Hessian's Cholesky factor. ``log p(z | E, c)`` is `gamma_log_density`, used by both. The
integrand is sharp (at 0.05 % frequency noise the data pin ``Y_t`` to about 1 %, ten times narrower
than the Gamma law), which defeats a Gauss-Gamma rule on the prior; the adaptive rule follows it
wherever it is, and falls back gracefully to the prior's shape when the data are weak. Measured
against `scipy.integrate.quad` (one joint, 9 points): about 1e-12 in each test's log-likelihood,
from the posterior out to sigma = 1 %, CoV 0.3; against a fine 2-D grid (two joints, 5 x 5
points): about 1e-6 absolute per test (7 x 7 would give 1e-8 at 1.6 times the cost; 1e-6 per test
is far below anything the sampler can see). Sampling the 40 x r latent moduli instead would
multiply the dimension by 4 to 8 and slow emcee's mixing accordingly.

**Forward model** ``f_k(Y)``: a Chebyshev interpolant (tensor, in ``log Y`` per joint,
`workbench.identify.surrogate.ForwardTable`) of the model's frequencies over the range the tests
occupy, built once around the reference moduli ``Y0`` of a preliminary fit (Gauss-Newton on the
test means with SMR1's sensitivities, `workbench.identify.nominal.reference_fit`). The table's
values are either exact eigen-solutions tracked by MAC (``forward="exact"``, default) or SMR2's
Rayleigh quotient around ``Y0`` (``forward="smr2"``, eq. 6-7). SMR1 is not used as the forward
model: its frequency error (measured on the one-bolt vertical frame, 0.1 % at Y / Y0 = 0.85 and
0.45 % at 0.7) is larger than the 0.05 % measurement noise and would be read as joint scatter.
SMR2 is good within +-15 % (1e-5) but reaches 2e-4 at +-30 % and 1e-3 at Y / Y0 = 0.6 (two-bolt
frame: 7e-4 at 0.7), inside the horizontal joint's range (CoV 0.22), so the default table holds
exact solutions: 7.5 ms each, 21 (one joint, degree 20 over Y0 exp(+-1.5)) or 169 (two joints,
degree 12 over Y0 exp(+-1)) of them. The table's interpolation error is checked at run time
against its source on points between the nodes and reported as ``Posterior.forward_error``
(2e-11 one joint, 1e-9 two joints). Frames with more than two joints are refused (a 4-D table and
4-D rule would not fit the time budget): `workbench.identify.laplace` integrates any number by Laplace.
"""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass

import numpy as np
from scipy.special import gammaln, logsumexp

from workbench.extraction.records import MeasuredModes
from workbench.identify.data import JointGroups, Values, check_moments, joint_groups
from workbench.identify.nominal import reference_fit
from workbench.identify.surrogate import ForwardTable, forward_table, frequencies_at
from workbench.model.structure import Structure, structure_at_moduli

__all__ = ["MODULUS_BOUNDS_PA", "COV_BOUNDS", "SIGMA_BOUNDS", "SIGMA_SCALE", "SIGMA_SPREAD", "GH_POINTS",
           "half_normal_log", "sigma_log_prior", "gamma_log_density", "LikelihoodModel",
           "PopulationModel", "Prepared", "prepare", "likelihood_model"]

MODULUS_BOUNDS_PA = (1e8, 1e12)
COV_BOUNDS = (0.005, 0.6)
SIGMA_BOUNDS = (1e-6, 0.05)
SIGMA_SCALE = 0.01  # half-normal scale of the modes' relative errors' geometric mean
SIGMA_SPREAD = 0.5  # log-sd of a mode's error about that mean: a factor 7 either way at 95 %
GH_POINTS = {1: 9, 2: 5}  # Gauss-Hermite points per dimension
NEWTON_STEPS = 2
LOG_2PI = math.log(2.0 * np.pi)
# The table spans Y0 * exp(+-Z_HALF_RANGE): far beyond the tests (a CoV of 0.3 puts 99.9 % of a
# Gamma law within exp(+-1)), so that the integrand never meets the table's edge, where it is clamped.
Z_HALF_RANGE = {1: 1.5, 2: 1.0}


def half_normal_log(log_s: np.ndarray, scale: float) -> np.ndarray:
    """Log density of ``log s`` when ``s`` is half-normal of the given scale, up to a constant."""
    return log_s - 0.5 * np.exp(2.0 * log_s) / scale**2


def sigma_log_prior(log_s: np.ndarray) -> np.ndarray:
    """Log prior density of the modes' ``log sigma_k`` (N, K), up to a constant (module docstring): their
    geometric mean half-normal (`SIGMA_SCALE`), each one's log normal about it (`SIGMA_SPREAD`).
    """
    centre = log_s.mean(axis=1)
    return half_normal_log(centre, SIGMA_SCALE) - 0.5 * np.sum((log_s - centre[:, None]) ** 2, axis=1) / SIGMA_SPREAD**2


def gamma_log_density(z: np.ndarray, shape: np.ndarray, log_scale: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Log density of ``z = log(Y / Y0)`` when ``Y / Y0 ~ Gamma(shape, exp(log_scale))`` (eq. 8-9), per joint.

    Parameters
    ----------
    z : latent log-moduli; shape, log_scale : the Gamma law's shape and log scale, broadcast with ``z``.

    Returns
    -------
    (log_density, e): ``shape u - exp(u)`` with ``u = z - log_scale``, without the constant
    ``-log Gamma(shape)``; and ``e = exp(u)``, minus the density's second derivative in ``z`` (its
    first is ``shape - e``).
    """
    u = z - log_scale
    e = np.exp(u)
    return shape * u - e, e


def _test_estimates(table: ForwardTable, f_obs: np.ndarray, mask: np.ndarray, iterations: int = 6) -> np.ndarray:
    """Each test's data-only ``z`` (relative least squares, Gauss-Newton on the table), (T, r)."""
    r = table.lower.size
    z = np.zeros((f_obs.shape[0], r))
    for _ in range(iterations):
        f, df = table(z, grad=True)
        res = np.where(mask, np.log(np.where(mask, f_obs, 1.0)) - np.log(f), 0.0)  # (T, K)
        jac = np.where(mask[:, None, :], df / f[:, None, :], 0.0)  # (T, r, K)
        h = np.einsum("trk,tsk->trs", jac, jac) + 1e-10 * np.eye(r)
        g = np.einsum("trk,tk->tr", jac, res)
        z = np.clip(z + np.linalg.solve(h, g[..., None])[..., 0], table.lower, table.upper)
    return z


class PopulationModel:
    """What both integrations of the likelihood share: the parameters ``theta`` (N, 2 G + K + E), ``log(E_g /
    Y0_g)``, ``log c_g``, ``log sigma_k`` and the log of each further error scale (`extra_bounds`, E of them),
    their priors, and the log-posterior from the subclass's ``log_likelihood`` (N,) or
    ``test_log_likelihood`` (N, T). Subclasses hold ``reference_pa`` (G,), ``fbar`` (K,), ``mask`` (T, K)
    and ``joint_group`` (r,).
    """

    reference_pa: np.ndarray
    fbar: np.ndarray
    mask: np.ndarray
    joint_group: np.ndarray

    @property
    def n_groups(self) -> int:
        return self.reference_pa.size

    @property
    def extra_bounds(self) -> tuple[tuple[float, float], ...]:
        """Bounds of the error scales sampled after the sigmas (none here)."""
        return ()

    @property
    def extra_scales(self) -> tuple[float, ...]:
        """Half-normal scales of the error scales sampled after the sigmas (none here)."""
        return ()

    @property
    def ndim(self) -> int:
        return 2 * self.n_groups + self.fbar.size + len(self.extra_bounds)

    def _split(self, theta: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        g = self.n_groups
        return theta[:, :g], theta[:, g:2 * g], theta[:, 2 * g:2 * g + self.fbar.size]

    @property
    def support_mean_bounds(self) -> np.ndarray:
        """(G, 2) the prior's support of each group's ``log(E_g / Y0_g)`` (`MODULUS_BOUNDS_PA`)."""
        return np.log(np.asarray(MODULUS_BOUNDS_PA))[None, :] - np.log(self.reference_pa)[:, None]

    @property
    def mean_bounds(self) -> np.ndarray:
        """(G, 2) where each group's ``log(E_g / Y0_g)`` may go: here the prior's support."""
        return self.support_mean_bounds

    def log_prior(self, theta: np.ndarray) -> np.ndarray:
        """Log prior density of ``theta`` (N, D) up to a constant; -inf outside the bounds."""
        eps, log_c, log_s = self._split(theta)
        box = self.mean_bounds
        inside = (np.all((eps > box[:, 0]) & (eps < box[:, 1]), axis=1)
                  & np.all((log_c > math.log(COV_BOUNDS[0])) & (log_c < math.log(COV_BOUNDS[1])), axis=1)
                  & np.all((log_s > math.log(SIGMA_BOUNDS[0])) & (log_s < math.log(SIGMA_BOUNDS[1])), axis=1))
        density = log_c.sum(axis=1) + sigma_log_prior(log_s)
        for i, ((lo, hi), scale) in enumerate(zip(self.extra_bounds, self.extra_scales)):
            x = theta[:, 2 * self.n_groups + self.fbar.size + i]
            inside &= (x > math.log(lo)) & (x < math.log(hi))
            density = density + half_normal_log(x, scale)
        # uniform in c: density of log c is proportional to c; log-uniform E: flat; error scales half-normal
        return np.where(inside, density, -np.inf)

    def population(self, theta: np.ndarray) -> tuple[np.ndarray, ...]:
        """Per joint the Gamma shape ``a`` and log scale (N, 1, r), per test and mode the data weight
        ``w`` (N, T, K), and the normalising constants of the data (N, T) and of the Gamma laws (N, 1).
        """
        eps, log_c, log_s = self._split(theta)
        jg = self.joint_group
        a = np.exp(-2.0 * log_c[:, jg])[:, None, :]
        log_th = (eps[:, jg] + 2.0 * log_c[:, jg])[:, None, :]  # log scale of Y / Y0
        log_sd = log_s + np.log(self.fbar)  # (N, K)
        w = np.exp(-2.0 * log_sd)[:, None, :] * self.mask
        const = -(self.mask @ (log_sd + 0.5 * LOG_2PI).T).T
        norm = -gammaln(a).sum(axis=-1)
        return a, log_th, w, const, norm

    def test_log_likelihood(self, theta: np.ndarray) -> np.ndarray:
        raise NotImplementedError

    def log_likelihood(self, theta: np.ndarray) -> np.ndarray:
        """``log p(f | theta)``, (N,): the tests' terms summed (tests independent given ``theta``)."""
        return self.test_log_likelihood(theta).sum(axis=1)

    def log_posterior(self, theta: np.ndarray) -> np.ndarray:
        """Unnormalised log posterior, (N,) for ``theta`` (N, D); -inf outside the prior's support."""
        theta = np.atleast_2d(np.asarray(theta, float))
        lp = self.log_prior(theta)
        ok = np.isfinite(lp)
        out = np.full(theta.shape[0], -np.inf)
        if np.any(ok):
            ll = self.log_likelihood(theta[ok])
            out[ok] = np.where(np.isfinite(ll), lp[ok] + ll, -np.inf)
        return out


@dataclass(frozen=True)
class LikelihoodModel(PopulationModel):
    """The data and fixed pieces of the log-posterior; parameters ``theta`` (..., n_groups * 2 + n_modes):
    ``log(E_g / Y0_g)``, ``log c_g``, ``log sigma_k``.

    Attributes
    ----------
    table : the forward model.
    f_obs : (T, K) measured frequencies (0 where missing); mask : (T, K) True where measured.
    fbar : (K,) mode means, the scale of the relative errors.
    joint_group : (r,) group index of each random joint.
    reference_pa : (n_groups,) ``Y0_g``.
    z_start : (T, r) Newton's starting points (each test's data-only estimate).
    """

    table: ForwardTable
    f_obs: np.ndarray
    mask: np.ndarray
    fbar: np.ndarray
    joint_group: np.ndarray
    reference_pa: np.ndarray
    z_start: np.ndarray

    def test_log_likelihood(self, theta: np.ndarray) -> np.ndarray:
        """``log p(f_t | theta)`` with the latent moduli integrated out, (N, T)."""
        theta = np.atleast_2d(np.asarray(theta, float))
        a, log_th, w, const, norm = self.population(theta)
        r = self.joint_group.size
        z = np.broadcast_to(self.z_start, (theta.shape[0],) + self.z_start.shape).copy()
        lo, hi = self.table.lower - 1.0, self.table.upper + 1.0
        for it in range(NEWTON_STEPS + 1):
            f, df = self.table(z, grad=True)  # (N, T, K), (N, T, r, K)
            wres = w * (self.f_obs - f)
            _, e = gamma_log_density(z, a, log_th)  # (N, T, r)
            grad = np.sum(df * wres[:, :, None, :], axis=-1) + a - e  # (N, T, r)
            wdf = df * w[:, :, None, :]
            h00 = np.sum(wdf[:, :, 0] * df[:, :, 0], axis=-1) + e[..., 0]  # -Hessian entries
            if r == 2:
                h01 = np.sum(wdf[:, :, 0] * df[:, :, 1], axis=-1)
                h11 = np.sum(wdf[:, :, 1] * df[:, :, 1], axis=-1) + e[..., 1]
            if it == NEWTON_STEPS:
                break
            if r == 1:
                step = grad / h00[..., None]
            else:
                det = h00 * h11 - h01 * h01
                step = np.stack([h11 * grad[..., 0] - h01 * grad[..., 1],
                                 h00 * grad[..., 1] - h01 * grad[..., 0]], axis=-1) / det[..., None]
            z = np.clip(z + np.clip(step, -0.5, 0.5), lo, hi)
        nodes, log_w = _gauss_hermite(r)  # (Q, r), (Q,) including + |x|^2
        # z_q = z* + sqrt(2) L^-T x_q with -H = L L^T (Cholesky)
        l00 = np.sqrt(h00)[..., None]
        if r == 1:
            zq = (z + np.sqrt(2.0) * nodes[:, 0] / l00)[..., None]  # (N, T, Q, 1)
            log_det = np.log(l00[..., 0])
        else:
            l10 = (h01[..., None] / l00)
            l11 = np.sqrt(h11[..., None] - l10 * l10)
            y1 = nodes[:, 1] / l11
            y0 = (nodes[:, 0] - l10 * y1) / l00
            zq = z[:, :, None, :] + np.sqrt(2.0) * np.stack([y0, y1], axis=-1)
            log_det = np.log(l00[..., 0] * l11[..., 0])
        fq = self.table(zq)  # (N, T, Q, K)
        res = self.f_obs[:, None, :] - fq
        data = -0.5 * np.sum(w[:, :, None, :] * res * res, axis=-1)
        prior = np.sum(gamma_log_density(zq, a[:, :, None, :], log_th[:, :, None, :])[0], axis=-1)
        total = logsumexp(data + prior + log_w, axis=-1)
        return total + 0.5 * r * math.log(2.0) - log_det + const + norm



@functools.lru_cache(maxsize=4)
def _gauss_hermite(r: int) -> tuple[np.ndarray, np.ndarray]:
    """Tensor Gauss-Hermite nodes (Q, r) and log weights with the ``exp(|x|^2)`` factor."""
    x, w = np.polynomial.hermite.hermgauss(GH_POINTS[r])
    grids = np.meshgrid(*([x] * r), indexing="ij")
    wgrid = np.meshgrid(*([w] * r), indexing="ij")
    nodes = np.stack([g.ravel() for g in grids], axis=1)
    log_w = np.sum(np.log(np.stack([g.ravel() for g in wgrid], axis=1)), axis=1) + np.sum(nodes**2, axis=1)
    return nodes, log_w


@dataclass(frozen=True)
class Prepared:
    """What every integration of the likelihood starts from (`prepare`).

    Attributes
    ----------
    groups : the joint groups; joint_group : (r,) group index of each joint.
    reference_pa : (n_groups,) ``Y0_g``, the preliminary fit; f_obs, mask : (T, K) frequencies (0 where
    missing) and where they exist; modes : (K,) model mode index (0 = lowest) of each measured mode.
    """

    groups: JointGroups
    joint_group: np.ndarray
    reference_pa: np.ndarray
    f_obs: np.ndarray
    mask: np.ndarray
    modes: np.ndarray


def prepare(model: Structure, measured: MeasuredModes, groups: JointGroups | None = None,
            start: Values | None = None) -> Prepared:
    """The checks and the preliminary fit shared by both integrations of the likelihood.

    Raises
    ------
    ValueError
        Moments that cannot be identified from (`check_moments`), published moments only, a bad ``start``.
    """
    check_moments(measured)
    if measured.published:
        raise ValueError(f"{measured.source or 'campaign'}: bayes needs every test's frequencies (modes.csv or FRFs); "
                         "this campaign has only published moments (moments.csv)")
    groups = groups or joint_groups(model)
    start_pa = np.asarray(start if start is not None else groups.nominal_pa, float)
    if start_pa.shape != (len(groups.groups),) or np.any(start_pa <= 0):
        raise ValueError(f"start: expected {len(groups.groups)} positive moduli (one per group "
                         f"{list(groups.groups)}), got {start}")
    joint_group = np.empty(len(model.joint_names), int)
    for g, members in enumerate(groups.members):
        joint_group[list(members)] = g
    ref_pa = reference_fit(model, measured, groups, start_pa)
    f_obs = np.asarray(measured.frequency_hz, float)
    mask = np.isfinite(f_obs)
    return Prepared(groups, joint_group, ref_pa, np.where(mask, f_obs, 0.0), mask,
                    np.asarray(measured.modes, int) - 1)


def likelihood_model(model: Structure, measured: MeasuredModes, groups: JointGroups | None = None,
                     start: Values | None = None, forward: str = "exact") -> tuple[LikelihoodModel, float]:
    """The `LikelihoodModel` of a campaign: reference fit, forward table, Newton starts.

    Parameters
    ----------
    model : assembled model of the campaign's frame (its joint moduli only start the reference fit).
    measured : every test's frequencies; published moments are refused.
    groups : joint groups (default: the frame's).
    start : (n_groups,) start moduli of the reference fit, Pa (default the frame file's).
    forward : "exact" or "smr2" values in the forward table.

    Returns
    -------
    (LikelihoodModel, forward_error): the table's largest relative error against its source
    between the nodes.

    Raises
    ------
    ValueError
        As `prepare`, and more than two random joints (`workbench.identify.laplace` takes any number).
    """
    n_joints = len(model.joint_names)
    if n_joints not in Z_HALF_RANGE:
        raise ValueError(f"{measured.source or 'campaign'}: the tensor rule integrates one or two random joints per "
                         f"test; this frame has {n_joints} ({', '.join(model.joint_names)}): use the Laplace "
                         "integration (workbench.identify.laplace)")
    p = prepare(model, measured, groups, start)
    y0 = p.reference_pa[p.joint_group]
    half = Z_HALF_RANGE[n_joints]
    lower, upper = np.full(n_joints, -half), np.full(n_joints, half)
    table = forward_table(model, p.modes, y0, lower, upper, source=forward)
    # interpolation check between the nodes
    fractions = np.array([0.07, 0.29, 0.537, 0.71, 0.93])
    probe = lower + (upper - lower) * np.stack([fractions, fractions[::-1]][:n_joints], axis=1)
    truth = frequencies_at(structure_at_moduli(model, y0), p.modes, np.exp(probe), forward)
    forward_error = float(np.max(np.abs(table(probe) / truth - 1.0)))
    z_start = _test_estimates(table, p.f_obs, p.mask)
    lm = LikelihoodModel(table, p.f_obs, p.mask, np.asarray(measured.mean_hz, float), p.joint_group,
                         p.reference_pa, z_start)
    return lm, forward_error

"""The full likelihood for any number of joints: each test's latent moduli integrated by Laplace.

`workbench.identify.likelihood` integrates one or two latent joint moduli per test on a tensor rule
over a tensor forward table; both grow exponentially with the number of joints. Here, for any
number ``r`` of random joints, the same likelihood (per joint group g a mean ``E_g`` and CoV
``c_g``, per mode k a relative error ``sigma_k``; the same priors)

    Y_tj ~ Gamma(1 / c_g^2, E_g c_g^2),   f_tk | Y_t ~ Normal(f_k(Y_t), (sigma_k fbar_k)^2)

has each test's integral over ``z_t = log(Y_t / Y0)`` replaced by its Laplace approximation:
Newton's method finds the mode ``z*`` of ``log p(f_t | z) + log p(z | E, c)`` and

    log p(f_t | theta) ~ log p(f_t | z*) + log p(z* | E, c) + (r / 2) log 2 pi - (1 / 2) log det H,

``H`` minus the Hessian there (the data term's exact Hessian, with the forward model's curvature,
plus the Gamma law's). Against brute-force integration of the same integrand on a fine 2-D grid
(two joints, 0.05 % noise, CoVs 0.09-0.3): 1e-4 to 1.2e-3 per test in the log-likelihood; with
the anchored forward model as well, against the exact tensor rule (1e-6): within 0.1 per test and,
what moves the posterior, varying by under 0.05 in the campaign's sum across parameters
(`tests/test_bayes_laplace.py`).

**Forward model, anchored per test.** Each test's frequencies are the Rayleigh quotients of the
model's eigenvectors at an anchor ``zbar_t`` near the test's own moduli (eq. 5 around that point):
``lambda_tk(z) = c_tk + sum_j L_tkj exp(z_j - zbar_tj)``, with ``c_tk`` and ``L_tkj`` the rest and joint
energies of the anchor's mode k (exact solves, modes tracked to the nominal ones by MAC). The anchor
is the test's maximum a posteriori point under a broad prior (Gauss-Newton with exact solves): the
joints the test's data pin sit within the posterior's width of it, where the quotient's error is of
second order in that width; the joints the data hardly see may move far, but then their energy
share is small. `AnchoredForward.error` measures the error against exact solves at points a
prior's width away, and `bayes_identify` reports it.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from workbench.extraction.records import MeasuredModes
from workbench.identify.data import JointGroups, Values
from workbench.identify.likelihood import (
    LOG_2PI,
    PopulationModel,
    gamma_log_density,
    prepare,
)
from workbench.model.modal import Modes
from workbench.model.structure import Structure, structure_at_moduli, structure_energies, structure_modes
from workbench.uq.stochastic import track_modes

__all__ = ["AnchoredForward", "tracked_nominal", "anchored_forward", "forward_error", "LaplaceLikelihood",
           "laplace_likelihood", "NEWTON_STEPS", "ANCHOR_PRIOR_SD"]

NEWTON_STEPS = 4  # Newton steps from the anchor per evaluation: 3 reach 1e-11 in the log-likelihood (four-bolt frame)
ANCHOR_PRIOR_SD = 0.5  # the anchors' broad prior on z: the data, not it, place them
ANCHOR_SIGMA = 5e-4  # relative frequency error assumed while anchoring
ANCHOR_ITERATIONS = 5
EXTRA_TRACKED = 4  # modes solved beyond the highest used, so that tracking finds a mode that moved up


@dataclass(frozen=True)
class AnchoredForward:
    """Each test's frequencies as Rayleigh quotients at its anchor (module docstring).

    Attributes
    ----------
    anchor : (T, r) ``zbar_t``.
    rest : (T, K) ``c_tk``, (rad/s)^2.
    joints : (T, K, r) ``L_tkj`` at the anchor, (rad/s)^2.
    """

    anchor: np.ndarray
    rest: np.ndarray
    joints: np.ndarray

    def __call__(self, z: np.ndarray, grad: bool = False) -> tuple[np.ndarray, np.ndarray] | np.ndarray:
        """Frequencies (..., T, K), Hz, at ``z`` (..., T, r); with ``grad`` also ``dlambda/dz`` (..., T, K, r)."""
        d = self.joints * np.exp(z - self.anchor)[..., None, :]  # (..., T, K, r)
        lam = self.rest + d.sum(axis=-1)
        f = np.sqrt(np.maximum(lam, 0.0)) / (2.0 * math.pi)
        return (f, d) if grad else f


def tracked_nominal(model: Structure, modes: np.ndarray) -> Modes:
    """The nominal modes the tests' modes are tracked to: ``modes`` (0-based) and `EXTRA_TRACKED` above."""
    return structure_modes(model, min(int(modes.max()) + 1 + EXTRA_TRACKED, model.size - 2))


def _tracked_at(model: Structure, nominal: Modes, modes: np.ndarray, z: np.ndarray) -> Modes:
    """The model's modes at ``z`` tracked to ``nominal``'s ``modes`` by MAC (eigenvalues, mass-normalised shapes)."""
    solved = structure_modes(model, nominal.count, np.exp(z))
    index, _ = track_modes(nominal, solved, model.mass)
    return Modes(solved.eigenvalues[index[modes]], solved.shapes[:, index[modes]])


def _split_at(model: Structure, nominal: Modes, modes: np.ndarray, z: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``c_k`` (K,) and ``L_kj`` (K, r) of the model's modes at ``z`` tracked to ``nominal``'s ``modes``."""
    rest, per_joint = structure_energies(model, _tracked_at(model, nominal, modes, z).shapes)
    return rest, (per_joint * np.exp(z)[:, None]).T


def anchored_forward(model: Structure, nominal: Modes, f_obs: np.ndarray, mask: np.ndarray,
                     modes: np.ndarray) -> AnchoredForward:
    """Each test's anchor and its Rayleigh-quotient split, by Gauss-Newton with exact solves.

    Parameters
    ----------
    model : the model with its joints at the reference moduli ``Y0`` (``z = 0``).
    nominal : its `tracked_nominal` modes.
    f_obs, mask : (T, K) measured frequencies, Hz, and where they exist.
    modes : (K,) model mode index (0 = lowest) of each measured mode.
    """
    r = len(model.joint_names)
    tests = f_obs.shape[0]
    anchor = np.zeros((tests, r))
    rest = np.empty((tests, modes.size))
    joints = np.empty((tests, modes.size, r))
    weight = 1.0 / ANCHOR_SIGMA**2
    for t in range(tests):
        z = np.zeros(r)
        for it in range(ANCHOR_ITERATIONS + 1):
            c, lk = _split_at(model, nominal, modes, z)
            if it == ANCHOR_ITERATIONS:
                break
            lam = c + lk.sum(axis=1)
            res = np.where(mask[t], np.log(np.where(mask[t], f_obs[t], 1.0)) - 0.5 * np.log(lam / (2 * math.pi) ** 2),
                           0.0)
            jac = np.where(mask[t][:, None], 0.5 * lk / lam[:, None], 0.0)  # dlog f / dz
            h = weight * jac.T @ jac + np.eye(r) / ANCHOR_PRIOR_SD**2
            step = np.linalg.solve(h, weight * jac.T @ res - z / ANCHOR_PRIOR_SD**2)
            z = z + np.clip(step, -0.5, 0.5)
        anchor[t], rest[t], joints[t] = z, c, lk
    return AnchoredForward(anchor, rest, joints)


def forward_error(model: Structure, nominal: Modes, forward: AnchoredForward, modes: np.ndarray,
                  spread: float = 0.2, tests: int = 3, seed: int = 0) -> float:
    """Largest relative frequency error of ``forward`` against exact solves ``spread`` (in z) from anchors."""
    rng = np.random.default_rng(seed)
    worst = 0.0
    for t in range(min(tests, forward.anchor.shape[0])):
        z = forward.anchor[t] + spread * rng.standard_normal(forward.anchor.shape[1])
        exact = _tracked_at(model, nominal, modes, z).frequency_hz
        moved = forward.anchor.copy()
        moved[t] = z
        approx = np.asarray(forward(moved))[t]
        worst = max(worst, float(np.max(np.abs(approx / exact - 1.0))))
    return worst


@dataclass(frozen=True)
class LaplaceLikelihood(PopulationModel):
    """The log-posterior with each test's moduli integrated by Laplace; the same parameters and
    priors as `workbench.identify.likelihood.LikelihoodModel`: ``theta`` (..., 2 G + K) is
    ``log(E_g / Y0_g)``, ``log c_g``, ``log sigma_k``.

    Attributes
    ----------
    table : the anchored forward model (``table(z)`` frequencies at ``z``, (T, r)).
    f_obs, mask, fbar, joint_group, reference_pa : as in `LikelihoodModel`.
    z_start : (T, r) the anchors, Newton's starting points.
    """

    table: AnchoredForward
    f_obs: np.ndarray
    mask: np.ndarray
    fbar: np.ndarray
    joint_group: np.ndarray
    reference_pa: np.ndarray
    z_start: np.ndarray

    def test_log_likelihood(self, theta: np.ndarray) -> np.ndarray:
        """``log p(f_t | theta)`` with the latent moduli integrated out by Laplace, (N, T)."""
        theta = np.atleast_2d(np.asarray(theta, float))
        a, log_th, w, const, norm = self.population(theta)
        r = self.joint_group.size
        z = np.broadcast_to(self.z_start, (theta.shape[0],) + self.z_start.shape).copy()
        eye = np.eye(r)
        for it in range(NEWTON_STEPS + 1):
            f, d = self.table(z, grad=True)  # (N, T, K), (N, T, K, r)
            lam = (2.0 * math.pi * f) ** 2
            df = f[..., None] * d / (2.0 * lam[..., None])  # df/dz
            res = self.f_obs - f
            _, e = gamma_log_density(z, a, log_th)  # (N, T, r)
            wr = w * res
            pull = (wr[..., None, :] @ df)[..., 0, :]  # the data's gradient, (N, T, r)
            grad = pull + a - e
            # minus the Hessian: the Gauss-Newton term, minus the residual times f's curvature
            # (d2f/dz_i dz_j = delta_ij df_j - df_i d_j / (2 lambda)), plus the Gamma law's
            gauss_newton = np.swapaxes(df * w[..., None], -1, -2) @ df
            curvature = np.swapaxes(df * (wr / (2.0 * lam))[..., None], -1, -2) @ d
            hess = gauss_newton + curvature + (e - pull)[..., None] * eye
            if it == NEWTON_STEPS:
                break
            step = np.linalg.solve(hess, grad[..., None])[..., 0]
            z = z + np.clip(step, -0.5, 0.5)
        data = -0.5 * np.sum(w * res * res, axis=-1)
        prior = np.sum(gamma_log_density(z, a, log_th)[0], axis=-1)
        sign, log_det = np.linalg.slogdet(hess)
        laplace = np.where(sign > 0, 0.5 * r * LOG_2PI - 0.5 * log_det, -np.inf)
        return data + prior + laplace + const + norm


def laplace_likelihood(model: Structure, measured: MeasuredModes, groups: JointGroups | None = None,
                       start: Values | None = None) -> tuple[LaplaceLikelihood, float]:
    """The `LaplaceLikelihood` of a campaign, for any number of joints, and its forward model's error.

    Raises
    ------
    ValueError
        As `workbench.identify.likelihood.prepare`.
    """
    p = prepare(model, measured, groups, start)
    at = structure_at_moduli(model, p.reference_pa[p.joint_group])
    nominal = tracked_nominal(at, p.modes)  # one solve serves the anchors and the error check
    forward = anchored_forward(at, nominal, p.f_obs, p.mask, p.modes)
    lm = LaplaceLikelihood(forward, p.f_obs, p.mask, np.asarray(measured.mean_hz, float), p.joint_group,
                           p.reference_pa, forward.anchor)
    return lm, forward_error(at, nominal, forward, p.modes)

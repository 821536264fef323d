"""Stochastic Model Reduction (paper section 3.2): SMR1, SMR2, the proximity factor, and the
second-order perturbation method it is compared with.

All methods take an assembled model (``K(gamma) = K_rest + sum_j gamma_j K_j``, eq. 3-4) and a
`JointModel` of independent Gamma laws (eq. 8-9), and return the first two moments of the first
eigenfrequencies, modes in the nominal model's order.

SMR1 (eq. 5) keeps the nominal eigenvectors: ``lambda_k = lambda_k,rest + sum_j gamma_j lambda_kj``
with ``lambda_kj = phi_k^T K_j phi_k``. Its frequency moments are computed exactly, without
sampling, from the Gamma laws' Laplace transforms (`workbench.uq.sqrt_moments`).

SMR2 (eq. 6-7) lets the eigenvector vary to first order, ``phi_k(gamma) = phi_k + sum_j
dphi_k/dgamma_j (gamma_j - 1)``, with Nelson's derivatives. We evaluate the eigenvalue as the
Rayleigh quotient ``phi^T K(gamma) phi / phi^T M phi`` rather than eq. (6)'s unnormalised
``phi^T K(gamma) phi``: the quotient is stationary, so an eigenvector error of order d gives an
eigenvalue error of order d^2, whereas the first-order vector is not mass-normalised at second
order and eq. (6) inherits that error at order d^2 directly (`smr2(..., rayleigh=False)` keeps
eq. (6) for comparison). Moments over gamma by a Gauss (or quasi-Monte Carlo) rule.

The adaptive strategy of Figure 10 refines a mode by SMR2 where SMR1's deterministic eigenvector
is not good enough. The paper's indicator, the proximity factor, is defined in its reference [27],
which we do not have. Ours, from the first two moments of neighbouring eigenvalues (SMR1, free):

    PF_k = min_(l != k) |E[lambda_k] - E[lambda_l]| / sqrt(sigma[lambda_k] sigma[lambda_l]).

To first order the eigenvector moves by ``sum_l c_kl phi_l`` with ``c_kl = phi_l^T dK phi_k /
(lambda_k - lambda_l)``, and joint by joint ``sigma[phi_l^T dK phi_k] <= sqrt(sigma[lambda_k]
sigma[lambda_l])`` (Cauchy-Schwarz), so ``1 / PF_k`` bounds the spread of the largest mixing
coefficient. It catches veering pairs: on a symmetric portal (benchmarks/smr_accuracy.py) SMR1's
std error on a close pair follows ``3.8 / PF^2``.

Our accuracy study also shows what PF cannot see: SMR1's std error on well-separated modes grows as
``kappa * D_k`` with the variance-weighted joint dispersion ``D_k = sum_j w_kj cov_j^2`` (``w_kj``,
joint j's share of ``Var[lambda_k]``) and ``kappa`` at most 1.93 on every frame and CoV we
tried: the strain redistributes inside a joint zone whose modulus varies a lot, a static effect of
the high modes that no neighbour's moments reveal (horizontal joint, CoV 0.22: 4-9 % error at
PF >= 36). So a mode is refined when ``PF_k < PF_THRESHOLD`` (30) or ``D_k > DISPERSION_THRESHOLD``
(0.0025); each keeps SMR1's predicted error under 0.5 %, half of the 1 % budget. Both come free
from SMR1's closed form.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spla

from workbench.model.modal import DEGENERATE_GAP, DENSE_LIMIT, Modes, count_below, shared_eigenvalues
from workbench.model.structure import Structure, structure_energies, structure_modes
from workbench.progress import Progress
from workbench.tasks import Mapper
from workbench.uq.degenerate import cluster_moments, describe
from workbench.uq.limits import check_cov
from workbench.uq.sqrt_moments import sqrt_moments
from workbench.uq.stochastic import TENSOR_LIMIT, FrequencyMoments, JointModel, expectation_rule, monte_carlo

__all__ = [
    "PROXIMITY_THRESHOLD",
    "DISPERSION_THRESHOLD",
    "dispersion",
    "Sensitivities",
    "sensitivities",
    "eigenvalue_moments",
    "proximity_factor",
    "eigenvector_derivatives",
    "smr1",
    "smr2",
    "smr2_frequencies",
    "adaptive",
    "pert2",
    "propagate",
    "METHODS",
]

PROXIMITY_THRESHOLD = 30.0  # 3.8 / PF^2 < 0.5 %
DISPERSION_THRESHOLD = 0.0025  # 1.9 * D < 0.5 %
RHS_CHUNK = 32  # joints whose derivative equations are solved together (memory: 2 x n x 32 doubles)
EXTRA_MODES = 4  # nominal modes computed beyond ``count`` so the last mode has an upper neighbour
TWO_PI = 2.0 * np.pi


@dataclass(frozen=True)
class Sensitivities:
    """Nominal modes and the eigenvalue split of eq. (5).

    Attributes
    ----------
    modes : nominal modes (``count + EXTRA_MODES`` of them when available).
    rest : (n_modes,) ``phi_k^T K_rest phi_k``, (rad/s)^2.
    joints : (n_modes, n_joints) ``lambda_kj = phi_k^T K_j phi_k``, (rad/s)^2.
    scale : the joint scale ``gamma`` they were computed at (None: the model's nominal point).
    """

    modes: Modes
    rest: np.ndarray
    joints: np.ndarray
    scale: np.ndarray | None = None

    def require_nominal(self) -> None:
        """SMR2, adaptive and Pert2 differentiate the model itself: they need its nominal point."""
        if self.scale is not None and not np.allclose(self.scale, 1.0, rtol=0.0, atol=1e-12):
            raise ValueError("sensitivities computed at a joint scale gamma != 1 serve SMR1 only; for SMR2, "
                             "adaptive and Pert2 move the model there with workbench.model.joints.model_at_moduli")


def sensitivities(model: Structure, count: int, gamma: np.ndarray | None = None,
                  extra: int = EXTRA_MODES) -> Sensitivities:
    """Nominal modes of ``model`` (joints at ``gamma``, default their means) and ``lambda_kj`` (eq. 5).

    With ``gamma``, ``lambda_kj`` is relative to that point: right for SMR1, which needs only the
    nominal solve there. SMR2, adaptive and Pert2 refuse such sensitivities; give them the model
    moved to that point instead (`workbench.model.joints.model_at_moduli`).
    """
    modes = structure_modes(model, min(count + extra, model.size - 2), gamma)
    rest, joints = structure_energies(model, modes.shapes)
    if gamma is not None:
        joints = joints * np.asarray(gamma, float)[:, None]
    return Sensitivities(modes, rest, joints.T, None if gamma is None else np.asarray(gamma, float))


def _smr1_sensitivities(model: Structure, count: int) -> Sensitivities:
    """SMR1's nominal solve: the ``count`` modes it needs, and the extra ones only when they matter.

    Eq. (5) needs nothing above mode ``count``; the extra modes serve the last modes' proximity
    factor, and catch a repeated eigenvalue split by the cut (its SMR needs the whole pair). On a
    large model they can cost as much again as the solve (a cluster just above the cut slows
    Lanczos): a Sturm count (one factorisation) shows whether an eigenvalue shares mode
    ``count``'s, and only then are they solved. Small models solve them always (dense, cheap).
    """
    if model.size <= DENSE_LIMIT or count + 1 >= model.size - 2:
        return sensitivities(model, count)
    sens = sensitivities(model, count, extra=0)
    top = sens.modes.eigenvalues[count - 1]
    below = count_below(model.stiffness(), model.mass, top * (1.0 + 2.0 * DEGENERATE_GAP))
    return sens if below == count else sensitivities(model, count)


def eigenvalue_moments(sens: Sensitivities, joints: JointModel) -> tuple[np.ndarray, np.ndarray]:
    """SMR1 mean and standard deviation of the eigenvalues (rad/s)^2, closed form (eq. 5)."""
    mean = sens.rest + sens.joints.sum(axis=1)
    std = np.sqrt((sens.joints**2) @ joints.cov**2)
    return mean, std


def proximity_factor(mean: np.ndarray, std: np.ndarray) -> np.ndarray:
    """``PF_k = min_(l != k) |mean_k - mean_l| / sqrt(std_k std_l)`` over the given eigenvalues.

    Large means well separated (SMR1 is enough); inf for a mode with no random neighbour.
    """
    gap = np.abs(mean[:, None] - mean[None, :])
    with np.errstate(divide="ignore", invalid="ignore"):
        pf = gap / np.sqrt(np.outer(std, std))
    pf[~np.isfinite(pf)] = np.inf
    np.fill_diagonal(pf, np.inf)
    return pf.min(axis=1)


def dispersion(sens: Sensitivities, joints: JointModel) -> np.ndarray:
    """``D_k = sum_j w_kj cov_j^2``, ``w_kj`` joint j's share of SMR1's ``Var[lambda_k]`` (0 if none)."""
    share = sens.joints**2 * joints.cov**2
    total = share.sum(axis=1)
    with np.errstate(invalid="ignore", divide="ignore"):
        d = (share * joints.cov**2).sum(axis=1) / total
    return np.where(total > 0, d, 0.0)


def _check(model: Structure, joints: JointModel) -> None:
    if joints.names != model.joint_names:
        raise ValueError(f"joint model {joints.names} does not match the model's joints {model.joint_names}")


def smr1(model: Structure, joints: JointModel, count: int = 10, sens: Sensitivities | None = None) -> FrequencyMoments:
    """SMR1 (eq. 5): frequency moments with the nominal eigenvectors, exact for that model.

    Parameters
    ----------
    model : assembled model.
    joints : Gamma laws of the joints' normalised moduli.
    count : number of modes.
    sens : precomputed `sensitivities` (the nominal solve is then not repeated).

    Returns
    -------
    FrequencyMoments
        ``mean_hz``, ``std_hz`` of the first ``count`` modes; ``proximity`` holds PF_k.
    """
    _check(model, joints)
    sens = sens or _smr1_sensitivities(model, count)
    r = joints.random
    if r.sum() <= TENSOR_LIMIT:
        # The tensor Gauss rule integrates sqrt of the linear form to about 1e-10 for CoV <= 0.22
        # (tests compare it with the exact integral) at a fraction of the cost.
        gamma, weights = expectation_rule(joints)
        f = np.sqrt(sens.rest[:count] + gamma @ sens.joints[:count].T) / TWO_PI
        mean = weights @ f
        std = np.sqrt(weights @ (f - mean) ** 2)
    else:
        constant = sens.rest[:count] + sens.joints[:count, ~r].sum(axis=1)
        mean, std = sqrt_moments(constant, sens.joints[:count, r], joints.shape[r], joints.scale[r])
        mean, std = mean / TWO_PI, std / TWO_PI
    _on_clusters(model, joints, sens, count, mean, std)
    lam_mean, lam_std = eigenvalue_moments(sens, joints)
    proximity = proximity_factor(lam_mean, lam_std)[:count]
    if sens.modes.count == count:
        proximity[-1] = np.nan  # its upper neighbour was not solved: no factor rather than half of one
    return _finite(FrequencyMoments(mean, std, "smr1", sens.modes.frequency_hz[:count], proximity=proximity,
                                    dispersion=dispersion(sens, joints)[:count]))


def _on_clusters(model: Structure, joints: JointModel, sens: Sensitivities, count: int, mean: np.ndarray,
                 std: np.ndarray, seed: int = 0) -> np.ndarray:
    """Overwrite, in place, the moments of modes sharing an eigenvalue with SMR on their subspace
    (`workbench.uq.degenerate`); returns the mask of those modes among the first ``count``.
    """
    shared = np.zeros(count, bool)
    for group in shared_eigenvalues(sens.modes, count):
        m, s = cluster_moments(model, sens.modes, group, joints, seed)
        inside = group < count
        mean[group[inside]], std[group[inside]] = m[inside], s[inside]
        shared[group[inside]] = True
    return shared


def _finite(result: FrequencyMoments) -> FrequencyMoments:
    """The last guard: a moment that is not a finite number is an error, never a number written out."""
    bad = np.flatnonzero(~(np.isfinite(result.mean_hz) & np.isfinite(result.std_hz)))
    if bad.size:
        raise ValueError(f"method {result.method}: the moments of mode(s) {', '.join(str(k + 1) for k in bad)} "
                         "are not finite numbers; use --method mc")
    return result


def eigenvector_derivatives(model: Structure, sens: Sensitivities, modes: np.ndarray,
                            joint_index: np.ndarray) -> np.ndarray:
    """Nelson's eigenvector derivatives ``dphi_k / dgamma_j`` at the nominal point.

    For each mode, ``(K - lambda_k M) v = -(K_j - lambda_kj M) phi_k`` is solved with ``v_p = 0`` at
    the dof ``p`` of largest ``|phi_k|``, which removes the singularity; then ``dphi = v + c phi_k``
    with ``c = -phi_k^T M v`` keeps the mass normalisation. One sparse factorisation per mode,
    shared by all joints. Requires distinct eigenvalues.

    Returns
    -------
    (len(modes), n_dof, len(joint_index)) derivatives.
    """
    sens.require_nominal()
    k_nominal = model.stiffness()
    mass = model.mass
    n = model.size
    out = np.empty((len(modes), n, len(joint_index)))
    for row, k in enumerate(modes):
        lam = sens.modes.eigenvalues[k]
        phi = sens.modes.shapes[:, k]
        mass_phi = mass @ phi
        p = int(np.abs(phi).argmax())
        keep = np.ones(n)
        keep[p] = 0.0
        mask = sp.diags(keep)
        pin = sp.csr_matrix(([1.0], ([p], [p])), shape=(n, n))
        lu = spla.splu((mask @ (k_nominal - lam * mass) @ mask + pin).tocsc())
        # right-hand sides a chunk at a time: at a million dofs all 200 joints' at once are 3 GB twice
        for start in range(0, len(joint_index), RHS_CHUNK):
            chunk = joint_index[start:start + RHS_CHUNK]
            rhs = np.stack([sens.joints[k, j] * mass_phi - model.stiffness_joints[j] @ phi for j in chunk], axis=1)
            rhs[p] = 0.0
            v = lu.solve(rhs)
            v -= np.outer(phi, mass_phi @ v)
            out[row][:, start:start + len(chunk)] = v
    return out


def smr2_frequencies(model: Structure, sens: Sensitivities, modes: np.ndarray, gammas: np.ndarray,
                     varying: np.ndarray | None = None, rayleigh: bool = True) -> np.ndarray:
    """SMR2 eigenfrequencies (eq. 6-7) at given joint scales: (n_points, len(modes)) Hz.

    Parameters
    ----------
    sens : `sensitivities` of ``model`` at its nominal point.
    modes : 0-based indices of the nominal modes.
    gammas : (n_points, n_joints) joint scales ``gamma``.
    varying : indices of the joints whose eigenvector derivatives enter eq. (7) (default: all).
    rayleigh : the Rayleigh quotient (default), or eq. (6) as printed.
    """
    varying = np.arange(gammas.shape[1]) if varying is None else np.asarray(varying)
    derivatives = eigenvector_derivatives(model, sens, modes, varying)
    coeff = np.concatenate([np.ones((len(gammas), 1)), gammas[:, varying] - 1.0], axis=1)  # (G, 1 + r)
    out = np.empty((len(gammas), len(modes)))
    for row, k in enumerate(modes):
        basis = np.concatenate([sens.modes.shapes[:, [k]], derivatives[row]], axis=1)  # (n, 1 + r)
        b = basis.shape[1]
        # reduced matrices from element energies: no cancellation (see assembly.element_energies)
        rest, per_joint = structure_energies(model, np.repeat(basis, b, axis=1), np.tile(basis, (1, b)))
        stiff = rest.reshape(b, b)[None] + np.einsum("gj,jab->gab", gammas, per_joint.reshape(-1, b, b))
        numerator = np.einsum("ga,gab,gb->g", coeff, stiff, coeff)
        if rayleigh:
            numerator = numerator / np.einsum("ga,ab,gb->g", coeff, basis.T @ (model.mass @ basis), coeff)
        out[:, row] = np.sqrt(np.clip(numerator, 0.0, None)) / TWO_PI
    return out


def _smr2_modes(model: Structure, joints: JointModel, sens: Sensitivities, modes: np.ndarray, rayleigh: bool,
                seed: int) -> tuple[np.ndarray, np.ndarray]:
    """Frequency mean and std of the given modes by SMR2 (eq. 6-7) over the joint law."""
    r = np.flatnonzero(joints.random)
    if r.size == 0:
        f = sens.modes.frequency_hz[modes]
        return f.copy(), np.zeros(len(modes))
    gamma, weights = expectation_rule(joints, seed)
    f = smr2_frequencies(model, sens, modes, gamma, r, rayleigh)
    mean = weights @ f
    return mean, np.sqrt(weights @ (f - mean) ** 2)


def smr2(model: Structure, joints: JointModel, count: int = 10, rayleigh: bool = True, seed: int = 0,
         sens: Sensitivities | None = None) -> FrequencyMoments:
    """SMR2 (eq. 6-7) on every mode: first-order eigenvectors, eigenvalue as a Rayleigh quotient.

    ``rayleigh=False`` evaluates eq. (6) as printed (``phi^T K(gamma) phi``, unnormalised).
    ``seed`` only matters above `workbench.uq.stochastic.TENSOR_LIMIT` random joints (QMC rule).
    """
    _check(model, joints)
    sens = sens or sensitivities(model, count)
    mean, std = np.empty(count), np.empty(count)
    shared = _on_clusters(model, joints, sens, count, mean, std, seed)
    single = np.flatnonzero(~shared)  # Nelson's derivatives exist only for distinct eigenvalues
    mean[single], std[single] = _smr2_modes(model, joints, sens, single, rayleigh, seed)
    lam_mean, lam_std = eigenvalue_moments(sens, joints)
    return _finite(FrequencyMoments(mean, std, "smr2", sens.modes.frequency_hz[:count],
                                    proximity=proximity_factor(lam_mean, lam_std)[:count],
                                    dispersion=dispersion(sens, joints)[:count], refined=~shared))


def adaptive(model: Structure, joints: JointModel, count: int = 10, proximity_threshold: float = PROXIMITY_THRESHOLD,
             dispersion_threshold: float = DISPERSION_THRESHOLD, seed: int = 0,
             sens: Sensitivities | None = None) -> FrequencyMoments:
    """The strategy of Figure 10: SMR1 on all modes, then SMR2 where ``PF_k < proximity_threshold``
    (close modes) or ``D_k > dispersion_threshold`` (a widely varying joint); see the module notes.
    """
    sens = sens or sensitivities(model, count)
    sens.require_nominal()
    first = smr1(model, joints, count, sens)
    assert first.proximity is not None and first.dispersion is not None  # smr1 always fills both
    shared = np.zeros(count, bool)
    for group in shared_eigenvalues(sens.modes, count):  # smr1 already took them on their subspace
        shared[group[group < count]] = True
    refined = ((first.proximity < proximity_threshold) | (first.dispersion > dispersion_threshold)) & ~shared
    mean, std = first.mean_hz.copy(), first.std_hz.copy()
    if np.any(refined):
        modes = np.flatnonzero(refined)
        mean[modes], std[modes] = _smr2_modes(model, joints, sens, modes, True, seed)
    return _finite(FrequencyMoments(mean, std, "adaptive", first.nominal_hz, proximity=first.proximity,
                                    dispersion=first.dispersion, refined=refined))


def pert2(model: Structure, joints: JointModel, count: int = 10, sens: Sensitivities | None = None) -> FrequencyMoments:
    """Second-order perturbation: mean to second order, variance to first order, of the frequencies.

    With ``f = sqrt(lambda) / 2 pi``, ``df/dgamma_j = lambda_kj / (4 pi sqrt(lambda))`` and
    ``d2f/dgamma_j^2 = lambda''_jj / (4 pi sqrt(lambda)) - lambda_kj^2 / (8 pi lambda^1.5)``, where
    ``lambda''_jj = 2 phi^T (K_j - lambda_kj M) dphi/dgamma_j``. Then ``E[f] = f + 1/2 sum_j
    d2f/dgamma_j^2 cov_j^2`` and ``Var[f] = sum_j (df/dgamma_j)^2 cov_j^2``.
    """
    _check(model, joints)
    sens = sens or sensitivities(model, count)
    r = np.flatnonzero(joints.random)
    lam = sens.modes.eigenvalues[:count]
    f0 = np.sqrt(lam) / TWO_PI
    if r.size == 0:
        return FrequencyMoments(f0.copy(), np.zeros(count), "pert2", f0)
    for group in shared_eigenvalues(sens.modes, count):
        raise ValueError(f"method pert2: {describe(sens.modes, group)} share one eigenvalue, where perturbation "
                         "derivatives do not exist; use --method smr1, smr2, adaptive (SMR on the shared "
                         "subspace) or mc")
    derivatives = eigenvector_derivatives(model, sens, np.arange(count), r)
    mean, std = np.empty(count), np.empty(count)
    for k in range(count):
        phi = sens.modes.shapes[:, k]
        first = sens.joints[k, r]
        second = np.array([2.0 * phi @ (model.stiffness_joints[j] @ derivatives[k][:, c]
                                        - first[c] * (model.mass @ derivatives[k][:, c]))
                           for c, j in enumerate(r)])
        df = first / (2.0 * TWO_PI * np.sqrt(lam[k]))
        d2f = second / (2.0 * TWO_PI * np.sqrt(lam[k])) - first**2 / (4.0 * TWO_PI * lam[k] ** 1.5)
        cov2 = joints.cov[r] ** 2
        mean[k] = f0[k] + 0.5 * d2f @ cov2
        std[k] = np.sqrt(df**2 @ cov2)
    return _finite(FrequencyMoments(mean, std, "pert2", f0))


METHODS = ("smr1", "smr2", "adaptive", "pert2", "mc")


def propagate(model: Structure, joints: JointModel, method: str, count: int = 10, samples: int = 10_000, seed: int = 0,
              mapper: Mapper | None = None, progress: Progress | None = None) -> FrequencyMoments:
    """Frequency moments by ``method`` (one of `METHODS`); ``samples``, ``mapper`` and ``progress`` are for ``mc``.

    Every method but ``mc`` refuses joints whose CoV is above `workbench.uq.limits.COV_LIMIT`.
    """
    check_cov(model, joints, method)
    if method == "smr1":
        return smr1(model, joints, count)
    if method == "smr2":
        return smr2(model, joints, count, seed=seed)
    if method == "adaptive":
        return adaptive(model, joints, count, seed=seed)
    if method == "pert2":
        return pert2(model, joints, count)
    if method == "mc":
        return monte_carlo(model, joints, count, samples, seed, mapper, progress).moments
    raise ValueError(f"method: {method!r} is not one of {', '.join(METHODS)}")

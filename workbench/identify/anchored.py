"""The forward model of the Laplace likelihood: each test's frequencies as Rayleigh quotients at an anchor.

Each test's frequencies are the Rayleigh quotients of the model's eigenvectors at an anchor
``zbar_t`` near the test's own moduli (eq. 5 around that point):

    lambda_tk(z) = c_tk + sum_j L_tkj exp(z_j - zbar_tj),

with ``c_tk`` and ``L_tkj`` the rest and joint energies of the anchor's mode k (exact solves, modes
tracked to the nominal ones by MAC). The anchor is the test's maximum a posteriori point under a
broad prior (Gauss-Newton with exact solves): the joints the test's data pin sit within the
posterior's width of it, where the quotient's error is of second order in that width; the joints
the data hardly see may move far, but then their energy share is small. `forward_error` measures
the error against exact solves at points a prior's width away, and
`workbench.identify.bayes.bayes_identify` reports it.

The first anchors come from each test's data under a broad prior; with more joints than modes, the
directions the data do not see are then placed by that broad prior, far from where the joint law
puts them. So `workbench.identify.bayes.bayes_identify` anchors a second time, at each test's
latent mode under the maximum a posteriori population (`forward_at`). On the 20-joint, 10-mode campaign
of `benchmarks/bayes_many_joints.py` the forward model's error a prior's width away fell from 1.0e-2
to 7.2e-3, and the group means' errors from -7.9 % / +10.2 % to -6.0 % / +0.7 %.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from workbench.model.modal import Modes
from workbench.model.structure import Structure, structure_energies, structure_modes
from workbench.uq.stochastic import track_modes

__all__ = ["AnchoredForward", "tracked_nominal", "anchored_forward", "forward_at", "forward_error", "ANCHOR_PRIOR_SD"]

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
    rest_grad, joints_grad : (T, K, P) and (T, K, r, P) their derivatives in the logs ``m`` of a frame's
        manufacturing factors (`workbench.identify.members`), or None without them.
    """

    anchor: np.ndarray
    rest: np.ndarray
    joints: np.ndarray
    rest_grad: np.ndarray | None = None
    joints_grad: np.ndarray | None = None

    @property
    def factor_count(self) -> int:
        return 0 if self.rest_grad is None else self.rest_grad.shape[-1]

    def __call__(self, z: np.ndarray, grad: bool = False,
                 m: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray] | np.ndarray:
        """Frequencies (..., T, K), Hz, at ``z`` (..., T, r); with ``grad`` also ``dlambda/dz`` (..., T, K, r).
        ``m`` (..., P): the manufacturing factors' logs, first order (`workbench.identify.members`); ignored
        by a forward model built without them (its frame is the drawing).
        """
        joints, rest = self.joints, self.rest
        if m is not None and self.joints_grad is not None and self.rest_grad is not None:
            joints = joints + np.einsum("tkrp,...p->...tkr", self.joints_grad, m)
            rest = rest + np.einsum("tkp,...p->...tk", self.rest_grad, m)
        d = joints * np.exp(z - self.anchor)[..., None, :]  # (..., T, K, r)
        lam = rest + d.sum(axis=-1)
        f = np.sqrt(np.maximum(lam, 0.0)) / (2.0 * math.pi)
        return (f, d) if grad else f

    def factor_terms(self, z: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """``dlambda/dm`` (..., T, K, P) at ``z`` (..., T, r) and its part through the joints,
        ``D_tkjp exp(z_tj - zbar_tj)`` (..., T, K, r, P) (``d2lambda / dz_j dm_p``).
        """
        if self.joints_grad is None or self.rest_grad is None:
            raise ValueError("factor_terms: this forward model has no manufacturing factors")
        dm = self.joints_grad * np.exp(z - self.anchor)[..., None, :, None]
        return self.rest_grad + dm.sum(axis=-2), dm


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


def forward_at(model: Structure, nominal: Modes, modes: np.ndarray, anchors: np.ndarray) -> AnchoredForward:
    """The Rayleigh-quotient split of every test at given anchors (T, r) in ``z``."""
    parts = [_split_at(model, nominal, modes, z) for z in anchors]
    return AnchoredForward(np.array(anchors, float), np.array([p[0] for p in parts]), np.array([p[1] for p in parts]))


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

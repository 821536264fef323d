"""Repeated eigenvalues: SMR on the degenerate subspace.

A structure with symmetry (a square frame, two identical bays) has modes that share one eigenvalue.
Their eigenvectors are then any basis of the shared subspace, so eq. (5) with one such basis is
arbitrary, and Nelson's derivatives (eq. 7) do not exist: the mode pair splits under any joint
perturbation, and its eigenvalues are not differentiable functions of gamma. What is well defined
is the Rayleigh-Ritz problem on the subspace: for each gamma, the eigenvalues of the q x q matrix
``Phi_C^T K(gamma) Phi_C`` (``Phi_C^T M Phi_C = I``), which is SMR1 (eq. 5) in a basis that turns
with gamma. `cluster_moments` takes their moments over the joint law; SMR1, SMR2 and the adaptive
strategy use it on every cluster, and Pert2, whose derivatives cannot exist there, refuses.
"""

from __future__ import annotations

import numpy as np

from workbench.model.modal import Modes
from workbench.model.structure import Structure, structure_energies
from workbench.uq.stochastic import JointModel, expectation_rule

__all__ = ["cluster_moments", "describe"]

TWO_PI = 2.0 * np.pi


def describe(modes: Modes, group: np.ndarray) -> str:
    """``modes 2 and 3 (167.066 Hz)``, 1-based as users count them."""
    numbers = [str(int(k) + 1) for k in group]
    listed = " and ".join(numbers) if len(numbers) == 2 else ", ".join(numbers[:-1]) + " and " + numbers[-1]
    return f"modes {listed} ({modes.frequency_hz[group[0]]:.6g} Hz)"


def cluster_moments(model: Structure, modes: Modes, group: np.ndarray, joints: JointModel,
                    seed: int = 0) -> tuple[np.ndarray, np.ndarray]:
    """Mean and std (Hz) of a degenerate group's frequencies, Rayleigh-Ritz on its subspace.

    Parameters
    ----------
    model : assembled model, at its nominal point.
    modes : its nominal modes (mass-normalised).
    group : indices of modes sharing one eigenvalue (from `workbench.model.modal.shared_eigenvalues`).
    joints : Gamma laws of the joints.
    seed : seed of the quasi-Monte Carlo rule above `workbench.uq.stochastic.TENSOR_LIMIT` random joints.

    Returns
    -------
    mean_hz, std_hz : (len(group),) the sorted split frequencies' moments, lowest first.
    """
    basis = modes.shapes[:, group]
    q = basis.shape[1]
    # reduced matrices from element energies, as SMR2 does: no cancellation in the small terms
    rest, per_joint = structure_energies(model, np.repeat(basis, q, axis=1), np.tile(basis, (1, q)))
    rest = rest.reshape(q, q)
    per_joint = per_joint.reshape(-1, q, q)
    gamma, weights = expectation_rule(joints, seed)
    stiff = rest[None] + np.einsum("gj,jab->gab", gamma, per_joint)
    stiff = 0.5 * (stiff + np.swapaxes(stiff, 1, 2))
    lam = np.linalg.eigvalsh(stiff)  # (n_points, q), increasing
    f = np.sqrt(np.clip(lam, 0.0, None)) / TWO_PI
    mean = weights @ f
    return mean, np.sqrt(weights @ (f - mean) ** 2)

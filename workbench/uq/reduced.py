"""Reduced-basis Monte Carlo: Rayleigh-Ritz of every joint draw on SMR2's basis.

SMR2 (paper eq. 7) moves each eigenvector to first order, ``phi_k + sum_j dphi_k/dgamma_j
(gamma_j - 1)``: its basis is the nominal modes and their joint sensitivities (Nelson's
derivatives, `workbench.uq.smr.eigenvector_derivatives`). Here the whole span of that basis is
kept, made mass-orthonormal once, and every draw of the joint moduli is solved in it exactly::

    V^T K(gamma) V x = lambda x,   V^T K(gamma) V = V^T K_rest V + sum_j gamma_j V^T K_j V   (eq. 4)

a dense eigenproblem of a few tens of unknowns instead of the model's size. The Ritz values are
upper bounds of the eigenvalues and, since the basis holds SMR2's first-order vectors, their error
is of second order in SMR2's vector error: measured against full solves on the paper's frames
(benchmarks/frf_band_speed.py, tests/test_prediction.py), below 1e-6 relative at joint CoVs up to
0.22, where SMR2's own Rayleigh quotient per mode is off by up to 6e-3 in the tails. Each draw's
Ritz modes are paired with the nominal modes by MAC, one to one, as exact solves are
(`workbench.uq.stochastic.track_modes`).

With many random joints the whole span is too large (10 modes and 200 joints: 2010 vectors, and
200 projected joint matrices of 2010^2 each, tens of GB). Above `MAX_FULL_BASIS` vectors each mode's
sensitivities are compressed first: the first-order change of mode k, ``sum_j dphi_k/dgamma_j
(gamma_j - 1)``, has the mass-weighted covariance ``D_k diag(cov^2) D_k^T``; its principal directions
are kept until the variance left out is below `VARIANCE_LEFT` of the total (a Karhunen-Loeve
truncation of SMR2's vector change; the Ritz error is of second order in what is left out). Each
mode's derivatives are computed and compressed in turn, so the memory is one mode's ``n x r``.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.linalg
import scipy.sparse as sp
from scipy.optimize import linear_sum_assignment
from threadpoolctl import threadpool_limits

from workbench.model.modal import Modes, shared_eigenvalues
from workbench.model.structure import Structure, structure_energies
from workbench.uq.smr import Sensitivities, eigenvector_derivatives
from workbench.uq.stochastic import JointModel

__all__ = ["ReducedBasis", "reduced_basis", "reduced_modes", "RELATIVE_RANK", "MAX_FULL_BASIS", "VARIANCE_LEFT"]

RELATIVE_RANK = 1e-10  # basis directions whose mass-Gram eigenvalue is below this (relative) are dependent
MAX_FULL_BASIS = 400  # SMR2's whole span kept up to this many vectors; compressed per mode above
VARIANCE_LEFT = 1e-8  # share of a mode's first-order vector variance the compressed basis may leave out
NEW_SHARE = 1e-8  # a direction adding less than this share of its (squared) length to the span is dropped
BATCH = 2000  # draws solved per stacked eigen-decomposition
BATCH_DOUBLES = 200_000_000  # and at most this many doubles of stacked matrices (1.6 GB)
SUBSET_ABOVE = 150  # basis size above which each draw's lowest pairs are solved alone


@dataclass(frozen=True)
class ReducedBasis:
    """SMR2's basis, mass-orthonormal, and the model's matrices projected on it.

    Attributes
    ----------
    blocks : ``V`` as column blocks (the nominal modes', then each mode's sensitivities'), with
        ``V^T M V = I``; kept apart because joining them would hold a second ``n x m`` copy (6 GB at
        a million dofs).
    rest : (m, m) ``V^T K_rest V``, N/m per unit modal mass.
    joints : (n_joints, m, m) ``V^T K_j V``, each joint at its mean modulus.
    nominal : (m, n_modes) reduced coordinates ``V^T M phi_k`` of the nominal modes.
    """

    blocks: tuple[np.ndarray, ...]
    rest: np.ndarray
    joints: np.ndarray
    nominal: np.ndarray

    @property
    def size(self) -> int:
        """Number of basis vectors ``m``."""
        return int(self.rest.shape[0])

    @property
    def basis(self) -> np.ndarray:
        """(n_dof, m) ``V`` in one array."""
        return np.concatenate(self.blocks, axis=1)

    def rows(self, dofs: np.ndarray) -> np.ndarray:
        """(len(dofs), m) the basis at the given free dofs."""
        return np.concatenate([block[dofs] for block in self.blocks], axis=1)


def reduced_basis(model: Structure, nominal: Modes, joints: JointModel, compress: bool | None = None) -> ReducedBasis:
    """SMR2's basis for ``nominal``: its modes and their sensitivities to the random joints (eq. 7).

    ``compress``: each mode's sensitivities compressed to their principal directions (module
    docstring); default, when the whole span would exceed `MAX_FULL_BASIS` vectors.

    Raises
    ------
    ValueError
        Two of the nominal modes share an eigenvalue (no Nelson derivative exists there).
    """
    if shared_eigenvalues(nominal, nominal.count):
        raise ValueError("reduced basis: nominal modes share an eigenvalue; Nelson's derivatives need "
                         "distinct ones (use exact solves)")
    rest, per_joint = structure_energies(model, nominal.shapes)
    sens = Sensitivities(nominal, rest, per_joint.T)
    random = np.flatnonzero(joints.random)
    if compress is None:
        compress = nominal.count * (1 + random.size) > MAX_FULL_BASIS
    blocks: list[np.ndarray] = []
    _append(blocks, model.mass, nominal.shapes)
    if compress:
        for k in range(nominal.count):  # one mode's derivatives at a time: n x joints, not n x modes x joints
            _append(blocks, model.mass, _principal(model, sens, k, random, joints.cov[random]))
    else:
        for part in eigenvector_derivatives(model, sens, np.arange(nominal.count), random):
            _append(blocks, model.mass, part)
    projected = np.array([_project(k, blocks) for k in (model.stiffness_rest, *model.stiffness_joints)])
    projected = 0.5 * (projected + projected.transpose(0, 2, 1))
    coordinates = np.concatenate([block.T @ (model.mass @ nominal.shapes) for block in blocks])
    return ReducedBasis(tuple(blocks), projected[0], projected[1:], coordinates)


def _append(blocks: list[np.ndarray], mass, new: np.ndarray) -> None:
    """Append to ``blocks`` the mass-orthonormal directions of ``new`` that they do not span yet.

    Block classical Gram-Schmidt in the mass inner product, done twice ("twice is enough",
    Giraud et al. 2005), then the block's own Gram matrix diagonalised. Orthogonalising block by
    block keeps each step well conditioned: a Gram matrix of the whole raw span (the derivatives of
    modes sharing a joint zone are nearly dependent) loses ``1 / RELATIVE_RANK`` in the projected
    matrices when they are formed from it.
    """
    mass_new = mass @ new
    norms = np.sqrt(np.einsum("ij,ij->j", new, mass_new))
    keep = norms > 0.0
    new, mass_new = new[:, keep] / norms[keep], mass_new[:, keep] / norms[keep]  # unit columns: one rank threshold
    # one scratch array for the products: at a million dofs each is 0.7 GB, and allocating it anew
    # for every block costs more in page faults than the product itself
    scratch = np.empty_like(new)
    for sweep in range(2):
        if sweep:
            mass_new = mass @ new
        for block in blocks:
            np.matmul(block, block.T @ mass_new, out=scratch)
            new -= scratch
    del scratch
    gram = new.T @ (mass @ new)
    values, vectors = np.linalg.eigh(0.5 * (gram + gram.T))
    keep = values > NEW_SHARE
    if keep.any():
        blocks.append(new @ (vectors[:, keep] / np.sqrt(values[keep])))


def _project(matrix, blocks: list[np.ndarray]) -> np.ndarray:
    """``V^T A V`` for a sparse ``A``, ``V`` given by column blocks.

    A joint's matrix lives on its zone's few dofs: it is projected on the rows and columns it
    touches only (the full product cost n m^2 per joint: 2.4 Tflop for 200 joints and 778 vectors
    at 20 000 dofs). A matrix touching most dofs is multiplied one block at a time, so that no
    second ``n x m`` array is held.
    """
    a = sp.csr_matrix(matrix)
    touched = np.unique(np.concatenate([np.repeat(np.arange(a.shape[0]), np.diff(a.indptr)), a.indices]))
    if touched.size > a.shape[0] // 4:
        columns = []
        for block in blocks:
            product = a @ block
            columns.append(np.concatenate([other.T @ product for other in blocks]))
        return np.concatenate(columns, axis=1)
    local = np.concatenate([block[touched] for block in blocks], axis=1)
    return local.T @ (a[touched][:, touched] @ local)


def _principal(model: Structure, sens: Sensitivities, mode: int, random: np.ndarray, cov: np.ndarray) -> np.ndarray:
    """The principal directions of one mode's first-order vector change (module docstring).

    Parameters
    ----------
    sens, mode : the model's nominal sensitivities and the 0-based mode.
    random : (r,) indices of the random joints.
    cov : (r,) their CoVs, the standard deviations of ``gamma_j - 1``.

    Returns
    -------
    (n, q) directions, mass-orthonormal, leaving out at most `VARIANCE_LEFT` of the variance.
    """
    weighted = eigenvector_derivatives(model, sens, np.array([mode]), random)[0]  # (n, r) dphi_k / dgamma_j
    weighted *= cov[None, :]  # in place: at a million dofs and 200 joints each copy is 1.6 GB
    gram = weighted.T @ (model.mass @ weighted)
    values, vectors = np.linalg.eigh(0.5 * (gram + gram.T))
    values, vectors = values[::-1], vectors[:, ::-1]
    total = float(values.clip(0.0).sum())
    if total <= 0.0:
        return np.zeros((weighted.shape[0], 0))
    left = total - np.cumsum(values.clip(0.0))
    keep = int(np.searchsorted(-left, -VARIANCE_LEFT * total)) + 1  # the first q with left_q <= share
    keep = min(keep, int(np.sum(values > RELATIVE_RANK * values[0])))
    return weighted @ (vectors[:, :keep] / np.sqrt(values[:keep]))


def reduced_modes(reduced: ReducedBasis, gammas: np.ndarray, dofs: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Each draw's modes by Rayleigh-Ritz on ``reduced``, paired with the nominal modes by MAC.

    Parameters
    ----------
    reduced : `reduced_basis` of the model.
    gammas : (n_draws, n_joints) joint scales ``gamma``.
    dofs : (n,) free-dof indices where the shapes are wanted.

    Returns
    -------
    natural_hz : (n_draws, n_modes) natural frequencies, Hz, column k paired with nominal mode k.
    shapes : (n_draws, n, n_modes) mass-normalised mode shapes at ``dofs``.
    """
    count = reduced.nominal.shape[1]
    candidates = min(reduced.size, count + 4)  # a mode moving up past its neighbour is still found
    at_dofs = reduced.rows(np.asarray(dofs, int))
    natural = np.empty((len(gammas), count))
    shapes = np.empty((len(gammas), at_dofs.shape[0], count))
    batch = max(1, min(BATCH, BATCH_DOUBLES // reduced.size**2))
    for start in range(0, len(gammas), batch):
        g = gammas[start:start + batch]
        stiffness = reduced.rest[None] + np.einsum("sj,jab->sab", g, reduced.joints)
        with threadpool_limits(1):  # thousands of tiny eigenproblems: a threaded LAPACK only thrashes
            if reduced.size > SUBSET_ABOVE:  # the lowest few pairs only (LAPACK syevr): 3x faster at 900
                pairs = [scipy.linalg.eigh(k, subset_by_index=[0, candidates - 1], driver="evr") for k in stiffness]
                values, vectors = np.array([p[0] for p in pairs]), np.array([p[1] for p in pairs])
            else:  # many small ones: numpy's stacked solver, all pairs
                values, vectors = np.linalg.eigh(stiffness)
                values, vectors = values[:, :candidates], vectors[:, :, :candidates]
        cross = np.einsum("ak,sac->skc", reduced.nominal, vectors) ** 2
        for s in range(len(g)):
            rows, cols = linear_sum_assignment(-cross[s])
            index = cols[np.argsort(rows)]
            natural[start + s] = np.sqrt(np.clip(values[s, index], 0.0, None)) / (2.0 * np.pi)
            shapes[start + s] = at_dofs @ vectors[s][:, index]
    return natural, shapes

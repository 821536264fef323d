"""``K(gamma) = K_rest + sum_j gamma_j K_j`` (eq. 3-4) on one sparsity pattern, for frames and matrix models alike.

Monte Carlo builds K(gamma) for every sample: summing one sparse matrix per joint costs a sparse
addition each, whereas on the union of the patterns the data are ``base + W @ gamma``, one sparse
product. scipy has no "sum on a fixed pattern", hence this small module.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp

__all__ = ["JointPattern"]


@dataclass(frozen=True)
class JointPattern:
    """The union pattern of ``K_rest`` and every ``K_j``: ``data(gamma) = base + weights @ gamma``.

    Attributes
    ----------
    indices, indptr : the CSR structure of the union, sorted.
    base : (nnz,) K_rest's entries on it.
    weights : (nnz, n_joints) sparse, column j holding K_j's entries.
    shape : (n, n).
    """

    indices: np.ndarray
    indptr: np.ndarray
    base: np.ndarray
    weights: sp.csr_matrix
    shape: tuple[int, int]

    @classmethod
    def of(cls, rest: sp.spmatrix, joints: tuple[sp.spmatrix, ...]) -> JointPattern:
        """The pattern of ``rest`` and ``joints`` (CSR matrices of one shape)."""
        # the union in one pass over every entry (adding the joints one by one made it joints x nnz)
        parts = [sp.coo_matrix(a) for a in (rest, *joints)]
        union = sp.csr_matrix((np.ones(sum(a.nnz for a in parts)),
                               (np.concatenate([a.row for a in parts]), np.concatenate([a.col for a in parts]))),
                              shape=rest.shape)
        union.sum_duplicates()
        union.sort_indices()
        n = union.shape[0]
        keys = np.repeat(np.arange(n, dtype=np.int64), np.diff(union.indptr)) * n + union.indices

        def positions(a: sp.spmatrix) -> tuple[np.ndarray, np.ndarray]:
            a = sp.coo_matrix(a)  # each entry's place in the union's data, by its sorted (row, col) key
            return np.searchsorted(keys, a.row.astype(np.int64) * n + a.col), a.data

        base = np.zeros(union.nnz)
        idx, val = positions(rest)
        np.add.at(base, idx, val)
        rows, cols, vals = [np.zeros(0, np.int64)], [np.zeros(0, np.int64)], [np.zeros(0)]
        for j, kj in enumerate(joints):
            idx, val = positions(kj)
            rows.append(idx)
            cols.append(np.full(idx.size, j))
            vals.append(val)
        weights = sp.csr_matrix((np.concatenate(vals), (np.concatenate(rows), np.concatenate(cols))),
                                shape=(union.nnz, len(joints)))
        return cls(union.indices, union.indptr, base, weights, (n, union.shape[1]))

    def stiffness(self, gamma: np.ndarray | None, names: tuple[str, ...]) -> sp.csr_matrix:
        """``K(gamma)``; ``gamma = None`` means every joint at its mean (all ones).

        Raises
        ------
        ValueError
            ``gamma`` of the wrong length (naming the joints ``names``), not finite, or not positive.
        """
        count = self.weights.shape[1]
        gamma = np.ones(count) if gamma is None else np.asarray(gamma, float)
        if gamma.shape != (count,):
            raise ValueError(f"gamma: expected {count} values (one per joint {list(names)}), got shape {gamma.shape}")
        if not np.all(np.isfinite(gamma)) or np.any(gamma <= 0):
            raise ValueError(f"gamma: joint moduli must be finite and positive, got {gamma}")
        return sp.csr_matrix((self.base + self.weights @ gamma, self.indices, self.indptr), shape=self.shape)

"""A surrogate of a frame's eigenfrequencies over its joint moduli: a Chebyshev table.

The Bayesian likelihood (`workbench.identify.bayes`) evaluates the first eigenfrequencies at every test's
joint moduli for every walker: tens of thousands of points per identification. A tensor
Chebyshev interpolant in ``z = log(Y / Y0)`` over the range that matters, built from exact,
MAC-tracked eigen-solutions at Chebyshev-Gauss nodes (or from SMR2 Rayleigh quotients), evaluates
them with its gradient at the cost of a small matrix product; its measured error between the
nodes is 2e-11 (one joint, degree 20) and 1e-9 (two joints, degree 12).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Literal, overload

import numpy as np

from workbench.model.structure import Structure, structure_at_moduli, structure_modes
from workbench.uq.smr import sensitivities, smr2_frequencies
from workbench.uq.stochastic import tracked_frequencies

__all__ = ["TABLE_DEGREE", "ForwardTable", "frequencies_at", "forward_table"]

TABLE_DEGREE = {1: 20, 2: 12}  # interpolation error measured 2e-11 (one joint), 1e-9 (two joints)


def _cheb(x: np.ndarray, degree: int) -> np.ndarray:
    """Chebyshev T_0..T_degree at x (..., ) -> (..., degree + 1)."""
    t = np.empty(x.shape + (degree + 1,))
    t[..., 0] = 1.0
    if degree:
        t[..., 1] = x
    for n in range(2, degree + 1):
        t[..., n] = 2.0 * x * t[..., n - 1] - t[..., n - 2]
    return t


def _cheb_derivative(x: np.ndarray, t: np.ndarray, degree: int) -> np.ndarray:
    """Derivatives of T_0..T_degree at x, from their values ``t = _cheb(x, degree)``, (..., degree + 1)."""
    d = np.zeros_like(t)
    if degree:
        d[..., 1] = 1.0
    for n in range(2, degree + 1):  # T_n' = 2 T_(n-1) + 2 x T_(n-1)' - T_(n-2)'
        d[..., n] = 2.0 * t[..., n - 1] + 2.0 * x * d[..., n - 1] - d[..., n - 2]
    return d


@dataclass(frozen=True)
class ForwardTable:
    """Frequencies ``f_k(z)`` (Hz) of chosen modes as a tensor Chebyshev series in ``z = log(Y / Y0)``.

    Attributes
    ----------
    reference_pa : (r,) ``Y0`` of each random joint.
    lower, upper : (r,) the range of ``z``; outside it the table is held constant (clipped).
    coef : (degree + 1,) * r + (n_modes,) Chebyshev coefficients.
    modes : (n_modes,) model mode indices (0 = lowest at Y0).
    source : "exact" or "smr2".
    """

    reference_pa: np.ndarray
    lower: np.ndarray
    upper: np.ndarray
    coef: np.ndarray
    modes: np.ndarray
    source: str

    @property
    def degree(self) -> int:
        return self.coef.shape[0] - 1

    @overload
    def __call__(self, z: np.ndarray, grad: Literal[False] = False) -> np.ndarray: ...

    @overload
    def __call__(self, z: np.ndarray, grad: Literal[True]) -> tuple[np.ndarray, np.ndarray]: ...

    def __call__(self, z: np.ndarray, grad: bool = False) -> np.ndarray | tuple[np.ndarray, np.ndarray]:
        """``f`` (..., n_modes) at ``z`` (..., r), and with ``grad`` its gradient (..., r, n_modes)."""
        z = np.asarray(z, float)
        r = self.lower.size
        half = 0.5 * (self.upper - self.lower)
        x = np.clip((z - 0.5 * (self.upper + self.lower)) / half, -1.0, 1.0)
        t = _cheb(x, self.degree)  # (..., r, n)
        if r == 1:
            f = t[..., 0, :] @ self.coef
            if not grad:
                return f
            d = _cheb_derivative(x, t, self.degree)
            return f, (d[..., 0, :] @ self.coef)[..., None, :] / half[0]
        if r == 2:
            n = self.degree + 1
            flat = self.coef.reshape(n, -1)  # (a, b * K)

            def contract(p, q):  # sum_ab p_a q_b coef_abk, in two steps (no (..., n * n) temporary)
                return np.einsum("...b,...bk->...k", q, (p @ flat).reshape(p.shape[:-1] + (n, -1)))

            f = contract(t[..., 0, :], t[..., 1, :])
            if not grad:
                return f
            d = _cheb_derivative(x, t, self.degree)
            g0 = contract(d[..., 0, :], t[..., 1, :]) / half[0]
            g1 = contract(t[..., 0, :], d[..., 1, :]) / half[1]
            return f, np.stack([g0, g1], axis=-2)
        raise ValueError(f"ForwardTable: {r} random joints; the table handles 1 or 2")


def frequencies_at(model0: Structure, modes: np.ndarray, gammas: np.ndarray, source: str = "exact") -> np.ndarray:
    """Eigenfrequencies (n_points, len(modes)) Hz of ``model0``'s modes (0-based) at joint scales ``gammas``.

    ``source`` "exact": eigen-solutions tracked by MAC against ``model0``'s modes; "smr2": the
    SMR2 Rayleigh quotients around ``model0`` (eq. 6-7).
    """
    modes = np.asarray(modes, int)
    count = int(modes.max()) + 1
    if source == "exact":
        return tracked_frequencies(model0, structure_modes(model0, count), gammas)[0][:, modes]
    if source == "smr2":
        return smr2_frequencies(model0, sensitivities(model0, count), modes, gammas)
    raise ValueError(f"forward: {source!r} is not 'exact' or 'smr2'")


def forward_table(model: Structure, modes: np.ndarray, reference_pa: np.ndarray, lower: np.ndarray, upper: np.ndarray,
                  degree: int | None = None, source: str = "exact") -> ForwardTable:
    """Build a `ForwardTable` of ``model``'s modes (0-based indices at ``reference_pa``).

    Parameters
    ----------
    model : assembled model; all its joints are random (one ``z`` each); moved to ``reference_pa``
        (`workbench.model.joints.model_at_moduli`), where ``z = 0``.
    modes : (n_modes,) mode indices, sorted order at the reference point.
    reference_pa : (n_joints,) ``Y0``, Pa.
    lower, upper : (n_joints,) range of ``z = log(Y / Y0)``.
    degree : Chebyshev degree per joint (default `TABLE_DEGREE`).
    source : "exact" (eigen-solutions, MAC-tracked) or "smr2" (Rayleigh quotient around Y0).
    """
    reference_pa = np.asarray(reference_pa, float)
    lower, upper = np.asarray(lower, float), np.asarray(upper, float)
    modes = np.asarray(modes, int)
    r = reference_pa.size
    if r not in (1, 2):
        raise ValueError(f"forward_table: {r} joints; the tabulated forward model handles 1 or 2")
    degree = degree if degree is not None else TABLE_DEGREE[r]
    n = degree + 1
    x = np.cos(np.pi * (np.arange(n) + 0.5) / n)  # Chebyshev-Gauss nodes: discrete orthogonality
    z_nodes = 0.5 * (upper + lower)[:, None] + 0.5 * (upper - lower)[:, None] * x[None, :]  # (r, n)
    grids = np.meshgrid(*z_nodes, indexing="ij")
    z = np.stack([g.ravel() for g in grids], axis=1)  # (n^r, r)
    f = frequencies_at(structure_at_moduli(model, reference_pa), modes, np.exp(z), source)
    t = _cheb(x, degree)  # (n, n): t[i, a] = T_a(x_i)
    scale = np.full(n, 2.0 / n)
    scale[0] = 1.0 / n
    project = t.T * scale[:, None]  # (a, i)
    values = f.reshape((n,) * r + (len(modes),))
    if r == 1:
        coef = project @ values
    else:
        coef = np.einsum("ai,bj,ijk->abk", project, project, values)
    return ForwardTable(reference_pa, lower, upper, coef, modes, source)

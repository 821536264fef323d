"""Minus the Hessian of the Laplace likelihood's log integrand, in the blocks its algebra takes.

`workbench.identify.laplace` integrates each test's latents ``x_t = (z_t, u_t)`` and the shared ones
``s`` (each mode's discrepancy ``delta_k``; with the sensitivity term each mode's ``eps_k``; with
tolerances the frame's manufacturing factors ``m``, `workbench.identify.members`). `hessian_blocks`
gives each test's block, its coupling to ``s`` and ``s``'s own block from the data, which
`workbench.identify.laplace_steps` solves; with ``exact`` the residual's curvature terms (the Laplace
determinant's), otherwise Gauss-Newton's (positive definite: Newton's direction).
"""

from __future__ import annotations

from typing import Protocol

import numpy as np

from workbench.identify.laplace_steps import Local

__all__ = ["Point", "hessian_blocks", "factor_hessian"]


class Point(Local, Protocol):
    """What the blocks read of the log integrand at a point (`workbench.identify.laplace._Local`): beside
    `workbench.identify.laplace_steps.Local`'s, the residuals ``res`` (N, T, K), ``lam`` (2 pi f /
    exp(u + delta))^2, ``d`` dlambda/dz (N, T, K, r), ``e`` the Gamma prior's curvature (N, T, r),
    ``factors`` dlambda/dm and its joints' part or None.
    """

    @property
    def res(self) -> np.ndarray: ...
    @property
    def lam(self) -> np.ndarray: ...
    @property
    def d(self) -> np.ndarray: ...
    @property
    def e(self) -> np.ndarray: ...
    @property
    def factors(self) -> tuple[np.ndarray, np.ndarray] | None: ...


def hessian_blocks(local: Point, w: np.ndarray, inv_u: np.ndarray | None, r: int, exact: bool
                   ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Minus the Hessian: each test's block (N, T, p, p), its coupling to the shared latents (N, T, S, p)
    and their own block from the data (N, S, S) (`workbench.identify.laplace_steps`). ``exact``: with the
    residual's curvature terms (the Laplace determinant's); otherwise Gauss-Newton's, positive definite
    (Newton's direction).
    """
    k = local.f.shape[-1]
    f, res, jz, share = local.f, local.res, local.jac[..., :r], local.share
    q = w * (f - res) if exact else w * f  # d2f/du2 = d2f/ddelta2 = d2f/du ddelta = f
    hess = np.swapaxes(jz * w[..., None], -1, -2) @ jz + local.e[..., None] * np.eye(r)
    if exact:  # d2f/dz_i dz_j = delta_ij df_j - df_i d_j / (2 lambda), lambda = (2 pi f / exp(u + delta))^2
        wr = w * res
        hess = hess + np.swapaxes(jz * (wr / (2.0 * local.lam))[..., None], -1, -2) @ local.d
        hess = hess - (wr[..., None, :] @ jz)[..., 0, :][..., None] * np.eye(r)
    if inv_u is not None:
        h_zu = np.sum(q[..., None] * jz, axis=-2)  # (N, T, r)
        h_uu = np.sum(q * f, axis=-1) + inv_u  # (N, T)
        hess = np.concatenate([np.concatenate([hess, h_zu[..., None]], axis=-1),
                               np.concatenate([h_zu, h_uu[..., None]], axis=-1)[..., None, :]], axis=-2)
    coupling = q[..., None] * local.jac  # (N, T, K, p); then eps's: d2f/deps dz = df/dz (1 - share),
    if share is not None:  # d2f/deps du = f share
        on_z = w * (f * share - res * (1.0 - share)) if exact else w * f * share
        on_u = q * share
        eps = local.jac * np.concatenate([np.broadcast_to(on_z[..., None], jz.shape), on_u[..., None]], axis=-1)[
            ..., :local.jac.shape[-1]]
        coupling = np.concatenate([coupling, eps], axis=-2)
    s = coupling.shape[-2]
    block = np.zeros((f.shape[0], s, s))
    diag = np.arange(k)
    block[:, diag, diag] = np.sum(q * f, axis=1)
    if share is not None:  # d2f/ddelta deps = f share; d2f/deps2 = f (share - share^2)
        block[:, diag, k + diag] = block[:, k + diag, diag] = np.sum(q * f * share, axis=1)
        curvature = w * f * f * share * share - (w * res * f * (share - share * share) if exact else 0.0)
        block[:, k + diag, k + diag] = np.sum(curvature, axis=1)
    if local.factors is not None:
        coupling, block = factor_hessian(local, local.factors, w, q, coupling, block, r, exact)
    return hess, coupling, block


def factor_hessian(local: Point, factors: tuple[np.ndarray, np.ndarray], w: np.ndarray, q: np.ndarray,
                   coupling: np.ndarray, block: np.ndarray, r: int, exact: bool) -> tuple[np.ndarray, np.ndarray]:
    """Minus the Hessian's rows of the factors ``m`` appended to the shared latents' (after delta):
    ``coupling`` (N, T, S, p) and ``block`` (N, S, S) of `hessian_blocks` grown to S + P. ``local``'s
    ``design`` holds ``df/dm`` in its last P columns; ``factors`` is ``local.factors``; ``w`` the data
    weights (N, T, K), ``q`` delta's curvature weights (``w (f - res)`` exact, ``w f`` otherwise).

    With ``a, b`` any two of ``z`` and ``m``,
    ``d2f/da db = f lambda_ab / (2 lambda) - f lambda_a lambda_b / (4 lambda^2)``; ``lambda`` is linear
    in ``m`` (``lambda_mm = 0``), ``lambda_{z_j m} = D_j exp(z_j - zbar_j)``, and ``d2f/dm ddelta =
    d2f/dm du = df/dm``. ``exact`` adds the residual's curvature (the Laplace determinant's); otherwise
    Gauss-Newton's.
    """
    gm, dm = factors
    f, lam = local.f, local.lam
    s0 = block.shape[-1]
    vm = local.design[..., s0:]  # (N, T, K, P)
    wv = w[..., None] * vm
    c_m = np.swapaxes(wv, -1, -2) @ local.jac  # (N, T, P, p)
    mm = np.einsum("ntkp,ntkq->npq", wv, vm)
    if exact:
        wr = w * local.res
        a, b = f / (2.0 * lam), f / (4.0 * lam * lam)
        d2 = a[..., None, None] * dm - b[..., None, None] * local.d[..., :, None] * gm[..., None, :]  # (N, T, K, r, P)
        c_m[..., :r] -= np.einsum("ntk,ntkrp->ntpr", wr, d2)
        if local.jac.shape[-1] > r:  # the common error u
            c_m[..., r] -= np.einsum("ntk,ntkp->ntp", wr, vm)
        mm = mm + np.einsum("ntk,ntkp,ntkq->npq", wr * b, gm, gm)
    k, p = q.shape[-1], vm.shape[-1]
    grown = np.zeros(block.shape[:1] + (s0 + p, s0 + p))
    grown[:, :s0, :s0] = block
    grown[:, s0:, s0:] = mm
    grown[:, :k, s0:] = np.einsum("ntk,ntkp->nkp", q, vm)
    grown[:, s0:, :k] = np.swapaxes(grown[:, :k, s0:], -1, -2)
    return np.concatenate([coupling, c_m], axis=-2), grown

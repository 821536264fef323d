"""The linear algebra of the Laplace likelihood's block-arrow system (`workbench.identify.laplace`).

Minus the Hessian of the log integrand in every test's latents ``x_t = (z_t, u_t)`` (p each) and the
shared latents ``s`` (S: each mode's discrepancy shift ``delta_k``, with the sensitivity term each
mode's ``eps_k``, with tolerances the manufacturing factors ``m``) is block-arrow: each test's block
``H_t`` (p x p) couples only to ``s``, through ``C_t`` (S x p); ``s``'s own block is ``B`` (S x S, from
the data) plus the prior's diagonal ``D``. So Newton's step and the Laplace determinant need the tests'
small solves and one S x S Schur complement ``S = B + D - sum_t C_t H_t^-1 C_t^T``
(`workbench.identify.laplace_hessian` builds the blocks).
"""

from __future__ import annotations

from typing import Protocol

import numpy as np

__all__ = ["Local", "shared_design", "gauss_newton_step", "direct_step", "schur", "over_tests"]


class Local(Protocol):
    """What the steps read of the log integrand at a point (`workbench.identify.laplace._Local`): model
    frequencies ``f`` (N, T, K), ``jac`` df/dx_t (N, T, K, p), ascent directions ``grad`` (N, T, p) in
    ``x_t`` and ``grad_d`` (N, S) in ``s``, ``share`` dlog f / deps_k (N, T, K) or None, ``design`` df/ds (N, T, K, S).
    """

    @property
    def f(self) -> np.ndarray: ...
    @property
    def jac(self) -> np.ndarray: ...
    @property
    def grad(self) -> np.ndarray: ...
    @property
    def grad_d(self) -> np.ndarray: ...
    @property
    def share(self) -> np.ndarray | None: ...
    @property
    def design(self) -> np.ndarray: ...


def shared_design(f: np.ndarray, share: np.ndarray | None) -> np.ndarray:
    """``df_tk / ds`` (N, T, K, S): ``f`` on delta's diagonal, ``f share`` on eps's."""
    k = f.shape[-1]
    columns = [f] if share is None else [f, f * share]
    return np.concatenate([c[..., None] * np.eye(k) for c in columns], axis=-1)


def gauss_newton_step(local: Local, w: np.ndarray, diagonal: np.ndarray, inv_d: np.ndarray | None
                      ) -> tuple[np.ndarray, np.ndarray]:
    """Gauss-Newton's step ``H^-1 grad`` in every test's ``x_t`` (N, T, p) and in ``s`` (N, S), when
    each test's data (rank K) are fewer than its latents p.

    Each test's block ``H_t = G_t^T G_t + D_t`` (``G_t = W_t^(1/2) J_t``, K x p, ``D_t`` the priors'
    ``diagonal`` (N, T, p)) is inverted by Woodbury through its K x K capacitance
    ``C_t = I + G_t D_t^-1 G_t^T``: a 20-joint frame (p = 21, K = 10) solves 10 x 10 systems. With
    ``V_t = W_t^(1/2) df_t/ds`` (K x S) the same algebra gives ``s``'s Schur complement
    ``S = D_s + sum_t V_t^T C_t^-1 V_t`` and

        step_s = S^-1 (grad_s - sum_t V_t^T C_t^-1 Gd_t grad_t),
        step_t = grad_t / D_t - Gd_t^T C_t^-1 (Gd_t grad_t + V_t step_s),   Gd_t = G_t D_t^-1.

    Woodbury's form with ``I +`` (not ``W^-1 +``) keeps a mode a test lacks (``w = 0``) harmless.
    """
    root_w = np.sqrt(w)
    g = root_w[..., None] * local.jac[..., :diagonal.shape[-1]]  # (N, T, K, p)
    gd = g / diagonal[..., None, :]
    k = g.shape[-2]
    c_inv = np.linalg.inv(np.eye(k) + gd @ np.swapaxes(g, -1, -2))  # (N, T, K, K)
    y = (c_inv @ (gd @ local.grad[..., None]))[..., 0]  # C^-1 Gd grad, (N, T, K)
    if inv_d is None:
        step_d = np.zeros(local.grad_d.shape)
    else:
        v = root_w[..., None] * local.design  # (N, T, K, S)
        c_v = c_inv @ v
        matrix = over_tests(np.swapaxes(v, -1, -2), c_v) + inv_d[..., None] * np.eye(inv_d.shape[-1])
        rhs = local.grad_d - over_tests(np.swapaxes(v, -1, -2), y[..., None])[..., 0]
        step_d = np.linalg.solve(matrix, rhs[..., None])[..., 0]
        y = y + (c_v @ step_d[:, None, :, None])[..., 0]
    step = local.grad / diagonal - (np.swapaxes(gd, -1, -2) @ y[..., None])[..., 0]
    return step, step_d


def direct_step(local: Local, hess: np.ndarray, coupling: np.ndarray, block: np.ndarray, inv_d: np.ndarray | None
                ) -> tuple[np.ndarray, np.ndarray]:
    """Newton's step ``H^-1 grad`` of the block-arrow system (module docstring) with each test's block
    ``hess`` (N, T, p, p) solved directly: the step in ``x_t`` (N, T, p) and in ``s`` (N, S).
    ``coupling`` (N, T, S, p) and ``block`` (N, S, S) as `workbench.identify.laplace_hessian.hessian_blocks`.
    """
    if inv_d is None:
        return np.linalg.solve(hess, local.grad[..., None])[..., 0], np.zeros(local.grad_d.shape)
    s = coupling.shape[-2]
    solved = np.linalg.solve(hess, np.concatenate([np.swapaxes(coupling, -1, -2), local.grad[..., None]], axis=-1))
    matrix = schur(block, inv_d, coupling, solved[..., :s])
    reduced = local.grad_d - over_tests(coupling, solved[..., s:])[..., 0]
    step_d = np.linalg.solve(matrix, reduced[..., None])
    step = solved[..., s] - (solved[..., :s] @ step_d[:, None])[..., 0]
    return step, step_d[..., 0]


def schur(block: np.ndarray, inv_d: np.ndarray, coupling: np.ndarray, solved: np.ndarray) -> np.ndarray:
    """``S = B + D - sum_t C_t H_t^-1 C_t^T`` (N, S, S): ``block`` B, the prior's precisions ``inv_d``
    (N, S) on the diagonal, and ``solved`` = ``H_t^-1 C_t^T`` (N, T, p, S).
    """
    return block + inv_d[..., None] * np.eye(inv_d.shape[-1]) - over_tests(coupling, solved)


def over_tests(coupling: np.ndarray, right: np.ndarray) -> np.ndarray:
    """``sum_t C_t X_t`` (N, S, L) of ``coupling`` (N, T, S, p) and ``right`` (N, T, p, L): one batched
    product over the tests' stacked rows (an einsum here took a fifth of the likelihood's time).
    """
    n, t, s, p = coupling.shape
    return coupling.transpose(0, 2, 1, 3).reshape(n, s, t * p) @ right.reshape(n, t * p, right.shape[-1])

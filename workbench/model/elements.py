"""Planar frame element matrices: Euler-Bernoulli and Timoshenko, consistent mass, geometric stiffness.

Pure functions over arrays of elements (shape ``(e,)`` in, ``(e, 6, 6)`` out). Local dofs per
element are ``(u1, v1, theta1, u2, v2, theta2)``: axial, transverse, rotation at each end.

References
----------
Przemieniecki, *Theory of Matrix Structural Analysis* (1968), ch. 5 and 11 (stiffness, mass).
Friedman & Kosmatka, "An improved two-node Timoshenko beam finite element", Computers &
Structures 47 (1993) 473-481 (Timoshenko stiffness, translational and rotary consistent mass).
"""

from __future__ import annotations

import numpy as np

__all__ = ["shear_parameter", "stiffness_local", "mass_local", "geometric_local", "string_local", "rotation",
           "to_global"]

_AXIAL = np.array([0, 3])
_BENDING = np.array([1, 2, 4, 5])


def shear_parameter(length: np.ndarray, second_moment: np.ndarray, area: np.ndarray,
                    shear_coefficient: np.ndarray, poisson_ratio: np.ndarray) -> np.ndarray:
    """Timoshenko shear parameter ``Phi = 12 E I / (kappa G A L^2)`` with ``G = E / (2 (1 + nu))``.

    It does not depend on E, which is why a Timoshenko joint zone whose shear modulus scales with
    its Young's modulus keeps the stiffness linear in that modulus (paper eq. 3-4).
    """
    return 24.0 * (1.0 + poisson_ratio) * second_moment / (shear_coefficient * area * length**2)


def _scatter(n: int, axial: np.ndarray | None, bending: np.ndarray) -> np.ndarray:
    """Place the (e, 2, 2) axial and (e, 4, 4) bending blocks in (e, 6, 6) element matrices."""
    out = np.zeros((n, 6, 6))
    if axial is not None:
        out[:, _AXIAL[:, None], _AXIAL[None, :]] = axial
    out[:, _BENDING[:, None], _BENDING[None, :]] = bending
    return out


def stiffness_local(length: np.ndarray, youngs_modulus: np.ndarray, area: np.ndarray,
                    second_moment: np.ndarray, phi: np.ndarray | float = 0.0) -> np.ndarray:
    """Element stiffness in local axes, N/m, shape ``(e, 6, 6)``.

    ``phi = 0`` gives Euler-Bernoulli bending; ``phi > 0`` the Timoshenko element, exact for static
    end loads (Przemieniecki 1968, eq. 5.116).
    """
    L = np.asarray(length, float)
    phi = np.broadcast_to(np.asarray(phi, float), L.shape)
    ea = youngs_modulus * area / L
    axial = ea[:, None, None] * np.array([[1.0, -1.0], [-1.0, 1.0]])
    c = youngs_modulus * second_moment / ((1.0 + phi) * L**3)
    z = np.zeros_like(L)
    L2 = L * L
    bending = c[:, None, None] * np.stack([
        np.stack([12.0 + z, 6 * L, -12.0 + z, 6 * L], -1),
        np.stack([6 * L, (4 + phi) * L2, -6 * L, (2 - phi) * L2], -1),
        np.stack([-12.0 + z, -6 * L, 12.0 + z, -6 * L], -1),
        np.stack([6 * L, (2 - phi) * L2, -6 * L, (4 + phi) * L2], -1),
    ], -2)
    return _scatter(L.size, axial, bending)


def mass_local(length: np.ndarray, density: np.ndarray, area: np.ndarray, second_moment: np.ndarray,
               phi: np.ndarray | float = 0.0, rotary_inertia: bool = False) -> np.ndarray:
    """Consistent element mass in local axes, kg, shape ``(e, 6, 6)``.

    Translational inertia for ``phi = 0`` is the cubic-Hermite (Euler-Bernoulli) matrix; for
    ``phi > 0`` and with ``rotary_inertia`` the Friedman-Kosmatka (1993) Timoshenko matrices.
    """
    L = np.asarray(length, float)
    phi = np.broadcast_to(np.asarray(phi, float), L.shape)
    rho_a = density * area
    axial = (rho_a * L / 6.0)[:, None, None] * np.array([[2.0, 1.0], [1.0, 2.0]])
    p, p2, L2 = phi, phi * phi, L * L
    a = rho_a * L / (210.0 * (1.0 + p) ** 2)
    m11 = 70 * p2 + 147 * p + 78
    m12 = (35 * p2 + 77 * p + 44) * L / 4
    m13 = 35 * p2 + 63 * p + 27
    m14 = -(35 * p2 + 63 * p + 26) * L / 4
    m22 = (7 * p2 + 14 * p + 8) * L2 / 4
    m24 = -(7 * p2 + 14 * p + 6) * L2 / 4
    bending = a[:, None, None] * np.stack([
        np.stack([m11, m12, m13, m14], -1),
        np.stack([m12, m22, -m14, m24], -1),
        np.stack([m13, -m14, m11, -m12], -1),
        np.stack([m14, m24, -m12, m22], -1),
    ], -2)
    if rotary_inertia:
        b = density * second_moment / (30.0 * (1.0 + p) ** 2 * L)
        r12 = -(15 * p - 3) * L
        r22 = (10 * p2 + 5 * p + 4) * L2
        r24 = (5 * p2 - 5 * p - 1) * L2
        t = 36.0 + np.zeros_like(L)
        bending = bending + b[:, None, None] * np.stack([
            np.stack([t, r12, -t, r12], -1),
            np.stack([r12, r22, -r12, r24], -1),
            np.stack([-t, -r12, t, -r12], -1),
            np.stack([r12, r24, -r12, r22], -1),
        ], -2)
    return _scatter(L.size, axial, bending)


def geometric_local(length: np.ndarray, axial_force: np.ndarray) -> np.ndarray:
    """Geometric stiffness of an axial force ``N`` (tension positive), N/m, shape ``(e, 6, 6)``.

    The consistent cubic-Hermite matrix ``N / (30 L) [36, 3L, -36, 3L; ...]`` on the transverse
    dofs; used for both beam theories (the Timoshenko correction is of order ``phi * N / (EA)``).
    """
    L = np.asarray(length, float)
    N = np.broadcast_to(np.asarray(axial_force, float), L.shape)
    z = np.zeros_like(L)
    L2 = L * L
    bending = (N / (30.0 * L))[:, None, None] * np.stack([
        np.stack([36.0 + z, 3 * L, -36.0 + z, 3 * L], -1),
        np.stack([3 * L, 4 * L2, -3 * L, -L2], -1),
        np.stack([-36.0 + z, -3 * L, 36.0 + z, -3 * L], -1),
        np.stack([3 * L, -L2, -3 * L, 4 * L2], -1),
    ], -2)
    return _scatter(L.size, None, bending)


def string_local(length: np.ndarray, axial_force: np.ndarray) -> np.ndarray:
    """Geometric stiffness of a straight bar (a string) between two nodes: what a force along its chord does
    when the chord turns.

    Parameters
    ----------
    length : (e,) chord lengths, m.
    axial_force : (e,) forces, N, tension positive.

    Returns
    -------
    (e, 6, 6) local matrices, N/m: ``N / L [1, -1; -1, 1]`` on the transverse dofs (v1, v2), zero elsewhere.
    """
    L = np.asarray(length, float)
    N = np.broadcast_to(np.asarray(axial_force, float), L.shape)
    out = np.zeros((L.size, 6, 6))
    for a, b, sign in ((1, 1, 1.0), (4, 4, 1.0), (1, 4, -1.0), (4, 1, -1.0)):
        out[:, a, b] = sign * N / L
    return out


def rotation(cos: np.ndarray, sin: np.ndarray) -> np.ndarray:
    """Transformation ``T`` (e, 6, 6) with ``u_local = T @ u_global`` for dofs (ux, uy, rz) per end."""
    c, s = np.asarray(cos, float), np.asarray(sin, float)
    t = np.zeros((c.size, 6, 6))
    for k in (0, 3):
        t[:, k, k] = c
        t[:, k, k + 1] = s
        t[:, k + 1, k] = -s
        t[:, k + 1, k + 1] = c
        t[:, k + 2, k + 2] = 1.0
    return t


def to_global(local: np.ndarray, t: np.ndarray) -> np.ndarray:
    """``T^T A T`` for each element: a local matrix in global axes."""
    return np.einsum("eji,ejk,ekl->eil", t, local, t, optimize=True)

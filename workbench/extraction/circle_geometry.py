"""Circle through complex points (the Nyquist plot of one mode's mobility, `circlefit`): an algebraic
start (Taubin's fit, in Chernov's SVD form) refined by geometric least squares on the radial
distances; the angle swept along it by one viscous mode and its derivatives (`sweep_angle`,
`sweep_gradient`); and the exact viscous damping from two points' angles on it (`pair_damping`).
"""

from __future__ import annotations

import numpy as np

from workbench.extraction.levenberg import lm

__all__ = ["MIN_SIDE_POINTS", "PAIR_ANGLES_DEG", "LOG_ZETA_BOUNDS", "taubin", "geometric", "pair_damping", "pairs",
           "mobility_factor", "wrap_angle", "sweep_angle", "sweep_gradient", "clip_log_zeta", "trend_basis"]

MIN_SIDE_POINTS = 2      # points each side of resonance for the damping pairs
PAIR_ANGLES_DEG = (90.0, 135.0, 160.0)  # half-power region first, widened if too few points
LOG_ZETA_BOUNDS = (-30.0, 5.0)  # log zeta in the fits' models: a wandering damping is a failed start, not an answer


def taubin(z: np.ndarray) -> tuple[complex, float]:
    """Algebraic circle fit (Taubin, in Chernov's SVD form) of complex points ``z``."""
    m = z.mean()
    x, y = z.real - m.real, z.imag - m.imag
    zz = x * x + y * y
    zm = zz.mean()
    if zm == 0.0:
        return m, 0.0
    z0 = (zz - zm) / (2.0 * np.sqrt(zm))
    _, _, vt = np.linalg.svd(np.column_stack([z0, x, y]), full_matrices=False)
    a = vt[2].copy()
    a0 = a[0] / (2.0 * np.sqrt(zm))
    a3 = -zm * a0
    if a0 == 0.0:  # points on a line: an "infinite" circle; start from the centroid instead
        return m, float(np.sqrt(zm))
    centre = complex(-a[1] / (2 * a0), -a[2] / (2 * a0)) + m
    radius = float(np.sqrt(max(a[1] ** 2 + a[2] ** 2 - 4 * a0 * a3, 0.0)) / (2 * abs(a0)))
    return centre, radius


def geometric(z: np.ndarray, centre: complex, radius: float) -> tuple[complex, float]:
    """Geometric least squares on the radial distances, in scaled coordinates."""
    scale = max(radius, float(np.abs(z - z.mean()).max()), np.finfo(float).tiny)
    w = (z - centre) / scale

    def residual(p):
        return np.hypot(w.real - p[0], w.imag - p[1]) - p[2]

    def jac(p):
        d = np.maximum(np.hypot(w.real - p[0], w.imag - p[1]), 1e-300)
        return np.column_stack([-(w.real - p[0]) / d, -(w.imag - p[1]) / d, -np.ones_like(d)])

    sol = lm(residual, [0.0, 0.0, radius / scale], jac, xtol=1e-14, ftol=1e-14)
    return centre + scale * complex(sol.x[0], sol.x[1]), float(abs(sol.x[2]) * scale)


def pair_damping(omega_a, theta_a, omega_b, theta_b, omega_r: float) -> np.ndarray:
    """Exact viscous damping ratio from a point above (a) and below (b) resonance on the mobility
    circle of one mode; angles (rad) from the resonance point, seen from the circle's centre.

    ``zeta = [(w_a^2 - w_r^2)/w_a + (w_r^2 - w_b^2)/w_b] / (2 w_r (tan(theta_a/2) + tan(theta_b/2)))``;
    to first order in the offsets it is Ewins' ``(w_a - w_b) / (w_r (tan(theta_a/2) +
    tan(theta_b/2)))``. Arguments broadcast; circular frequencies in rad/s.
    """
    omega_a, omega_b = np.asarray(omega_a, float), np.asarray(omega_b, float)
    numerator = (omega_a**2 - omega_r**2) / omega_a + (omega_r**2 - omega_b**2) / omega_b
    return numerator / (2.0 * omega_r * (np.tan(np.asarray(theta_a) / 2) + np.tan(np.asarray(theta_b) / 2)))


def pairs(omega, psi, omega_r, sense):
    """Pairwise damping estimates from points within the half-power region, widened if needed."""
    above = (omega > omega_r) & (sense * psi < 0.0)   # above resonance the angle runs on
    below = (omega < omega_r) & (sense * psi > 0.0)
    theta = np.abs(psi)
    for limit in np.radians(PAIR_ANGLES_DEG):
        a = above & (theta <= limit)
        b = below & (theta <= limit)
        if a.sum() >= MIN_SIDE_POINTS and b.sum() >= MIN_SIDE_POINTS:
            break
    if a.sum() == 0 or b.sum() == 0:
        return np.array([]), 0, 0
    z = pair_damping(omega[a][:, None], theta[a][:, None], omega[b][None, :], theta[b][None, :], omega_r)
    return z.ravel(), int(a.sum()), int(b.sum())


def wrap_angle(angle: np.ndarray) -> np.ndarray:
    """Angles (rad) brought into [-pi, pi)."""
    return (angle + np.pi) % (2.0 * np.pi) - np.pi


def sweep_angle(omega, phi0: float, omega_r: float, zeta: float, sense: float):
    """Angle (rad) seen from the circle's centre of the point at ``omega`` (rad/s) of one viscous
    mode (``omega_r`` rad/s, ``zeta``), ``phi0`` at resonance; ``sense`` +1 for a clockwise sweep.
    """
    x = (omega**2 - omega_r**2) / (2.0 * zeta * omega_r * omega)
    return phi0 - sense * 2.0 * np.arctan(x)


def mobility_factor(quantity: str, omega: float) -> float:
    """What turns a level of ``quantity`` at ``omega`` (rad/s) into mobility: ``omega``, 1 or ``1 / omega``."""
    return {"receptance": omega, "mobility": 1.0, "accelerance": 1.0 / omega}[quantity]


def trend_basis(omega: np.ndarray, omega_ref: float) -> np.ndarray:
    """Mobility residual shapes ``i w``, ``-i / w``, ``i w^3 / w_ref^2`` (receptance ``U``,
    ``-L / w^2``, ``U_2 w^2``), shape (n, 3).
    """
    return np.column_stack([1j * omega, -1j / omega, 1j * omega**3 / omega_ref**2])


def clip_log_zeta(log_zeta: float) -> float:
    """``log zeta`` kept within `LOG_ZETA_BOUNDS`: ``np.clip`` of one number, but ten times quicker (it runs at
    every residual evaluation).
    """
    return min(max(log_zeta, LOG_ZETA_BOUNDS[0]), LOG_ZETA_BOUNDS[1])


def sweep_gradient(omega: np.ndarray, phi0: float, ratio: float, log_zeta: float, w0: float,
                    sense: float) -> np.ndarray:
    """Derivatives of `sweep_angle` with ``omega_r = ratio * w0``, ``zeta = exp(log_zeta)`` (clipped
    as in the fits: zero outside the clip) with respect to (phi0, ratio, log_zeta), shape (n, 3).
    Written out because finite differences were two thirds of a campaign's circle-fit time.
    """
    inside = LOG_ZETA_BOUNDS[0] < log_zeta < LOG_ZETA_BOUNDS[1]
    zeta = np.exp(clip_log_zeta(log_zeta))
    omega_r = ratio * w0
    x = (omega**2 - omega_r**2) / (2.0 * zeta * omega_r * omega)
    d_angle = -sense * 2.0 / (1.0 + x**2)               # d model / d x
    dx_domega_r = -omega / (2.0 * zeta * omega_r**2) - 1.0 / (2.0 * zeta * omega)
    out = np.empty((omega.size, 3))  # filled in place: np.column_stack cost as much as the columns
    out[:, 0] = 1.0
    out[:, 1] = d_angle * dx_domega_r * w0
    out[:, 2] = d_angle * -x * inside
    return out

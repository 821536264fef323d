"""Circle through complex points (the Nyquist plot of one mode's mobility, `circlefit`): an algebraic
start (Taubin's fit, in Chernov's SVD form) refined by geometric least squares on the radial
distances; the angle swept along it by one viscous mode and its derivatives (`sweep_angle`,
`sweep_gradient`), and its least-squares fit to the points' angles (`fit_sweep`); and the exact viscous damping
from two points' angles on it (`pair_damping`).
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from workbench.extraction.levenberg import LMResult, lm

__all__ = ["MIN_SIDE_POINTS", "PAIR_ANGLES_DEG", "LOG_ZETA_BOUNDS", "taubin", "geometric", "pair_damping", "pairs",
           "mobility_factor", "wrap_angle", "sweep_angle", "sweep_gradient", "clip_log_zeta", "trend_basis",
           "SENSE_RETRY", "SETTLED_RMS", "fit_sweep", "angle_rms"]

MIN_SIDE_POINTS = 2      # points each side of resonance for the damping pairs
PAIR_ANGLES_DEG = (90.0, 135.0, 160.0)  # half-power region first, widened if too few points
SENSE_RETRY = 0.3  # rad RMS angle misfit above which the anticlockwise sweep is tried too (`fit_sweep`)
SETTLED_RMS = 0.1  # rad RMS: a sweep fit this close to the angles has found its mode; other starts are not tried
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


def fit_sweep(omega: np.ndarray, phi: np.ndarray,
              peak_start: Callable[[], tuple[float, float, float, float] | None] | None = None,
              ) -> tuple[float, float, float, float]:
    """Natural frequency, damping and diameter angle from the angles ``phi`` (rad) of the points
    seen from the centre: start where the sweep is fastest, then least squares on the exact
    one-mode angle model. Returns (phi0, omega_r, zeta, sense): ``sense`` +1 for a clockwise sweep
    (exp(+i omega t)), -1 for data in the other convention, tried when the clockwise fit misses the
    angles by more than `SENSE_RETRY` rad RMS (the direction cannot be read off the data: a mode
    resolved by one or two lines steps by nearly pi).

    Before the other sense, ``peak_start()`` (`workbench.extraction.circlefit`: the start the peak's magnitudes
    give, or None) is tried: a mode a third or half a line wide can turn by more than pi between the
    two lines at its peak, and the wrapped steps then put the fastest rate, so every start read off
    the steps, on the wrong line (the fit ended 2 Hz away, flagged ``edge_of_band``, in 45 % of such
    fits: ``tests/test_circlefit.py``). Fits the steps' starts already fit are left as they were.
    """
    step = wrap_angle(np.diff(phi))
    mid = 0.5 * (omega[1:] + omega[:-1])
    best, best_sense, scale = None, 1.0, 1.0

    def attempt(phi0: float, w0: float, z0: float, sense: float) -> None:
        nonlocal best, best_sense, scale

        def residual(p):
            return wrap_angle(phi - sweep_angle(omega, p[0], p[1] * w0, np.exp(clip_log_zeta(p[2])), sense))

        def jacobian(p):
            return -sweep_gradient(omega, p[0], p[1], p[2], w0, sense)

        sol = lm(residual, [phi0, 1.0, np.log(z0)], jacobian, xtol=1e-15, ftol=1e-15)
        if best is None or sol.cost < best.cost:
            best, best_sense, scale = sol, sense, w0

    for sense in (1.0, -1.0):
        if best is not None and angle_rms(best, phi) < SENSE_RETRY:
            break  # the contract's clockwise sweep fits: no need to try the other way
        rate = -sense * step / np.diff(omega)
        k = int(np.argmax(rate))
        w0 = mid[k]
        if 0 < k < rate.size - 1:  # vertex of the parabola through the three fastest rates
            c = np.polyfit(mid[k - 1:k + 2], rate[k - 1:k + 2], 2)
            if c[0] < 0.0:
                w0 = float(np.clip(-c[1] / (2 * c[0]), mid[k - 1], mid[k + 1]))
        zeta0 = float(np.clip(2.0 / (w0 * max(float(rate[k]), 1e-300)), 1e-6, 0.5))
        phi0 = float(phi[k] - sense * step[k] / 2)
        for z0 in (zeta0, zeta0 / 3.0, zeta0 * 3.0):
            attempt(phi0, w0, z0, sense)
            if best is not None and angle_rms(best, phi) < SETTLED_RMS:
                break
        assert best is not None  # one start at least ran
        if sense > 0 and peak_start is not None and angle_rms(best, phi) >= SENSE_RETRY:
            start = peak_start()
            if start is not None:
                attempt(start[0], start[1], start[2], start[3])
    assert best is not None
    zeta = float(np.exp(clip_log_zeta(best.x[2])))
    # a negative omega_r is the same angle model swept the other way: keep omega_r positive
    flip = 1.0 if best.x[1] >= 0.0 else -1.0
    return float(best.x[0]), float(flip * best.x[1] * scale), zeta, flip * best_sense


def angle_rms(fit: LMResult, phi: np.ndarray) -> float:
    """RMS angle misfit (rad) of a sweep fit over the angles ``phi``."""
    return float(np.sqrt(2.0 * fit.cost / phi.size))

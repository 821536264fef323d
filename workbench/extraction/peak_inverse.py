"""A mode the circle's angles cannot resolve: natural frequency and damping from the magnitudes at its peak.

When the half-power bandwidth ``2 zeta f_r`` is under about a line spacing, all but the peak line sit near the
far end of the mobility circle, and the circle's angle model fits them about as well with a damping of zero
and the pole on the peak line: the sweep's least squares slides down a flat valley (damping 1e-11, frequency
on the line to 1e-10 Hz) and stops where rounding stops it, so two processes whose memory is laid out
differently stop at different points. The magnitudes still tell the mode: for one viscous mode the mobility
``Y = D / (1 + i x)``, ``x = (w^2 - w_r^2) / (2 zeta w_r w)``, gives exactly

    g(w) = w^2 / |Y|^2 = (w^2 + (w^2 - w_r^2)^2 / (4 zeta^2 w_r^2)) / |D|^2,

a parabola in ``s = w^2`` (the inverse-FRF idea of Dobson, 1987, written for the mobility's exact form). It is
fitted by weighted least squares through the peak line and up to two lines either side, and gives ``w_r``,
``zeta`` and ``|D|`` in closed form, with no valley to wander in. Written here because no library fits this
form; it is a small linear solve.
"""

from __future__ import annotations

import numpy as np

from workbench.extraction.circle_geometry import sweep_angle

__all__ = ["UNRESOLVED_LINES", "SIDE_LINES", "peak_inverse", "unresolved_peak", "peak_phase"]

UNRESOLVED_LINES = 0.1  # a circle fit narrower than this many line spacings has collapsed onto a line
SIDE_LINES = 2  # lines each side of the peak in the parabola: nearest the peak, the least touched by neighbours


def _solve(omega: np.ndarray, magnitude: np.ndarray, weight: np.ndarray) -> tuple[float, float, float] | None:
    """``(omega_r, zeta, chi2)`` of the weighted parabola in ``w^2`` through the lines; None where it is not one
    mode's. ``weight``: the inverse variances of ``g = w^2 / |Y|^2``.
    """
    s = omega**2
    k = int(np.argmax(magnitude))
    s0, scale = s[k], (s[-1] - s[0]) / (s.size - 1)
    t = (s - s0) / scale  # centred on the peak, a line about 1 apart: the solve is well conditioned
    g = s / magnitude**2
    root_w = np.sqrt(weight)
    (a, b, c), *_ = np.linalg.lstsq(np.vander(t, 3) * root_w[:, None], g * root_w, rcond=None)
    if not (a > 0.0 and np.isfinite(a)):
        return None
    # g = u s + A (s - s_r)^2 with s = s0 + scale t, s_r = s0 + scale tau, A = a / scale^2:
    # a tau^2 + p tau + q = 0, its small root in the stable form
    p, q = 2.0 * a * s0 / scale, b * s0 / scale - c
    root = p * p - 4.0 * a * q
    if root < 0.0:
        return None
    tau = -2.0 * q / (p + np.sqrt(root))
    u = (b + 2.0 * a * tau) / scale  # 1 / |D|^2
    s_r = s0 + scale * tau
    if not (u > 0.0 and s[0] <= s_r <= s[-1]):
        return None
    chi2 = float(np.sum(weight * (g - np.vander(t, 3) @ [a, b, c]) ** 2))
    return float(np.sqrt(s_r)), float(np.sqrt(u * scale**2 / (4.0 * s_r * a))), chi2


def peak_inverse(omega: np.ndarray, data: np.ndarray, noise: float) -> tuple[float, float, float, float] | None:
    """Natural frequency and damping of a mode narrower than the line spacing, from the magnitudes at its peak.

    Parameters
    ----------
    omega : (n,) rad/s, the band's lines, increasing.
    data : (n,) complex mobility on them.
    noise : RMS of the curve's complex noise (``E|n|^2``), mobility units: each magnitude's sd is
        ``noise / sqrt(2)``.

    Returns
    -------
    ``(omega_r, zeta, sd_omega, sd_log_zeta)``: rad/s, the viscous damping ratio, and their standard deviations
    from the magnitudes' noise (first order), times the Birge ratio ``sqrt(chi^2 / dof)`` where the lines miss
    one mode's form by more than their noise (a neighbour's residual, a distortion); None when the highest line
    is at the band's end, or the lines are not one mode's peak (no parabola opening upward with its vertex
    among them).
    """
    k = int(np.argmax(np.abs(data)))
    if not 0 < k < data.size - 1:
        return None
    lines = slice(max(k - SIDE_LINES, 0), min(k + SIDE_LINES + 1, data.size))
    w, m = omega[lines], np.abs(data[lines])
    if not np.all(np.isfinite(m) & (m > 0.0)):
        return None
    # var g = (dg/dm)^2 var m, g = w^2 / m^2: the weights relative to the largest, so that a curve whose noise
    # level is nil (a noise-free or zero-padded record) neither overflows them nor divides by it
    weight = (m**3 / (2.0 * w**2)) ** 2
    largest = float(weight.max())
    weight = weight / largest
    found = _solve(w, m, weight)
    if found is None:
        return None
    jac = np.empty((2, m.size))
    for i in range(m.size):  # central differences: the closed form is smooth wherever it is defined
        step = np.zeros(m.size)
        step[i] = 1e-4 * m[i]
        up, down = _solve(w, m + step, weight), _solve(w, m - step, weight)
        if up is None or down is None:
            return None
        jac[:, i] = [(up[0] - down[0]) / (2 * step[i]), (np.log(up[1]) - np.log(down[1])) / (2 * step[i])]
    # the magnitudes' sd: the noise's, or what the lines' misfit to one mode's form says when larger (the noise
    # times the Birge ratio sqrt(chi^2 / dof))
    misfit = float(np.sqrt(largest * found[2] / (m.size - 3))) if m.size > 3 else 0.0
    spread = np.sqrt((jac**2).sum(axis=1)) * max(noise / np.sqrt(2.0), misfit)
    return found[0], found[1], float(spread[0]), float(spread[1])


def unresolved_peak(omega: np.ndarray, data: np.ndarray, noise: float) -> tuple[float, float, tuple, bool]:
    """What a circle fit reports for a mode its angles could not resolve (module docstring).

    Returns
    -------
    ``(omega_r, zeta, (sd_omega, sd_log_zeta, dof), found)``: `peak_inverse`'s answer, its frequency's sd
    widened by `UNRESOLVED_LINES` lines in quadrature (``found`` True); where it has none, the highest line, the
    damping whose bandwidth is `UNRESOLVED_LINES` lines, the line spacing over sqrt(12) (a uniform place between
    the neighbours' midpoints) and a damping known to a factor of e^3 either way (``found`` False: the fit is
    flagged ``"unresolved"``).
    """
    peak = peak_inverse(omega, data, noise)
    lines = float(np.median(np.diff(omega)))
    if peak is not None:
        # a form error of a tenth of a line: a neighbour's residual shifts the peak's magnitudes, and their form
        # has no term for it (a mode 20 % away at 1 % damping moves 21.77 Hz by up to 0.023 Hz on 0.25 Hz lines)
        return peak[0], peak[1], (float(np.hypot(peak[2], UNRESOLVED_LINES * lines)), peak[3], 10**6), True
    omega_r = float(omega[int(np.argmax(np.abs(data)))])
    return omega_r, UNRESOLVED_LINES * lines / (2.0 * omega_r), (lines / np.sqrt(12.0), 3.0 / 1.96, 10**6), False


def peak_phase(omega: np.ndarray, data: np.ndarray, centre: complex, omega_r: float,
               zeta: float) -> tuple[float, float]:
    """``(phi0, sense)``: the diameter's angle and the sweep's sense that put the points, seen from ``centre``,
    closest to one mode's angles at ``omega_r`` and ``zeta`` (the circular mean of each point's angle less
    its model angle; the sense whose mean resultant is longer).
    """
    best = (-1.0, 0.0, 1.0)
    for sense in (1.0, -1.0):
        turn = np.exp(1j * (np.angle(data - centre) - sweep_angle(omega, 0.0, omega_r, zeta, sense)))
        mean = complex(np.mean(turn))
        if abs(mean) > best[0]:
            best = (abs(mean), float(np.angle(mean)), sense)
    return best[1], best[2]

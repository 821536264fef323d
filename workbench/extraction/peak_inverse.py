"""A mode narrower than the line spacing: natural frequency and damping from the three lines at its peak.

When the half-power bandwidth ``2 zeta f_r`` is well under one line spacing, all but the peak line sit near
the far end of the mobility circle, and the circle's angle model fits them about as well with a damping of
zero and the pole on the peak line: the sweep's least squares slides down a flat valley (damping 1e-11,
frequency on the line to 1e-10 Hz) and stops where rounding stops it, so two processes whose memory is laid
out differently stop at different points. The magnitudes still tell the damping: for one viscous mode the
mobility ``Y = D / (1 + i x)``, ``x = (w^2 - w_r^2) / (2 zeta w_r w)``, gives exactly

    w^2 / |Y|^2 = (w^2 + (w^2 - w_r^2)^2 / (4 zeta^2 w_r^2)) / |D|^2,

a parabola in ``s = w^2`` (the inverse-FRF idea of Dobson, 1987, written for the mobility's exact form).
Through the peak line and its two neighbours it gives ``w_r``, ``zeta`` and ``|D|`` in closed form, with
no valley to wander in. Written here because no library fits this three-line form; it is a 3 x 3 solve.
"""

from __future__ import annotations

import numpy as np

__all__ = ["UNRESOLVED_LINES", "peak_inverse", "unresolved_peak"]

UNRESOLVED_LINES = 0.1  # a fitted half-power bandwidth under this many line spacings: the circle could not see it


def _solve(omega: np.ndarray, magnitude: np.ndarray) -> tuple[float, float] | None:
    """``(omega_r, zeta)`` of the parabola in ``w^2`` through three lines, None where it is not one mode's."""
    s = omega**2
    s0, scale = s[1], 0.5 * (s[2] - s[0])
    t = (s - s0) / scale  # centred: -1, ~0, 1, so the 3 x 3 solve is well conditioned
    g = s / magnitude**2
    a, b, c = np.linalg.solve(np.vander(t, 3), g)
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
    if not (u > 0.0 and s_r > 0.0 and -1.0 <= tau <= 1.0):
        return None
    return float(np.sqrt(s_r)), float(np.sqrt(u * scale**2 / (4.0 * s_r * a)))


def peak_inverse(omega: np.ndarray, data: np.ndarray, noise: float) -> tuple[float, float, float, float] | None:
    """Natural frequency and damping of a mode narrower than the line spacing, from its peak's three lines.

    Parameters
    ----------
    omega : (n,) rad/s, the band's lines, increasing.
    data : (n,) complex mobility on them.
    noise : RMS of the curve's complex noise (``E|n|^2``), mobility units: each magnitude's sd is
        ``noise / sqrt(2)``.

    Returns
    -------
    ``(omega_r, zeta, sd_omega, sd_log_zeta)``: rad/s, the viscous damping ratio, and their standard deviations
    from the magnitudes' noise (first order); None when the highest line is at the band's end, or the three
    magnitudes are not one mode's peak (no parabola opening upward with its vertex between the neighbours).
    """
    k = int(np.argmax(np.abs(data)))
    if not 0 < k < data.size - 1:
        return None
    w, m = omega[k - 1:k + 2], np.abs(data[k - 1:k + 2])
    found = _solve(w, m)
    if found is None:
        return None
    sd = noise / np.sqrt(2.0)
    jac = np.empty((2, 3))
    for i in range(3):  # central differences: the closed form is smooth wherever it is defined
        step = np.zeros(3)
        step[i] = 1e-4 * m[i]
        up, down = _solve(w, m + step), _solve(w, m - step)
        if up is None or down is None:
            return None
        jac[:, i] = [(up[0] - down[0]) / (2 * step[i]), (np.log(up[1]) - np.log(down[1])) / (2 * step[i])]
    spread = np.sqrt((jac**2).sum(axis=1)) * sd
    return found[0], found[1], float(spread[0]), float(spread[1])


def unresolved_peak(omega: np.ndarray, data: np.ndarray, noise: float) -> tuple[float, float, tuple, bool]:
    """What a circle fit reports for a mode narrower than `UNRESOLVED_LINES` line spacings.

    Returns
    -------
    ``(omega_r, zeta, (sd_omega, sd_log_zeta, dof), found)``: `peak_inverse`'s answer (``found`` True); where it
    has none, the highest line, the damping whose bandwidth is `UNRESOLVED_LINES` lines (the most a collapse can
    hide), the line spacing over sqrt(12) (a uniform place between the neighbours' midpoints) and a damping
    known to a factor of e^3 either way (``found`` False: the fit is flagged ``"unresolved"``).
    """
    peak = peak_inverse(omega, data, noise)
    if peak is not None:
        return peak[0], peak[1], (peak[2], peak[3], 10**6), True
    lines = float(np.median(np.diff(omega)))
    omega_r = float(omega[int(np.argmax(np.abs(data)))])
    return omega_r, UNRESOLVED_LINES * lines / (2.0 * omega_r), (lines / np.sqrt(12.0), 3.0 / 1.96, 10**6), False

"""How strongly a mechanism shows in the data, and its intensity calibrated to a footprint.

A magnitude ladder means something only relative to the noise floor, and the same mass or spring shows
differently on each geometry. So the cases ask for a **footprint** and the intensity ``x`` of the
mechanism is found to give it (`calibrate`):

- ``frequency``: the largest relative shift of the article's modes below the band's top (of its first
  `FOOTPRINT_MODES`) against the nominal article (each nominal mode paired with the nearest shifted one);
- ``amplitude``: the same between the lowest and the highest amplitude (high = 5 x low, paper 2.2.2);
- ``damping``: the largest added damping ratio of a mode below the band's top, ``phi_r^T C phi_r /
  (2 omega_r)`` (first order in the dashpots' C, mass-normalised modes).

Everything is computed on nuisance-free articles at the joints' mean moduli.
"""

from __future__ import annotations

import math

import numpy as np

from workbench.proving.article import Article
from workbench.proving.beams import solve_modes
from workbench.proving.fem import discretise
from workbench.proving.mechanisms import Mechanism

__all__ = ["article_frequencies", "paired_shift", "footprint", "calibrate", "HIGH_AMPLITUDE", "FOOTPRINT_MODES"]

HIGH_AMPLITUDE = 5.0  # paper 2.2.2: the high amplitude is five times the low one
FOOTPRINT_MODES = 10  # the modes a campaign's band holds, about


def article_frequencies(article: Article, count: int = FOOTPRINT_MODES, amplitude: float = 1.0) -> np.ndarray:
    """(count,) natural frequencies (Hz) of the article at the joints' mean moduli and amplitude ratio ``amplitude``."""
    frame = article.frame
    soft = {s.joint: s.factor(amplitude) for s in article.softening}
    moduli = {j.name: j.youngs_modulus * soft.get(j.name, 1.0) for j in frame.joints}
    d = discretise(article, moduli)
    return solve_modes(d.system.stiffness, d.system.mass, count).frequency_hz


def paired_shift(reference: np.ndarray, shifted: np.ndarray, f_max_hz: float = math.inf) -> np.ndarray:
    """Relative shift of each reference mode below ``f_max_hz`` (Hz) to the nearest (in ratio) shifted mode."""
    reference = reference[reference <= f_max_hz]
    if reference.size == 0:
        raise ValueError(f"footprint: no mode below the band's top, {f_max_hz:g} Hz")
    nearest = shifted[np.argmin(np.abs(np.log(shifted[None, :] / reference[:, None])), axis=1)]
    return nearest / reference - 1.0


def _largest_shift(reference: np.ndarray, shifted: np.ndarray, f_max_hz: float = math.inf) -> float:
    return float(np.max(np.abs(paired_shift(reference, shifted, f_max_hz))))


def footprint(base: Article, mechanism: Mechanism, x: float, count: int = FOOTPRINT_MODES,
              f_max_hz: float = math.inf) -> float:
    """The footprint (module docstring) of ``mechanism`` at intensity ``x`` on the article ``base``, over its
    first ``count`` modes below ``f_max_hz`` (the campaign's band: a shift above it is never measured).
    """
    article = mechanism.build(base, x)
    if mechanism.channel == "amplitude":
        return _largest_shift(article_frequencies(article, count), article_frequencies(article, count, HIGH_AMPLITUDE),
                              f_max_hz)
    if mechanism.channel == "damping":
        frame = article.frame
        d = discretise(article, {j.name: j.youngs_modulus for j in frame.joints})
        modes = solve_modes(d.system.stiffness, d.system.mass, count)
        if d.system.damping is None:
            return 0.0
        added = np.einsum("ir,ir->r", modes.shapes, d.system.damping @ modes.shapes) / (2.0 * modes.omega)
        inside = modes.frequency_hz <= f_max_hz
        if not inside.any():
            raise ValueError(f"footprint: no mode below the band's top, {f_max_hz:g} Hz")
        return float(added[inside].max())
    reference = base if mechanism.nominal is None else Article(mechanism.nominal(base.frame, x), shear=False,
                                                                rotary_inertia=False)
    return _largest_shift(article_frequencies(reference, count), article_frequencies(article, count + 4), f_max_hz)


def calibrate(base: Article, mechanism: Mechanism, target: float, tolerance: float = 0.05,
              iterations: int = 30, f_max_hz: float = math.inf) -> tuple[float, float]:
    """The intensity whose footprint is ``target`` (within ``tolerance``, relative), and that footprint
    (`footprint` over the modes below ``f_max_hz``).

    Regula falsi (Illinois) on ``log footprint`` against ``log x`` inside ``mechanism.bounds``: the footprint
    grows with ``x``; a target beyond the bounds' footprints gives the bound.
    """
    lo, hi = (math.log(v) for v in mechanism.bounds)

    def g(log_x: float) -> tuple[float, float]:
        fp = footprint(base, mechanism, math.exp(log_x), f_max_hz=f_max_hz)
        return math.log(max(fp, 1e-300) / target), fp

    g_lo, fp_lo = g(lo)
    if g_lo >= 0:
        return math.exp(lo), fp_lo
    g_hi, fp_hi = g(hi)
    if g_hi <= 0:
        return math.exp(hi), fp_hi
    side = 0
    best = (math.exp(hi), fp_hi)
    for _ in range(iterations):
        mid = (lo * g_hi - hi * g_lo) / (g_hi - g_lo)
        g_mid, fp_mid = g(mid)
        best = (math.exp(mid), fp_mid)
        if abs(fp_mid / target - 1.0) <= tolerance:
            break
        if g_mid < 0:
            lo, g_lo = mid, g_mid
            if side == -1:
                g_hi /= 2.0
            side = -1
        else:
            hi, g_hi = mid, g_mid
            if side == 1:
                g_lo /= 2.0
            side = 1
    return best

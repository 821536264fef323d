"""How strongly a mechanism shows in the data, and its intensity calibrated to a footprint.

A magnitude ladder means something only relative to the noise floor, and the same mass or spring shows
differently on each geometry. So the cases ask for a **footprint** and the intensity ``x`` of the
mechanism is found to give it (`calibrate`):

- ``frequency``: the largest relative shift of the article's measurable modes (of its first
  `FOOTPRINT_MODES`) against the nominal article (each nominal mode paired with the nearest shifted one);
- ``amplitude``: the same between the lowest and the highest amplitude (high = 5 x low, paper 2.2.2);
- ``damping``: the largest added damping ratio of a measurable mode, ``phi_r^T C phi_r / (2 omega_r)``
  (first order in the dashpots' C, mass-normalised modes).

A mode is **measurable** when its half-power band lies inside the campaign's band: at or below
``f_max / (1 + EDGE_SHARE)`` (`measurable_top_hz`). `EDGE_SHARE` is the largest damping ratio a mode near the
band's top has on the proving ground: the nuisances' damping level up to 0.6 % at 100 Hz with a trend up to
``(f / 100 Hz) ** 0.3`` (1.3 % at 1.2 kHz, `workbench.proving.nuisances.NuisanceSettings`) plus the large
damping rung's 1 %. Until seed 28 the footprint counted every mode below the band's top, and a mode 1.6 % under
it, whose resonance the band cuts, could carry a case's whole footprint: a "large" joint damping whose 1 % sat
on a mode no extraction can read (seeds 24 and 27, two-bolt frames at 1230 Hz in a 1250 Hz band).

Everything is computed on nuisance-free articles at the joints' mean moduli.
"""

from __future__ import annotations

import math

import numpy as np

from workbench.proving.article import Article
from workbench.proving.beams import solve_modes
from workbench.proving.fem import discretise
from workbench.proving.mechanisms import Mechanism

__all__ = ["article_frequencies", "paired_shift", "footprint", "calibrate", "measurable_top_hz", "HIGH_AMPLITUDE",
           "FOOTPRINT_MODES", "EDGE_SHARE"]

HIGH_AMPLITUDE = 5.0  # paper 2.2.2: the high amplitude is five times the low one
FOOTPRINT_MODES = 10  # the modes a campaign's band holds, about
EDGE_SHARE = 0.025  # the largest damping ratio near the band's top (module docstring)


def measurable_top_hz(f_max_hz: float) -> float:
    """The highest natural frequency (Hz) whose half-power band a campaign measuring up to ``f_max_hz`` (Hz) holds,
    at the proving ground's largest damping (`EDGE_SHARE`, module docstring).
    """
    return f_max_hz / (1.0 + EDGE_SHARE)


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
        raise ValueError(f"footprint: no measurable mode at or below {f_max_hz:g} Hz")
    nearest = shifted[np.argmin(np.abs(np.log(shifted[None, :] / reference[:, None])), axis=1)]
    return nearest / reference - 1.0


def _largest_shift(reference: np.ndarray, shifted: np.ndarray, f_max_hz: float = math.inf) -> float:
    return float(np.max(np.abs(paired_shift(reference, shifted, f_max_hz))))


def footprint(base: Article, mechanism: Mechanism, x: float, count: int = FOOTPRINT_MODES,
              f_max_hz: float = math.inf) -> float:
    """The footprint (module docstring) of ``mechanism`` at intensity ``x`` on the article ``base``, over its
    first ``count`` modes measurable in a band up to ``f_max_hz`` (Hz; `measurable_top_hz`: a shift above the
    band, or on a resonance the band cuts, is never measured).
    """
    article = mechanism.build(base, x)
    f_max_hz = measurable_top_hz(f_max_hz)
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
            raise ValueError(f"footprint: no measurable mode at or below {f_max_hz:g} Hz")
        return float(added[inside].max())
    reference = base if mechanism.nominal is None else Article(mechanism.nominal(base.frame, x), shear=False,
                                                                rotary_inertia=False)
    return _largest_shift(article_frequencies(reference, count), article_frequencies(article, count + 4), f_max_hz)


def calibrate(base: Article, mechanism: Mechanism, target: float, tolerance: float = 0.05,
              iterations: int = 30, f_max_hz: float = math.inf) -> tuple[float, float]:
    """The intensity whose footprint is ``target`` (within ``tolerance``, relative), and that footprint
    (`footprint` over the modes measurable in a band up to ``f_max_hz``).

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

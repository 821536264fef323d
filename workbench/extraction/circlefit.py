"""Circle-fit modal extraction from measured FRFs (the paper's reference [61]: Ewins, *Modal
Testing: Theory, Practice and Application*, 2000, section 4.3).

Conventions (CONTRACTS.md): time as exp(+i omega t); receptance
``H = sum_r A_r / (omega_r^2 - omega^2 + 2 i zeta_r omega_r omega)`` (m/N), mobility ``i omega H``,
accelerance ``-omega^2 H``; frequencies in Hz at the interface, viscous modal damping ratios.

Why the mobility. With viscous damping the *mobility* of one mode is an exact circle through the
origin::

    Y_r(omega) = i omega A_r / (omega_r^2 - omega^2 + 2 i zeta_r omega_r omega) = D_r / (1 + i x),
    D_r = A_r / (2 zeta_r omega_r),   x = (omega^2 - omega_r^2) / (2 zeta_r omega_r omega),

(the receptance circle is exact only for hysteretic damping). Every curve is therefore converted to
mobility first: ``Y = i omega H_receptance = H_accelerance / (i omega)``. Seen from the circle's
centre, a point at ``omega`` lies at the angle ``arg D_r - 2 arctan x`` (``psi = -2 arctan x``
from the resonance point, the end of the diameter), hence, for a point at ``theta = |psi|``, the
exact relation ``tan(theta/2) = |omega^2 - omega_r^2| / (2 zeta_r omega_r omega)``.

Per mode and curve (`circle_fit`):

1. algebraic circle (Taubin's fit, Chernov's SVD form), refined by geometric least squares on the
   radial distances (Levenberg-Marquardt, `workbench.extraction.levenberg.lm`);
2. angle sweep: a first ``omega_r`` where the angle sweeps fastest (parabola through the three
   fastest sweep rates), then a least-squares fit of the exact angle model above,
   ``phi(omega) = phi_0 - 2 arctan x(omega; omega_r, zeta)``, to all the points' angles. The fitted
   ``omega_r`` is the natural frequency: the raw sweep-rate maximum sits ``zeta^2 / 2`` (relative)
   below it, 4.5e-4 at 3 % damping, too far for the 1e-4 target. A mode a third or half a line wide
   can turn by more than pi between the two lines at its peak, so that the wrapped steps put the
   fastest rate on the wrong line; where those starts miss the angles, the start the peak's
   magnitudes give (`peak_inverse`) is tried too (`circle_geometry.fit_sweep`);
3. neighbouring modes: their contribution is not constant across the band and distorts the circle
   (frequency errors of a few 1e-6 at 3 % damping with a neighbour 2.5 times higher). The circle
   (centre, radius), the sweep (``phi_0, omega_r, zeta``) and the *variation* across the band of
   the residual terms (mobility shapes ``i w``, ``-i / w``, ``i w^3 / w_r^2``, i.e. receptance
   ``U``, ``-L / w^2``, ``U_2 w^2``; up to 3 as the band's points allow) are then refined together
   by least squares on the complex points, started from steps 1-2. (A fixed-point alternation of
   circle fit and residual fit converges to the same answer, but slowly: tens of passes.) The
   points, minus that variation, lie on the refined circle;
4. damping from every pair of those points (a above, b below resonance, preferably within the
   half-power region ``theta <= 90 deg``, widened to 135 then 160 deg when fewer than
   `MIN_SIDE_POINTS` a side), with the *exact* viscous form derived from the relation above
   (Ewins' first-order form is ``(omega_a - omega_b) / (omega_r (tan + tan))``)::

       zeta_ab = [(omega_a^2 - omega_r^2) / omega_a + (omega_r^2 - omega_b^2) / omega_b]
                 / (2 omega_r (tan(theta_a / 2) + tan(theta_b / 2)));

   `ModalFit.damping_ratio` is their mean, `ModalFit.damping_scatter` their standard deviation
   (the least-squares ``zeta`` of step 3 is only 10-20 % less noisy, and the pairs give Ewins'
   scatter diagnostic);
5. modal constant ``A_r = 2 zeta_r omega_r D_r`` with ``D_r = 2 R exp(i phi_0)`` (receptance
   units, to compare with ``phi_j phi_k`` of a mass-normalised model);
6. residual terms: what the circle's offset from the origin stands for, fitted by linear least
   squares on the data minus the modal term, as receptance ``U - L / omega^2`` (mobility
   ``i omega U - i L / omega``): ``U`` (m/N) the upper residual (residual flexibility of the modes
   above), ``L`` (1/kg) the lower residual (inverse residual mass of the modes below). Over one
   narrow band L and U are nearly collinear: their sum at resonance, ``i w_r U - i L / w_r``, is
   well determined, each alone is not.

Quality and flags (no exception for a doubtful mode, a flag): ``circle_error`` (RMS radial distance
over the radius), the curve's noise level estimated from second differences over all its lines
(`noise_level`, independent of the fit), and

- ``"weak"``: circle diameter, or the points' largest distance from their median, under
  `WEAK_FACTOR` noise levels (a mode hidden in noise: white noise alone rarely strays beyond
  3 noise levels, while a circle fitted through it can be large and sharp);
- ``"poor_circle"``: circle error above `POOR_CIRCLE`;
- ``"close_mode"``: a second mode is really there. The trigger: the points miss the one-mode
  model systematically, not by noise (misfit RMS above `CLOSE_EXCESS` noise levels, or its lag-1
  correlation along frequency above ``CLOSE_CORRELATION / sqrt(n)``: white noise gives
  ``0 +- 1/sqrt(n)``), by more than `CLOSE_FLOOR` radii, and the mode is not weak. Real curves are
  never perfect circles (leakage, a slightly nonlinear joint), so the trigger alone proves
  nothing: a two-pole fit of the band (`workbench.extraction.multimode.second_mode`; over all the
  curves of the test in `fit_modes`) must then find a significant second pole within
  `CLOSE_BANDWIDTHS` half-power bandwidths. Also raised by `fit_modes` for two fitted modes that
  close, and on every mode of a band that holds two (`workbench.extraction.modes`);
- ``"few_points"``: fewer than `MIN_SIDE_POINTS` points on a side of resonance for the pairs;
- ``"edge_of_band"``: natural frequency closer to a band edge than a half-power half-width.
- ``"unresolved"``: the angles could not resolve the mode (they collapsed: a fitted bandwidth under
  `UNRESOLVED_LINES` lines), nor could the peak's magnitudes (`peak_inverse`, which otherwise gives the fit's
  frequency, damping and intervals, unflagged): the peak line, known to a line.

95 % intervals (`ModalFit.frequency_ci95_hz`, `ModalFit.damping_ci95`, `_intervals`): from the
covariance of the joint refinement (step 3), ``s^2 (J^T J)^-1`` with ``s^2`` its residual variance,
and the Student-t quantile on its residual degrees of freedom; so they widen with the noise, with
a poor circle and with few lines across the peak. The damping interval spans both the pairwise
mean and the least-squares ``zeta``, each widened by that half-width (their disagreement is the
model-form term). Where the misfit is systematic (the close-mode trigger) the curve is distorted
(leakage, a nonlinear joint) in a way no noise covariance sees: the half-power bandwidth is then
taken as known to `LEAKAGE_LINES` lines only (`ModalFit.damping_model_form`), as for a mode narrower
than the angles resolve (its intervals `peak_inverse`'s). Measured coverage: ``tests/test_close_modes.py``.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from workbench.extraction.circle_geometry import (
    MIN_SIDE_POINTS,
    clip_log_zeta,
    fit_sweep,
    geometric,
    mobility_factor,
    pair_damping,
    pairs,
    sweep_angle,
    sweep_gradient,
    taubin,
    trend_basis,
    wrap_angle,
)
from workbench.extraction.levenberg import lm
from workbench.extraction.multimode import inverse_normal, noise_level, second_mode, t975
from workbench.extraction.peak_inverse import UNRESOLVED_LINES, peak_inverse, peak_phase, unresolved_peak

__all__ = [
    "QUANTITIES", "FLAGS", "WEAK_FACTOR", "POOR_CIRCLE", "CLOSE_CORRELATION", "CLOSE_EXCESS", "CLOSE_FLOOR",
    "CLOSE_BANDWIDTHS", "LEAKAGE_LINES", "MIN_SIDE_POINTS", "MIN_BAND_POINTS", "ModalFit", "to_mobility",
    "pair_damping", "noise_level", "circle_fit"
]

QUANTITIES = ("receptance", "mobility", "accelerance")
FLAGS = ("close_mode", "weak", "poor_circle", "few_points", "edge_of_band", "unresolved")
WEAK_FACTOR = 5.0        # diameter / noise RMS below which a mode is "weak"
POOR_CIRCLE = 0.05       # circle error (RMS radial distance / radius) above which "poor_circle"
CLOSE_CORRELATION = 3.0  # lag-1 correlation of the misfit above this / sqrt(n): not white noise
CLOSE_EXCESS = 2.0       # misfit RMS above this many noise levels: not noise
CLOSE_FLOOR = 5e-4       # systematic misfit / radius below this is not evidence of a second mode
CLOSE_BANDWIDTHS = 3.0   # two modes closer than this many half-power bandwidths are "close"
LEAKAGE_LINES = 2.0      # a distorted curve's half-power bandwidth is known to +- this many lines
MIN_BAND_POINTS = 6      # fewer points in a band is an error
WEIGHT_FLOOR = 1e-4      # circle-error floor in the combination weights


@dataclass(frozen=True)
class ModalFit:
    """One mode identified on one FRF curve by the circle fit.

    Attributes
    ----------
    frequency_hz : natural frequency, Hz.
    damping_ratio : viscous damping ratio, mean of the pairwise estimates (`peak_inverse`'s where the angles
        could not resolve the mode).
    damping_scatter : standard deviation of the pairwise estimates (0 for a single pair, NaN for none).
    modal_constant : complex receptance modal constant ``A_r`` (m/N (rad/s)^2, i.e. 1/kg for a
        mass-normalised model: ``phi_j phi_k``).
    residual_lower : complex ``L`` of the receptance term ``-L / omega^2`` (1/kg): modes below.
    residual_upper : complex ``U`` of the receptance term ``+U`` (m/N): modes above.
    circle_error : RMS radial distance of the points to the circle over its radius.
    noise : the curve's noise RMS (`noise_level`, independent of the fit) converted to mobility
        at resonance (m/s/N).
    diameter : circle diameter, mobility units (m/s/N).
    points_used : points of the band used in the circle fit.
    pairs_used : point pairs averaged for the damping.
    band : (f_lo, f_hi) in Hz.
    flags : subset of `FLAGS`.
    frequency_ci95_hz : (low, high) 95 % interval of the natural frequency, Hz (`_intervals`).
    damping_ci95 : (low, high) 95 % interval of the damping ratio (`_intervals`).
    damping_model_form : the part of ``damping_ci95`` common to every curve of the test (damping
        ratio, absolute half-width): `LEAKAGE_LINES` lines of half-power bandwidth when the misfit
        is systematic or the mode narrower than the angles resolve, else 0.
    """

    frequency_hz: float
    damping_ratio: float
    damping_scatter: float
    modal_constant: complex
    residual_lower: complex
    residual_upper: complex
    circle_error: float
    noise: float
    diameter: float
    points_used: int
    pairs_used: int
    band: tuple[float, float]
    flags: tuple[str, ...] = ()
    frequency_ci95_hz: tuple[float, float] = (float("nan"), float("nan"))
    damping_ci95: tuple[float, float] = (float("nan"), float("nan"))
    damping_model_form: float = 0.0

    def __post_init__(self) -> None:
        unknown = set(self.flags) - set(FLAGS)
        if unknown:
            raise ValueError(f"ModalFit: flags {sorted(unknown)} are not among {FLAGS}")
        if not self.band[0] < self.band[1]:
            raise ValueError(f"ModalFit: band {self.band} Hz is not increasing")

    @property
    def ok(self) -> bool:
        """True when the fit raised no flag."""
        return not self.flags


# --------------------------------------------------------------------------------------------
# input checks and conversions

def _check_frequency(frequency_hz) -> np.ndarray:
    f = np.asarray(frequency_hz, dtype=float)
    if f.ndim != 1 or f.size < MIN_BAND_POINTS:
        raise ValueError(f"frequency_hz: expected a 1-D array of at least {MIN_BAND_POINTS} lines, "
                         f"got shape {f.shape}")
    if not np.all(np.isfinite(f)):
        raise ValueError("frequency_hz: contains NaN or infinite values")
    if np.any(np.diff(f) <= 0.0):
        i = int(np.argmax(np.diff(f) <= 0.0))
        raise ValueError(f"frequency_hz: not strictly increasing at index {i + 1} ({f[i]} -> {f[i + 1]} Hz)")
    return f


def _check_frfs(frfs, n_freq: int) -> np.ndarray:
    h = np.asarray(frfs, dtype=complex)
    if h.ndim == 1:
        h = h[None, :]
    if h.ndim != 2 or h.shape[1] != n_freq:
        raise ValueError(f"frfs: expected shape (n_curves, {n_freq}), got {np.shape(frfs)}")
    if not np.all(np.isfinite(h)):
        raise ValueError("frfs: contains NaN or infinite values")
    return h


def _check_quantity(quantity: str) -> str:
    if quantity not in QUANTITIES:
        raise ValueError(f"quantity: {quantity!r} is not one of {', '.join(QUANTITIES)}")
    return quantity


def _check_band(f: np.ndarray, band) -> tuple[float, float]:
    lo, hi = float(band[0]), float(band[1])
    inside = (f >= lo) & (f <= hi)
    if not (hi > lo) or inside.sum() < MIN_BAND_POINTS:
        raise ValueError(f"band: ({lo}, {hi}) Hz holds {int(inside.sum())} lines, "
                         f"at least {MIN_BAND_POINTS} are needed")
    return lo, hi


def to_mobility(frequency_hz: np.ndarray, frf: np.ndarray, quantity: str) -> np.ndarray:
    """Convert an FRF to mobility (m/s/N): ``i omega H`` from receptance, ``H / (i omega)`` from
    accelerance. ``frf`` (..., n_freq) complex; accelerance at 0 Hz raises ValueError.
    """
    _check_quantity(quantity)
    omega = 2.0 * np.pi * np.asarray(frequency_hz, float)
    if quantity == "receptance":
        return frf * (1j * omega)
    if quantity == "accelerance":
        if np.any(omega == 0.0):
            raise ValueError("frequency_hz: accelerance cannot be converted to mobility at 0 Hz")
        return frf / (1j * omega)
    return np.asarray(frf, complex)


# --------------------------------------------------------------------------------------------
# circle and sweep

def _peak_sweep_start(omega: np.ndarray, data: np.ndarray, centre: complex,
                      noise: float) -> tuple[float, float, float, float] | None:
    """``(phi0, omega_r, zeta, sense)`` from the magnitudes at the peak (`peak_inverse`) where they are one mode's,
    else None: the start of `fit_sweep` that does not read the angles' steps. ``noise``: the curve's noise in
    mobility units at the peak.
    """
    peak = peak_inverse(omega, data, noise)
    if peak is None:
        return None
    omega_r, zeta = peak[0], peak[1]
    phi0, sense = peak_phase(omega, data, centre, omega_r, zeta)
    return phi0, omega_r, zeta, sense


def _refine(omega, data, centre, radius, phi0, omega_r, zeta, sense, n_trend):
    """Joint least squares on the complex points: circle (centre, radius), sweep (phi0, omega_r,
    zeta) and the variation of the residual terms across the band (``n_trend`` shapes of
    `trend_basis`, zero at the starting omega_r).
    """
    scale = radius if radius > 0.0 else max(float(np.abs(data).max()), np.finfo(float).tiny)
    basis = trend_basis(omega, omega_r)[:, :n_trend]
    basis = basis - trend_basis(np.array([omega_r]), omega_r)[:, :n_trend]
    norms = np.maximum(np.abs(basis).max(axis=0), 1e-300) if n_trend else np.ones(0)
    basis = basis / norms
    u = data / scale
    w0 = omega_r

    def model(p):
        c = complex(p[0], p[1])
        zeta_p = np.exp(clip_log_zeta(p[5]))
        circle = c + p[2] * np.exp(1j * sweep_angle(omega, p[3], p[4] * w0, zeta_p, sense))
        if n_trend:
            circle = circle + basis @ (p[6:6 + n_trend] + 1j * p[6 + n_trend:])
        return circle

    def residual(p):
        r = u - model(p)
        return np.concatenate([r.real, r.imag])

    # the Jacobian's columns of the centre and the trend do not move: written once, the circle's filled in
    fixed = np.column_stack([np.ones_like(u), np.full_like(u, 1j), np.zeros((u.size, 4)), basis, 1j * basis])
    fixed, n = -np.concatenate([fixed.real, fixed.imag]), u.size

    def jacobian(p):
        on_circle = np.exp(1j * sweep_angle(omega, p[3], p[4] * w0, np.exp(clip_log_zeta(p[5])), sense))
        turn = (p[2] * 1j * on_circle)[:, None] * sweep_gradient(omega, p[3], p[4], p[5], w0, sense)
        d = fixed.copy()
        d[:n, 2], d[n:, 2], d[:n, 3:6], d[n:, 3:6] = -on_circle.real, -on_circle.imag, -turn.real, -turn.imag
        return d

    c0 = centre / scale
    p0 = np.concatenate([[c0.real, c0.imag, 1.0, phi0, 1.0, np.log(zeta)], np.zeros(2 * n_trend)])
    sol = lm(residual, p0, jacobian, xtol=1e-15, ftol=1e-15, gtol=1e-15)
    p = sol.x
    t = (p[6:6 + n_trend] + 1j * p[6 + n_trend:]) * scale
    trend = basis @ t if n_trend else np.zeros_like(data)
    # covariance of (omega_r / w0, log zeta): residual variance on its degrees of freedom, (J^T J)^-1
    dof = max(2 * omega.size - p.size, 1)
    cov = (2.0 * sol.cost / dof) * inverse_normal(sol.jac)[4:6, 4:6]
    flip = 1.0 if p[4] >= 0.0 else -1.0  # as in `fit_sweep`: omega_r kept positive, the sense follows
    return (complex(p[0], p[1]) * scale, abs(p[2]) * scale, float(p[3]) + (np.pi if p[2] < 0 else 0.0),
            float(flip * p[4] * w0), float(np.exp(clip_log_zeta(p[5]))), trend,
            (np.sqrt(max(cov[0, 0], 0.0)) * w0, np.sqrt(max(cov[1, 1], 0.0)), dof), flip * sense)


def _intervals(f_r: float, zeta: float, zeta_sweep: float, spread: tuple[float, float, int],
               model_form: float) -> tuple[tuple[float, float], tuple[float, float]]:
    """95 % intervals of frequency (Hz) and damping from the joint refinement's covariance, or from
    `peak_inverse` (``spread = (sd omega_r rad/s, sd log zeta, dof)``), Student-t on its degrees of freedom.

    The damping interval spans both estimators, the reported pairwise mean ``zeta`` and the
    least-squares ``zeta_sweep``, each widened by the least-squares half-width (in log): their
    disagreement is a model-form term (the pairwise mean is the noisier, and differs from the
    least-squares value when the circle is not one viscous mode's). ``model_form`` (absolute,
    ``ModalFit.damping_model_form``) is added in quadrature to each side.
    """
    sd_omega, sd_log, dof = spread
    t = t975(dof)
    half_f = t * sd_omega / (2.0 * np.pi)
    low = np.log(zeta / min(zeta, zeta_sweep)) + t * sd_log
    high = np.log(max(zeta, zeta_sweep) / zeta) + t * sd_log
    ratio = model_form / zeta
    low = min(float(np.hypot(low, -np.log(1.0 - min(ratio, 0.99)))), 50.0)
    high = min(float(np.hypot(high, np.log(1.0 + ratio))), 50.0)
    return (float(f_r - half_f), float(f_r + half_f)), (float(zeta * np.exp(-low)), float(zeta * np.exp(high)))


def circle_fit(frequency_hz, frf, band: tuple[float, float], quantity: str = "accelerance") -> ModalFit:
    """Identify one mode on one FRF curve by the circle fit (module docstring, Ewins 2000, 4.3).

    Parameters
    ----------
    frequency_hz : (n_freq,) frequency lines, Hz, strictly increasing.
    frf : (n_freq,) complex FRF in the unit of ``quantity`` (receptance m/N, mobility m/s/N,
        accelerance m/s^2/N); converted to mobility, whose one-mode Nyquist plot is a circle for
        viscous damping.
    band : (f_lo, f_hi), Hz: the lines used, both ends included.
    quantity : ``"receptance"``, ``"mobility"`` or ``"accelerance"``.

    Returns
    -------
    ModalFit (with flags rather than exceptions for doubtful modes).

    Raises
    ------
    ValueError
        NaN, non-increasing frequencies, shape mismatch, unknown quantity, or fewer than
        `MIN_BAND_POINTS` lines in the band.
    """
    f = _check_frequency(frequency_hz)
    h = _check_frfs(frf, f.size)
    if h.shape[0] != 1:
        raise ValueError(f"frf: expected one curve of {f.size} lines, got shape {np.shape(frf)}")
    _check_quantity(quantity)
    noise = noise_level(h)
    fit, triggered = _circle_fit(f, h[0], _check_band(f, band), quantity, float(noise[0]))
    if not triggered:
        return fit
    # the misfit is systematic: a second mode, or a curve that is not a perfect circle?
    found = _second_mode_near(f, h, fit, quantity, noise)
    return replace(fit, flags=tuple(x for x in FLAGS if x in fit.flags or (x == "close_mode" and found)))


def _second_mode_near(f: np.ndarray, h: np.ndarray, fit: ModalFit, quantity: str, noise: np.ndarray) -> bool:
    """True when a two-pole fit of ``fit.band`` over the curves ``h`` (n_curves, n_freq; ``noise`` their
    `noise_level`) finds a second mode (`multimode.second_mode`) within `CLOSE_BANDWIDTHS` half-power bandwidths.
    """
    _, two, accepted = second_mode(f, h, fit.band, quantity, noise, (fit.frequency_hz, fit.damping_ratio))
    bandwidth = 2.0 * float(np.max(two.damping_ratio * two.frequency_hz))
    return accepted and float(np.ptp(two.frequency_hz)) < CLOSE_BANDWIDTHS * bandwidth


def _circle_fit(f: np.ndarray, h: np.ndarray, band: tuple[float, float], quantity: str,
                curve_noise: float) -> tuple[ModalFit, bool]:
    """`circle_fit` of the checked curve ``h`` (n_freq,) of `noise_level` ``curve_noise``, without the
    second-mode test; returns the fit and whether its misfit is systematic (the trigger of that test).
    """
    lo, hi = band
    inside = (f >= lo) & (f <= hi)
    omega = 2.0 * np.pi * f[inside]
    data = to_mobility(f[inside], h[inside], quantity)

    first = geometric(data, *taubin(data))
    peak_noise = curve_noise * mobility_factor(quantity, float(omega[np.argmax(np.abs(data))]))
    phi0, omega_r, zeta_sweep, sense = fit_sweep(omega, np.angle(data - first[0]),
                                                 lambda: _peak_sweep_start(omega, data, first[0], peak_noise))
    n_trend = int(np.clip((omega.size - 6) // 4, 0, 3))  # 2n real equations, 6 + 2 n_trend unknowns
    centre, radius, phi0, omega_r, zeta_sweep, trend, spread, sense = _refine(
        omega, data, *first, phi0, omega_r, zeta_sweep, sense, n_trend)
    unresolved, found = bool(2.0 * zeta_sweep * omega_r < UNRESOLVED_LINES * np.median(np.diff(omega))), True
    if unresolved:  # the angles collapsed onto a line: the peak's magnitudes instead (`peak_inverse`)
        (centre, radius), trend = first, np.zeros_like(data)
        peak_line = mobility_factor(quantity, float(omega[np.argmax(np.abs(data))]))  # the noise taken there
        omega_r, zeta_sweep, spread, found = unresolved_peak(omega, data, curve_noise * peak_line)
        phi0, sense = peak_phase(omega, data, centre, omega_r, zeta_sweep)
    to_mob = mobility_factor(quantity, omega_r)
    y = data - trend
    psi = wrap_angle(np.angle(y - centre) - phi0)
    estimates, n_above, n_below = pairs(omega, psi, omega_r, sense)
    estimates = estimates[:0] if unresolved else estimates
    zeta = float(np.mean(estimates)) if estimates.size else zeta_sweep
    zeta = zeta if np.isfinite(zeta) and zeta > 0 else zeta_sweep
    diameter = 2.0 * radius * np.exp(1j * phi0)
    x = (omega**2 - omega_r**2) / (2.0 * zeta_sweep * omega_r * omega)
    modal = diameter / (1.0 + 1j * sense * x)
    # residual terms on the data: Y - modal = i w U - i L / w, linear least squares
    coefficients, *_ = np.linalg.lstsq(trend_basis(omega, omega_r)[:, :2], data - modal, rcond=None)
    upper, lower = coefficients[0], coefficients[1]

    radial = np.abs(y - centre) - radius
    misfit = y - (centre + radius * np.exp(1j * sweep_angle(omega, phi0, omega_r, zeta_sweep, sense)))
    n = omega.size
    circle_error = float(np.sqrt(np.mean(radial**2)) / radius) if radius > 0 else np.inf
    noise = curve_noise * to_mob  # the curve's own noise, independent of the fit, in mobility units at resonance
    power = float(np.sum(np.abs(misfit) ** 2))
    misfit_rms = np.sqrt(power / n)
    # a second mode leaves a misfit larger than the noise, or smooth (correlated) along frequency
    correlation = float(np.real(np.vdot(misfit[:-1], misfit[1:]))) / power if power > 0 else 0.0
    systematic = misfit_rms > CLOSE_EXCESS * noise or correlation > CLOSE_CORRELATION / np.sqrt(n)

    flags = []
    # a degenerate circle through one noisy point can be large: the points' own span must be too
    span = float(np.abs(y - (np.median(y.real) + 1j * np.median(y.imag))).max())
    weak = min(2.0 * radius, span) < WEAK_FACTOR * noise
    if weak:
        flags.append("weak")
    if circle_error > POOR_CIRCLE:
        flags.append("poor_circle")
    if min(n_above, n_below) < MIN_SIDE_POINTS:
        flags.append("few_points")
    half_width = zeta * omega_r / (2 * np.pi)
    f_r = omega_r / (2 * np.pi)
    if not (lo + half_width <= f_r <= hi - half_width):
        flags.append("edge_of_band")
    if unresolved and not found:
        flags.append("unresolved")
    # a mode the circle could not resolve was not fitted by it: its misfit says nothing of a second mode
    triggered = bool(systematic and misfit_rms > CLOSE_FLOOR * radius and not weak and not unresolved)
    # a systematic misfit is a distortion (or a second mode): a finite record's window smears the
    # peak over its main lobe (+-1 line rectangular, +-2 Hanning), so the half-power bandwidth
    # 2 zeta f_r is known to LEAKAGE_LINES line spacings only; so is a mode narrower than a line
    model_form = LEAKAGE_LINES * float(np.median(np.diff(omega))) / (2.0 * omega_r) if triggered or unresolved else 0.0
    f_ci, z_ci = _intervals(f_r, zeta, zeta_sweep, spread, model_form)
    fit = ModalFit(
        frequency_hz=float(f_r),
        damping_ratio=float(zeta),
        damping_scatter=float(np.std(estimates)) if estimates.size else float("nan"),
        modal_constant=complex(2.0 * zeta * omega_r * diameter),
        residual_lower=complex(lower),
        residual_upper=complex(upper),
        circle_error=circle_error,
        noise=noise,
        diameter=float(2.0 * radius),
        points_used=int(n),
        pairs_used=int(estimates.size),
        band=(lo, hi),
        flags=tuple(flags),
        frequency_ci95_hz=f_ci,
        damping_ci95=z_ci,
        damping_model_form=model_form,
    )
    return fit, triggered  # the trigger of the second-mode test: systematic, beyond CLOSE_FLOOR radii

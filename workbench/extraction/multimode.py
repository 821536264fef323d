"""Multi-mode fit of one band: poles common to all the curves of a test, modal constants per curve.

Used where one peak may hide two modes (`workbench.extraction.modes`) and where a circle fit's
misfit is systematic (`workbench.extraction.circlefit`): is it a second mode, or only a curve that is
not a perfect circle (leakage, a slightly nonlinear joint)?

Model, in the curves' own quantity (``p`` = 0, 1, 2 for receptance, mobility, accelerance;
exp(+i omega t), CONTRACTS.md)::

    H_c(omega) = (i omega)^p [ sum_r A_cr / (omega_r^2 - omega^2 + 2 i zeta_r omega_r omega)
                               + U_c - L_c / omega^2 ],

the poles ``(omega_r, zeta_r)`` shared by every curve ``c`` (one structure, one test), the complex
modal constants ``A_cr`` (receptance, 1/kg) and residuals ``U_c`` (m/N), ``L_c`` (1/kg) per curve.
Each curve is divided by its noise level first, so that the residual sum of squares reads in
noise variances. For given poles the model is linear in ``A, U, L``: they are solved by least
squares and eliminated (variable projection, Golub & Pereyra 1973), and only ``log omega_r,
log zeta_r`` are refined by Levenberg-Marquardt (`workbench.extraction.levenberg.lm`). The covariance of those from the
projected Jacobian, ``s^2 (J^T J)^-1`` with ``s^2`` the residual variance on ``N - P`` degrees of
freedom (``N`` real observations, ``P`` real parameters, linear ones included), gives 95 %
intervals with the Student-t quantile on ``N - P``.

One mode or two (`second_mode`): the two-pole fit is started from the one-pole fit (the second pole
where the one-pole misfit is largest, and either side of the first at a half-power bandwidth) and
accepted only when every one of these holds:

- the residual drops beyond what the extra parameters buy: the F statistic
  ``((RSS_1 - RSS_2) / (P_2 - P_1)) / (RSS_2 / (N - P_2))`` above its ``1 - SPLIT_ALPHA`` quantile;
- the second pole explains most of the one-pole misfit in excess of the noise: what remains in
  excess after two poles is below ``UNEXPLAINED`` times the drop (a curve that is not a perfect
  circle, e.g. a softening joint's skewed peak or leakage, is fitted a little better by any extra
  pole, but is not explained by one);
- both poles lie inside the band by at least their half-power half-width (a pole at the edge stands
  for a neighbour's tail), with a damping ratio in ``DAMPING_RANGE``, and at least
  `RESOLVED_LINES` lines apart (closer, a finite record's window cannot tell them from one mode);
- over two curves or more, the two poles' modal constants differ in shape: their MAC is below
  `SAME_SHAPE` (one mode distorted by leakage or a nonlinear joint gives a "second pole" of the
  same shape; measured on UNESP-BERT's 18.7 Hz mode: MAC 1.000);
- each pole's peak contribution exceeds `MIN_PEAK_NOISE` noise levels on some curve and
  `MIN_PEAK_FRACTION` of the larger pole's peak (summed over curves in noise levels).
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import cache

import numpy as np
from scipy.stats import chi2
from scipy.stats import f as f_dist
from scipy.stats import t as t_dist

from workbench.extraction.levenberg import LastCall, lm

__all__ = [
    "SPLIT_ALPHA",
    "UNEXPLAINED",
    "RESOLVED_LINES",
    "SAME_SHAPE",
    "DAMPING_RANGE",
    "MIN_PEAK_NOISE",
    "MIN_PEAK_FRACTION",
    "PoleFit",
    "inverse_normal",
    "noise_level",
    "pole_fit",
    "second_mode",
    "t975",
]

SPLIT_ALPHA = 1e-3            # F-test level for a second pole
UNEXPLAINED = 0.1             # misfit left in excess of noise after two poles / the drop they bring
RESOLVED_LINES = 2.0          # two poles closer than this many lines are one mode seen through a window
SAME_SHAPE = 0.99             # MAC of the two poles' constants over >= 2 curves above which one mode
DAMPING_RANGE = (1e-5, 0.1)   # a plausible modal damping ratio
MIN_PEAK_NOISE = 5.0          # a pole's peak, in noise levels, on its best curve (as WEAK_FACTOR)
MIN_PEAK_FRACTION = 0.05      # a pole's peak over the larger pole's (noise-weighted over curves)
_POWER = {"receptance": 0, "mobility": 1, "accelerance": 2}


@dataclass(frozen=True)
class PoleFit:
    """Poles common to several curves over one band, with modal constants per curve.

    Attributes
    ----------
    frequency_hz, damping_ratio : (n_poles,) Hz and viscous ratios, increasing in frequency.
    frequency_ci95_hz, damping_ci95 : (n_poles, 2) 95 % intervals (Student-t on ``dof``).
    modal_constants : (n_curves, n_poles) complex receptance constants ``A_cr`` (1/kg).
    residual_upper, residual_lower : (n_curves,) complex ``U`` (m/N) and ``L`` (1/kg).
    peak_noise : (n_curves, n_poles) each pole's peak contribution over the band, in the curve's
        noise levels.
    misfit_noise : (n_curves,) RMS misfit per line of each curve, in its noise levels.
    rss : residual sum of squares, in noise variances (``E|n|^2`` per complex point).
    observations, parameters : real observations ``N`` and real parameters ``P``; ``dof = N - P``.
    band : (f_lo, f_hi), Hz.
    resolution_hz : median line spacing in the band, Hz.
    """

    frequency_hz: np.ndarray
    damping_ratio: np.ndarray
    frequency_ci95_hz: np.ndarray
    damping_ci95: np.ndarray
    modal_constants: np.ndarray
    residual_upper: np.ndarray
    residual_lower: np.ndarray
    peak_noise: np.ndarray
    misfit_noise: np.ndarray
    rss: float
    observations: int
    parameters: int
    band: tuple[float, float]
    resolution_hz: float

    @property
    def dof(self) -> int:
        return self.observations - self.parameters


@cache
def t975(dof: int) -> float:
    """The Student-t 97.5 % quantile on ``dof`` degrees of freedom, remembered: `scipy.stats` takes 70 us a call,
    and the fits of a campaign ask it for a few dozen ``dof`` some 1500 times.
    """
    return float(t_dist.ppf(0.975, dof))


@cache
def _chi2_level(dof: int) -> float:
    """The ``1 - SPLIT_ALPHA`` quantile of ``chi^2(dof)`` (`second_mode`), remembered as `t975` is."""
    return float(chi2.ppf(1.0 - SPLIT_ALPHA, dof))


@cache
def _f_level(extra: int, dof: int) -> float:
    """The ``1 - SPLIT_ALPHA`` quantile of ``F(extra, dof)`` (`accept_second`), remembered as `t975` is."""
    return float(f_dist.ppf(1.0 - SPLIT_ALPHA, extra, dof))


def noise_level(frfs) -> np.ndarray:
    """Noise RMS of each curve, (n_curves,), from second differences along frequency: for white
    circular noise of ``E|n|^2 = sigma^2``, ``|n_(i+1) - 2 n_i + n_(i-1)|`` is Rayleigh with median
    ``sigma sqrt(6 ln 2)``; the median ignores the few large second differences at sharp peaks.
    On a noise-free curve it measures the curve's own smoothness instead.
    """
    h = np.atleast_2d(np.asarray(frfs, complex))
    second = np.abs(h[:, 2:] - 2.0 * h[:, 1:-1] + h[:, :-2])
    sigma = np.median(second, axis=1) / np.sqrt(6.0 * np.log(2.0))
    return np.maximum(sigma, np.finfo(float).tiny * np.abs(h).max(axis=1) + np.finfo(float).tiny)


def inverse_normal(jac: np.ndarray) -> np.ndarray:
    """``(J^T J)^-1`` of a least-squares Jacobian (n_obs, n_par), columns scaled to unit norm first:
    parameters whose scales differ by orders of magnitude make an unscaled pseudo-inverse drop the
    small directions and understate the variances (measured: by 20 % on the circle fit's frequency).
    """
    norms = np.linalg.norm(jac, axis=0)
    norms = np.maximum(norms, 1e-12 * norms.max() + 1e-300)  # an unidentified parameter: a huge variance
    return np.linalg.pinv((jac / norms).T @ (jac / norms)) / norms[:, None] / norms[None, :]


def _basis(omega: np.ndarray, x: np.ndarray, power: int) -> np.ndarray:
    """(n, n_poles + 2) complex columns: pole terms, then ``U`` and ``-L / w^2``, all times (i w)^p."""
    n_poles = x.size // 2
    wr, zeta = np.exp(x[:n_poles]), np.exp(x[n_poles:])
    poles = 1.0 / (wr[None, :] ** 2 - omega[:, None] ** 2 + 2j * zeta[None, :] * wr[None, :] * omega[:, None])
    columns = np.column_stack([poles, np.ones_like(omega), -1.0 / omega**2])
    return columns * ((1j * omega) ** power)[:, None]


def _projection_jacobian(omega: np.ndarray, data: np.ndarray, x: np.ndarray, power: int,
                         basis: np.ndarray | None = None) -> np.ndarray:
    """Jacobian of the variable-projection residual ``r = (I - P) d`` (`_solve`, stacked as in
    `pole_fit`) with respect to the poles' ``(log w_r, log zeta)``: Golub and Pereyra's
    ``dr = -(I - P) dPhi c - (Phi^+)^H dPhi^H r`` (1973), valid for complex columns and coefficients
    with real parameters since ``P`` is Hermitian. Written out because finite differences of the
    projected residual were most of the cost of telling a second mode (`second_mode`). ``basis``:
    `_basis` at ``x`` when the residual there has computed it already.
    """
    n_poles = x.size // 2
    wr, zeta = np.exp(x[:n_poles]), np.exp(x[n_poles:])
    basis = _basis(omega, x, power) if basis is None else basis
    norms = np.maximum(np.abs(basis).max(axis=0), 1e-300)
    q, upper = np.linalg.qr(basis / norms)
    q_h = q.conj().T
    coefficients = np.linalg.solve(upper, q_h @ data) / norms[:, None]
    r = data - basis @ coefficients
    damping = 2j * zeta[None, :] * wr[None, :] * omega[:, None]
    core = wr[None, :] ** 2 - omega[:, None] ** 2 + damping  # the same sum, term for term, as `_basis`'s
    g = basis[:, :n_poles] / core  # d(1 / core) = -d(core) / core^2, the pole column being (i w)^p / core
    # d/d log w_r, then d/d log zeta, of each pole column: (n, 2 n_poles), parameter k moving column k % n_poles
    d = np.concatenate([-g * (2.0 * wr[None, :] ** 2 + damping), -g * damping], axis=1)
    pole = np.tile(np.arange(n_poles), 2)
    first = d[:, :, None] * coefficients[pole][None, :, :]                      # (n, 2 n_poles, n_curves)
    flat = first.reshape(first.shape[0], -1)
    first = (flat - q @ (q_h @ flat)).reshape(first.shape)                       # (I - P) dPhi c
    lift = q @ np.linalg.solve(upper.conj().T, np.eye(upper.shape[0])[:, :n_poles]) / norms[:n_poles]
    second = lift[:, pole][:, :, None] * (d.conj().T @ r)[None, :, :]            # (Phi^+)^H dPhi^H r
    v = -(first + second).transpose(1, 0, 2).reshape(2 * n_poles, -1)
    return np.concatenate([v.real, v.imag], axis=1).T


def _solve(omega, data, x, power, basis=None):
    """Linear coefficients (m, n_curves) for given poles, and the residual (n, n_curves); ``basis``:
    `_basis` at ``x`` when computed already.
    """
    basis = _basis(omega, x, power) if basis is None else basis
    norms = np.maximum(np.abs(basis).max(axis=0), 1e-300)  # column scaling for the conditioning
    coefficients, *_ = np.linalg.lstsq(basis / norms, data, rcond=None)
    coefficients = coefficients / norms[:, None]
    return coefficients, data - basis @ coefficients


def pole_fit(frequency_hz, frfs, band: tuple[float, float], quantity: str, noise, starts) -> PoleFit:
    """Least-squares poles common to ``frfs`` over ``band`` (module docstring), best of ``starts``.

    Parameters
    ----------
    frequency_hz : (n_freq,) Hz, strictly increasing.
    frfs : (n_curves, n_freq) complex FRFs in the unit of ``quantity``.
    band : (f_lo, f_hi) Hz, both ends included.
    quantity : receptance, mobility or accelerance.
    noise : (n_curves,) each curve's noise RMS, its own unit (`circlefit.noise_level`).
    starts : sequence of starting poles, each a sequence of (frequency Hz, damping ratio); all of one
        length, the number of poles.

    Returns
    -------
    PoleFit (poles sorted by frequency).
    """
    f = np.asarray(frequency_hz, float)
    inside = (f >= band[0]) & (f <= band[1])
    omega = 2.0 * np.pi * f[inside]
    data = (np.atleast_2d(frfs)[:, inside] / np.asarray(noise, float)[:, None]).T  # (n, n_curves)
    power = _POWER[quantity]

    # poles kept within the band widened by its width, damping within (1e-6, 0.5) (clipped in the
    # model: a wandering pole is a failed start, not an answer)
    width = band[1] - band[0]
    w_lo, w_hi = np.log(2.0 * np.pi * max(band[0] - width, 0.5 * band[0])), np.log(2.0 * np.pi * (band[1] + width))
    z_lo, z_hi = np.log(1e-6), np.log(0.5)

    def bounded(x):
        n = x.size // 2
        # np.minimum(np.maximum()): np.clip's values, without its 4 us of dispatch at every evaluation
        return np.concatenate([np.minimum(np.maximum(x[:n], w_lo), w_hi),
                               np.minimum(np.maximum(x[n:], z_lo), z_hi)])

    # the basis at the last poles: lmder asks the Jacobian where it had the residual
    basis_at = LastCall(lambda poles: _basis(omega, poles, power))

    def residual(x):
        x = bounded(x)
        r = _solve(omega, data, x, power, basis_at(x))[1].ravel()
        return np.concatenate([r.real, r.imag])

    def jacobian(x):
        poles = bounded(x)
        inside = (x == poles).astype(float)  # a clipped parameter does not move the model
        return _projection_jacobian(omega, data, poles, power, basis_at(poles)) * inside[None, :]

    best = None
    for start in starts:
        s = np.asarray(start, float)
        # a start outside the poles' range (a wide one-pole fit's f (1 - 2 zeta) can reach 0 Hz) is
        # brought to its edge before the logarithm
        w0 = np.clip(2.0 * np.pi * s[:, 0], np.exp(w_lo), np.exp(w_hi))
        x0 = bounded(np.concatenate([np.log(w0), np.log(np.clip(s[:, 1], 1e-6, 0.5))]))
        sol = lm(residual, x0, jacobian, xtol=1e-10, ftol=1e-10)
        if best is None or sol.cost < best.cost:
            best = sol
    assert best is not None, "pole_fit: no start given"
    n_poles = best.x.size // 2
    solution = bounded(best.x)
    order = np.argsort(solution[:n_poles])
    x = np.concatenate([solution[:n_poles][order], solution[n_poles:][order]])
    jac = best.jac[:, np.concatenate([order, order + n_poles])]
    coefficients, r = _solve(omega, data, x, power)
    n_obs = 2 * data.size
    n_par = 2 * n_poles + 2 * coefficients.size
    rss = float(np.sum(np.abs(r) ** 2))
    dof = max(n_obs - n_par, 1)
    # covariance of (log w_r, log zeta_r): residual variance per real observation, (J^T J)^-1
    variance = rss / dof
    cov = variance * inverse_normal(jac)
    half = np.minimum(t975(dof) * np.sqrt(np.clip(np.diag(cov), 0.0, None)), 50.0)
    wr, zeta = np.exp(x[:n_poles]), np.exp(x[n_poles:])
    fr = wr / (2.0 * np.pi)
    constants = coefficients[:n_poles].T * np.asarray(noise, float)[:, None]   # (n_curves, n_poles)
    # each pole's contribution at its own peak, |A| / (2 zeta w_r^2) times w_r^p, in noise levels
    peak = np.abs(coefficients[:n_poles].T) / (2.0 * zeta * wr**2) * wr**power
    return PoleFit(
        frequency_hz=fr, damping_ratio=zeta,
        frequency_ci95_hz=np.column_stack([fr * np.exp(-half[:n_poles]), fr * np.exp(half[:n_poles])]),
        damping_ci95=np.column_stack([zeta * np.exp(-half[n_poles:]), zeta * np.exp(half[n_poles:])]),
        modal_constants=constants,
        residual_upper=coefficients[n_poles] * np.asarray(noise, float),
        residual_lower=coefficients[n_poles + 1] * np.asarray(noise, float),
        peak_noise=peak, misfit_noise=np.sqrt(np.mean(np.abs(r) ** 2, axis=0)), rss=rss,
        observations=n_obs, parameters=n_par, band=(float(band[0]), float(band[1])),
        resolution_hz=float(np.median(np.diff(f[inside]))))


def _second_starts(frequency_hz, one: PoleFit, frfs, quantity, noise) -> list:
    """Two-pole starts from the one-pole fit: the largest misfit, and a bandwidth either side."""
    f = np.asarray(frequency_hz, float)
    inside = (f >= one.band[0]) & (f <= one.band[1])
    omega = 2.0 * np.pi * f[inside]
    data = (np.atleast_2d(frfs)[:, inside] / np.asarray(noise, float)[:, None]).T
    x = np.log(np.concatenate([2.0 * np.pi * one.frequency_hz, one.damping_ratio]))
    misfit = np.sum(np.abs(_solve(omega, data, x, _POWER[quantity])[1]) ** 2, axis=1)
    f1, z1 = float(one.frequency_hz[0]), float(one.damping_ratio[0])
    worst = float(f[inside][int(np.argmax(np.convolve(misfit, np.ones(3) / 3, mode="same")))])
    starts = [[(f1, z1), (worst, z1)]]
    for k in (1.0, 2.0):
        starts.append([(f1 * (1 - k * z1), z1 / 2), (f1 * (1 + k * z1), z1 / 2)])
    return starts


def second_mode(frequency_hz, frfs, band: tuple[float, float], quantity: str, noise,
                start: tuple[float, float], screen: bool = True) -> tuple[PoleFit, PoleFit, bool]:
    """One pole or two over ``band`` (module docstring: the tests for a second pole).

    Parameters
    ----------
    frequency_hz, frfs, band, quantity, noise : as `pole_fit`.
    start : (frequency Hz, damping ratio) of the mode seen, e.g. the circle fit's.
    screen : skip the two-pole fit (and return the one-pole fit twice) when the one-pole residual
        is noise, below the ``1 - SPLIT_ALPHA`` quantile of ``chi^2(dof) / 2``.

    Returns
    -------
    (one-pole fit, two-pole fit, True when the second pole is accepted).
    """
    one = pole_fit(frequency_hz, frfs, band, quantity, noise, [[start]])
    if screen and one.rss <= 0.5 * _chi2_level(one.dof):
        return one, one, False  # the one-pole fit leaves noise only: nothing for a second pole
    two = pole_fit(frequency_hz, frfs, band, quantity, noise,
                   _second_starts(frequency_hz, one, frfs, quantity, noise))
    return one, two, accept_second(one, two)


def accept_second(one: PoleFit, two: PoleFit) -> bool:
    """True when ``two`` (two poles) is a better account of the band than ``one`` (module docstring)."""
    if two.dof < 1 or not two.rss < one.rss:
        return False
    extra = two.parameters - one.parameters
    statistic = ((one.rss - two.rss) / extra) / (two.rss / two.dof)
    if statistic < _f_level(extra, two.dof):
        return False
    # noise-normalised data: pure noise leaves RSS = N / 2 (E|n|^2 = 1 split over real and imaginary)
    excess = max(two.rss - 0.5 * two.dof, 0.0)
    if excess > UNEXPLAINED * (one.rss - two.rss):
        return False
    lo, hi = two.band
    if np.diff(two.frequency_hz).min() < RESOLVED_LINES * two.resolution_hz:
        return False
    # each pole a half-power half-width inside the band: a pole at the edge stands for a mode outside
    half = two.damping_ratio * two.frequency_hz
    if not (np.all((two.frequency_hz - half > lo) & (two.frequency_hz + half < hi))
            and np.all((two.damping_ratio > DAMPING_RANGE[0]) & (two.damping_ratio < DAMPING_RANGE[1]))):
        return False
    a, b = two.modal_constants[:, 0], two.modal_constants[:, 1]
    if a.size >= 2 and abs(np.vdot(a, b)) ** 2 > SAME_SHAPE * np.vdot(a, a).real * np.vdot(b, b).real:
        return False
    strength = two.peak_noise.sum(axis=0)
    return bool(np.all(two.peak_noise.max(axis=0) > MIN_PEAK_NOISE)
                and strength.min() > MIN_PEAK_FRACTION * strength.max())

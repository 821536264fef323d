"""Fitting one candidate: in sample, and leave one mode out.

**Frequency candidates** are fitted on their curve (`workbench.diagnose.curves`): a scan of the
parameter then Brent's method on the frequency chi-square (covariance-weighted). Amplitude
softening reuses a joint's stiffness curve at ``gamma(a) = 1 - slope * a`` per condition.
**Damping**: one modal damping ratio for every mode (the baseline; the frame file's ratio is a
placeholder, not a model), plus for ``joint_damping`` a loss per unit of the joint's strain-energy
share, fitted by least squares.

**Held-out protocol: leave one mode out.** For each measured mode, every candidate is refitted on
the other modes and predicts that mode (all its conditions, frequency and damping). The held-out
error is the error of those predictions. A candidate that fits by bending one parameter to noise
predicts the held-out modes badly; the effect that is present predicts them. The baseline has no
frequency parameter, so its held-out frequency error is its in-sample error. Candidates are ranked
by their total held-out chi-square (frequency and damping, each residual over its standard error);
the ranking also lists the BIC, ``chi2 + p ln N``.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import numpy as np
from scipy.optimize import minimize_scalar

from workbench.diagnose.baseline import Baseline
from workbench.diagnose.curves import Curve
from workbench.diagnose.observations import (
    Observations,
    damping_chi2,
    damping_whiten,
    frequency_chi2,
    frequency_chi2_many,
    frequency_score,
    mode_frequency_hz,
    rms,
)
from workbench.rig.effects import JOINT_DAMPING

__all__ = ["DAMPING_TREND_MODES", "CandidateFit", "Frequencies", "fit_curve", "damping_columns", "damping_fit",
           "evaluate"]

DAMPING_TREND_MODES = 3  # the damping fit takes a trend in log frequency from this many modes on
SCAN_POINTS = 161  # parameter values scanned before Brent's method
BOUND_TOLERANCE = 1e-3  # of a parameter's range: a fit this close to a range's end sits at that bound


@dataclass(frozen=True)
class CandidateFit:
    """One effect at one place, fitted: in-sample and held-out errors (module docstring)."""

    effect: str
    where: str | None
    parameters: dict
    channel: str  # "frequency" or "damping": the data it changes
    chi2: float  # in-sample, frequency + damping
    chi2_frequency: float  # in-sample, frequency
    heldout_chi2: float
    heldout_chi2_frequency: float
    heldout_chi2_damping: float
    freq_rms_rel_error: float
    heldout_freq_rms_rel_error: float
    damping_rms_error: float | None
    heldout_damping_rms_error: float | None
    parameter_count: int
    bic: float
    heldout_logdet: float = 0.0  # log det of the covariance widened by the form's error, over the plain one
    observations: int = 1  # means fitted (frequency and damping), for the parameters' charge
    form: str = ""  # which of the effect's forms at this place (its swept parameter and fixed ones)
    at_bound: bool = False  # its in-sample parameter at a far end of its range (`Frequencies.at_bound`)

    @property
    def key(self) -> tuple[str, str | None, str]:
        """``(effect, where, form)``: one candidate, where one effect may have several forms at one place (a
        support's rotational and translational springs, masses at several positions along one member).
        """
        return self.effect, self.where, self.form

    @property
    def heldout_score(self) -> float:
        """Minus twice the held-out log predictive density, up to a constant (chi-square plus log det), plus
        ``ln N`` for each parameter beyond the one every candidate has (`extra_charge`).
        """
        return self.heldout_chi2 + self.heldout_logdet + self.extra_charge

    @property
    def extra_charge(self) -> float:
        """``ln N`` per parameter beyond the first (`heldout_score`): an added mass's place and position, and
        a two-form candidate's second parameter (a support's second stiffness, the drive's moving mass), which
        leave-one-out refits but which is charged as a prior against the richer form
        (`workbench.diagnose.combined.form_pairs`).
        """
        return max(self.parameter_count - 1, 0) * math.log(max(self.observations, 2))


class Frequencies:
    """Predicted condition means as a function of one parameter, fitted by a scan and Brent.

    ``u`` is the curve's coordinate (`Curve.coordinate`), or with ``amplitude_joint`` the slope
    ``c`` of a joint's relative modulus ``gamma(a) = 1 - c (a / a_min - 1)`` on a joint stiffness curve:
    a law in the excitation level, nil at the lowest level.
    """

    def __init__(self, base: Baseline, obs: Observations, curve: Curve, amplitude_joint: bool = False):
        self.base, self.obs, self.curve, self.amplitude = base, obs, curve, amplitude_joint
        self.spline = curve.interpolant()
        # softening is nil at the lowest level, where the model is the linear one: gamma = 1 - c (a / a_min - 1)
        self.excess = obs.amplitude / obs.amplitude.min() - 1.0
        if amplitude_joint:  # c up to where the curve's lowest modulus (or 0.1) is reached
            lowest = float(curve.values.min())
            self.lo, self.hi = 0.0, (1.0 - max(lowest, 0.1)) / max(float(self.excess.max()), 1e-12)
        else:
            u = curve.coordinate(curve.values)
            self.lo, self.hi = float(u.min()), float(u.max())

    def predict(self, u: float) -> np.ndarray:
        """(n_cond, n_measured) predicted means, Hz, at ``u``."""
        return self.predict_many(np.array([u]))[0]

    def predict_many(self, u: np.ndarray) -> np.ndarray:
        """(n_u, n_cond, n_measured) predicted means, Hz, at each of ``u`` (n_u,)."""
        if self.amplitude:
            # the range's end reaches the curve's lowest modulus to within rounding, which can fall just off
            # the spline (NaN): held on the grid
            gamma = np.maximum(1.0 - u[:, None] * self.excess[None, :], float(self.curve.values.min()))
            model_hz = self.spline(np.log(gamma))  # (n_u, n_cond, n_model)
        else:
            model_hz = np.broadcast_to(self.spline(u)[:, None, :], (u.size, self.obs.amplitude.size, self.base.count))
        return self.base.frequency(np.asarray(model_hz))

    def at_bound(self, u: float) -> bool:
        """Whether the coordinate ``u`` sits at an end of the range (within `BOUND_TOLERANCE` of it) that is
        not the no-effect end: the data ask for more of the effect than the range holds (a joint 10 times
        stiffer, a member at the last force its grid solved before buckling), and the fitted value is a bound,
        not an estimate.
        """
        nominal = 0.0 if self.amplitude else (None if self.curve.nominal is None
                                              else float(self.curve.coordinate(self.curve.nominal)))
        tolerance = BOUND_TOLERANCE * (self.hi - self.lo)
        return any(abs(u - end) <= tolerance and (nominal is None or abs(end - nominal) > tolerance)
                   for end in (self.lo, self.hi))

    def fit(self, modes_mask: np.ndarray) -> tuple[float, np.ndarray]:
        """``(u, predicted means)`` fitted on the modes in ``modes_mask``."""
        u, predicted, _ = self.fit_cost(modes_mask)
        return u, predicted

    def fit_cost(self, modes_mask: np.ndarray) -> tuple[float, np.ndarray, float]:
        """``(u, predicted means, frequency chi-square)`` fitted on the modes in ``modes_mask``."""
        cache: dict = {}

        def cost(u: float) -> float:  # inf where the curve has no value (outside its grid)
            return frequency_chi2(self.obs, self.predict(u), modes_mask, cache)

        grid = np.linspace(self.lo, self.hi, SCAN_POINTS)
        costs = frequency_chi2_many(self.obs, self.predict_many(grid), modes_mask, cache)
        i = int(np.argmin(costs))
        a, b = grid[max(i - 1, 0)], grid[min(i + 1, grid.size - 1)]
        if b > a:
            res = minimize_scalar(cost, bounds=(a, b), method="bounded", options={"xatol": 1e-6 * (self.hi - self.lo)})
            u = float(res.x) if res.fun <= costs[i] else float(grid[i])
        else:
            u = float(grid[i])
        return u, self.predict(u), cost(u)


def fit_curve(base: Baseline, obs: Observations, curve: Curve,
              modes_mask: np.ndarray) -> tuple[float, np.ndarray, float]:
    """`Frequencies.fit_cost` of ``curve``."""
    return Frequencies(base, obs, curve).fit_cost(modes_mask)


def damping_fit(obs: Observations, share: np.ndarray | None, modes_mask: np.ndarray) -> tuple[np.ndarray, dict]:
    """Least squares of ``zeta = c0 + c1 ln(f / f_mean) (+ eta * share)``, eta >= 0, on the modes in ``modes_mask``.

    The trend in log frequency is the baseline's: modal damping of a real structure drifts with frequency
    (material loss, air, the supports), and a joint is named only for the part that follows its energy share.
    The means are weighted by their standard errors and the damping model's error, one per mode (`damping_chi2`).

    Returns
    -------
    (n_cond, n_measured) predicted damping ratios on every mode, and ``{"eta": eta}`` with a share.
    """
    if obs.damping is None or obs.damping_se is None:
        raise ValueError("damping_fit: no damping was measured")
    columns = damping_columns(obs, modes_mask)
    if share is not None:
        columns.append(np.broadcast_to(share, obs.damping.shape))
    # generalised least squares under the means' covariance (one model error per mode, `damping_whiten`)
    d = damping_whiten(obs, obs.damping)[:, modes_mask].ravel()

    def solve(cols: list[np.ndarray]) -> np.ndarray:
        a = np.stack([damping_whiten(obs, c)[:, modes_mask].ravel() for c in cols], axis=1)
        return np.linalg.lstsq(a, d, rcond=None)[0]

    coef = solve(columns)
    if share is not None and coef[-1] < 0:  # a joint does not remove damping
        columns = columns[:-1]
        coef = np.append(solve(columns), 0.0)
        columns.append(np.broadcast_to(share, obs.damping.shape))
    full = sum(c * k for c, k in zip(columns, coef))
    return np.asarray(full, float), ({JOINT_DAMPING.parameter: float(coef[-1])} if share is not None else {})


def damping_columns(obs: Observations, modes_mask: np.ndarray) -> list[np.ndarray]:
    """The damping baseline's columns (n_cond, n_modes) for a fit on ``modes_mask`` (`damping_fit`): its level,
    and from `DAMPING_TREND_MODES` modes on its trend in log frequency, each mode at its mean frequency over the
    levels (a linear model damps a mode alike at every level).
    """
    if obs.damping is None:
        raise ValueError("damping_columns: no damping was measured")
    log_f = np.log(mode_frequency_hz(obs) / np.nanmean(obs.frequency_hz))
    trend = np.broadcast_to(np.nan_to_num(log_f - np.nanmean(log_f)), obs.damping.shape)
    return [np.ones_like(obs.damping)] + ([trend] if int(np.sum(modes_mask)) >= DAMPING_TREND_MODES else [])


def _held_out(fit: Callable[[np.ndarray], np.ndarray], like: np.ndarray) -> np.ndarray:
    """Each mode's column predicted by ``fit`` on the other modes."""
    n_modes = like.shape[1]
    held = np.full_like(like, np.nan)
    for k in range(n_modes):
        mask = np.ones(n_modes, bool)
        mask[k] = False
        held[:, k] = fit(mask)[:, k]
    return held


def evaluate(effect: str, where: str | None, parameters_of: Callable[[Any], dict], channel: str,
             fit_frequency: Callable[[np.ndarray], tuple[Any, np.ndarray]] | None,
             fit_damping: Callable[[np.ndarray], tuple[np.ndarray, dict]] | None,
             obs: Observations, baseline_hz: np.ndarray, p_count: int,
             form: str = "", at_bound: Callable[[Any], bool] | None = None) -> tuple[CandidateFit, np.ndarray]:
    """In-sample fit and leave-one-mode-out predictions of one candidate.

    Parameters
    ----------
    effect, where, channel : the candidate (``channel``: the data it changes).
    parameters_of : its parameters from the fitted frequency coordinate (a float, or an array of two for two
        forms at one place).
    fit_frequency : `Frequencies.fit` (or a `workbench.diagnose.combined.PairGrid`'s), or None for a candidate
        that leaves the frequencies at ``baseline_hz``.
    fit_damping : `damping_fit` for a mode mask, or None when no damping was measured.
    obs : the observations; baseline_hz : (n_cond, n_measured) the baseline's means, Hz.
    p_count : number of fitted parameters, for the BIC.
    form : which form of the effect at ``where`` (`CandidateFit.form`).
    at_bound : `Frequencies.at_bound`, whether the in-sample coordinate sits at a bound.

    Returns
    -------
    The fit, and its in-sample predicted means (n_cond, n_measured), Hz.
    """
    everything = np.ones(obs.frequency_hz.shape[1], bool)
    params: dict = {}
    bound = False
    if fit_frequency is not None:
        u, in_f = fit_frequency(everything)
        params = parameters_of(u)
        bound = bool(at_bound(u)) if at_bound is not None else False
        held_f = _held_out(lambda mask: fit_frequency(mask)[1], obs.frequency_hz)
    else:
        in_f = held_f = baseline_hz
    in_chi2 = in_chi2_f = frequency_chi2(obs, in_f)
    held_chi2_f, held_logdet = frequency_score(obs, held_f, baseline_hz)
    held_chi2_d = 0.0
    d_rms = held_d_rms = None
    n_obs = int(np.sum(~np.isnan(obs.frequency_hz)))
    damping, damping_se = obs.damping, obs.damping_se
    if damping is not None and damping_se is not None:
        if fit_damping is None:
            raise ValueError(f"{effect}: damping was measured, but no damping fit was given")
        in_d, d_params = fit_damping(everything)
        held_d = _held_out(lambda mask: fit_damping(mask)[0], damping)
        if channel == "damping":
            params = d_params
        in_chi2 += damping_chi2(obs, in_d)
        held_chi2_d = damping_chi2(obs, held_d)
        d_rms, held_d_rms = rms(in_d - damping), rms(held_d - damping)
        n_obs += int(np.sum(~np.isnan(damping)))
    fit = CandidateFit(effect, where, params, channel, in_chi2, in_chi2_f, held_chi2_f + held_chi2_d, held_chi2_f,
                       held_chi2_d, rms(in_f / obs.frequency_hz - 1.0), rms(held_f / obs.frequency_hz - 1.0),
                       d_rms, held_d_rms, p_count, in_chi2 + p_count * math.log(max(n_obs, 2)), held_logdet, n_obs,
                       form, bound)
    return fit, in_f


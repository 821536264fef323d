"""Sim-to-real gap diagnosis: where the nominal model misses, which effect explains it, how far it shrinks.

The paper (section 5.2) ends with a gap it cannot close: the four-bolt frame's mean frequencies are
over-estimated, and the authors suspect the beam model, the boundary conditions, the joint model
or stress locked in by the tightening sequence. `diagnose` answers with the vocabulary of
CONTRACTS.md section 3 (the registry `workbench.rig.effects`), in stages:

- **Observations** (`workbench.diagnose.observations`): condition means of the measured modes per
  excitation amplitude, their standard errors and covariances.
- **Baseline** (`workbench.diagnose.baseline`): the frame file's model at its stochastic mean,
  paired with the measured modes. Damping baseline: one modal damping ratio for every mode, fitted.
- **Where** (`workbench.diagnose.localise`): regions scored by the share of the residual a change
  of their stiffness, mass or damping explains.
- **Which** (`workbench.diagnose.candidates`, `workbench.diagnose.curves`): each candidate effect
  of the registry, at each place it can sit, with one parameter (a support's rotational stiffness,
  a mass, a shear coefficient, a stinger stiffness, an axial force, a joint's modulus factor, a
  softening slope, a joint loss factor); added masses also choose their position along a member.
- **Held-out protocol** (`workbench.diagnose.fitting`): leave one mode out; candidates ranked by
  their total held-out chi-square.

**Verdict.** ``none`` when the baseline's chi-square per observation is within `GAP_RATIO` of 1 on
both frequency and damping. Otherwise the best-ranked candidate, if its held-out chi-square per
observation on the data it acts on is within `EXPLAINED_RATIO` (the gap is then explained down to
measurement scatter) and it shrinks the held-out error by at least `MIN_SHRINKAGE`; else
``unexplained``: a real gap remains that no candidate of the vocabulary brings to the scatter.
``shrinkage = 1 - heldout error after / baseline error`` on the held-out data, the RMS of the
relative frequency errors (the RMS of the damping errors for ``joint_damping``).
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass
from functools import partial

import numpy as np

from workbench.diagnose.baseline import Baseline, baseline
from workbench.diagnose.candidates import frame_curves
from workbench.diagnose.curves import Curve
from workbench.diagnose.fitting import CandidateFit, Frequencies, damping_fit, evaluate
from workbench.diagnose.localise import Region, energy_shares, localise
from workbench.diagnose.matrix_candidates import matrix_curves
from workbench.diagnose.observations import DAMPING_FLOOR, RELATIVE_FLOOR, Observations, frequency_chi2, observations
from workbench.extraction.records import MeasuredModes
from workbench.model.frame import Frame
from workbench.model.matrix_model import MatrixModel
from workbench.rig.effects import AMPLITUDE_SOFTENING, EFFECTS, JOINT_DAMPING, JOINT_STIFFNESS_SHIFT, NONE, UNEXPLAINED

__all__ = ["GAP_RATIO", "EXPLAINED_RATIO", "MIN_SHRINKAGE", "Diagnosis", "diagnose", "diagnosis_record"]

GAP_RATIO = 4.0  # baseline chi2 per observation above this: a gap beyond scatter
EXPLAINED_RATIO = 10.0  # held-out chi2 per observation at most this: explained down to scatter
MIN_SHRINKAGE = 0.3  # and the held-out error must shrink by at least this much

DampingFit = Callable[[np.ndarray], tuple[np.ndarray, dict]]


@dataclass(frozen=True)
class Diagnosis:
    """Everything `diagnosis_record` writes, plus the arrays the report plots.

    Frequencies are (n_cond, n_modes) condition means, Hz; ``best_hz`` is the verdict's in-sample
    prediction, or None; ``wall_time_s`` in s.
    """

    modes: np.ndarray  # measured mode labels
    amplitude: np.ndarray
    measured_hz: np.ndarray  # (n_cond, n_modes)
    frequency_se_hz: np.ndarray
    baseline_hz: np.ndarray  # (n_cond, n_modes)
    best_hz: np.ndarray | None  # the verdict's in-sample prediction, or None
    baseline: CandidateFit
    ranking: list[CandidateFit]
    localisation: list[Region]
    verdict: str
    where: str | None
    shrinkage: float
    observations_count: dict
    wall_time_s: float = 0.0
    partial: dict | None = None  # with an unexplained verdict, the best partial explanation (or None)


def _candidate_fits(base: Baseline, obs: Observations, curves: list[Curve], baseline_hz: np.ndarray,
                    fit_base_damping: DampingFit | None,
                    joint_share: np.ndarray) -> tuple[list[CandidateFit], dict[tuple[str, str | None], np.ndarray]]:
    """Every candidate fitted, ranked by held-out chi-square then BIC, and their in-sample predictions."""
    ranking, predictions = [], {}
    for curve in curves:
        fit, in_f = evaluate(curve.effect, curve.where, curve.parameters, EFFECTS[curve.effect].channel,
                             Frequencies(base, obs, curve).fit, fit_base_damping, obs, baseline_hz,
                             1 + ("position" in curve.fixed))
        ranking.append(fit)
        predictions[(fit.effect, fit.where)] = in_f
    slope = AMPLITUDE_SOFTENING.fitted_parameter
    if obs.amplitude.size > 1:  # softening: a joint's stiffness curve read at gamma(a) = 1 - slope * a
        for curve in curves:
            if curve.effect != JOINT_STIFFNESS_SHIFT.name:
                continue
            model = Frequencies(base, obs, curve, amplitude_joint=True)
            fit, in_f = evaluate(AMPLITUDE_SOFTENING.name, curve.where, lambda u: {slope: float(u)},
                                 AMPLITUDE_SOFTENING.channel, model.fit, fit_base_damping, obs, baseline_hz, 1)
            ranking.append(fit)
            predictions[(fit.effect, fit.where)] = in_f
    if obs.damping is not None:
        for j, joint in enumerate(base.frame.joint_names):
            fit, _ = evaluate(JOINT_DAMPING.name, joint, lambda u: {}, JOINT_DAMPING.channel, None,
                              partial(damping_fit, obs, joint_share[j]), obs, baseline_hz, 1)
            ranking.append(fit)
            predictions[(fit.effect, fit.where)] = baseline_hz
    ranking.sort(key=lambda c: (c.heldout_chi2, c.bic))
    return ranking, predictions


def _shrinkage(fit: CandidateFit, baseline: CandidateFit) -> float:
    if fit.channel == "damping":  # a damping candidate exists only where damping was measured
        after, before = fit.heldout_damping_rms_error, baseline.heldout_damping_rms_error
        if after is None or before is None:
            raise ValueError(f"{fit.effect}: a damping candidate without measured damping")
        return 1.0 - after / before
    return 1.0 - fit.heldout_freq_rms_rel_error / baseline.heldout_freq_rms_rel_error


def _channel_chi2(fit: CandidateFit, n_f: int, n_d: int) -> float:
    """Held-out chi2 per observation on the data the candidate changes."""
    if fit.channel == "damping":
        return fit.heldout_chi2_damping / max(n_d, 1)
    return fit.heldout_chi2_frequency / max(n_f, 1)


def _verdict(obs: Observations, baseline_hz: np.ndarray, baseline_fit: CandidateFit, ranking: list[CandidateFit],
             predictions: dict) -> tuple[str, str | None, float, np.ndarray | None, dict[str, int], dict | None]:
    """``(verdict, where, shrinkage, best_hz, observation counts, partial)`` (module docstring).

    ``partial``: with an ``unexplained`` verdict, the best candidate on a channel with a gap when its
    held-out error shrinks at all (``effect``, ``where``, ``shrinkage``: CONTRACTS.md section 3's
    optional key), else None.
    """
    n_f = int(np.sum(~np.isnan(obs.frequency_hz)))
    n_d = int(np.sum(~np.isnan(obs.damping))) if obs.damping is not None else 0
    chi2_f = frequency_chi2(obs, baseline_hz)
    chi2_d = baseline_fit.chi2 - chi2_f  # the damping baseline's in-sample part
    # each channel tested on its own: an effect may be named only where its own data show a gap
    # (a damping gap alone once licensed a frequency effect that fitted the noise)
    gaps = {"frequency": bool(chi2_f > GAP_RATIO * n_f), "damping": bool(n_d > 1 and chi2_d > GAP_RATIO * (n_d - 1))}
    verdict, where, shrinkage, best_hz, partial = NONE.name, None, 0.0, None, None
    if any(gaps.values()):
        verdict = UNEXPLAINED
        eligible = [c for c in ranking if gaps[c.channel]]
        if eligible:
            best = eligible[0]
            shrink = _shrinkage(best, baseline_fit)
            held_channel = _channel_chi2(best, n_f, n_d)
            if held_channel <= EXPLAINED_RATIO and shrink >= MIN_SHRINKAGE:
                verdict, where, shrinkage = best.effect, best.where, shrink
                best_hz = predictions[(best.effect, best.where)]
            elif shrink > 0.0:
                partial = {"effect": best.effect, "where": best.where, "shrinkage": float(shrink)}
    return verdict, where, shrinkage, best_hz, {"frequency": n_f, "damping": n_d}, partial


def diagnose(frame: Frame | MatrixModel, measured: MeasuredModes, notify: Callable[[str], None] | None = None, *,
             relative_floor: float = RELATIVE_FLOOR, damping_floor: float = DAMPING_FLOOR) -> Diagnosis:
    """Locate, name and measure the gap between ``frame`` and a campaign's modes (module docstring).

    Parameters
    ----------
    frame : the nominal model (the campaign's frame file or matrix model), joints at their mean modulus.
    measured : the measured modes (per test, with damping and amplitudes when known, or published means).
    notify : called with a short message before each stage.
    relative_floor, damping_floor : floors of the relative standard errors of the mean frequencies
        and damping ratios (`workbench.diagnose.observations`).

    Returns
    -------
    Diagnosis
    """
    start = time.perf_counter()
    say = notify or (lambda message: None)
    obs = observations(measured, relative_floor, damping_floor)
    say("baseline model and pairing")
    base = baseline(frame, obs)
    baseline_hz = np.broadcast_to(base.frequency(base.modes.frequency_hz), obs.frequency_hz.shape).copy()
    residual = (obs.frequency_hz / baseline_hz - 1.0).mean(axis=0)
    weight = 1.0 / np.nanmean((obs.frequency_se / obs.frequency_hz) ** 2, axis=0)
    shares = energy_shares(base)
    fit_base_damping = (lambda mask: damping_fit(obs, None, mask)) if obs.damping is not None else None

    baseline_fit, _ = evaluate("baseline", None, lambda u: {}, "frequency", None, fit_base_damping, obs,
                               baseline_hz, 0)
    damping_residual = None
    if obs.damping is not None:
        damping_residual = np.nanmean(obs.damping - damping_fit(obs, None, np.ones(obs.damping.shape[1], bool))[0],
                                      axis=0)
    regions = localise(base, obs, baseline_hz, damping_residual, shares)

    say("candidate effects: exact frequencies on parameter grids")
    curves = (matrix_curves(base, obs, residual, weight) if isinstance(frame, MatrixModel)
              else frame_curves(base, obs, residual, weight))
    ranking, predictions = _candidate_fits(base, obs, curves, baseline_hz, fit_base_damping, shares[0])
    verdict, where, shrinkage, best_hz, counts, partial = _verdict(obs, baseline_hz, baseline_fit, ranking,
                                                                   predictions)
    return Diagnosis(measured.modes, obs.amplitude, obs.frequency_hz, obs.frequency_se, baseline_hz, best_hz,
                     baseline_fit, ranking, regions, verdict, where, shrinkage, counts, time.perf_counter() - start,
                     partial)


def _ranking_entry(c: CandidateFit) -> dict:
    return {"effect": c.effect, "where": c.where, "parameters": c.parameters,
            "freq_rms_rel_error": c.freq_rms_rel_error, "heldout_freq_rms_rel_error": c.heldout_freq_rms_rel_error,
            "damping_rms_error": c.damping_rms_error, "heldout_damping_rms_error": c.heldout_damping_rms_error,
            "chi2": c.chi2, "heldout_chi2": c.heldout_chi2, "bic": c.bic, "parameter_count": c.parameter_count}


def diagnosis_record(campaign_name: str, diagnosis: Diagnosis) -> dict:
    """``diagnosis.json`` (CONTRACTS.md section 3), plus fields a reader may ignore."""
    d = diagnosis
    mean_measured = np.nanmean(d.measured_hz, axis=0)
    mean_model = np.nanmean(d.baseline_hz, axis=0)
    rows = [{"mode": int(m), "measured_hz": float(fm), "model_hz": float(fp), "rel_error": float(fp / fm - 1.0)}
            for m, fm, fp in zip(d.modes, mean_measured, mean_model) if np.isfinite(fm)]
    return {
        "campaign": campaign_name,
        "baseline": {"freq_rms_rel_error": d.baseline.freq_rms_rel_error, "modes": rows,
                     "damping_rms_error": d.baseline.damping_rms_error, "chi2": d.baseline.chi2,
                     "observations": d.observations_count},
        "localization": [{"region": r.region, "score": r.score, "kind": r.kind, "mechanism": r.mechanism}
                         for r in d.localisation],
        "ranking": [_ranking_entry(c) for c in d.ranking],
        "verdict": {"effect": d.verdict, "where": d.where, "shrinkage": d.shrinkage,
                    **({"partial": d.partial} if d.verdict == UNEXPLAINED else {})},
        "protocol": "leave one mode out: each candidate refitted on the other modes predicts the held-out mode",
        "wall_time_s": d.wall_time_s,
    }

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
  of the registry, at each place it can sit, with one parameter (a support's rotational or translational
  stiffness, a mass, a shear coefficient, a stinger stiffness, an axial force carried by the frame or locked
  in between a member's ends, a joint's modulus factor, a softening slope, a joint loss, hysteretic or
  viscous); added masses also choose their position along a member; a
  support also gives way in two of its dofs at once, and the drive acts by its spring and the mass moving with
  it at once, that mass never alone (`workbench.diagnose.combined.form_pairs`, `PAIRED_ONLY`: a clamp that rocks
  and slides, a shaker's suspension and armature), the second parameter charged in the score.
- **Held-out protocol** (`workbench.diagnose.fitting`): leave one mode out; candidates ranked by
  their total held-out chi-square.

**Verdict** (`workbench.diagnose.decision`): each channel tested for a gap against the measurement
error plus the model-form error the campaign allows (`workbench.diagnose.observations.Discrepancy`); the
best candidate on a channel with a gap named when its held-out error is within that error and its effect
outweighs the others (``confidence``); two effects (``also``) when only a pair explains the gap
(`workbench.diagnose.combined`); else ``unexplained`` with the best partial explanation.
``shrinkage = 1 - heldout error after / baseline error`` on the held-out data, the RMS of the
relative frequency errors (the RMS of the damping errors for ``joint_damping``).
"""

from __future__ import annotations

import time
import warnings
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field, replace
from functools import partial

import numpy as np
from threadpoolctl import threadpool_limits

from workbench.diagnose.baseline import Baseline, baseline
from workbench.diagnose.candidates import frame_curves
from workbench.diagnose.combined import PairFit, PairGrid, form_pairs, pair_fits
from workbench.diagnose.curves import Curve
from workbench.diagnose.decision import damping_family, decide, frequency_null
from workbench.diagnose.fitting import CandidateFit, Frequencies, damping_fit, evaluate
from workbench.diagnose.frf_levels import LevelChannel, LevelTest
from workbench.diagnose.geometry import stepped_models, tolerance_columns
from workbench.diagnose.localise import Region, energy_shares, localise
from workbench.diagnose.matrix_candidates import matrix_curves
from workbench.diagnose.observations import (
    DAMPING_FLOOR,
    DEFAULT_ALLOWANCE,
    FORM_SD,
    RELATIVE_FLOOR,
    Allowance,
    Discrepancy,
    Observations,
    mode_frequency_hz,
    observations,
)
from workbench.extraction.records import MeasuredModes
from workbench.model.frame import Frame
from workbench.model.matrix_model import MatrixModel
from workbench.rig.effects import (
    ADDED_MASS,
    AMPLITUDE_SOFTENING,
    EFFECTS,
    JOINT_DAMPING,
    JOINT_STIFFNESS_SHIFT,
    STINGER_STIFFNESS,
    SUPPORT_COMPLIANCE,
    UNEXPLAINED,
)
from workbench.tasks import Mapper

__all__ = ["Diagnosis", "diagnose", "diagnosis_record"]

DampingFit = Callable[[np.ndarray], tuple[np.ndarray, dict]]
# effects that act in two forms at one place, fitted together as one candidate (`combined.form_pairs`): a clamp
# that rocks and slides; a shaker's drive, its spring and the mass moving with it
TWO_FORMS = (SUPPORT_COMPLIANCE.name, STINGER_STIFFNESS.name)
# forms that are a candidate only with their effect's other form: a mass moving with the drive point alone is what
# an added mass there also is, on the drive's axis, and the frequencies cannot tell which (development seeds 10-12:
# as a candidate of its own it named two masses on the driven column the drive's and took a stocky frame's shear
# to unexplained; only with its spring, it lost none of them and named three stingers the spring alone did not)
PAIRED_ONLY = ((STINGER_STIFFNESS.name, "moving_mass"),)


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
    confidence: float = 0.0  # in [0, 1] (`workbench.diagnose.decision`)
    also: list[dict] = field(default_factory=list)  # further effects of a combined verdict
    gaps: dict = field(default_factory=dict)  # each channel's gap test
    discrepancy: Discrepancy = Discrepancy()
    frf_levels: dict | None = None  # the FRF-level test of the named frequency effect (`workbench.diagnose.frf_levels`)


def _parameter_count(curve: Curve) -> int:
    """A candidate's parameters: one, plus two for an added mass whose place and position a search over the
    whole frame chose on every mode (the leave-one-mode-out refit keeps them, so the score charges them).
    """
    return 3 if curve.effect == ADDED_MASS.name else 1


def _damping_forms(obs: Observations, share: np.ndarray) -> dict[str, tuple[np.ndarray, dict]]:
    """A joint's damping ratio per unit of its loss parameter, mode by mode, in the two textbook forms.

    ``hysteretic``: a loss factor (friction, material loss), ``zeta_i = eta * e_i`` with ``e_i`` the joint's
    share of mode ``i``'s strain energy; ``viscous``: a dashpot across the joint, whose dissipation per cycle
    grows with frequency, ``zeta_i = eta * e_i * f_i / f_ref`` (``f_i`` the mode's mean frequency over the
    levels, ``f_ref`` the measured modes' mean frequency, where ``eta`` is read). Over a band of a decade or
    more the two forms damp the modes very differently, and a dashpot fitted as a loss factor predicts no
    held-out mode.
    """
    reference = float(np.nanmean(obs.frequency_hz))
    # each mode's frequency over the levels: a linear dashpot damps a mode the same at every level, and the
    # levels' own frequencies would let it follow a damping that moves with the level (Brake-Reuss, until seed 21)
    ratio = np.nan_to_num(mode_frequency_hz(obs) / reference)
    return {"hysteretic": (np.asarray(share, float), {"form": "hysteretic"}),
            "viscous": (share * ratio, {"form": "viscous", "reference_hz": reference})}


def _damping_candidates(obs: Observations, joint_names: Sequence[str],
                        joint_share: np.ndarray) -> list[tuple[str, str, np.ndarray, dict]]:
    """Every joint's damping candidate in each form (`_damping_forms`): ``(joint, form, share, stated)``."""
    return [(joint, form, share, stated) for j, joint in enumerate(joint_names)
            for form, (share, stated) in _damping_forms(obs, joint_share[j]).items()]


def _stated_damping_fit(obs: Observations, share: np.ndarray, stated: dict, mask: np.ndarray) -> tuple[np.ndarray,
                                                                                                        dict]:
    """`damping_fit` whose parameters also state the form they are read in (the report shows them)."""
    predicted, parameters = damping_fit(obs, share, mask)
    return predicted, {**parameters, **stated}


def _candidate_fits(base: Baseline, obs: Observations, curves: list[Curve], baseline_hz: np.ndarray,
                    fit_base_damping: DampingFit | None, joint_share: np.ndarray) -> tuple[
                        list[CandidateFit], dict[tuple[str, str | None, str], np.ndarray],
                        dict[tuple[str, str | None, str], Frequencies],
                        dict[tuple[str, str | None, str], tuple[Frequencies, ...]]]:
    """Every candidate fitted, ranked by held-out chi-square then BIC, their in-sample predictions, the models of
    the one-curve frequency candidates (the pairs' pool) and the curves of every frequency candidate (a
    two-form candidate: two; the targeted test's draws), all by `CandidateFit.key`.
    """
    ranking, predictions, models = [], {}, {}
    two_forms: dict[tuple[str, str | None, str], tuple[Frequencies, ...]] = {}
    paired_only = []
    for curve in curves:
        model = Frequencies(base, obs, curve)
        if (curve.effect, curve.parameter) in PAIRED_ONLY:
            paired_only.append(model)
            continue
        fit, in_f = evaluate(curve.effect, curve.where, curve.parameters, EFFECTS[curve.effect].channel,
                             model.fit, fit_base_damping, obs, baseline_hz, _parameter_count(curve), curve.form,
                             model.at_bound)
        ranking.append(fit)
        predictions[fit.key] = in_f
        models[fit.key] = model
    for a, b in [p for effect in TWO_FORMS for p in form_pairs([*models.values(), *paired_only], effect)]:
        fit, in_f = _two_forms(a, b, obs, baseline_hz, fit_base_damping)
        ranking.append(fit)
        predictions[fit.key] = in_f
        two_forms[fit.key] = (a, b)
    slope = AMPLITUDE_SOFTENING.fitted_parameter
    if obs.amplitude.size > 1:  # softening: a joint's stiffness curve read at gamma(a) = 1 - slope * a
        for curve in curves:
            if curve.effect != JOINT_STIFFNESS_SHIFT.name:
                continue
            model = Frequencies(base, obs, curve, amplitude_joint=True)
            fit, in_f = evaluate(AMPLITUDE_SOFTENING.name, curve.where, lambda u: {slope: float(u)},
                                 AMPLITUDE_SOFTENING.channel, model.fit, fit_base_damping, obs, baseline_hz, 1,
                                 at_bound=model.at_bound)
            ranking.append(fit)
            predictions[fit.key] = in_f
            models[fit.key] = model
    if obs.damping is not None:
        for joint, form, share, stated in _damping_candidates(obs, base.frame.joint_names, joint_share):
            fit, _ = evaluate(JOINT_DAMPING.name, joint, lambda u: {}, JOINT_DAMPING.channel, None,
                              partial(_stated_damping_fit, obs, share, stated), obs, baseline_hz, 1, form)
            ranking.append(fit)
            predictions[fit.key] = baseline_hz
    ranking.sort(key=lambda c: (c.heldout_score, c.bic))
    return ranking, predictions, models, {**{k: (m,) for k, m in models.items()}, **two_forms}


def _two_forms(a: Frequencies, b: Frequencies, obs: Observations, baseline_hz: np.ndarray,
               fit_base_damping: DampingFit | None) -> tuple[CandidateFit, np.ndarray]:
    """One effect in two of its forms at one place (`workbench.diagnose.combined.form_pairs`: a support that
    gives way in two dofs, the drive's spring and moving mass), fitted on both parameters; scored as any
    candidate, its second parameter charged.
    """
    grid = PairGrid((a, b), obs, baseline_hz)
    return evaluate(a.curve.effect, a.curve.where,
                    lambda u: {**a.curve.parameters(float(u[0])), **b.curve.parameters(float(u[1]))},
                    EFFECTS[a.curve.effect].channel, lambda mask: grid.fit(mask)[:2], fit_base_damping, obs,
                    baseline_hz, 2, f"{a.curve.form}+{b.curve.form}", grid.at_bound)


def diagnose(frame: Frame | MatrixModel, measured: MeasuredModes, notify: Callable[[str], None] | None = None, *,
             relative_floor: float = RELATIVE_FLOOR, damping_floor: float = DAMPING_FLOOR,
             mapper: Mapper | None = None, allowance: Allowance = DEFAULT_ALLOWANCE) -> Diagnosis:
    """Locate, name and measure the gap between ``frame`` and a campaign's modes (module docstring).

    Parameters
    ----------
    frame : the nominal model (the campaign's frame file or matrix model), joints at their mean modulus.
    measured : the measured modes (per test, with damping and amplitudes when known, or published means).
    notify : called with a short message before each stage.
    relative_floor, damping_floor : floors of the relative standard errors of the mean frequencies
        and damping ratios (`workbench.diagnose.observations`).
    mapper : solves the candidates' grids (`workbench.diagnose.curves.solve_sweeps`; default, one after the
        other); the verdict is the same on any.
    allowance : how well a frame's member ends (m) and members' sections (relative) are known
        (`workbench.diagnose.observations.Allowance`; its defaults, a frame measured with a rule).

    Returns
    -------
    Diagnosis
    """
    # a mode missing at one excitation level, or left unpaired, is NaN there by design: its means are empty.
    # One BLAS thread: every matrix here is small (a few hundred dofs, reduced bases of tens), where threads
    # cost more than they give (a diagnosis took 3.2 s with two, 1.3 s with one, and 13 s as one of two
    # processes sharing two cores)
    with warnings.catch_warnings(), threadpool_limits(limits=1):
        warnings.filterwarnings("ignore", "Mean of empty slice", RuntimeWarning)
        return _diagnose(frame, measured, say=notify or (lambda message: None), relative_floor=relative_floor,
                         damping_floor=damping_floor, mapper=mapper, allowance=allowance)


def _diagnose(frame: Frame | MatrixModel, measured: MeasuredModes, say: Callable[[str], None],
              relative_floor: float, damping_floor: float, mapper: Mapper | None,
              allowance: Allowance) -> Diagnosis:
    """`diagnose`'s work."""
    start = time.perf_counter()
    obs = observations(measured, relative_floor, damping_floor)
    say("baseline model and pairing")
    base = baseline(frame, obs)
    if base.unpaired is not None and base.unpaired.any():  # a measured mode the model does not have: left out
        gone = base.unpaired[None, :]
        obs = replace(obs, frequency_hz=np.where(gone, np.nan, obs.frequency_hz),
                      damping=None if obs.damping is None else np.where(gone, np.nan, obs.damping))
    stepped = stepped_models(base, allowance)  # the toleranced columns' models, solved once for both channels
    if isinstance(frame, Frame):  # the frame's member ends and sections known to the allowance (observations.py)
        geometry, sections = tolerance_columns(base, stepped)
        obs = replace(obs, discrepancy=replace(
            obs.discrepancy, geometry=geometry, sections=sections, allowance=allowance,
            geometry_names=tuple(s.name for s in stepped if s.kind == "geometry"),
            section_names=tuple(s.name for s in stepped if s.kind == "section")))
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
    curves = (matrix_curves(base, obs, residual, weight, mapper) if isinstance(frame, MatrixModel)
              else frame_curves(base, obs, residual, weight, mapper))
    ranking, predictions, models, groups = _candidate_fits(base, obs, curves, baseline_hz, fit_base_damping,
                                                           shares[0])
    null = frequency_null(obs, ranking, groups)
    damping_null = None if obs.damping is None else damping_family(  # the damping candidates' columns, as fitted
        obs, [share for _, _, share, _ in _damping_candidates(obs, base.frame.joint_names, shares[0])])
    channel = LevelChannel(base, measured, stepped)

    def frf_levels(fit: CandidateFit) -> LevelTest | None:
        return channel.test(fit.effect, fit.where, fit.parameters)

    verdict = decide(obs, baseline_hz, baseline_fit, ranking, predictions, null=null, frf_levels=frf_levels,
                     damping=damping_null)
    pairs: list[PairFit] = []
    contradicted = bool((verdict.frf_levels or {}).get("contradicted"))  # a pair would name the same single again
    if verdict.effect == UNEXPLAINED and verdict.gaps.get("frequency", {}).get("gap") and not contradicted:
        say("pairs of effects")
        pairs = pair_fits(ranking, models, obs, baseline_hz)
        verdict = decide(obs, baseline_hz, baseline_fit, ranking, predictions, pairs, null, frf_levels, damping_null)
    counts = {name: verdict.gaps[name]["observations"] if name in verdict.gaps else 0
              for name in ("frequency", "damping")}
    return Diagnosis(measured.modes, obs.amplitude, obs.frequency_hz, obs.frequency_se, baseline_hz,
                     verdict.best_hz, baseline_fit, ranking, regions, verdict.effect, verdict.where, verdict.shrinkage,
                     counts, time.perf_counter() - start, verdict.partial, verdict.confidence, verdict.also,
                     verdict.gaps, obs.discrepancy, verdict.frf_levels)


def _geometry_entry(d: Discrepancy) -> dict:
    """The geometry's part of the discrepancy: each coordinate's sd (m), each member's section's relative sds,
    and the largest per-mode sd each gives.
    """
    def largest(columns: np.ndarray | None) -> float:
        return 0.0 if columns is None else float(np.sqrt(np.max(np.sum(columns ** 2, axis=1))))

    a = d.allowance
    if a is None:
        return {}
    return {"geometry_sd_m": a.geometry_sd_m, "geometry_largest_mode_sd": largest(d.geometry),
            "section_second_moment_sd": a.section_sd[0], "section_area_sd": a.section_sd[1],
            "section_largest_mode_sd": largest(d.sections)}


def _ranking_entry(c: CandidateFit) -> dict:
    return {"effect": c.effect, "where": c.where, "parameters": c.parameters, "form": c.form,
            "freq_rms_rel_error": c.freq_rms_rel_error, "heldout_freq_rms_rel_error": c.heldout_freq_rms_rel_error,
            "at_bound": c.at_bound,
            "damping_rms_error": c.damping_rms_error, "heldout_damping_rms_error": c.heldout_damping_rms_error,
            "chi2": c.chi2, "heldout_chi2": c.heldout_chi2, "heldout_score": c.heldout_score, "bic": c.bic,
            "parameter_count": c.parameter_count}


def diagnosis_record(campaign_name: str, diagnosis: Diagnosis) -> dict:
    """``diagnosis.json`` (CONTRACTS.md section 3), plus fields a reader may ignore."""
    d = diagnosis
    with warnings.catch_warnings():  # a mode left out (unpaired, or never extracted) has no mean
        warnings.filterwarnings("ignore", "Mean of empty slice", RuntimeWarning)
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
        "verdict": {"effect": d.verdict, "where": d.where, "shrinkage": d.shrinkage, "confidence": d.confidence,
                    **({"partial": d.partial} if d.verdict == UNEXPLAINED else {}),
                    **({"also": d.also} if d.also else {}),
                    **({"frf_levels": d.frf_levels} if d.frf_levels is not None else {})},
        "gaps": d.gaps,
        "discrepancy": {"mode_sd": d.discrepancy.mode_sd, "common_sd": d.discrepancy.common_sd,
                        "damping_sd": d.discrepancy.damping_sd, "form_sd": FORM_SD, **_geometry_entry(d.discrepancy)},
        "protocol": "leave one mode out: each candidate refitted on the other modes predicts the held-out mode",
        "wall_time_s": d.wall_time_s,
    }

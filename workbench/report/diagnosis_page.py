"""The gap diagnosis's page and text: the readable ``index.html`` beside ``diagnosis.json`` (with each
of its tables as CSV).

The numbers come from `workbench.workflow.diagnosis` (`workbench.diagnose`);
this module only draws figures and writes HTML and text. Frequencies in Hz, relative errors,
shrinkage and confidence in %, each fitted parameter in its registry unit (`workbench.rig.effects`).
"""

from __future__ import annotations

import html
import math
from typing import Any

import numpy as np

from workbench.diagnose.decision import EXPLAINED_LEVEL, GAP_LEVEL, NAME_CONFIDENCE
from workbench.diagnose.verdict import Diagnosis
from workbench.report.page import CSS
from workbench.report.pieces import html_figure
from workbench.report.plots import plt
from workbench.report.summary import SUMMARY_CSS
from workbench.report.tables import Tables
from workbench.rig.effects import EFFECTS, JOINT_DAMPING, NONE, UNEXPLAINED

__all__ = ["diagnosis_html", "diagnosis_files", "verdict_summary"]


def _verdict_fitted(d: Diagnosis) -> bool:
    """True when ``d.best_hz`` is the verdict's own candidate: the verdict names an effect (not
    ``none`` nor ``unexplained``) and that effect at that place is a ranked candidate.
    """
    return (d.best_hz is not None and d.verdict not in (NONE.name, UNEXPLAINED)
            and any(c.effect == d.verdict and c.where == d.where for c in d.ranking))


def _figures(d: Diagnosis) -> list[str]:
    """The page's figures as embedded HTML: residuals, localisation, ranking."""
    out = []
    fitted = _verdict_fitted(d)
    name = f"{d.verdict} @ {d.where}" if d.where else d.verdict
    modes = np.asarray(d.modes)
    fig, ax = plt.subplots(figsize=(9, 3.6))
    width = 0.8 / max(len(d.amplitude), 1)
    for c, a in enumerate(d.amplitude):
        x = modes - 0.4 + width * (c + 0.5)
        base = 100 * (d.baseline_hz[c] / d.measured_hz[c] - 1)
        err = 200 * d.frequency_se_hz[c] / d.measured_hz[c]
        label = "" if len(d.amplitude) == 1 else f" (amplitude x{a:g})"
        ax.bar(x, base, width, color="tab:red", alpha=0.35 + 0.5 * c / max(len(d.amplitude), 1),
               label=f"nominal model{label}")
        ax.errorbar(x, np.zeros_like(x), yerr=err, fmt="none", ecolor="k", capsize=2,
                    label="2 standard errors of the measured mean" if c == 0 else None)
        if fitted and d.best_hz is not None:
            ax.plot(x, 100 * (d.best_hz[c] / d.measured_hz[c] - 1), "o", color="tab:blue",
                    label=f"with the verdict's {name}" if c == 0 else None)
    ax.axhline(0, color="k", lw=0.8)
    ax.set_xlabel("mode")
    ax.set_ylabel("model / measured - 1 (%)")
    ax.set_xticks(modes)
    ax.legend(fontsize=8)
    fig.tight_layout()
    dots = (f"and of the model with the verdict's own effect, {name}, fitted (dots)" if fitted else
            f"(no dots: the verdict is {d.verdict}, no candidate effect was accepted)")
    out.append(html_figure(fig, f"Per-mode frequency residual (%) of the nominal model (bars) {dots}, against twice "
                           "the standard error of each measured mean.", "frequency residual per mode"))

    top = d.localisation[:12][::-1]
    if top:
        fig, ax = plt.subplots(figsize=(9, 0.3 * len(top) + 1.0))
        ax.barh([f"{r.region} ({r.kind}, {r.mechanism})" for r in top], [r.score for r in top], color="tab:purple")
        ax.set_xlim(0, 1)
        ax.set_xlabel("share of the weighted residual explained by the region alone")
        fig.tight_layout()
        out.append(html_figure(fig, "Localisation: how much of the residual a change of each region's stiffness, "
                               "mass or damping explains, from the modes' strain and kinetic energy (first order).",
                               "localisation scores"))

    ranked = d.ranking[:12][::-1]
    if ranked:
        fig, ax = plt.subplots(figsize=(9, 0.3 * len(ranked) + 1.2))
        labels = [(f"{c.effect} @ {c.where}" if c.where else c.effect) + (f" ({c.form})" if c.form else "")
                  for c in ranked]
        held = [np.nan if h is None else h for h in (c.heldout_freq_rms_rel_error if c.channel == "frequency"
                                                     else c.heldout_damping_rms_error for c in ranked)]
        ax.barh(labels, held, color=["tab:green" if c.channel == "frequency" else "tab:orange" for c in ranked])
        ax.axvline(d.baseline.heldout_freq_rms_rel_error, color="tab:red", ls="--", label="nominal model (frequency)")
        ax.set_xscale("log")
        ax.set_xlabel(f"held-out RMS error (relative frequency; damping ratio for {JOINT_DAMPING.name}, orange)")
        ax.legend(fontsize=8)
        fig.tight_layout()
        out.append(html_figure(fig, "Candidates ranked by held-out error (leave one mode out): the lower, the better "
                               "the effect predicts modes it was not fitted on.", "held-out error per candidate"))
    return out


def _unit(effect: str, key: str) -> str:
    """The unit of a fitted parameter of ``effect`` (the registry's), or "" for a label."""
    kind = EFFECTS.get(effect)
    if kind is None:
        return ""
    if key in (kind.parameter, kind.fitted_parameter):
        return kind.unit
    return {"position": "fraction of the member's length", "rotary_inertia": "kg.m2", "ux": "N/m", "uy": "N/m",
            "reference_hz": "Hz", "moving_mass": "kg",
            "rz": "N.m/rad", "poisson_ratio": "1", "ps_n": "N"}.get(key, "")


def _parameters(effect: str, parameters: dict[str, Any]) -> str:
    def one(key: str, value: Any) -> str:
        unit = _unit(effect, key)
        text = format(value, ".4g") if isinstance(value, float) else str(value)
        return f"{key} = {text}" + (f" {unit}" if unit and unit != "1" else "")
    return "; ".join(one(k, v) for k, v in parameters.items()) or "-"


def _pct(value: float | None) -> float | None:
    return None if value is None else 100 * float(value)


def _share_text(after: float, before: float, what: str = "RMS") -> str:
    """The held-out error left as a share of the nominal model's, in words that never round an exact
    candidate to "0 %" nor a real remainder to nothing; ``what`` names the error (relative frequency RMS, or the
    damping ratio's RMS in points of critical damping).
    """
    if not (math.isfinite(after) and math.isfinite(before)):
        return "no held-out mode to judge it on"
    if before <= 0:
        return "the nominal model's held-out error is already 0"
    share = after / before
    if share == 0:
        return "the candidate leaves no held-out error at all (an exact fit of the held-out modes)"
    if share < 0.005:
        return (f"the candidate leaves {100 * share:.2g} % of the nominal model's held-out error (held-out {what} "
                f"{100 * after:.2g} % against {100 * before:.3g} %): below 0.5 %, an almost exact fit")
    return (f"the candidate leaves {100 * share:.1f} % of the nominal model's held-out error (held-out {what} "
            f"{100 * after:.3g} % against {100 * before:.3g} %)")


def _candidate_share_text(candidate: dict, diagnosis: Diagnosis) -> str | None:
    """`_share_text` on the candidate's own channel: its damping error for a joint's damping, else its
    frequencies'; None where the record holds no held-out error for it.
    """
    if candidate["effect"] == JOINT_DAMPING.name:
        after, before = candidate["heldout_damping_rms_error"], diagnosis.baseline.heldout_damping_rms_error
        if after is None or before is None:
            return None
        return _share_text(after, before, "damping-ratio RMS")
    if candidate["heldout_freq_rms_rel_error"] is None:
        return None
    return _share_text(candidate["heldout_freq_rms_rel_error"], diagnosis.baseline.heldout_freq_rms_rel_error)


def _discrepancy_text(record: dict) -> str:
    d = record.get("discrepancy")
    if not d:
        return "not stated"
    return (f"{100 * d['mode_sd']:.2f} % per mode, {100 * d['common_sd']:.2f} % common to every mode, damping "
            f"{100 * d['damping_sd']:.0f} % of its typical value, a candidate's prediction "
            f"{100 * d.get('form_sd', 0.0):.0f} % of the change it predicts"
            + (f", each member end's position {1e3 * d['geometry_sd_m']:.2f} mm (up to "
               f"{100 * d['geometry_largest_mode_sd']:.2f} % on a mode)" if d.get("geometry_sd_m") else "")
            + (", the frame's geometry taken as exact" if d.get("geometry_sd_m") == 0.0 else "")
            + (f", each member's second moment of area {100 * d['section_second_moment_sd']:.1f} % and area "
               f"{100 * d['section_area_sd']:.1f} % (up to {100 * d['section_largest_mode_sd']:.2f} % on a mode)"
               if d.get("section_second_moment_sd") is not None else ""))


def _levels_text(gap: dict) -> str:
    levels = gap.get("levels")
    if not levels:
        return ""
    softening = (f", softening's best drop p = {levels['softening_p_value']:.2g}" if "softening_p_value" in levels
                 else "")  # damping's levels: no candidate of the vocabulary follows them
    return (f" (the means; the levels' line in amplitude: chi-square {levels['chi2']:.3g} on {levels['dof']}, p = "
            f"{levels['p_value']:.2g} against F with the scatter's {levels['scatter_dof']:.0f} degrees of freedom"
            f"{softening}: the levels {'differ' if levels.get('gap') else 'do not differ beyond chance'})")


def _gaps_text(record: dict) -> str:
    gaps = record.get("gaps") or {}
    parts = [f"{name}: chi-square {g['chi2']:.3g} against {g['threshold']:.3g} allowed{_levels_text(g)}"
             f"{_evidence_text(g.get('evidence'))}{_allowance_text(g.get('allowance'))} "
             f"({'a gap' if g['gap'] else 'within the errors'})"
             for name, g in gaps.items()]
    return "; ".join(parts) or "not tested"


def _allowance_text(allowance: dict | None) -> str:
    """The test along the frame's toleranced columns (`workbench.diagnose.allowance`)."""
    if not allowance:
        return ""
    return (f"; along the frame's toleranced columns, {allowance['direction']} lowers it by "
            f"{allowance['chi2_drop']:.3g} (p = {allowance['p_value']:.2g} over {allowance['columns']} columns)")


def _evidence_text(evidence: dict | None) -> str:
    """The targeted test's best candidate (`workbench.diagnose.decision`), when one lowers the chi-square."""
    if not evidence or not evidence.get("effect"):
        return ""
    where = f" at {evidence['where']}" if evidence.get("where") else ""
    how = {"min-p": ", their least p-value's law under no effect"}.get(evidence.get("adjustment", ""), "")
    return (f", {evidence['effect']}{where} lowers it by {evidence['chi2_drop']:.3g} (p = {evidence['p_value']:.2g} "
            f"over {evidence['candidates']} candidates{how})")


def verdict_summary(record: dict, diagnosis: Diagnosis) -> list[tuple[str, str]]:
    """The summary's lines, ``(label, text)``: verdict, where, confidence, shrinkage, what is left unexplained."""
    v = record["verdict"]
    meaning = {NONE.name: "the nominal model already fits within measurement scatter",
               UNEXPLAINED: "a real gap remains that no effect of the vocabulary brings down to the scatter"}
    effect = v["effect"]
    kind = EFFECTS.get(effect)
    lines = [("verdict", f"{effect}: {meaning.get(effect) or (kind.meaning if kind else '')}"),
             ("where", str(v["where"]) if v.get("where") else "nowhere in particular (a global effect or none)")]
    confidence = v.get("confidence")
    lines.append(("confidence", f"{100 * confidence:.0f} %" if confidence is not None
                  else "not given by this diagnosis (diagnosis.json carries no confidence)"))
    base = diagnosis.baseline.heldout_freq_rms_rel_error
    ranking = record["ranking"]
    if effect not in meaning:
        own = next((c for c in ranking if c["effect"] == effect and c["where"] == v.get("where")), None)
        lines.append(("shrinkage", f"{100 * v['shrinkage']:.1f} % of the nominal model's held-out error removed"))
        if own is not None and own["heldout_freq_rms_rel_error"] is not None and effect != JOINT_DAMPING.name:
            lines.append(("left unexplained", _share_text(own["heldout_freq_rms_rel_error"], base)))
    elif effect == UNEXPLAINED:
        lines.append(("shrinkage", "none accepted: no candidate met the verdict's rules, so the verdict claims no "
                      "shrinkage (the record's 0)"))
        top = ranking[0] if ranking else None
        left = _candidate_share_text(top, diagnosis) if top is not None else None
        if top is not None and left is not None:
            at = f" @ {top['where']}" if top["where"] else ""
            lines.append(("best candidate", f"{top['effect']}{at}, not accepted: " + left))
        partial = v.get("partial")
        if partial:
            bound = (", its parameter at a bound of its range: the data ask for more of it than the range holds"
                     if partial.get("at_bound") else "")
            weight = (f"; it explains the gap, but its effect carries {100 * partial['weight']:.0f} % of the "
                      f"candidates' weight, under the {100 * NAME_CONFIDENCE:g} % a name needs: another effect "
                      "predicts the held-out modes almost as well" if partial.get("weight") is not None else "")
            lines.append(("partial explanation", f"{partial['effect']} @ {partial.get('where')}, shrinkage "
                          f"{100 * partial['shrinkage']:.1f} %{bound}{weight}"))
    else:
        lines.append(("shrinkage", "nothing to shrink: no gap beyond the scatter"))
    frf_levels = v.get("frf_levels")
    if frf_levels:
        lines.append(("FRF levels", _frf_levels_text(frf_levels)))
    lines.append(("gap tests", _gaps_text(record)))
    for also in v.get("also") or ():
        lines.append(("together with", f"{also['effect']} @ {also.get('where')}, shrinkage "
                      f"{100 * also['shrinkage']:.1f} %"))
    return lines


def _frf_levels_text(test: dict) -> str:
    """The FRF-level channel's test in words (`workbench.diagnose.frf_levels`)."""
    pairs = ", ".join(f"{m}: {100 * (a - 1):+.1f} / {100 * (b - 1):+.1f} %"
                      for m, a, b in zip(test["modes"], test["measured"], test["predicted"]))
    told = (f"measured / predicted change of each mode's modal-constant level from the nominal model's, before the "
            f"common scale (a force calibration) is removed ({pairs}); "
            f"chi2 {test['chi2']:.1f} on {test['dof']} degrees of freedom (nominal model {test['nominal_chi2']:.1f}), "
            f"p = {test['p_value']:.2g}")
    moved = test.get("instead_of")
    if moved:  # the levels placed the effect (`workbench.diagnose.decision._placed_by_levels`)
        told += (f"; the frequencies preferred {moved['effect']} at {moved['where']}, whose levels contradict it "
                 f"(p = {moved['p_value']:.2g}), so the place the levels agree with is named")
    if test["contradicted"]:
        return (f"{told}: the levels contradict the frequencies' best candidate (p < {test['level']:g}, and it fits "
                "them worse than the nominal model), so it is only a partial explanation: another mechanism moved "
                "the frequencies that way")
    if test["p_value"] < test["level"]:
        return (f"{told}: the levels miss the candidate's model too, but less than the nominal model's, so they do not "
                "contradict it: something besides it moves the levels")
    return f"{told}: consistent with the verdict"


def diagnosis_files(record: dict, diagnosis: Diagnosis, synthetic: bool, source: str) -> dict[str, str]:
    """The page (``index.html``) and one CSV per table of it, file name -> text (`workbench.report.tables`).

    Parameters
    ----------
    record : the ``diagnosis.json`` record (CONTRACTS.md section 3); diagnosis : the `Diagnosis` it
        was made from (the arrays the figures draw); synthetic : the campaign is from the virtual rig;
        source : where the data come from, as the campaign says.
    """
    tables = Tables()
    banner = ('<p class="banner synthetic">SYNTHETIC campaign (virtual test rig): not a measurement.</p>'
              if synthetic else '<p class="banner real">Real measured data.</p>')
    lines = verdict_summary(record, diagnosis)
    summary_table = tables.add("summary", ["item", "finding"], lines, left=2, wrap=True)
    figures = "".join(_figures(diagnosis))
    base = record["baseline"]
    modes = tables.add("baseline", ["mode", "measured (Hz)", "model (Hz)", "model/measured - 1 (%)"],
                       [(m["mode"], m["measured_hz"], m["model_hz"], 100 * m["rel_error"]) for m in base["modes"]],
                       ["", ".2f", ".2f", "+.3f"], left=0)
    loc = tables.add("localisation", ["region", "kind", "mechanism", "score (-)"],
                     [(r["region"], r["kind"], r["mechanism"], r["score"]) for r in record["localization"]],
                     ["", "", "", ".2f"], left=3)
    rank = tables.add("candidates", ["rank", "effect", "where", "fitted parameters (units)",
                                     "RMS rel. frequency error (%)", "held-out RMS rel. frequency error (%)",
                                     "held-out RMS damping error (%)", "held-out chi2 (-)", "BIC (-)"],
                      [(i, c["effect"], c["where"] or "-", _parameters(c["effect"], c["parameters"]),
                        _pct(c["freq_rms_rel_error"]), _pct(c["heldout_freq_rms_rel_error"]),
                        _pct(c.get("heldout_damping_rms_error")), c["heldout_chi2"], c["bic"])
                       for i, c in enumerate(record["ranking"], start=1)],
                      ["", "", "", "", ".3g", ".3g", ".3g", ".4g", ".4g"], left=4)
    title = html.escape(record["campaign"])
    page = f"""<!DOCTYPE html><html lang="en"><head><meta charset="utf-8"><title>Diagnosis: {title}</title>
<style>{CSS}{SUMMARY_CSS}</style></head><body><main>
<h1>Sim-to-real gap diagnosis: {title}</h1>{banner}
<section class="summary" id="summary"><h2>Summary</h2>{summary_table}</section>
<p>Source: {html.escape(source)}. Observations: {base['observations']['frequency']} frequency and
{base['observations']['damping']} damping means. Wall time {record['wall_time_s']:.1f} s. Frequencies in Hz, errors
and shrinkage in %; every table is also a CSV file beside this page (linked below it).</p>
<h2>Where the model misses</h2>{figures}
<h2>Baseline: nominal model against the measured means</h2>
<p>RMS relative frequency error {100 * base['freq_rms_rel_error']:.3f} %, chi-square {base['chi2']:.4g}.</p>{modes}
<h2>Localisation</h2>{loc}
<h2>Candidate effects, all {len(record['ranking'])}, best first</h2>{rank}
<h2>Protocol</h2><p>{html.escape(record['protocol'])}. Each candidate is the nominal frame changed by one effect
of the vocabulary (CONTRACTS.md section 3) with one parameter (a mass on a member also its position; a
support giving way in two dofs, two stiffnesses),
fitted on exact eigen-solutions. Every test measures residuals against the measurement error plus the
model-form error a nominal model of a real structure carries ({_discrepancy_text(record)}). Verdict rules,
channel by channel (frequency, damping): <code>none</code> when no channel's chi-square exceeds its
{100 * (1 - GAP_LEVEL):g} % quantile; otherwise the best candidate on a channel with a gap, if its held-out
chi-square is within its {100 * (1 - EXPLAINED_LEVEL):g} % quantile and below the nominal model's,
its parameter is not at a bound of its range and its effect carries more than {100 * NAME_CONFIDENCE:g} % of
the weight of all candidates (the confidence); two effects (<code>also</code>) when only a pair explains the
gap (neither at a bound, amplitude softening only where the levels differ); else
<code>unexplained</code> with the best partial explanation. See <code>workbench/diagnose/decision.py</code>.</p>
</main></body></html>
"""
    return {"index.html": page, **tables.files()}


def diagnosis_html(record: dict, diagnosis: Diagnosis, synthetic: bool, source: str) -> str:
    """The self-contained page alone (`diagnosis_files`'s ``index.html``)."""
    return diagnosis_files(record, diagnosis, synthetic, source)["index.html"]

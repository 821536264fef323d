"""The gap diagnosis's page and text: the readable ``index.html`` beside ``diagnosis.json``, and the
blind validation's printed summary.

The numbers come from `workbench.workflow.diagnosis` (`workbench.diagnose`, `workbench.workflow.rig_cases`);
this module only draws figures and writes HTML and text.
"""

from __future__ import annotations

import html
from typing import Any

import numpy as np

from workbench.diagnose.verdict import Diagnosis
from workbench.report.page import CSS, html_figure, html_table
from workbench.report.plots import plt
from workbench.rig.effects import JOINT_DAMPING, NONE, UNEXPLAINED

__all__ = ["diagnosis_html", "validation_text"]


def _figures(d: Diagnosis) -> list[str]:
    """The page's figures as embedded HTML: residuals, localisation, ranking."""
    out = []
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
        if d.best_hz is not None:
            ax.plot(x, 100 * (d.best_hz[c] / d.measured_hz[c] - 1), "o", color="tab:blue",
                    label=f"with {d.verdict}" if c == 0 else None)
    ax.axhline(0, color="k", lw=0.8)
    ax.set_xlabel("mode")
    ax.set_ylabel("model / measured - 1 (%)")
    ax.set_xticks(modes)
    ax.legend(fontsize=8)
    fig.tight_layout()
    out.append(html_figure(fig, "Per-mode frequency residual of the nominal model (bars) and of the model with the "
                           "verdict's effect fitted (dots), against twice the standard error of each measured mean.",
                           "frequency residual per mode"))

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
        labels = [f"{c.effect} @ {c.where}" if c.where else c.effect for c in ranked]
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


def _fmt(value: Any, spec: str = ".3g") -> str:
    if value is None:
        return "-"
    if isinstance(value, float):
        return format(value, spec)
    return str(value)


def diagnosis_html(record: dict, diagnosis: Diagnosis, synthetic: bool, source: str) -> str:
    """A self-contained page: verdict, residuals, localisation, ranking, protocol."""
    v = record["verdict"]
    banner = ('<p class="banner synthetic">SYNTHETIC campaign (virtual test rig): not a measurement.</p>'
              if synthetic else '<p class="banner real">Real measured data.</p>')
    meaning = {NONE.name: "the nominal model already fits within measurement scatter",
               UNEXPLAINED: "a real gap remains that no effect of the vocabulary brings down to the scatter"}
    where = f" at <b>{html.escape(str(v['where']))}</b>" if v["where"] else ""
    verdict = (f"<b>{html.escape(v['effect'])}</b>" + where
               + f": held-out error shrinks by {100 * v['shrinkage']:.0f} %" if v["effect"] not in meaning
               else f"<b>{v['effect']}</b>: {meaning[v['effect']]}")
    figures = "".join(_figures(diagnosis))
    base = record["baseline"]
    modes = html_table(["mode", "measured (Hz)", "model (Hz)", "model/measured - 1"],
                   [[m["mode"], f"{m['measured_hz']:.2f}", f"{m['model_hz']:.2f}", f"{100 * m['rel_error']:+.3f} %"]
                    for m in base["modes"]])
    loc = html_table(["region", "kind", "mechanism", "score"],
                 [[r["region"], r["kind"], r["mechanism"], f"{r['score']:.2f}"] for r in record["localization"][:12]],
                 left=3)
    rank = html_table(["effect", "where", "parameters", "RMS rel. error", "held-out", "held-out chi2", "BIC"],
                  [[c["effect"], _fmt(c["where"]), ", ".join(f"{k}={_fmt(x)}" for k, x in c["parameters"].items()),
                    _fmt(c["freq_rms_rel_error"]), _fmt(c["heldout_freq_rms_rel_error"]),
                    _fmt(c["heldout_chi2"], ".4g"),
                    _fmt(c["bic"], ".4g")] for c in record["ranking"][:15]], left=3)
    title = html.escape(record["campaign"])
    return f"""<!DOCTYPE html><html lang="en"><head><meta charset="utf-8"><title>Diagnosis: {title}</title>
<style>{CSS}</style></head><body><main>
<h1>Sim-to-real gap diagnosis: {html.escape(record['campaign'])}</h1>{banner}
<p>Source: {html.escape(source)}. Observations: {base['observations']['frequency']} frequency and
{base['observations']['damping']} damping means. Wall time {record['wall_time_s']:.1f} s.</p>
<p class="note">Verdict: {verdict}</p>
<h2>Where the model misses</h2>{figures}
<h2>Baseline: nominal model against the measured means</h2>
<p>RMS relative frequency error {100 * base['freq_rms_rel_error']:.3f} %, chi-square {base['chi2']:.4g}.</p>{modes}
<h2>Localisation</h2>{loc}
<h2>Candidate effects, best first</h2>{rank}
<h2>Protocol</h2><p>{html.escape(record['protocol'])}. Each candidate is the nominal frame changed by one effect
of the vocabulary (CONTRACTS.md section 3) with one parameter (two for a mass on a member: its position),
fitted on exact eigen-solutions. Verdict rules: <code>none</code> when the nominal model's chi-square per
observation is within the scatter; otherwise the best candidate if its held-out chi-square per observation is
within the scatter allowance and it shrinks the held-out error meaningfully; else <code>unexplained</code>.
See <code>workbench/diagnose/</code>.</p>
</main></body></html>
"""


def validation_text(summary: dict) -> str:
    """The confusion matrix, accuracies and shrinkage quantiles as printed by the command."""
    confusion = summary["confusion"]
    verdicts = [v for v in next(iter(confusion.values())) if any(row[v] for row in confusion.values())]
    short = {v: v.replace("_", " ")[:11] for v in verdicts}
    lines = [f"blind validation: {summary['cases']} cases, seed {summary['seed']}, frame {summary['frame']}",
             "confusion (rows: hidden effect, columns: verdict)",
             f"{'':22s}" + "".join(f"{short[v]:>12s}" for v in verdicts)]
    for truth, row in confusion.items():
        if sum(row.values()):
            lines.append(f"{truth:22s}" + "".join(f"{row[v]:12d}" for v in verdicts))
    place = summary["place_accuracy"]
    lines += [f"top-1 effect right: {100 * summary['top1_accuracy']:.1f} %",
              f"place right: {'-' if place is None else f'{100 * place:.1f} %'} of the "
              f"{summary['place_checked']} right "
              "verdicts that have a place",
              f"no effect -> none: {summary['none_right']}; outside the vocabulary -> unexplained: "
              f"{summary['outside_right']}"]
    for key, label in (("shrinkage_right_verdicts", "shrinkage, right verdicts"),
                       ("shrinkage_all_effects", "shrinkage, every vocabulary case (0 when wrong)")):
        q = summary[key]
        if q:
            lines.append(f"{label}: median {100 * q['median']:.1f} % (min {100 * q['min']:.1f}, p10 "
                         f"{100 * q['p10']:.1f}, p90 {100 * q['p90']:.1f}, max {100 * q['max']:.1f})")
    lines.append(f"mean diagnosis time per case {summary['mean_wall_time_s']:.1f} s; "
                 f"total {summary['wall_time_s']:.0f} s")
    return "\n".join(lines)

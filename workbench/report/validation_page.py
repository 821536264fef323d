"""The blind validation's page and printed summary, from ``validation.json`` (`workbench.workflow.diagnosis`).

Rates in %, each with its Wilson 95 % interval; the confusion matrix (the case's primary effect against the
verdict); accuracy by footprint; every case in a table. This module only writes HTML and text.
"""

from __future__ import annotations

import html
from typing import Any

from workbench.report.page import CSS, html_table
from workbench.report.pieces import html_figure
from workbench.report.plots import plt

__all__ = ["SCORES", "validation_html", "validation_text"]

SCORES = (  # key, label, what it should be (the targets)
    ("single_accuracy", "nameable single effect named right (faint ones aside)", ">= 80 %"),
    ("confident_wrong", "confident-wrong: a named effect the case does not hold (over all cases)", "<= 5 %"),
    ("named_wrong", "named effects that are wrong (over the cases that name one)", ""),
    ("none_false_positive", "no-effect case given anything but none", "<= 10 %"),
    ("outside_unexplained", "out-of-vocabulary case given unexplained (or partial), faint ones aside", ">= 80 %"),
    ("combined_primary", "combined case: its primary effect named (verdict or also)", ""),
    ("single_partial_right", "nameable single effect named right or as the partial explanation", ""),
    ("abstention", "effect case given none or unexplained", ""),
    ("place_accuracy", "place of a right verdict right", ""),
    ("faint_none", "faint case (footprint reached below half the small rung) given none", ""),
)
LEVEL_TABLES = (  # key, what the level is
    ("single_accuracy_by_level", "footprint reached"),
    ("single_accuracy_by_requested_level", "footprint asked for (every single case)"),
    ("single_accuracy_by_measurement", "measured as"),
)


def _level_tables(record: dict[str, Any]) -> list[tuple[str, dict[str, Any]]]:
    """(what the level is, scores by level): a record written before the rung reached was scored (seed 12 and
    before) has its levels as asked for.
    """
    if "single_accuracy_by_requested_level" not in record:
        return [("footprint asked for", record["single_accuracy_by_level"])]
    return [(what, record[key]) for key, what in LEVEL_TABLES if key in record]  # by measurement: seed 19 on


def _rate(score: dict[str, Any]) -> str:
    if not score or score.get("rate") is None:
        return "no case"
    lo, hi = score["ci95"]
    return f"{100 * score['rate']:.1f} % ({score['hits']}/{score['n']}; 95 % {100 * lo:.1f} to {100 * hi:.1f})"


def validation_text(record: dict[str, Any]) -> str:
    """The scores and the confusion matrix as the command prints them."""
    lines = [f"blind validation on the proving ground: {record['cases']} cases, seed {record['seed']}"]
    lines += [f"{label}: {_rate(record.get(key, {}))}" + (f"  [target {target}]" if target else "")
              for key, label, target in SCORES]
    for what, scores in _level_tables(record):
        for level, score in scores.items():
            lines.append(f"  single effects, {level} ({what}): {_rate(score)}")
    verdicts = sorted({v for row in record["confusion"].values() for v in row})
    lines.append("confusion (rows: the case's primary effect, columns: verdict)")
    lines.append(f"{'':36s}" + "".join(f"{v[:11]:>12s}" for v in verdicts))
    for truth, row in sorted(record["confusion"].items()):
        lines.append(f"{truth[:36]:36s}" + "".join(f"{row.get(v, 0):12d}" for v in verdicts))
    t = record["diagnosis_time_s"]
    lines.append(f"diagnosis time per case: median {t['median']:.1f} s, max {t['max']:.1f} s; "
                 f"whole run {record['wall_time_s']:.0f} s")
    return "\n".join(lines)


def _confidence_figure(cases: list[dict[str, Any]]) -> str:
    """Confidence of the named verdicts, right against wrong, and of the abstentions."""
    fig, ax = plt.subplots(figsize=(6.4, 3.2))
    groups = {"named, right": [c["confidence"] for c in cases if c["verdict"] not in ("none", "unexplained")
                               and not c["named_wrong"]],
              "named, wrong": [c["confidence"] for c in cases if c["named_wrong"]],
              "none or unexplained": [c["confidence"] for c in cases if c["verdict"] in ("none", "unexplained")]}
    ax.hist(list(groups.values()), bins=10, range=(0, 1), label=[f"{k} ({len(v)})" for k, v in groups.items()])
    ax.set_xlabel("verdict.confidence (-)")
    ax.set_ylabel("cases")
    ax.legend(fontsize=8)
    return html_figure(fig, "Confidence the diagnosis gave, by outcome.", "histogram of confidences")


def validation_html(record: dict[str, Any]) -> str:
    """The self-contained ``index.html`` of a validation run."""
    cases = record["case_results"]
    scores = html_table(["score", "rate (95 % Wilson interval)", "target"],
                        [(label, _rate(record.get(key, {})), target or "-") for key, label, target in SCORES], left=3)
    levels = "".join(html_table([what, "single effects named right"],
                                [(level, _rate(s)) for level, s in scores.items()], left=2)
                     for what, scores in _level_tables(record))
    verdicts = sorted({v for row in record["confusion"].values() for v in row})
    confusion = html_table(["primary effect \\ verdict", *verdicts],
                           [(t, *(row.get(v, 0) for v in verdicts)) for t, row in sorted(record["confusion"].items())])
    columns = ["case", "frame", "category", "truth", "secondary", "level", "reached", "mechanism", "truth_where",
               "verdict", "where", "also", "partial", "confidence", "right", "named_wrong"]
    rows = [tuple("-" if c.get(k) is None else (f"{c[k]:.2f}" if isinstance(c[k], float) else c[k])
                  for k in columns) for c in cases]
    levels_text = ", ".join(f"{k} = {v}" for k, v in record["levels"].items())
    return f"""<!DOCTYPE html><html lang="en"><head><meta charset="utf-8">
<title>Diagnosis: blind validation on the proving ground</title><style>{CSS}</style></head><body><main>
<h1>Diagnosis: blind validation on the proving ground</h1>
<p class="banner synthetic">SYNTHETIC cases from the proving ground: {html.escape(record['generator'])}.</p>
<p>{record['cases']} cases of seed {record['seed']}. The diagnosis saw each campaign only (FRFs, circle fit, the
nominal frame file); the truth was read afterwards. The decision's levels were frozen before this run:
{html.escape(levels_text)}. Whole run {record['wall_time_s']:.0f} s.</p>
<h2>Scores</h2>{scores}
<h2>Single effects by footprint</h2>
<p>A case asks for a rung of the footprint ladder (the largest relative frequency shift in the band: 0.3, 1 and
3 %; added damping ratio 0.1, 0.3 and 1 %); where its mechanism cannot reach it within its physical bounds, it
is read at the rung nearest the footprint it reached. Below half the small rung it is <em>faint</em>: as small
as the as-built frame's own residual, it counts in none of the single, out-of-vocabulary or combined-primary
rates.</p>{levels}
<h2>Confusion matrix</h2>{confusion}
<h2>Confidence</h2>{_confidence_figure(cases)}
<h2>Every case</h2>{html_table(columns, rows, left=len(columns))}
</main></body></html>
"""

"""The summary box at the top of the identification report: what was identified, from which modes,
and, where a diagnosis is part of the run, what it found.

Moduli in GPa, CoV in %, each with its 95 % interval where the estimator gives one; the same
numbers as the joint-model sections below (`workbench.workflow.study.Study.joints` and
``posterior``), registered as the ``summary`` table (`workbench.report.tables.Tables`).
"""

from __future__ import annotations

import numpy as np

from workbench.report.pieces import escape
from workbench.report.tables import Tables
from workbench.workflow.runs import Run
from workbench.workflow.study import Study

__all__ = ["joint_rows", "modes_line", "diagnosis_line", "summary_box", "SUMMARY_CSS"]

SUMMARY_CSS = (".summary{border:2px solid #1f4e79;background:#f5f9fd;border-radius:5px;padding:8px 16px;margin:12px 0}"
               ".summary h2{margin-top:.3em;border:0}.summary ul{margin:4px 0 8px;padding-left:20px}"
               "p.csv{font-size:.8em;margin:-8px 0 10px}")


def _gpa(ci) -> tuple[float, float] | None:
    return None if ci is None else (float(ci[0]) / 1e9, float(ci[1]) / 1e9)


def _pct(ci) -> tuple[float, float] | None:
    return None if ci is None else (100 * float(ci[0]), 100 * float(ci[1]))


def joint_rows(study: Study) -> list[tuple]:
    """``(campaign, group, estimator, E GPa, E interval GPa, CoV %, CoV interval %)`` per group and estimator."""
    rows = []
    post = study.posterior
    for group, src in study.joints.items():
        rows.append((study.name, group, "moment matching", src.youngs_modulus_pa / 1e9, _gpa(src.youngs_modulus_ci95),
                     100 * src.cov, _pct(src.cov_ci95)))
        if post is not None and group in post.groups:
            i = post.groups.index(group)
            rows.append((study.name, group, "Bayesian (emcee)", float(post.youngs_modulus[i]) / 1e9,
                         _gpa(post.youngs_modulus_ci95[i]), 100 * float(post.cov[i]), _pct(post.cov_ci95[i])))
    return rows


def modes_line(study: Study) -> str:
    """One sentence: how many modes were measured on how many tests, how many fits are usable or flagged."""
    data = study.data
    if data.published:
        return (f"{study.name}: {data.count} modes, published means and standard deviations over "
                f"{data.tests_count or '?'} tests ({escape(data.source)}).")
    f = data.frequency_hz
    usable = int(np.isfinite(f).sum())
    flagged = sum(bool(flags) for row in data.flags for flags in row)
    flags = (f"; {flagged} of the {f.size} fits flagged (close mode, few points, poor circle...)" if data.flags
             else "; no quality flags recorded")
    return (f"{study.name}: {data.count} measured modes (modes {', '.join(str(int(m)) for m in data.modes)}) on "
            f"{f.shape[0]} tests, {usable} of {f.size} frequencies usable{flags}. Source: {escape(data.source)}.")


def diagnosis_line(record: dict) -> str:
    """The diagnosis verdict in one sentence: effect, where, confidence, shrinkage (CONTRACTS.md section 3)."""
    v = record["verdict"]
    where = f" at {v['where']}" if v.get("where") else ""
    confidence = v.get("confidence")
    said = f", confidence {100 * confidence:.0f} %" if confidence is not None else ", confidence not given"
    return (f"Diagnosis of {escape(record.get('campaign', ''))}: {escape(v['effect'])}{escape(where)}{said}; "
            f"held-out error shrinks by {100 * v['shrinkage']:.1f} % against the nominal model.")


def summary_box(run: Run, tables: Tables) -> str:
    """The box's HTML; registers the ``summary`` table (one row per campaign, group and estimator)."""
    rows = [r for study in run.studies for r in joint_rows(study)]
    items = [f"<li>{modes_line(study)}</li>" for study in run.studies]
    for pred in run.predictions:
        c = pred.comparison
        worst = float(np.nanmax(np.abs(c.mean_rel_error))) if np.isfinite(c.mean_rel_error).any() else float("nan")
        items.append(f"<li>Section 5, {escape(pred.name)}: {c.modes.size} modes predicted from the identified joint "
                     f"models; largest mean-frequency error {100 * worst:.2f} %.</li>")
    if run.diagnosis is not None:
        items.append(f"<li>{diagnosis_line(run.diagnosis)}</li>")
    table = (tables.add("summary", ["campaign", "joint group", "estimator", "E (GPa)", "E 95 % interval (GPa)",
                                    "CoV (%)", "CoV 95 % interval (%)"], rows,
                        ["", "", "", ".4g", ".4g", ".3g", ".3g"], left=3)
             if rows else "<p>No joint group identified.</p>")
    return (f'<section class="summary" id="summary"><h2>Summary</h2><p>Identified joint models (mean modulus E '
            f"and its coefficient of variation CoV, 95 % intervals where the estimator gives one):</p>{table}"
            f"<ul>{''.join(items)}</ul></section>")

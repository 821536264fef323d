"""The page of `workbench design`: the candidates' predicted widths, the choice and what it assumes."""

from __future__ import annotations

import html
from pathlib import Path

import numpy as np

from workbench.model.matrix_model import MatrixModel
from workbench.plan.candidates import FAMILIES
from workbench.report.page import CSS
from workbench.report.pieces import html_figure
from workbench.report.plots import design_width_figure
from workbench.report.summary import SUMMARY_CSS
from workbench.report.tables import Table
from workbench.workflow.design import DesignPlan, Verification, design_files

__all__ = ["design_page", "design_outputs"]


def _curves(plan: DesignPlan) -> dict[str, dict[str, tuple[np.ndarray, np.ndarray]]]:
    out: dict[str, dict[str, tuple[np.ndarray, np.ndarray]]] = {}
    for g, group in enumerate(plan.groups.groups):
        out[group] = {}
        for family in FAMILIES:
            rows = sorted((p.design.tests, 100 * p.width[g, 1]) for p in plan.predictions if p.design.family == family)
            if rows:
                out[group][family] = (np.array([r[0] for r in rows]), np.array([r[1] for r in rows]))
    return out


def _verification(check: Verification | None, plan: DesignPlan) -> str:
    if check is None:
        return ("<p>No simulation check was run (<code>--verify N</code> runs moment matching on N simulated "
                "campaigns of the recommended design).</p>")
    pred = plan.recommended
    rows = []
    for g, group in enumerate(plan.groups.groups):
        for c, parameter in enumerate(("mean modulus", "CoV")):
            rows.append((group, parameter, 100 * pred.width[g, c], 100 * check.median_width[g, c],
                         100 * pred.spread[g, c], 100 * check.spread[g, c], 100 * pred.bias[g, c],
                         100 * check.bias[g, c]))
    table = Table("verification", ("group", "parameter", "predicted width (%)", "simulated width (%)",
                                   "predicted spread (%)", "simulated spread (%)", "predicted bias (%)",
                                   "simulated bias (%)"), tuple(rows), ("", "", ".1f", ".1f", ".1f", ".1f", "+.1f",
                                                                       "+.1f"), left=2)
    return (f"<p>{check.estimate.shape[0]} campaigns of {html.escape(check.design.name)} simulated with exact "
            "eigen-solutions at each test's moduli and the extraction scatter, each identified by moment matching "
            "with its own bootstrap intervals. Width: the median reported 95 % width over the true value; spread: "
            "2 x 1.96 x the sd of the log estimates.</p>" + table.html(link=False))


def design_page(plan: DesignPlan, model_name: str, check: Verification | None = None) -> str:
    """The self-contained ``index.html`` of `workbench design`."""
    s = plan.settings
    best = plan.recommended
    chosen = (best.design.tests, {g: 100 * best.width[i, 1] for i, g in enumerate(plan.groups.groups)})
    figure = html_figure(design_width_figure(_curves(plan), 100 * plan.target, chosen),
                         "Predicted 95 % interval width of each group's CoV against the number of tests, by family "
                         "(log scale); the dashed line is the target, the star the recommended design.",
                         "predicted CoV width against tests")
    rows = []
    for p in sorted(plan.predictions, key=lambda p: (p.design.tests, p.design.name)):
        for g, group in enumerate(plan.groups.groups):
            rows.append((p.design.name, p.design.tests, group, 100 * p.width[g, 0], 100 * p.width[g, 1],
                         100 * p.bias[g, 1], "yes" if p is best else ""))
    table = Table("designs", ("design", "tests", "group", "mean width (%)", "CoV width (%)", "CoV bias (%)",
                              "recommended"), tuple(rows), ("", "", "", ".1f", ".1f", "+.1f", ""), left=1)
    laws = ", ".join(f"{g}: E {m / 1e9:.3g} GPa, CoV {100 * c:.3g} %"
                     for g, m, c in zip(plan.groups.groups, plan.mean_pa, plan.cov))
    verdict = ("reaches" if plan.reached else "is the most precise within the budget; no design reaches")
    widths = "; ".join(f"{g}: mean {100 * best.width[i, 0]:.1f} %, CoV {100 * best.width[i, 1]:.0f} %"
                       for i, g in enumerate(plan.groups.groups))
    levels = "".join(f"<li>{i}: {html.escape(n)}</li>" for i, n in enumerate(best.design.level_names, start=1))
    return f"""<!DOCTYPE html><html lang="en"><head><meta charset="utf-8"><title>Design: {html.escape(model_name)}
</title><style>{CSS}{SUMMARY_CSS}</style></head><body><main>
<h1>Campaign design for {html.escape(model_name)}</h1>
<section class="summary" id="summary"><h2>Summary</h2>
<p><b>Recommended: {html.escape(best.design.name)}, {best.design.tests} tests</b>; it {verdict} the target CoV
width of {100 * plan.target:.0f} % for every group (budget {plan.budget} tests). Predicted 95 % widths:
{html.escape(widths)}. Its levels (design.csv, campaign.toml):</p>
<ul>{levels}</ul>
<p>Planned for the joint laws {html.escape(laws)}.</p></section>
{figure}
<h2>What the prediction assumes</h2>
<ul><li>Estimator: the paper's moment matching (eq. 10-11), with the intervals <code>workbench identify --method
moments</code> reports (a bootstrap of the tests carried through the linearised two steps); the Bayesian
variant's intervals are not predicted here.</li>
<li>Modes used: the first {s.count}; each extracted frequency scatters by {100 * s.frequency_scatter:.3g} % (sd).</li>
<li>Each tightening level draws the joint's modulus from its own equal-probability stratum of the group's Gamma
law (level 1 the softest): the levels span the law, as the paper chose its nine sweep levels to. Designs
whose levels are unbalanced or tighten all bolts alike show a bias: the estimator assumes independent joints.</li>
<li>{s.campaigns} virtual campaigns per design (seed {s.seed}), frequencies by the Rayleigh quotient of the nominal
modes (eq. 5). Width: the median reported 95 % width over the true value.</li></ul>
<h2>Simulation check</h2>{_verification(check, plan)}
<h2>Every candidate</h2>{table.html(link=False)}
<p>The same numbers in <a href="designs.csv">designs.csv</a>.</p>
</main></body></html>
"""


def design_outputs(plan: DesignPlan, check: Verification | None, model_path: Path,
                   out: Path) -> dict[str, str | bytes]:
    """Every file of `workbench design`'s output set: designs.csv, design.csv, campaign.toml, index.html."""
    frame = plan.model if isinstance(plan.model, MatrixModel) else plan.model.frame
    return {**design_files(plan, model_path, out, frame), "index.html": design_page(plan, frame.name, check)}

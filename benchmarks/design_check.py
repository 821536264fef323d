"""`workbench design`'s predictions checked on campaigns the workbench did not make (issue 17).

What it measures
----------------
For the two-bolt and the four-bolt frame, `plan_design` scores the candidates at the default target
(0.5) and budget and recommends one. For the four-bolt frame it also takes the paper's Table 6 design
(``two_level_centre``, 17 tests) and the smallest candidate whose predicted CoV widths are at most Table
6's for both groups (the issue's four-bolt question). Each of these designs is then run ``--campaigns``
times on the proving ground (`workbench.proving`): a Timoshenko article on its own mesh, a real lab's
nuisances on (manufacturing errors on E, density and dimensions, temperature drift over the sequence,
damping trend and jitter, 30-40 dB SNR per sensor), each joint's modulus drawn from its level's slice
of the file's Gamma law (`stratified_gamma_draws`, the proving ground's own code), FRFs through the
workbench's circle fit, modes paired by MAC, and moment matching on the bundled frame file
(Euler-Bernoulli, none of the as-built errors: misspecified). Nothing of `workbench.plan` makes the data.

Printed per design, group and parameter: the predicted width (the median 95 % interval width moment
matching will report, over the true value) beside the median width the campaigns' identifications
reported, and their ratio; the spread (2 x 1.96 x the sd of the log estimates, the simulated one from
their median absolute deviation) and the bias, predicted and found; how many estimates had no interval
(at a bound). The issue asks for a CoV width within 25 % of the prediction (12 or more campaigns).

    python benchmarks/design_check.py [--campaigns 16] [--frames two four] [--workers 2] [--out reports/design_check]

Campaign ``r`` of a design uses ``SeedSequence((seed, frame, design's tests, r))``. Rows go to
``OUT/rows.jsonl`` as they come (a run resumes), the summary to ``OUT/summary.md``.
"""

from __future__ import annotations

import argparse
import json
import math
import time
from dataclasses import replace
from pathlib import Path

import numpy as np

from workbench.identify.data import joint_groups, usable_modes
from workbench.identify.moments import moment_matching
from workbench.identify.pairing import pair_by_mac
from workbench.io.campaign import Factor
from workbench.model.frame_file import read_frame
from workbench.model.structure import structure_of
from workbench.plan.candidates import Design
from workbench.plan.predict import DesignPrediction
from workbench.proving.article import Article
from workbench.proving.campaigns import simulate_campaign
from workbench.proving.frames import proving_frame
from workbench.workflow.design import DesignPlan, plan_design
from workbench.workflow.execution import mapper
from workbench.workflow.measured import measured_modes

FRAMES = {"two": "two_bolt", "four": "four_bolt"}
COUNT = 8  # modes identified: the prediction's default


def checked_designs(plan: DesignPlan, frame: str, extra: list[str]) -> dict[str, DesignPrediction]:
    """The designs to simulate: the recommended one; for four bolts also Table 6, its cheapest predicted
    match, and the ``extra`` candidates named (the J2 sizes between, to find the match by simulation)."""
    out = {"recommended": plan.recommended}
    if frame == "four":
        table6 = next(p for p in plan.predictions if p.design.name == "two_level_centre")
        match = min((p for p in plan.predictions if np.all(p.width[:, 1] <= table6.width[:, 1])),
                    key=lambda p: (p.design.tests, float(p.width[:, 1].max())))
        out.update({"table6": table6, "matches_table6": match})
        out.update({name: p for p in plan.predictions for name in extra if p.design.name == name})
    return out


def one_campaign(_shared: None, job: tuple[str, str, Design, int, int]) -> dict:
    """Moment matching on one proving-ground campaign of ``design``: estimates and reported widths."""
    frame_key, role, design, rep, seed = job
    name = FRAMES[frame_key]
    article_frame = proving_frame(name)
    joints = [j.name for j in article_frame.joints]
    levels = {str(i): text for i, text in enumerate(design.level_names, start=1)}
    factors = tuple(Factor(f"bolt_{j}", "tightening", levels, joint=j) for j in joints)
    tests = [{f.name: str(v) for f, v in zip(factors, row)} for row in design.levels]
    laws = {j.name: (j.youngs_modulus, j.cov) for j in article_frame.joints}
    case_seed = int(np.random.SeedSequence((seed, list(FRAMES).index(frame_key), design.tests, rep))
                    .generate_state(1)[0])
    campaign, _ = simulate_campaign(article_frame, Article(article_frame), factors, tests, laws, case_seed,
                                    strata={j: f"bolt_{j}" for j in joints})
    frame = read_frame(f"frames/{name}.toml")  # the bundled file: Euler-Bernoulli, nominal dimensions
    model = structure_of(frame)
    groups = joint_groups(model)
    row = {"frame": frame_key, "role": role, "design": design.name, "tests": design.tests, "rep": rep}
    try:
        data = pair_by_mac(model, measured_modes(replace(campaign, frame=frame), COUNT, "identify from"))
    except ValueError as error:
        return {**row, "refused": str(error)}
    data, dropped = usable_modes(data)
    fit = moment_matching(model, data, groups, seed=rep)
    truth = {g: (groups.nominal_pa[i], float(np.mean([model.joints[k].cov for k in groups.members[i]])))
             for i, g in enumerate(groups.groups)}
    for i, g in enumerate(groups.groups):
        for c, (value, ci) in enumerate(((fit.mean_pa[i], fit.mean_ci95), (fit.cov[i], fit.cov_ci95))):
            key = ("youngs_modulus", "cov")[c]
            true = truth[g][c]
            row[f"{g}.{key}"] = float(value / true)
            row[f"{g}.{key}.width"] = math.nan if ci is None else float((ci[i][1] - ci[i][0]) / true)
    row["modes_dropped"] = dropped
    return row


def _robust_spread(values: np.ndarray) -> float:
    """2 x 1.96 x the sd of ``values`` from their median absolute deviation (x 1.4826): one estimate pinned
    at a bound (no interval) does not make the spread of fifteen."""
    if values.size < 2:
        return math.nan
    return float(2 * 1.959964 * 1.4826 * np.median(np.abs(values - np.median(values))))


def summarise(rows: list[dict], predictions: dict) -> list[dict]:
    out = []
    for (frame_key, role), pred in predictions.items():
        sel = [r for r in rows if r["frame"] == frame_key and r["role"] == role and "refused" not in r]
        for i, g in enumerate(pred["groups"]):
            for c, key in enumerate(("youngs_modulus", "cov")):
                ratio = np.array([r[f"{g}.{key}"] for r in sel])
                widths = np.array([r[f"{g}.{key}.width"] for r in sel])
                found = float(np.nanmedian(widths)) if sel else math.nan
                out.append({"frame": frame_key, "role": role, "design": pred["design"], "tests": pred["tests"],
                            "group": g, "parameter": key, "campaigns": len(sel),
                            "refused": sum(1 for r in rows if r["frame"] == frame_key and r["role"] == role
                                           and "refused" in r),
                            "predicted_width": pred["width"][i][c], "simulated_width": found,
                            "ratio": found / pred["width"][i][c],
                            "predicted_spread": pred["spread"][i][c],
                            "simulated_spread": _robust_spread(np.log(ratio)),
                            "at_bound": int(np.sum(np.isnan(widths))),
                            "predicted_bias": pred["bias"][i][c], "simulated_bias": float(ratio.mean() - 1)})
    return out


def markdown(summary: list[dict]) -> str:
    lines = ["| frame | design (role) | tests | group | parameter | campaigns | predicted width (%) | "
             "simulated width (%) | simulated / predicted | predicted spread (%) | simulated spread (%) | "
             "predicted bias (%) | simulated bias (%) | no interval |", "|---" * 14 + "|"]
    for s in summary:
        lines.append(f"| {s['frame']} | {s['design']} ({s['role']}) | {s['tests']} | {s['group']} | {s['parameter']} | "
                     f"{s['campaigns']} | {100 * s['predicted_width']:.1f} | {100 * s['simulated_width']:.1f} | "
                     f"{s['ratio']:.2f} | {100 * s['predicted_spread']:.1f} | {100 * s['simulated_spread']:.1f} | "
                     f"{100 * s['predicted_bias']:+.1f} | {100 * s['simulated_bias']:+.1f} | {s['at_bound']} |")
    return "\n".join(lines) + "\n"


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--campaigns", type=int, default=16, help="campaigns per design (default 16)")
    parser.add_argument("--frames", nargs="+", choices=list(FRAMES), default=list(FRAMES))
    parser.add_argument("--seed", type=int, default=17)
    parser.add_argument("--extra", nargs="*", default=[f"j2_optimal_{n}" for n in (10, 12, 14, 17, 20, 24)],
                        help="further four-bolt candidates to simulate (default J2 sizes 10 to 24)")
    parser.add_argument("--out", type=Path, default=Path("reports/design_check"))
    parser.add_argument("--workers", type=int, default=1)
    parser.add_argument("--scheduler", help="a running Dask scheduler (tcp://host:8786) instead of local workers")
    args = parser.parse_args(argv)
    args.out.mkdir(parents=True, exist_ok=True)
    predictions, jobs = {}, []
    for frame_key in args.frames:
        t0 = time.perf_counter()
        plan = plan_design(structure_of(read_frame(f"frames/{FRAMES[frame_key]}.toml")))
        print(f"{frame_key}: {len(plan.predictions)} candidates scored in {time.perf_counter() - t0:.1f} s; "
              f"recommended {plan.recommended.design.name}")
        for role, p in checked_designs(plan, frame_key, args.extra).items():
            predictions[(frame_key, role)] = {"design": p.design.name, "tests": p.design.tests,
                                              "groups": list(plan.groups.groups), "width": p.width.tolist(),
                                              "spread": p.spread.tolist(), "bias": p.bias.tolist()}
            jobs += [(frame_key, role, p.design, r, args.seed) for r in range(args.campaigns)]
    rows_file = args.out / "rows.jsonl"
    rows = [json.loads(line) for line in rows_file.read_text().splitlines()] if rows_file.exists() else []
    done = {(r["frame"], r["role"], r["design"], r["rep"]) for r in rows}
    pending = [j for j in jobs if (j[0], j[1], j[2].name, j[3]) not in done]
    batch = 2 * max(args.workers, 1)
    with mapper(args.workers, args.scheduler) as run:
        for start in range(0, len(pending), batch):
            t0 = time.perf_counter()
            new = run(one_campaign, pending[start:start + batch], "campaigns", None)
            with rows_file.open("a") as f:
                f.writelines(json.dumps(r) + "\n" for r in new)
            rows += new
            names = ", ".join(f"{r['frame']}/{r['design']}/{r['rep']}" for r in new)
            print(f"  {names}: "
                  f"{time.perf_counter() - t0:.0f} s", flush=True)
    current = {(k[0], k[1]): v["design"] for k, v in predictions.items()}
    rows = [r for r in rows if current.get((r["frame"], r["role"])) == r["design"] and r["rep"] < args.campaigns]
    summary = summarise(rows, predictions)
    (args.out / "summary.json").write_text(json.dumps(summary, indent=1))
    (args.out / "summary.md").write_text(markdown(summary))
    print(markdown(summary))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())

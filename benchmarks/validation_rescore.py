"""The blind validations in ``reports/`` scored again with the current scores, from their ``cases.csv``.

Run from the repository root: ``python benchmarks/validation_rescore.py [--since SEED]`` (under a second), or
``--outcomes`` (also what each kind of case was called: right, a wrong name, ``none`` or ``unexplained``), or
``--calibration`` (how often a named effect was right, by its stated confidence, and what a higher naming bar
would have kept and taken away; pooled over the seeds from ``--since`` on), or
``--pair RUN_A RUN_B`` (two output directories of the same cases, e.g. ``reports/diagnosis_validation_seed19
reports/diagnosis_validation_paired/seed19_fixed``): the cases whose verdict, place, ``also`` or partial differ.

A run's verdicts are fixed once it has run; the scores read them. Since the footprint each case reached was
recorded from the start, the runs of seeds before the ``reached`` column (up to 12) are read at the rung
their footprint reached (`workbench.proving.cases.reached_level`) with ``faint`` cases set aside, as later runs
are, so that every seed is scored alike. Prints, per seed, the headline rates with their Wilson 95 % intervals,
and pooled over the seeds from ``--since`` on (8 by default). Each seed ran the rules of its day
(``reports/diagnosis.md``): a pooled rate is over those rule sets, not the current rules'.
"""

from __future__ import annotations

import argparse
import csv
from collections import Counter
from pathlib import Path

from workbench.proving.cases import FAINT, LEVELS, reached_level
from workbench.rig.effects import NONE, UNEXPLAINED
from workbench.workflow.proving_validation import ProvingResult, measurement_label, quantity_label, score, wilson

REPO = Path(__file__).resolve().parents[1]
HEADLINE = ("single_accuracy", "confident_wrong", "none_false_positive", "outside_unexplained", "faint_none")


def _number(text: str) -> float | None:
    return float(text) if text not in ("", "None") else None


def load(path: Path) -> list[ProvingResult]:
    """The `ProvingResult` of every row of a ``cases.csv`` (without the per-case record)."""
    results = []
    for row in csv.DictReader(path.open()):
        footprint = _number(row["footprint"])
        channel = "damping" if row["truth"] == "joint_damping" else "frequency"
        reached = row.get("reached") or (reached_level(footprint, channel) if footprint is not None else "")
        results.append(ProvingResult(
            int(row["case"]), int(row["seed"]), row["frame"], row["category"], row["truth"], row["secondary"] or None,
            row["level"], row["truth_where"] or None, row["mechanism"] or None, footprint, row["verdict"],
            row["where"] or None, tuple(row["also"].split()), row["partial"] or None, float(row["confidence"]),
            float(row["shrinkage"]), row["right"] == "True", row["named_wrong"] == "True",
            None if row["place_right"] in ("", "None") else row["place_right"] == "True",
            float(row["wall_time_s"]), {}, reached, row.get("quantity", ProvingResult.quantity),
            row.get("sensed", ProvingResult.sensed), float(row.get("df_hz", ProvingResult.df_hz))))  # before seed 19
    return results


def _rate(s: dict) -> str:
    if s["rate"] is None:
        return f"{'-':>24s}"
    lo, hi = s["ci95"]
    return f"{s['hits']:4d}/{s['n']:<4d} {100 * s['rate']:5.1f} [{100 * lo:4.1f}, {100 * hi:4.1f}]"


def pair(first: Path, second: Path) -> None:
    """Print the cases of two runs of the same cases whose verdict, place, ``also`` or partial differ."""
    a, b = (load(Path(d) / "cases.csv") for d in (first, second))
    if [r.seed for r in a] != [r.seed for r in b]:
        raise SystemExit(f"--pair: {first} and {second} do not hold the same cases")

    def said(r: ProvingResult) -> tuple:
        return r.verdict, r.where, r.also, r.partial

    differ = [(x, y) for x, y in zip(a, b) if said(x) != said(y)]
    print(f"{len(differ)} of {len(a)} cases differ (verdict, place, also, partial)")
    for x, y in differ:
        print(f"case {x.case:3d} {x.frame:21s} {x.category:8s} {x.truth:20s} {x.reached:6s} | "
              f"{measurement_label(x)}: {said(x)} right={x.right} | {measurement_label(y)}: {said(y)} right={y.right}")


def outcomes(results: list[ProvingResult]) -> None:
    """Print what each kind of case was called, pooled: right, a wrong name, or the verdict it got instead
    (``none``: no channel had a gap; ``unexplained``), single effects by the rung their footprint reached.
    """
    def called(r: ProvingResult) -> str:
        return "right" if r.right else ("named wrong" if r.named_wrong else r.verdict)

    groups = [(f"single {level}", [r for r in results if r.category == "single" and r.reached == level])
              for level in LEVELS]
    groups += [(category, [r for r in results if r.category == category and r.reached != FAINT])
               for category in ("none", "outside", "combined")]
    for name, rows in groups:
        cells = ", ".join(f"{k} {v}" for k, v in Counter(called(r) for r in rows).most_common())
        print(f"pooled {name:15s} {len(rows):4d} cases: {cells}")


CONFIDENCE_BINS = (0.5, 0.6, 0.7, 0.8, 0.9, 0.99, 0.9999, 1.0)


def calibration(results: list[ProvingResult]) -> None:
    """Print how often a named effect was right, by its stated confidence (Wilson 95 %), and for each bar of
    `CONFIDENCE_BINS` what naming only above it would have done: the right names lost (single effects, and all)
    and the wrong names taken away. A verdict's effect is read here as named when it is neither ``none`` nor
    ``unexplained``; a bar's cases would read ``unexplained`` (a rescoring, not a run: the pair the decision
    would then try is not).
    """
    named = [r for r in results if r.verdict not in (NONE.name, UNEXPLAINED)]
    print(f"{len(named)} named of {len(results)} cases; right by stated confidence:")
    for lo, hi in zip(CONFIDENCE_BINS, CONFIDENCE_BINS[1:]):
        rows = [r for r in named if lo < r.confidence <= hi]
        w = wilson(sum(r.right for r in rows), len(rows))
        print(f"  ({lo:g}, {hi:g}] {_rate(w)}")
    for bar in CONFIDENCE_BINS[1:-1]:
        below = [r for r in named if r.confidence <= bar]
        lost = sum(r.right and r.category == "single" for r in below)
        wrong = sum(r.named_wrong for r in below)
        left = sum(r.named_wrong for r in named) - wrong
        print(f"  named only above {bar:g}: right single names lost {lost}, right names lost "
              f"{sum(r.right for r in below)}, wrong names taken away {wrong}, "
              f"wrong names left {left}/{len(results)} = {100 * left / len(results):.1f} %")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--since", type=int, default=8, help="pool the seeds from this one on (default 8)")
    parser.add_argument("--pair", nargs=2, metavar="RUN", help="two runs of the same cases: what differs")
    parser.add_argument("--outcomes", action="store_true", help="also what each kind of case was called, pooled")
    parser.add_argument("--calibration", action="store_true",
                        help="also how often a named effect was right by its confidence, pooled")
    args = parser.parse_args()
    if args.pair:
        pair(*args.pair)
        return
    since = args.since
    runs = sorted((int(p.parent.name.removeprefix("diagnosis_validation_seed")), p)
                  for p in (REPO / "reports").glob("diagnosis_validation_seed*/cases.csv"))
    print(f"{'seed':>6s} " + " ".join(f"{k:>24s}" for k in HEADLINE))
    pooled: list[ProvingResult] = []
    for seed, path in runs:
        results = load(path)
        if seed >= since:
            pooled += results
        s = score(results)
        print(f"{seed:>6d} " + " ".join(_rate(s[k]) for k in HEADLINE))
    s = score(pooled)
    print(f"{'>=' + str(since):>6s} " + " ".join(_rate(s[k]) for k in HEADLINE))
    by_level = ", ".join(f"{level} {_rate(v).strip()}" for level, v in s["single_accuracy_by_level"].items())
    print(f"pooled single effects by the rung reached: {by_level}")
    # how the cases were measured (seeds up to 18: accelerance on 0.25 Hz lines, all of them)
    for what, key in (("quantity", quantity_label),
                      ("line spacing", lambda r: f"{r.df_hz:.3g} Hz")):
        groups = sorted({key(r) for r in pooled})
        cells = [f"{g} {_rate(score([r for r in pooled if key(r) == g])['single_accuracy']).strip()}" for g in groups]
        print(f"pooled single effects by {what}: " + ", ".join(cells))
    if args.outcomes:
        outcomes(pooled)
    if args.calibration:
        calibration(pooled)


if __name__ == "__main__":
    main()

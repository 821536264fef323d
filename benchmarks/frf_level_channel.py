"""What the FRF-level channel takes away: the right and the wrong names the modal constants' levels contradict.

Run from the repository root: ``python benchmarks/frf_level_channel.py [--seeds 10 11 12] [--cases 200]
[--workers 2]`` (about 11 minutes a seed of 200 cases on 2 cores).

Each case of each seed's validation mix (`workbench.workflow.proving_validation.validation_specs`, the cases
`workbench validate-diagnosis` runs) is simulated by the proving ground and diagnosed blind with the current
rules. Where the frequencies name one effect and the levels contradict it (`workbench.diagnose.frf_levels`), the
verdict is ``unexplained`` with that effect in ``partial.frf_levels``: this script scores the effect the level
test took away as `run_proving_case` would have scored it named (right: the true primary effect; wrong: an
effect the case does not hold). It prints, per seed and pooled, the frequency names the test let through and
those it took away, right and wrong: names, counted over every case that gives one (faint cases too, which the
single-effect rate sets aside; the confident-wrong rate counts them). The levels of the test were set on seeds 10 to 12 (spent validation seeds,
the development set) and frozen before seed 14 ran; on them it is a development figure, on later seeds a
validation one.
"""

from __future__ import annotations

import argparse
from collections import Counter

from workbench.diagnose.observations import DEFAULT_ALLOWANCE
from workbench.proving.mechanisms import NONE
from workbench.workflow.execution import mapper
from workbench.workflow.proving_validation import ProvingResult, run_proving_case, validation_specs


def _taken_away(result: ProvingResult) -> str | None:
    """The effect the level test took away from ``result``'s verdict, or None."""
    partial = result.record["verdict"].get("partial") or {}
    return partial["effect"] if (partial.get("frf_levels") or {}).get("contradicted") else None


def tally(results: list[ProvingResult]) -> Counter:
    """Counts of ``kept right``, ``kept wrong``, ``taken right``, ``taken wrong`` and ``tested`` (a level test ran
    on a named effect, kept or taken away).
    """
    out: Counter = Counter()
    for r in results:
        taken = _taken_away(r)
        tested = taken is not None or "frf_levels" in r.record["verdict"]
        out["tested"] += tested
        if taken is not None:
            allowed = {r.truth, r.secondary} - {None, NONE}
            right = r.category in ("single", "combined") and taken == r.truth
            out["taken right"] += right
            out["taken wrong"] += taken not in allowed
        elif tested:
            out["kept right"] += r.right
            out["kept wrong"] += r.named_wrong
    return out


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seeds", nargs="+", type=int, default=[10, 11, 12])
    parser.add_argument("--cases", type=int, default=200)
    parser.add_argument("--workers", type=int, default=2)
    args = parser.parse_args()
    pooled: Counter = Counter()
    with mapper(args.workers) as run:
        for seed in args.seeds:
            counts = tally(run(run_proving_case, validation_specs(args.cases, seed, "fixed"), "cases", DEFAULT_ALLOWANCE))
            pooled += counts
            print(f"seed {seed}: {dict(counts)}", flush=True)
    print(f"pooled over seeds {args.seeds}: level tests {pooled['tested']}; taken away: "
          f"{pooled['taken wrong']} wrong names (of {pooled['taken wrong'] + pooled['kept wrong']} wrong names "
          f"tested), {pooled['taken right']} right ones (of {pooled['taken right'] + pooled['kept right']} right "
          "names tested)")


if __name__ == "__main__":
    main()

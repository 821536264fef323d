"""Same seed, same numbers: run the commands on the bundled campaigns with two versions and compare.

    python benchmarks/same_numbers.py --ref 55bb894            # a git ref against the working tree
    python benchmarks/same_numbers.py --save DIR                # only run the working tree, keep its outputs
    python benchmarks/same_numbers.py --against DIR             # compare the working tree with saved outputs
    python benchmarks/same_numbers.py --quick ...               # without the demo and the bayes run
    python benchmarks/same_numbers.py --only demo ...           # only the outputs named

Each version runs as ``python -m workbench.cli`` from its own checkout (a temporary ``git worktree`` for
``--ref``), so the two share no code. What is compared:

- CSV files cell for cell as text (floats are written with ``repr``: full precision), less wall-time columns;
- JSON files key by key, after dropping wall times (``wall_time_s`` and the like);
- HTML pages by their figures (the SHA-256 of each embedded PNG: the pixels) and every number of their
  text in order, less the "what was done" section and "Wall time N s" sentences (wall times); the
  wording may change, the numbers may not.

The renovation of issue 13 must leave every one of these identical. Prints one line per output and
exits 1 on any difference.
"""

from __future__ import annotations

import argparse
import csv
import filecmp
import hashlib
import json
import os
import re
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
EXAMPLE = ROOT.parent / "shared" / "examples" / "independent-two-test-campaign"

# (output name, command arguments after ``workbench``); outputs go to OUT/<name>
RUNS: list[tuple[str, list[str]]] = [
    ("modes_four_bolt", ["modes", "frames/four_bolt.toml", "--count", "12"]),
    *[(f"propagate_{m}", ["propagate", "frames/four_bolt.toml", "--method", m, "--samples", "400", "--seed", "3"])
      for m in ("smr1", "smr2", "adaptive", "pert2", "mc")],
    ("propagate_mc_2workers", ["propagate", "frames/four_bolt.toml", "--method", "mc", "--samples", "400",
                               "--seed", "3", "--workers", "2"]),
    ("propagate_horizontal", ["propagate", "frames/one_bolt_horizontal.toml", "--method", "adaptive"]),
    ("extract_table5", ["extract", "campaigns/two_bolt_table5"]),
    ("extract_vertical", ["extract", "campaigns/one_bolt_vertical_sweep", "--count", "8"]),
    ("identify_table3", ["identify", "campaigns/paper_table3_one_bolt_vertical", "--method", "moments"]),
    ("identify_table5", ["identify", "campaigns/two_bolt_table5", "--method", "moments", "--seed", "1"]),
    ("identify_horizontal", ["identify", "campaigns/one_bolt_horizontal_sweep", "--method", "moments"]),
    ("diagnose_four_bolt", ["diagnose", "campaigns/four_bolt_table6"]),
    ("diagnose_table3", ["diagnose", "campaigns/paper_table3_one_bolt_vertical"]),
    ("validate_diagnosis", ["validate-diagnosis", "--cases", "3", "--seed", "5"]),
    ("report_table3", ["report", "campaigns/paper_table3_one_bolt_vertical"]),
]
SLOW_RUNS: list[tuple[str, list[str]]] = [
    ("identify_vertical_bayes", ["identify", "campaigns/one_bolt_vertical_sweep", "--method", "bayes", "--seed", "2"]),
    ("demo", ["demo"]),
]
WALL = re.compile(r"(wall|seconds|time_s|elapsed)", re.I)
PNG = re.compile(r"data:image/png;base64,([A-Za-z0-9+/=]+)")
NUMBER = re.compile(r"[-+]?\d+(?:\.\d+)?(?:[eE][-+]?\d+)?")
WALL_TEXT = re.compile(r"[Ww]all time [0-9.]+ s")
DONE = re.compile(r'<h2 id="done">.*?(?=<h2|</body>)', re.S)


def run_version(source: Path, out: Path, runs: list[tuple[str, list[str]]]) -> None:
    """Run every command with the package and the data of ``source``, writing under ``out``."""
    env = dict(os.environ, PYTHONPATH=str(source), PYTHONHASHSEED="0")
    for name, args in runs:
        target = out / name
        extra = ["--out", str(target)]
        start = time.perf_counter()
        done = subprocess.run([sys.executable, "-m", "workbench.cli", *args, *extra], cwd=source, env=env,
                              capture_output=True, text=True)
        (out / f"{name}.stdout").write_text(done.stdout)
        status = "ok" if done.returncode == 0 else f"exit {done.returncode}: {done.stderr.strip()[-300:]}"
        print(f"  {source.name:>12} {name:<26} {time.perf_counter() - start:7.1f} s  {status}", flush=True)


def _strip_times(value: object) -> object:
    if isinstance(value, dict):
        return {k: _strip_times(v) for k, v in value.items() if not WALL.search(k)}
    if isinstance(value, list):
        return [_strip_times(v) for v in value]
    return value


def _html_digest(text: str) -> list[str]:
    """The page's figures (a hash of each PNG) and every number of its text, in order; wording is free."""
    figures = ["png:" + hashlib.sha256(m.group(1).encode()).hexdigest()[:16] for m in PNG.finditer(text)]
    text = WALL_TEXT.sub("wall time", DONE.sub("", PNG.sub("", text)))
    return figures + NUMBER.findall(re.sub(r"<[^>]*>", " ", text))


def _csv_without_times(path: Path) -> list[list[str]]:
    rows = list(csv.reader(path.open(newline="")))
    keep = [i for i, name in enumerate(rows[0] if rows else []) if not WALL.search(name)]
    return [[row[i] for i in keep if i < len(row)] for row in rows]


def same(a: Path, b: Path) -> tuple[bool, str]:
    """Whether two output files carry the same numbers, and a short reason when they do not."""
    if a.suffix == ".json":
        ja, jb = _strip_times(json.loads(a.read_text())), _strip_times(json.loads(b.read_text()))
        return ja == jb, "" if ja == jb else "JSON values differ"
    if a.suffix == ".html":
        ha, hb = _html_digest(a.read_text()), _html_digest(b.read_text())
        if ha == hb:
            return True, ""
        na, nb = PNG.findall(a.read_text()), PNG.findall(b.read_text())
        figures = sum(x != y for x, y in zip(na, nb)) + abs(len(na) - len(nb))
        return False, f"HTML differs ({figures} of {max(len(na), len(nb))} figures differ)"
    if a.suffix == ".csv":
        ok = _csv_without_times(a) == _csv_without_times(b)
        return ok, "" if ok else "CSV values differ"
    ok = filecmp.cmp(a, b, shallow=False)
    return ok, "" if ok else "bytes differ"


def compare(before: Path, after: Path, runs: list[tuple[str, list[str]]]) -> int:
    """Print one line per output file; return the number of differences."""
    differences = 0
    for name, _ in runs:
        files_a = sorted(p.relative_to(before) for p in (before / name).rglob("*") if p.is_file())
        files_b = sorted(p.relative_to(after) for p in (after / name).rglob("*") if p.is_file())
        if not files_a and not files_b:
            print(f"MISSING {name}: neither version wrote anything")
            differences += 1
            continue
        for rel in sorted(set(files_a) | set(files_b)):
            if rel.suffix in (".png", ".nc"):  # screenshots; posterior.nc embeds creation times
                continue
            if rel not in files_a or rel not in files_b:
                print(f"DIFF {rel}: only in {'after' if rel not in files_a else 'before'}")
                differences += 1
                continue
            ok, why = same(before / rel, after / rel)
            print(f"{'same' if ok else 'DIFF'} {rel}{'' if ok else ': ' + why}")
            differences += not ok
    return differences


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--ref", help="git ref of the 'before' version (checked out in a temporary worktree)")
    parser.add_argument("--save", type=Path, help="run the working tree only and keep its outputs here")
    parser.add_argument("--against", type=Path, help="compare the working tree with outputs saved by --save")
    parser.add_argument("--quick", action="store_true", help="leave out the bayes run and the demo")
    parser.add_argument("--only", nargs="+", metavar="NAME", help="run only these outputs (names as printed)")
    args = parser.parse_args()
    runs = RUNS if args.quick else RUNS + SLOW_RUNS
    if args.only:
        runs = [r for r in RUNS + SLOW_RUNS if r[0] in args.only]
    with tempfile.TemporaryDirectory() as tmp:
        after = args.save or Path(tmp) / "after"
        after.mkdir(parents=True, exist_ok=True)
        print(f"working tree {ROOT}:")
        run_version(ROOT, after, runs)
        if args.save:
            return 0
        if args.against:
            before = args.against
        elif args.ref:
            tree = Path(tmp) / "before"
            subprocess.run(["git", "worktree", "add", "--detach", str(tree), args.ref], cwd=ROOT, check=True,
                           capture_output=True)
            try:
                before = Path(tmp) / "before_out"
                before.mkdir()
                print(f"{args.ref} in {tree}:")
                run_version(tree, before, runs)
                differences = compare(before, after, runs)
            finally:
                subprocess.run(["git", "worktree", "remove", "--force", str(tree)], cwd=ROOT, capture_output=True)
                shutil.rmtree(tree, ignore_errors=True)
            print(f"same_numbers: {differences} differences against {args.ref}")
            return 1 if differences else 0
        else:
            parser.error("give --ref, --save or --against")
        differences = compare(before, after, runs)
        print(f"same_numbers: {differences} differences against {before}")
        return 1 if differences else 0


if __name__ == "__main__":
    sys.exit(main())

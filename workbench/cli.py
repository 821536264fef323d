"""The ``workbench`` command line (CONTRACTS.md section 3): thin over the library; exit 2 on bad input, one line."""

from __future__ import annotations

import argparse
import json
import sys
import time
import warnings
from collections.abc import Sequence
from pathlib import Path
from typing import NoReturn

import numpy as np
from tqdm import tqdm

from workbench import __version__
from workbench.cli_options import allowance as _allowance
from workbench.cli_options import allowance_options as _allowance_options
from workbench.cli_options import positive_int as _positive_int
from workbench.cli_options import tolerances as _tolerances
from workbench.identify.laplace import ERROR_TERMS
from workbench.io.outputs import OutputExistsError, OutputSet, claim_output, csv_text, json_text
from workbench.model.assembly import assemble
from workbench.model.frame_file import read_frame
from workbench.model.matrix_file import is_matrix_model, model_files, read_matrix_model
from workbench.model.matrix_model import MatrixModel
from workbench.model.structure import Structure, structure_modes
from workbench.progress import Progress
from workbench.report.tables import declared_files
from workbench.tasks import local_cores
from workbench.uq.limits import smr1_cov_warning
from workbench.uq.smr import propagate
from workbench.uq.stochastic import joint_model

# The campaign, workflow and report layers load pandas, matplotlib and arviz (seconds on a busy
# machine): each command imports them when it runs, so that `modes`, `propagate` and --help need not.

__all__ = ["main", "ProgressBars"]


class _Parser(argparse.ArgumentParser):
    def error(self, message: str) -> NoReturn:  # one line and exit 2, as for any bad input
        self.exit(2, f"{self.prog}: error: {message}\n")


class ProgressBars:
    """tqdm bars on standard error for the `workbench.progress` callbacks of the library, one per label."""

    def __init__(self) -> None:
        self.bars: dict[str, tqdm] = {}

    def __call__(self, label: str, done: int, total: int) -> None:
        bar = self.bars.get(label)
        if bar is None:
            bar = self.bars[label] = tqdm(total=total, desc=label, leave=False)
        bar.update(done - bar.n)
        if done >= total:
            bar.close()
            del self.bars[label]


def _progress() -> Progress | None:
    """Bars when standard error is a terminal; nothing in pipes, logs and tests."""
    return ProgressBars() if sys.stderr.isatty() else None


def _structure(path: Path) -> Structure:
    """A frame file assembled, or a matrix model read (CONTRACTS.md sections 1 and 4)."""
    return read_matrix_model(path) if is_matrix_model(path) else assemble(read_frame(path))


def _modes(args: argparse.Namespace, out: OutputSet) -> str:
    model = _structure(args.frame)
    modes = structure_modes(model, args.count)
    name, size = (model.name if isinstance(model, MatrixModel) else model.frame.name), model.size
    text = csv_text(["mode", "frequency_hz"],
                    ((k + 1, float(f)) for k, f in enumerate(modes.frequency_hz)))
    out.commit({"modes.csv": text})
    return f"{modes.count} modes of {name!r} ({size} dofs) written to {args.out}/modes.csv"


def _propagate(args: argparse.Namespace, out: OutputSet) -> str:
    model = _structure(args.frame)
    joints = joint_model(model)
    if not joints.random.any():
        raise ValueError(f"{args.frame}: joints: no joint has a cov > 0, so nothing varies")
    if (caution := smr1_cov_warning(model, joints, args.method)) is not None:
        warnings.warn(caution, stacklevel=1)
    from workbench.workflow.execution import mapper

    start = time.perf_counter()
    if args.method == "mc":  # the one command of the three whose work is handed out
        with mapper(args.workers, args.scheduler, _progress()) as tasks:
            moments = propagate(model, joints, "mc", args.count, args.samples, args.seed, tasks)
    else:
        moments = propagate(model, joints, args.method, args.count, seed=args.seed)
    wall = time.perf_counter() - start
    table = csv_text(["mode", "mean_hz", "std_hz"],
                     ((k + 1, float(m), float(s)) for k, (m, s) in enumerate(zip(moments.mean_hz, moments.std_hz))))
    run = {"method": args.method, "wall_time_s": wall, "samples": args.samples if args.method == "mc" else 0,
           "seed": args.seed, "frame": str(args.frame),
           "joints": {n: float(c) for n, c in zip(joints.names, joints.cov)},
           "nominal_hz": moments.nominal_hz.tolist()}
    if moments.refined is not None:
        run["smr2_modes"] = [int(k) + 1 for k in moments.refined.nonzero()[0]]
    if moments.proximity is not None:
        run["proximity_factor"] = [float(p) if np.isfinite(p) else None for p in moments.proximity]
        run["dispersion"] = np.asarray(moments.dispersion).tolist()
    out.commit({"moments.csv": table, "run.json": json_text(run)})
    return f"{args.method}: moments of {moments.count} modes in {wall:.3f} s written to {args.out}"


def _import(args: argparse.Namespace, out: OutputSet) -> str:
    from workbench.io.importing import import_campaign, imported_files

    campaign = import_campaign(args.files, args.frame, args.design, args.name, args.quantity)
    files = imported_files(campaign, args.frame)
    out.commit(files)
    sensors = 0 if campaign.frf is None else campaign.frf["sensor"].nunique()
    return (f"{len(campaign.test_ids)} test(s), {sensors} sensor(s) of {campaign.quantity} imported as campaign "
            f"{campaign.name!r} into {args.out}")


def _import_writes(args: argparse.Namespace) -> tuple[str, ...]:
    """The campaign's files; with a matrix model, its model.toml and the files it names instead of frame.toml."""
    names = ("campaign.toml", "design.csv", "frf.csv")
    try:
        if is_matrix_model(args.frame):
            return names + ("model.toml", *model_files(args.frame))
    except (OSError, ValueError, KeyError, TypeError):
        pass  # a broken model is reported by its reader, with the file and the key
    return names + ("frame.toml",)


def _extract(args: argparse.Namespace, out: OutputSet) -> str:
    from workbench.io.campaign import load_campaign
    from workbench.workflow.measured import (
        MODES_HEADER,
        QUALITY_HEADER,
        SHAPES_HEADER,
        extract_campaign,
        extraction_rows,
    )

    campaign = load_campaign(args.campaign)
    bands = None
    if args.bands:
        bands = [tuple(float(v) for v in band.split(":")) for band in args.bands.split(",")]
    from workbench.workflow.execution import mapper

    with mapper(args.workers, args.scheduler, _progress()) as tasks:
        extraction = extract_campaign(campaign, bands, args.count, tasks)
    rows = extraction_rows(extraction)
    headers = {"modes.csv": MODES_HEADER, "shapes.csv": SHAPES_HEADER, "quality.csv": QUALITY_HEADER}
    out.commit({name: csv_text(list(headers[name]), table) for name, table in rows.items()})
    flagged = sum(bool(e.flags) for per_mode in extraction.estimates.values() for e in per_mode)
    note = f"; {flagged} flagged (see quality.csv)" if flagged else ""
    return (f"{len(extraction.bands)} modes x {len(extraction.estimates)} tests of {campaign.name!r} by circle fit"
            f"{note}; written to {args.out}")


def _identify(args: argparse.Namespace, out: OutputSet) -> str:
    from workbench.workflow.identification import IdentifyOptions, identify_campaign

    options = IdentifyOptions(args.method, args.count, args.seed, args.steps, args.max_steps, args.errors,
                              args.tolerances, args.allow_bounds)
    done = identify_campaign(args.campaign, options, _progress())
    out.commit(done.files)
    summary = ", ".join(f"{name}: E = {j['youngs_modulus'] / 1e9:.3g} GPa, CoV = {j['cov']:.3g}"
                        for name, j in done.record["joints"].items())
    return f"{args.method} on {done.campaign!r} ({done.source}): {summary}; written to {args.out}"


def _notify(line: str) -> None:
    print(line, file=sys.stderr, flush=True)


def _write_report(run, out: OutputSet, start: float, workers: int = 1) -> str:
    from workbench.report.page import report_files

    files = report_files(run, time.perf_counter() - start, workers)
    out.commit(dict(files))  # the page and its tables as CSV: one output set, all or nothing
    return f"{out.out}/index.html (and {len(files) - 1} table(s) as CSV beside it)"


def _report(args: argparse.Namespace, out: OutputSet) -> str:
    from workbench.workflow.report_inputs import parse_bands
    from workbench.workflow.runs import report_run

    start = time.perf_counter()
    run = report_run(args.campaign, joints_from=args.joints_from or (), seed=args.seed, samples=args.samples,
                     bayes=not args.no_bayes, bayes_steps=args.steps, workers=args.workers,
                     bands=parse_bands(args.bands), progress=_progress(), notify=_notify)
    return f"report of {run.studies[0].name!r} written to {_write_report(run, out, start, args.workers)}"


DEMO_OUT = "out/demo"  # untracked (.gitignore): the demo never rewrites a file of the repository


def _demo(args: argparse.Namespace, out: OutputSet) -> str:
    from workbench.workflow.runs import demo_run

    start = time.perf_counter()
    run = demo_run(args.campaigns, seed=args.seed, samples=args.samples, bayes_steps=args.steps,
                   workers=args.workers, progress=_progress(), notify=_notify)
    return f"demo report written to {_write_report(run, out, start, args.workers)}"


def _diagnose(args: argparse.Namespace, out: OutputSet) -> str:
    from workbench.report.diagnosis_page import diagnosis_files
    from workbench.workflow.diagnosis import diagnose_campaign
    from workbench.workflow.execution import mapper

    def say(message: str) -> None:
        print(f"diagnose: {message}", file=sys.stderr, flush=True)

    # stages are shown on a terminal, as the bars are: in pipes and logs an error stays one line
    with mapper(args.workers, args.scheduler, _progress()) as tasks:  # band votes, circle fits
        done = diagnose_campaign(args.campaign, args.count, say if sys.stderr.isatty() else None, tasks,
                                 allowance=_allowance(args))
    record, campaign = done.record, done.campaign
    pages = diagnosis_files(record, done.diagnosis, campaign.synthetic, str(campaign.source or args.campaign))
    out.commit({"diagnosis.json": json_text(record), **pages})  # the page and its tables as CSV, all or nothing
    v = record["verdict"]
    where = f" at {v['where']}" if v["where"] else ""
    return (f"{record['campaign']!r}: {v['effect']}{where}, shrinkage {100 * v['shrinkage']:.0f} % (baseline RMS "
            f"{100 * record['baseline']['freq_rms_rel_error']:.3f} %); written to {args.out}")


def _validate_diagnosis(args: argparse.Namespace, out: OutputSet) -> str:
    from workbench.report.validation_page import validation_html, validation_text
    from workbench.workflow.diagnosis import validate, validation_files
    from workbench.workflow.execution import mapper
    with mapper(args.workers, args.scheduler, _progress()) as run:
        files = validation_files(validate(args.cases, args.seed, mapper=run, measurement=args.measurement,
                                          allowance=_allowance(args)))
    record = json.loads(files["validation.json"])
    out.commit({**files, "index.html": validation_html(record)})
    print(validation_text(record))
    return f"{record['cases']} blind proving-ground cases; written to {args.out}"


def _design(args: argparse.Namespace, out: OutputSet) -> str:
    from workbench.report.design_page import design_outputs
    from workbench.workflow.design import PlanSettings, cov_guesses, plan_design, verify_design, with_settings
    from workbench.workflow.execution import mapper

    settings = with_settings(PlanSettings(), count=args.count, frequency_scatter=args.frequency_scatter, seed=args.seed)
    with mapper(args.workers, args.scheduler, _progress()) as tasks:
        plan = plan_design(_structure(args.model), args.budget, args.target, cov_guesses(args.cov), settings, tasks)
        best = plan.recommended
        check = verify_design(plan, best.design, args.verify, settings.seed + 1, tasks) if args.verify else None
    out.commit(design_outputs(plan, check, Path(args.model), Path(args.out)))
    widths = ", ".join(f"{g} {100 * w:.0f} %" for g, w in zip(plan.groups.groups, best.width[:, 1]))
    return f"recommended {best.design.name} ({best.design.tests} tests; CoV widths {widths}); written to {args.out}"


def _parser() -> argparse.ArgumentParser:
    parser = _Parser(prog="workbench", description="Identify and propagate the variability of bolted joints "
                     "in light assembled frames (Ghienne, Laurent & Blanze, MSSP 2020).")
    parser.add_argument("--version", action="version", version=f"workbench {__version__}")
    sub = parser.add_subparsers(dest="command", required=True, parser_class=_Parser)

    def command(name: str, description: str, run, writes) -> argparse.ArgumentParser:
        # every command writes one output set under --out (CONTRACTS.md section 3), replaced only with --force
        p = sub.add_parser(name, help=description)
        p.add_argument("--out", required=True, help="output directory (created if absent; never an input's)")
        p.add_argument("--force", action="store_true", help="replace the output set of an earlier run in --out")
        p.set_defaults(run=run, writes=writes)
        return p

    p = command("modes", "nominal eigenfrequencies of a frame file (joints at their mean)", _modes,
                ("modes.csv",))
    p.add_argument("frame", help="frame.toml (CONTRACTS.md section 1) or a matrix model.toml (section 4)")
    p.add_argument("--count", type=_positive_int, default=10, help="number of modes (default 10)")

    p = command("import", "a new campaign from UFF 58/58b or tidy CSV files as test software exports them", _import,
                _import_writes)
    p.add_argument("files", nargs="+", metavar="FILE",
                   help="universal files (.uff, .unv, .uf: one test per file, or per test id in our headers) or "
                        "tidy CSV (sensor, frequency_hz, real, imag, optional test_id)")
    p.add_argument("--frame", required=True, help="the tested article's frame.toml, or a matrix model.toml with its "
                   "files, copied into the campaign")
    p.add_argument("--design", help="design CSV: test_id and one column per factor (default: one factor 'test')")
    p.add_argument("--name", help="the campaign's name (default: from the first file)")
    p.add_argument("--quantity", choices=["receptance", "mobility", "accelerance"],
                   help="what the files hold; required for CSV, checked against UFF headers")

    p = command("extract", "modal frequencies and damping of every test by circle fit", _extract,
                ("modes.csv", "quality.csv", "shapes.csv"))
    p.add_argument("campaign", help="campaign directory (CONTRACTS.md section 2) with frf.csv or frf.parquet")
    p.add_argument("--count", type=_positive_int, help="keep the N lowest modes found")
    _work_options(p)
    p.add_argument("--bands", help="override the mode bands: 'lo:hi,lo:hi,...' in Hz")

    p = command("identify", "mean and CoV of each joint group's modulus from a campaign", _identify,
                ("identification.json", "posterior.nc"))
    p.add_argument("campaign", help="campaign directory (modes.csv, FRFs, or moments.csv)")
    _identify_options(p)

    p = command("propagate", "moments of the eigenfrequencies under random joint moduli", _propagate,
                ("moments.csv", "run.json"))
    p.add_argument("frame", help="frame.toml whose joints have a cov (CONTRACTS.md section 1)")
    p.add_argument("--method", required=True, choices=["smr1", "smr2", "adaptive", "pert2", "mc"])
    p.add_argument("--samples", type=_positive_int, default=10_000, help="Monte Carlo samples (default 10000)")
    p.add_argument("--seed", type=int, default=0, help="seed of the joint draws (default 0)")
    p.add_argument("--count", type=_positive_int, default=10, help="number of modes (default 10)")
    _work_options(p)

    p = command("report", "a self-contained HTML identification report of a campaign (index.html, tables as CSV)",
                _report, ("index.html", *declared_files("report")))
    _report_options(p)

    p = sub.add_parser("demo", help="the main job on the bundled campaigns: identify, propagate, predict, report")
    p.add_argument("--out", default=DEMO_OUT,
                   help=f"output directory (default {DEMO_OUT}); the demo replaces its own report on every run")
    p.add_argument("--force", action="store_true", help="accepted for symmetry: the demo always replaces its report")
    p.add_argument("--campaigns", default="campaigns", help="directory of the bundled campaigns (default ./campaigns)")
    p.add_argument("--seed", type=int, default=0, help="seed of every random step (default 0)")
    p.add_argument("--samples", type=_positive_int, default=500,
                   help="Monte Carlo samples of the Figure 11 references (default 500; the FRF bands "
                        "always take 10000 SMR draws)")
    p.add_argument("--steps", type=_positive_int, default=2000, help="emcee steps kept per walker (default 2000)")
    p.add_argument("--workers", type=_positive_int, default=2, help="processes for circle fits and Monte Carlo")
    p.set_defaults(run=_demo, writes=("index.html", *declared_files("report")))

    p = command("diagnose", "sim-to-real gap: where the model misses, which effect, how far it shrinks", _diagnose,
                ("diagnosis.json", "index.html", *declared_files("diagnosis")))
    p.add_argument("campaign", help="campaign directory (modes.csv, FRFs, or moments.csv)")
    p.add_argument("--count", type=_positive_int, help="use at most the first N modes")
    _allowance_options(p)
    _work_options(p, every_core=True)

    _design_options(command("design", "plan the fewest tests that identify every joint group's mean and CoV",
                            _design, ("designs.csv", "design.csv", "campaign.toml", "index.html")))

    p = sub.add_parser("validate-diagnosis", help="blind validation of the diagnosis on proving-ground cases")
    p.add_argument("--cases", type=_positive_int, default=200, help="number of cases (default 200)")
    p.add_argument("--seed", type=int, default=0, help="seed of the case mix (default 0)")
    p.add_argument("--measurement", choices=["drawn", "fixed"], default="drawn",
                   help="drawn (default): each case measured as a lab might (accelerometer or vibrometer; accelerance, "
                        "mobility or receptance exported; 3200-6400 lines); fixed: accelerance on 0.25 Hz lines, as "
                        "the runs up to seed 18")
    _allowance_options(p)
    _work_options(p, every_core=True)
    p.add_argument("--out", required=True, help="output directory: validation.json, cases.csv, index.html")
    p.add_argument("--force", action="store_true", help="replace the output set of an earlier run in --out")
    p.set_defaults(run=_validate_diagnosis, writes=("validation.json", "cases.csv", "index.html"))
    return parser


def _identify_options(p: argparse.ArgumentParser) -> None:
    p.add_argument("--method", required=True, choices=["moments", "bayes"])
    p.add_argument("--count", type=_positive_int, help="use at most the first N modes")
    p.add_argument("--seed", type=int, default=0, help="seed of the bootstrap (moments) or the chains (bayes)")
    p.add_argument("--allow-bounds", action="store_true",
                   help="write an estimate within 1 %% of its search interval's bound (flagged \"at_bound\": true), "
                        "or chains that have not converged (\"converged\": false), instead of failing")
    p.add_argument("--steps", type=_positive_int, default=3000, help="bayes: steps kept per walker, at least "
                   "(default 3000)")
    p.add_argument("--max-steps", type=_positive_int, default=12000, help="bayes: the chains run on until every "
                   "R-hat <= 1.01 and ESS >= 400, up to this many steps (default 12000)")
    p.add_argument("--errors", choices=sorted(ERROR_TERMS), default="full",
                   help="bayes: error terms besides each mode's measurement error: full (common error, discrepancy per "
                        "mode; default), common, discrepancy, none, sensitivity (full, joint energies uncertain)")
    p.add_argument("--tolerances", type=_tolerances, metavar="SECTION[,MATERIAL]",
                   help="bayes: the frame's manufacturing tolerances as relative sds, integrated as latent factors: "
                        "each member's width and thickness, each material's E and density (default: the first)")


def _report_options(p: argparse.ArgumentParser) -> None:
    """The arguments of ``workbench report``."""
    p.add_argument("campaign", help="campaign directory (FRFs, modes.csv or moments.csv)")
    p.add_argument("--seed", type=int, default=0, help="seed of every random step (default 0)")
    p.add_argument("--samples", type=_positive_int, default=1000,
                   help="Monte Carlo samples of the Figure 11 reference (default 1000; the FRF bands "
                        "always take 10000 SMR draws)")
    p.add_argument("--steps", type=_positive_int, default=3000,
                   help="emcee steps kept per walker (default 3000; burn-in a quarter of it, at most 500)")
    p.add_argument("--no-bayes", action="store_true", help="skip the Bayesian identification")
    p.add_argument("--joints-from", action="append", metavar="CAMPAIGN",
                   help="section 5: identify joint groups on this (one-bolt) campaign and predict CAMPAIGN with "
                        "them; repeat for each group")
    p.add_argument("--workers", type=_positive_int, default=1, help="processes for circle fits and Monte Carlo")
    p.add_argument("--bands", help="circle-fit the campaign's FRFs with these mode bands, 'lo:hi,lo:hi,...' in Hz "
                                   "(also when it has a modes.csv, which is used as it is otherwise)")


def _design_options(p: argparse.ArgumentParser) -> None:
    """The arguments of ``workbench design``."""
    p.add_argument("model", help="frame.toml or matrix model.toml whose joints are to be identified")
    p.add_argument("--budget", type=_positive_int, help="most tests the lab can run (default: the full factorial's)")
    p.add_argument("--target", type=float, default=0.5, help="target 95 %% width of every group's CoV, relative "
                   "to its value (default 0.5)")
    p.add_argument("--cov", action="append", metavar="NAME=VALUE", help="a guess of a group's (or joint's) CoV "
                   "to plan for, where the model's is missing or doubtful; repeat for each")
    p.add_argument("--count", type=_positive_int, help="modes the identification will use (default 8)")
    p.add_argument("--frequency-scatter", type=float, help="relative sd of an extracted frequency (default 3e-4)")
    p.add_argument("--verify", type=int, default=0, metavar="N", help="also identify N simulated campaigns of "
                   "the recommended design by moment matching and compare (default 0: none)")
    p.add_argument("--seed", type=int, default=0, help="seed of the virtual campaigns (default 0)")
    _work_options(p)


def _work_options(p: argparse.ArgumentParser, every_core: bool = False) -> None:
    """``--workers`` and ``--scheduler`` of the commands whose work is handed out (CONTRACTS.md section 3);
    ``every_core``: by default one worker per core this process may use (`local_cores`), else one.
    """
    default = local_cores() if every_core else 1
    p.add_argument("--workers", type=_positive_int, default=default,
                   help=f"worker processes on this machine (a local Dask cluster above 1; default {default}"
                        f"{', the cores this process may use, at most 8' if every_core else ''})")
    p.add_argument("--scheduler", metavar="ADDRESS",
                   help="a running Dask scheduler (tcp://host:8786) to run the work on; same numbers as without")


def main(argv: Sequence[str] | None = None) -> int:
    """Run the command line; returns the exit status."""
    try:
        args = _parser().parse_args(argv)
    except SystemExit as exc:  # usage errors (exit 2) and --help (exit 0) return like the rest
        return int(exc.code or 0)
    start = time.perf_counter()
    try:
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always", UserWarning)
            try:
                names = args.writes(args) if callable(args.writes) else args.writes
                with claim_output(args.out, command=args.command, names=names,
                                  force=args.force or args.command == "demo", inputs=_inputs(args)) as out:
                    message = args.run(args, out)
            finally:  # warnings first, one line each, also when the command then fails
                _print_warnings(args.command, caught)
    except (ValueError, KeyError, OutputExistsError, OSError) as exc:
        text = exc.args[0] if isinstance(exc, KeyError) and exc.args else str(exc)
        print(f"workbench {args.command}: {' '.join(str(text).split())}", file=sys.stderr)
        return 2
    print(f"{message} in {time.perf_counter() - start:.2f} s")
    return 0


def _inputs(args: argparse.Namespace) -> list[Path]:
    """The paths a command reads, which --out may neither be, lie inside, nor hold."""
    paths = [Path(p) for p in (getattr(args, "frame", None), getattr(args, "model", None),
                               getattr(args, "campaign", None),
                               getattr(args, "campaigns", None), getattr(args, "design", None),
                               *(getattr(args, "joints_from", None) or ()), *(getattr(args, "files", None) or ()))
             if p]
    # a matrix model's folder holds its matrices: it is an input directory as a campaign is
    return [p.parent if p.is_file() and p.suffix == ".toml" and is_matrix_model(p) else p for p in paths]


def _print_warnings(command: str, caught: list[warnings.WarningMessage]) -> None:
    for seen in dict.fromkeys(" ".join(str(w.message).split()) for w in caught if issubclass(w.category, UserWarning)):
        print(f"workbench {command}: warning: {seen}", file=sys.stderr)


if __name__ == "__main__":
    sys.exit(main())

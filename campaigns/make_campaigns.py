"""Regenerate every bundled campaign of this directory, deterministically (fixed seeds).

    python campaigns/make_campaigns.py            # refuses to replace existing files
    python campaigns/make_campaigns.py --force    # replaces them

One real campaign (the paper's Table 3 moments, synthetic = false) and five synthetic ones from the
workbench's virtual test rig (`workbench.rig.simulate`), each with its README.md and, for the synthetic
ones, ``<name>.truth.json`` beside the directory. FRFs in parquet, float32.
"""

from __future__ import annotations

import os

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")
os.environ.setdefault("OMP_NUM_THREADS", "1")

import argparse  # noqa: E402
import shutil  # noqa: E402
import sys  # noqa: E402
import time  # noqa: E402
from pathlib import Path  # noqa: E402

import numpy as np  # noqa: E402
import pandas as pd  # noqa: E402

from workbench.io.campaign import Campaign, Factor, load_campaign, write_campaign  # noqa: E402
from workbench.io.outputs import write_outputs  # noqa: E402
from workbench.model.frame_file import read_frame  # noqa: E402
from workbench.plan.designs import full_factorial, one_defective_at_a_time, sweep_preloads, two_level_factorial  # noqa: E402
from workbench.rig.simulate import LockedStress, RigSettings, simulate_campaign, truth_path, write_with_truth  # noqa: E402

HERE = Path(__file__).resolve().parent
FRAMES = HERE.parent / "frames"
PAPER = HERE.parent.parent / "shared" / "paper"
DOI = "10.1016/j.ymssp.2019.106510"
PAPER_REF = f"Ghienne, Laurent & Blanze, Mechanical Systems and Signal Processing 136 (2020), doi:{DOI}"
TIGHTENING = {"1": "hand-tight, preload < 100 N", "2": "1800 N", "3": "6000 N"}
AMPLITUDE = {"low": "linear range", "high": "five times low"}
FOUR_BOLTS = {"bolt_A": "L1", "bolt_B": "L2", "bolt_C": "L3", "bolt_D": "L4"}

# name -> (frame file, seed, title); the seeds are also written in each README and truth file
SYNTHETIC = {
    "one_bolt_vertical_sweep": ("one_bolt_vertical", 3001, "one bolt (vertical joint A), 9-level tightening sweep"),
    "one_bolt_horizontal_sweep": ("one_bolt_horizontal", 3002, "one bolt (horizontal joint B), 9-level tightening sweep"),
    "two_bolt_table5": ("two_bolt", 3005, "two bolts, the paper's Table 5 design"),
    "four_bolt_table6": ("four_bolt", 3006, "four bolts, low amplitude, the paper's Table 6 design"),
    "four_bolt_table7": ("four_bolt", 3007, "four bolts, high amplitude, the paper's Table 7 design"),
}


def sweep_factor(name: str, joint: str) -> tuple[Factor, list[dict[str, str]]]:
    keys = [str(int(round(p))) for p in sweep_preloads()]
    factor = Factor(name, "tightening", {k: f"preload {k} N" for k in keys}, joint)
    return factor, [{name: k} for k in keys]


def definitions() -> dict[str, tuple[tuple[Factor, ...], list[dict[str, str]], RigSettings]]:
    plain = RigSettings()
    locked = RigSettings(locked_stress=LockedStress())
    amplitude = Factor("amplitude", "amplitude", dict(AMPLITUDE))
    v_factor, v_design = sweep_factor("bolt_A", "A")
    h_factor, h_design = sweep_factor("bolt_B", "B")
    two = (amplitude, Factor("bolt_A", "tightening", dict(TIGHTENING), "A"),
           Factor("bolt_B", "tightening", dict(TIGHTENING), "B"))
    four = (amplitude,) + tuple(Factor(b, "tightening", dict(TIGHTENING), j) for b, j in FOUR_BOLTS.items())
    bolts = list(FOUR_BOLTS)
    return {
        "one_bolt_vertical_sweep": ((v_factor,), v_design, plain),
        "one_bolt_horizontal_sweep": ((h_factor,), h_design, plain),
        "two_bolt_table5": (two, full_factorial({"amplitude": ["low", "high"], "bolt_A": [1, 2, 3],
                                                 "bolt_B": [1, 2, 3]}), plain),
        "four_bolt_table6": (four, two_level_factorial(bolts, "1", "3", centre="2", fixed={"amplitude": "low"}),
                             locked),
        "four_bolt_table7": (four, one_defective_at_a_time(bolts, good="3", defective="1", uniform=["3", "1", "2"],
                                                           fixed={"amplitude": "high"}), locked),
    }


def synthetic_readme(name: str, frame_file: str, seed: int, title: str, factors, design, settings: RigSettings,
                     truth: dict) -> str:
    f = np.array([t["frequency_hz"] for t in truth["tests"]])
    lines = [
        f"# {name}: {title} (synthetic)",
        "",
        "**Synthetic data**, produced by the workbench's virtual test rig (`workbench/rig/`), not measured.",
        f"The design and the factor definitions follow {PAPER_REF}.",
        "",
        "| item | value |",
        "|---|---|",
        f"| frame | `frame.toml`, a copy of `frames/{frame_file}.toml` (the nominal model: no rig effect in it) |",
        f"| tests | {len(design)} (`design.csv`) |",
        f"| factors | {', '.join(f'`{x.name}` ({x.kind}' + (f', joint {x.joint})' if x.joint else ')') for x in factors)} |",
        f"| FRFs | `frf.parquet`, float32, accelerance (m/s2/N), "
        f"0-{settings.f_max_hz:g} Hz every {settings.df_hz:g} Hz, sensors {', '.join(s.name for s in read_frame(FRAMES / (frame_file + '.toml')).sensors)} |",
        f"| noise | complex Gaussian, SNR {settings.snr_db:g} dB per curve (RMS of the FRF magnitude over the band / noise RMS) |",
        f"| seed | **{seed}** |",
        f"| locked-in stress | {'yes: ' + repr(settings.locked_stress) + ', compression in the beam = mobilised x friction x min(preload of L2, L3)' if settings.locked_stress else 'no'} |",
        "",
        "Made by `python campaigns/make_campaigns.py` (regenerates every bundled campaign identically).",
        "Tightening levels map to preloads 1 -> 50 N, 2 -> 1800 N, 3 -> 6000 N"
        + (" ; the sweep's levels are named by their preload in N (`workbench.plan.designs.sweep_preloads()`)."
           if "sweep" in name else "."),
        "Amplitude: low -> ratio 1, high -> ratio 5." if any(x.kind == "amplitude" for x in factors) else "",
    ]
    if name.startswith("four_bolt"):
        lines.append("Bolts of the paper's tables map to the frame's joints: bolt_A -> L1 (left column), "
                     "bolt_B -> L2 (beam, left end), bolt_C -> L3 (beam, right end), bolt_D -> L4 (right column).")
    lines += [
        "",
        "## The truth beside it",
        "",
        f"`../{name}.truth.json` (beside this directory, never inside it) holds what the rig simulated: per test the",
        "levels, preloads (N), amplitude ratio, joint moduli (Pa) and gamma (modulus over the frame file's),",
        "temperature offset, locked-in axial forces, the true first 10 frequencies and damping ratios and the",
        "joints' strain-energy shares; the joint laws, the rig settings, the effect (none here) and the seed.",
        "No identification or diagnosis code reads it; it is there to score them.",
        "",
        "True frequencies over the tests (Hz), from the truth file:",
        "",
        "| mode | min | mean | max | CoV |",
        "|---|---|---|---|---|",
    ]
    for k in range(f.shape[1]):
        lines.append(f"| {k + 1} | {f[:, k].min():.2f} | {f[:, k].mean():.2f} | {f[:, k].max():.2f} | "
                     f"{f[:, k].std(ddof=1) / f[:, k].mean():.2e} |")
    return "\n".join(lines) + "\n"


def make_real(force: bool) -> Path:
    directory = HERE / "paper_table3_one_bolt_vertical"
    table = pd.read_csv(PAPER / "table3_single_bolt_vertical_moments.csv")
    frame = read_frame(FRAMES / "one_bolt_vertical.toml")
    campaign = Campaign(
        name="paper Table 3: one bolt (vertical beam), 9 tightening levels, measured moments",
        frame=frame, synthetic=False, quantity="mobility",
        description="Mean and standard deviation of the 9 measured eigenfrequencies over 9 tightening "
                    "levels of the single bolt on the vertical beam (no individual test is published).",
        source=f"{PAPER_REF}, Table 3 (measured with a laser scanning vibrometer)",
        moments=table[["mode", "mean_hz", "std_hz"]].copy())
    write_campaign(campaign, directory, force=force)
    shutil.copyfile(FRAMES / "one_bolt_vertical.toml", directory / "frame.toml")  # a verbatim copy
    readme = f"""# paper_table3_one_bolt_vertical: the paper's measured Table 3 moments (real data)

**Measured data, synthetic = false.** {PAPER_REF}, Table 3: the mean and standard deviation of the
first 9 eigenfrequencies of the frame with one bolt on the vertical beam, measured over 9 tightening
levels (non-linearly spaced, more at low tightening; paper section 4.2), laser scanning vibrometer,
0-1250 Hz. The paper publishes only these moments, not the individual tests, so the campaign holds
`moments.csv` (`mode, mean_hz, std_hz`, copied from `shared/paper/table3_single_bolt_vertical_moments.csv`,
its `cov` column dropped) and no design or FRFs (the contract allows a campaign with only moments).

`frame.toml` is a verbatim copy of `frames/one_bolt_vertical.toml`: our calibrated geometry, not the
paper's (see `frames/README.md`). `quantity = "mobility"` records what the vibrometer measured; there are no FRFs.
Made by `python campaigns/make_campaigns.py` (no randomness).
"""
    # moments.csv with the paper's digits as printed (the writer's %.17g would show binary noise)
    source_lines = (PAPER / "table3_single_bolt_vertical_moments.csv").read_text().splitlines()
    moments = "\n".join(",".join(line.split(",")[:3]) for line in source_lines) + "\n"
    write_outputs(directory, {"README.md": readme, "moments.csv": moments}, force=True)
    return directory


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--force", action="store_true", help="replace existing campaigns")
    args = parser.parse_args(argv)
    t0 = time.perf_counter()
    made = [make_real(args.force)]
    for name, (factors, design, settings) in definitions().items():
        frame_file, seed, title = SYNTHETIC[name]
        frame = read_frame(FRAMES / f"{frame_file}.toml")
        campaign, truth = simulate_campaign(
            frame, factors, design, settings, seed, name=f"{name}: {title} (synthetic)",
            description=f"Synthetic campaign of the workbench's virtual test rig: {title}. Seed {seed}.",
            source=f"synthetic: workbench.rig.simulate (campaigns/make_campaigns.py, seed {seed}); design from {PAPER_REF}")
        directory = HERE / name
        write_with_truth(campaign, truth, directory, force=args.force)
        shutil.copyfile(FRAMES / f"{frame_file}.toml", directory / "frame.toml")  # verbatim nominal frame
        write_outputs(directory, {"README.md": synthetic_readme(name, frame_file, seed, title, factors, design,
                                                               settings, truth)}, force=True)
        made.append(directory)
    for directory in made:
        c = load_campaign(directory)
        size = sum(p.stat().st_size for p in directory.iterdir())
        extra = truth_path(directory).stat().st_size if c.synthetic else 0
        print(f"{directory.name:32s} synthetic={str(c.synthetic).lower():5s} tests={len(c.test_ids):3d} "
              f"{(size + extra) / 1e6:6.2f} MB")
    total = sum(p.stat().st_size for p in HERE.rglob("*") if p.is_file())
    print(f"campaigns/ in all: {total / 1e6:.2f} MB; {time.perf_counter() - t0:.1f} s")
    return 0


if __name__ == "__main__":
    sys.exit(main())

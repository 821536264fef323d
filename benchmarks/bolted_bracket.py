"""The matrix-model figures of the worked example (examples/bolted_bracket/build.py), in one run.

Prints: the two formats against each other and against a dense eigen-solution of the scikit-fem
matrices; the joints identified by moment matching from the 30-test campaign (circle fit, MAC
pairing) against the sample values of the drawn moduli; SMR1 and adaptive SMR against a 10 000-draw
Monte Carlo on the matrix model. About 3 minutes on 2 cores (the Monte Carlo is 2 minutes of it).

    python benchmarks/bolted_bracket.py [--samples 10000] [--workers 2]
"""

from __future__ import annotations

import argparse
import csv
import importlib.util
import json
import tempfile
from pathlib import Path

import numpy as np
import scipy.linalg as sla

from workbench.cli import main

REPO = Path(__file__).resolve().parents[1]


def column(path: Path, name: str) -> np.ndarray:
    with open(path, newline="") as f:
        return np.array([float(r[name]) for r in csv.DictReader(f)])


def run(argv: list[str]) -> None:
    if main(argv) != 0:
        raise SystemExit(f"failed: workbench {' '.join(argv)}")


def bench(samples: int, workers: int) -> None:
    spec = importlib.util.spec_from_file_location("build", REPO / "examples" / "bolted_bracket" / "build.py")
    example = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(example)
    with tempfile.TemporaryDirectory() as tmp:
        out = Path(tmp) / "bracket"
        truth = example.build(out)
        found, _, _ = example.matrices()
        dense = np.sqrt(sla.eigh((found["K0"] + found["KA"] + found["KB"]).toarray(), found["M"].toarray(),
                                 eigvals_only=True, subset_by_index=[0, 9])) / (2 * np.pi)
        freqs = {}
        for folder in ("model_mtx", "model_op4"):
            run(["modes", str(out / folder / "model.toml"), "--out", f"{tmp}/{folder}"])
            freqs[folder] = column(Path(tmp) / folder / "modes.csv", "frequency_hz")
        print(f"model: {found['M'].shape[0]} dofs; 10 frequencies, Matrix Market vs OP4: "
              f"{np.max(np.abs(freqs['model_mtx'] / freqs['model_op4'] - 1)):.1e}; vs dense eigh of the "
              f"scikit-fem matrices: {np.max(np.abs(freqs['model_mtx'] / dense - 1)):.1e}")
        campaign = out / "campaign"
        run(["identify", str(campaign), "--method", "moments", "--out", f"{tmp}/id"])
        record = json.loads((Path(tmp) / "id" / "identification.json").read_text())
        print(f"moment matching, 30 tests, modes {record['modes_used']} (circle fit, MAC pairing), "
              f"{record['wall_time_s']:.1f} s:")
        for joint, got in record["joints"].items():
            s = truth["sample"][joint]
            print(f"  joint {joint}: E {got['youngs_modulus'] / 1e9:.2f} GPa against the sample's "
                  f"{s['youngs_modulus'] / 1e9:.2f} ({got['youngs_modulus'] / s['youngs_modulus'] - 1:+.1%}); CoV "
                  f"{got['cov']:.3f} [{got['cov_ci95'][0]:.3f}, {got['cov_ci95'][1]:.3f}] against "
                  f"{s['cov']:.3f} ({got['cov'] / s['cov'] - 1:+.1%})")
        model = str(out / "model_mtx" / "model.toml")
        run(["propagate", model, "--method", "mc", "--samples", str(samples), "--seed", "1",
             "--workers", str(workers), "--out", f"{tmp}/mc"])
        mc_mean, mc_std = column(Path(tmp) / "mc" / "moments.csv", "mean_hz"), column(Path(tmp) / "mc" / "moments.csv",
                                                                                     "std_hz")
        mc_time = json.loads((Path(tmp) / "mc" / "run.json").read_text())["wall_time_s"]
        for method in ("smr1", "adaptive"):
            run(["propagate", model, "--method", method, "--out", f"{tmp}/{method}"])
            mean = column(Path(tmp) / method / "moments.csv", "mean_hz")
            std = column(Path(tmp) / method / "moments.csv", "std_hz")
            wall = json.loads((Path(tmp) / method / "run.json").read_text())["wall_time_s"]
            print(f"{method} against MC ({samples} draws, {mc_time:.0f} s): mean within "
                  f"{np.max(np.abs(mean / mc_mean - 1)):.2%}, std within {np.max(np.abs(std / mc_std - 1)):.1%}, "
                  f"in {wall:.3f} s")


if __name__ == "__main__":
    parser = argparse.ArgumentParser()
    parser.add_argument("--samples", type=int, default=10_000)
    parser.add_argument("--workers", type=int, default=2)
    args = parser.parse_args()
    bench(args.samples, args.workers)

"""Frame files of the paper's configurations (Ghienne, Laurent & Blanze, MSSP 2020, Figures 1 and 13).

The paper's Figure 1 dimensions are not available, so the geometry here is *ours*: a plausible
three-bar aluminium portal whose genuinely unknown parameters (at most six) are calibrated so that
the one-bolt vertical frame with its joint at the paper's nominal modulus (11.5 GPa, Table 2)
reproduces the measured eigenfrequencies of Table 2. See frames/README.md for every assumption.

Usage
-----
    python frames/build_frames.py              # write the five frame files from CALIBRATED
    python frames/build_frames.py --calibrate  # re-run the (seeded) calibration and print it
    python frames/build_frames.py --check-mesh # compare element_length 0.005 and 0.01

The builder itself, `paper_frame(configuration, parameters) -> Frame`, with `FIXED` and `CALIBRATED`, lives in
the package (`workbench.model.paper_frames`, which the proving ground uses); importable from here too, with
`table2_frame(...)` and `rms_max_error(...)`. After a new calibration, paste its output into `CALIBRATED` there.
"""

from __future__ import annotations

import argparse
import csv
import dataclasses
import math
import os
import sys
import time
from pathlib import Path

# One BLAS thread: the models are small and thread start-up dominates (and contends on shared machines).
for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")

import numpy as np  # noqa: E402

HERE = Path(__file__).resolve().parent
REPO = HERE.parent
if str(REPO) not in sys.path:
    sys.path.insert(0, str(REPO))

from workbench.io.outputs import write_frame  # noqa: E402
from workbench.model.assembly import assemble  # noqa: E402
from workbench.model.frame import Frame  # noqa: E402
from workbench.model.modal import model_modes  # noqa: E402
from workbench.model.paper_frames import (  # noqa: E402, F401 (CONFIGURATIONS and FIXED: importable from here)
    CALIBRATED,
    CONFIGURATIONS,
    FIXED,
    TABLE2_JOINT_MODULUS,
    paper_frame,
)

# Bounds of the calibration of CALIBRATED (physical ranges).
BOUNDS: dict[str, tuple[float, float]] = {
    "beam_length": (0.30, 0.70),
    "left_height": (0.30, 0.70),
    "right_height": (0.30, 0.70),
    "clamp_rz": (2.0e2, 2.0e5),
    "bracket_mass": (0.02, 0.30),
    "stinger_k": (1.0e2, 1.0e5),
}
LOG_PARAMETERS = ("clamp_rz", "stinger_k")
PAPER = REPO / ".." / "shared" / "paper"


def with_joint_modulus(frame: Frame, modulus: float) -> Frame:
    """``frame`` with every joint's mean modulus set to ``modulus`` (cov and group unchanged)."""
    return dataclasses.replace(frame, joints=tuple(dataclasses.replace(j, youngs_modulus=modulus)
                                                   for j in frame.joints))


def frequencies(frame: Frame, count: int = 10) -> np.ndarray:
    """First ``count`` eigenfrequencies, Hz (sparse shift-invert Lanczos: a few ms per solve)."""
    return model_modes(assemble(frame), count, method="sparse").frequency_hz


def read_table2(path: Path | None = None) -> list[dict[str, str]]:
    path = PAPER / "table2_single_bolt_nominal.csv" if path is None else path
    with open(path, newline="", encoding="utf-8") as fh:
        return list(csv.DictReader(fh))


def measured_table2() -> np.ndarray:
    return np.array([float(r["f_exp_hz"]) for r in read_table2()])


def table2_frame(params: dict[str, float] | None = None) -> Frame:
    """The one-bolt vertical frame with its joint at the paper's nominal 11.5 GPa (Table 2)."""
    return with_joint_modulus(paper_frame("one_bolt_vertical", params), TABLE2_JOINT_MODULUS)


def rms_max_error(model_hz: np.ndarray, measured_hz: np.ndarray) -> tuple[float, float]:
    rel = model_hz[: measured_hz.size] / measured_hz - 1.0
    return float(np.sqrt(np.mean(rel**2))), float(np.max(np.abs(rel)))


# ----------------------------------------------------------------------------------- calibration
CAL_KEYS = tuple(CALIBRATED)


def _to_unit(values: dict[str, float]) -> np.ndarray:
    out = []
    for k in CAL_KEYS:
        lo, hi = BOUNDS[k]
        v = values[k]
        if k in LOG_PARAMETERS:
            lo, hi, v = math.log(lo), math.log(hi), math.log(v)
        out.append((v - lo) / (hi - lo))
    return np.array(out)


def _from_unit(x: np.ndarray) -> dict[str, float]:
    out = {}
    for k, u in zip(CAL_KEYS, np.clip(x, 0.0, 1.0)):
        lo, hi = BOUNDS[k]
        if k in LOG_PARAMETERS:
            out[k] = float(math.exp(math.log(lo) + u * (math.log(hi) - math.log(lo))))
        else:
            out[k] = float(lo + u * (hi - lo))
    return out


def calibrate(seed: int = 20200, verbose: bool = True) -> dict[str, float]:
    """Fit CALIBRATED's parameters on Table 2 (one-bolt vertical frame, joint at 11.5 GPa).

    Objective: mean squared relative frequency error over the 9 measured modes, modes paired by
    order (model modes 1..9). Global search by differential evolution (seeded, Sobol start) on the
    unit box of BOUNDS (log scale for the two stiffnesses), then Nelder-Mead from the DE optimum and
    from three seeded perturbations of it; the best point wins.
    """
    from scipy.optimize import differential_evolution, minimize

    measured = measured_table2()

    def objective(x):
        penalty = float(np.sum(np.clip(x - 1.0, 0.0, None) ** 2 + np.clip(-x, 0.0, None) ** 2))
        try:
            f = frequencies(table2_frame(_from_unit(x)), measured.size)
        except ValueError:
            return 1.0
        return float(np.mean((f / measured - 1.0) ** 2)) + penalty

    t0 = time.perf_counter()
    de = differential_evolution(objective, [(0.0, 1.0)] * len(CAL_KEYS), seed=seed, popsize=15,
                                maxiter=150, tol=1e-12, polish=False, init="sobol")
    if verbose:
        print(f"differential evolution: rms {math.sqrt(de.fun):.4%} after {de.nfev} solves "
              f"({time.perf_counter() - t0:.0f} s)")
    best_x, best_f = de.x, de.fun
    rng = np.random.default_rng(seed)
    starts = [("DE optimum", de.x)] + [(f"perturbed start {i + 1}", np.clip(de.x + rng.normal(0.0, 0.05, de.x.size), 0, 1))
                                       for i in range(3)]
    for label, start in starts:
        nm = minimize(objective, start, method="Nelder-Mead",
                      options={"xatol": 1e-8, "fatol": 1e-13, "maxiter": 3000, "maxfev": 3000})
        if verbose:
            print(f"Nelder-Mead from {label}: rms {math.sqrt(max(nm.fun, 0.0)):.4%} ({nm.nfev} solves)")
        if nm.fun < best_f:
            best_x, best_f = nm.x, nm.fun
    result = _from_unit(best_x)
    if verbose:
        f = frequencies(table2_frame(result), measured.size)
        rms, mx = rms_max_error(f, measured)
        print(f"final: rms {rms:.4%}, max {mx:.4%} ({time.perf_counter() - t0:.0f} s)")
        print("CALIBRATED = {")
        for k, v in result.items():
            print(f"    {k!r}: {v:.6g},")
        print("}")
    return result


def check_mesh(params: dict[str, float] | None = None) -> None:
    """First 10 frequencies of every configuration at element_length 0.005 and 0.01."""
    for conf in CONFIGURATIONS:
        fine = frequencies(paper_frame(conf, {**(params or {}), "element_length": 0.005}))
        coarse = frequencies(paper_frame(conf, {**(params or {}), "element_length": 0.01}))
        print(f"{conf:20s} max |f(0.01)/f(0.005) - 1| over 10 modes: {np.max(np.abs(coarse / fine - 1)):.2e}")


def write_all(directory: Path = HERE) -> list[Path]:
    paths = []
    for conf in CONFIGURATIONS:
        path = directory / f"{conf}.toml"
        write_frame(paper_frame(conf), path)
        paths.append(path)
    return paths


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--calibrate", action="store_true", help="re-run the seeded calibration and print it")
    ap.add_argument("--check-mesh", action="store_true", help="compare element_length 0.005 and 0.01")
    ap.add_argument("--seed", type=int, default=20200)
    args = ap.parse_args(argv)
    if args.calibrate:
        calibrate(seed=args.seed)
        return 0
    if args.check_mesh:
        check_mesh()
        return 0
    for path in write_all():
        print(f"wrote {path}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())

"""Regenerate tests/reference/propagation_one_bolt.json: the references of the Figure 11 check.

For each one-bolt frame (the paper's section 4.3: vertical joint E = 24 GPa, CoV 0.09; horizontal
joint E = 73.5 GPa, CoV 0.22) it stores the first 10 eigenfrequency moments by
- Monte Carlo, 10 000 samples, seed 20200 (exact solves, MAC tracking), with their standard errors;
- the tensor Gauss rule over exact solves (12 points), which has no sampling noise.

Run from the repository root: ``python tests/reference/make_propagation_reference.py`` (about
2 minutes per frame on the 2-core reference machine).
"""

from __future__ import annotations

import json
import platform
import time
from datetime import date
from pathlib import Path

import numpy as np
import scipy

from workbench.cli import ProgressBars
from workbench.model.assembly import assemble
from workbench.model.frame_file import read_frame
from workbench.uq.stochastic import joint_model, monte_carlo, quadrature_reference

REPO = Path(__file__).resolve().parents[2]
OUT = Path(__file__).with_name("propagation_one_bolt.json")
SEED = 20200
SAMPLES = 10_000


def main() -> None:
    data = {"generated_by": "tests/reference/make_propagation_reference.py", "date": date.today().isoformat(),
            "numpy": np.__version__, "scipy": scipy.__version__, "python": platform.python_version(),
            "seed": SEED, "samples": SAMPLES, "frames": {}}
    for name in ("one_bolt_vertical", "one_bolt_horizontal"):
        model = assemble(read_frame(REPO / "frames" / f"{name}.toml"))
        joints = joint_model(model.frame)
        start = time.perf_counter()
        mc = monte_carlo(model, joints, 10, SAMPLES, SEED, progress=ProgressBars())
        mc_time = time.perf_counter() - start
        se_mean, se_std = mc.standard_errors()
        quad = quadrature_reference(model, joints, 10, points=12)
        data["frames"][name] = {
            "joint": {j.name: {"youngs_modulus": j.youngs_modulus, "cov": j.cov} for j in model.frame.joints},
            "mc": {"mean_hz": mc.moments.mean_hz.tolist(), "std_hz": mc.moments.std_hz.tolist(),
                   "se_mean_hz": se_mean.tolist(), "se_std_hz": se_std.tolist(),
                   "min_mac": float(mc.min_mac.min()), "wall_time_s": mc_time},
            "quadrature": {"mean_hz": quad.mean_hz.tolist(), "std_hz": quad.std_hz.tolist(), "points": 12},
        }
        print(f"{name}: MC {mc_time:.1f} s, worst MAC {mc.min_mac.min():.4f}")
    OUT.write_text(json.dumps(data, indent=1) + "\n")
    print(f"written {OUT}")


if __name__ == "__main__":
    main()

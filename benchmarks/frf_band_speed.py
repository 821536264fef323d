"""Cost of the stochastic FRF band (Figures 14, 16) against the eigen-solves it cannot avoid.

Run from the repository root: ``python benchmarks/frf_band_speed.py`` (about 15 s). Target: 500
samples of the four-bolt frame over 0-1250 Hz at 0.25 Hz in well under 15 s on one core. Printed
side by side in the same run: `frf_band`, and as many plain `model_modes` solves of the sampled
joint moduli as it has samples (and of the larger solves it makes to track modes); the ratio is
what the extra modes, the tracking and the FRF synthesis add.
"""

from __future__ import annotations

import os

for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")  # small dense problems: one BLAS thread is fastest here

import argparse  # noqa: E402
from pathlib import Path  # noqa: E402

import numpy as np  # noqa: E402
from timing import best_of  # noqa: E402

from workbench.model.assembly import assemble  # noqa: E402
from workbench.model.frame_file import read_frame  # noqa: E402
from workbench.model.modal import model_modes, solve_modes  # noqa: E402
from workbench.uq.prediction import TRACKING_MODES, frf_band  # noqa: E402
from workbench.uq.stochastic import joint_model  # noqa: E402

REPO = Path(__file__).resolve().parents[1]


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--samples", type=int, default=500)
    parser.add_argument("--step", type=float, default=0.25, help="frequency step, Hz")
    parser.add_argument("--repeat", type=int, default=1)
    parser.add_argument("--seed", type=int, default=0)
    args = parser.parse_args()

    # the joint models the bundled campaigns imply (Table 4), as the frame file sets them
    model = assemble(read_frame(REPO / "frames" / "four_bolt.toml"))
    joints = joint_model(model.frame)
    axis = np.arange(0.0, 1250.0 + args.step / 2, args.step)
    zeta = np.array(model.frame.damping_ratios)
    t_band, band = best_of(args.repeat, lambda: frf_band(model, joints, axis, zeta, samples=args.samples,
                                                         seed=args.seed))
    count = band.natural_hz.shape[1]
    gammas = joints.sample(args.samples, np.random.default_rng(args.seed))
    t_solve, _ = best_of(args.repeat, lambda: [model_modes(model, count, g) for g in gammas])
    # what frf_band itself solves: TRACKING_MODES more, so that a mode moving up is still tracked
    solved = count + TRACKING_MODES
    t_tracked, _ = best_of(args.repeat, lambda: [solve_modes(model.stiffness(g), model.mass, solved) for g in gammas])

    print(f"four-bolt frame ({model.size} dofs), joints "
          + ", ".join(f"{j.name} {j.youngs_modulus / 1e9:g} GPa cov {j.cov:g}" for j in model.frame.joints))
    print(f"{args.samples} samples, {count} modes summed, {axis.size} lines (0-1250 Hz at {args.step:g} Hz), "
          f"{len(band.sensors)} sensors")
    print(f"{'what':28s} {'time s':>8s} {'/ solves':>9s}")
    print(f"{'frf_band':28s} {t_band:8.2f} {t_band / t_solve:9.2f}")
    print(f"{f'{args.samples} x model_modes({count})':28s} {t_solve:8.2f} {1.0:9.2f}")
    print(f"{f'{args.samples} x solve_modes({solved})':28s} {t_tracked:8.2f} {t_tracked / t_solve:9.2f}")
    print(f"target: frf_band under 15 s {'met' if t_band < 15 else 'MISSED'}")


if __name__ == "__main__":
    main()

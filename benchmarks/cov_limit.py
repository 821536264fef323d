"""Where SMR and perturbation stop being usable: moment errors against exact full solves as the joints' CoV grows.

Run from the repository root: ``python benchmarks/cov_limit.py`` (about 20 s on 2 cores).

For each frame and each joint CoV (the same on every joint), the first 8 frequencies' mean and
standard deviation by SMR1, SMR2, the adaptive strategy and Pert2 are compared with the tensor-Gauss
reference (full eigen-solves at the Gauss points of the Gamma laws, modes tracked by MAC), and the
worst relative error over the modes is printed. The limit `workbench.uq.limits.COV_LIMIT` was read off
the calibration frames (one-bolt vertical and horizontal) as the largest CoV at which every method's
std error stays under 10 % for SMR2 and the adaptive strategy (`COV_LIMIT`) and for SMR1 and Pert2
(`SMR1_COV_WARNING`), then frozen; the held-out frames (two-bolt, four-bolt: other geometries, several
joints) check them: the two last columns must say "ok" up to their limits.
"""

from __future__ import annotations

import os

for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")

from pathlib import Path  # noqa: E402

import numpy as np  # noqa: E402

from workbench.model.assembly import assemble  # noqa: E402
from workbench.model.frame_file import read_frame  # noqa: E402
from workbench.uq.smr import adaptive, pert2, smr1, smr2  # noqa: E402
from workbench.uq.stochastic import joint_model, quadrature_reference  # noqa: E402

REPO = Path(__file__).resolve().parents[1]
CALIBRATION = ("one_bolt_vertical", "one_bolt_horizontal")
HELD_OUT = ("two_bolt", "four_bolt")
COVS = (0.1, 0.2, 0.3, 0.4, 0.5, 0.7, 1.0, 1.5)
METHODS = {"smr1": smr1, "smr2": smr2, "adaptive": adaptive, "pert2": pert2}
COUNT = 8


def errors(name: str, cov: float) -> dict[str, tuple[float, float]]:
    frame = read_frame(REPO / "frames" / f"{name}.toml")
    model = assemble(frame)
    joints = joint_model(frame, {j: cov for j in frame.joint_names})
    ref = quadrature_reference(model, joints, COUNT, points=6 if len(frame.joint_names) <= 2 else 4)
    out = {}
    for method, run in METHODS.items():
        try:
            got = run(model, joints, COUNT)
        except ValueError:
            out[method] = (np.nan, np.nan)
            continue
        out[method] = (float(np.max(np.abs(got.mean_hz / ref.mean_hz - 1))),
                       float(np.max(np.abs(got.std_hz / ref.std_hz - 1))))
    return out


def main() -> None:
    from workbench.uq.limits import COV_LIMIT, SMR1_COV_WARNING

    print(f"worst relative error over the first {COUNT} modes, mean / std, against exact full solves")
    print(f"COV_LIMIT = {COV_LIMIT}, SMR1_COV_WARNING = {SMR1_COV_WARNING} (frozen from the calibration frames)")
    for group, names in (("calibration", CALIBRATION), ("held out", HELD_OUT)):
        for name in names:
            print(f"\n{group}: {name}")
            print(f"{'cov':>5} " + " ".join(f"{m:>17}" for m in METHODS) + "   std < 10 %: smr2/adaptive  smr1/pert2")
            for cov in COVS:
                errs = errors(name, cov)
                verdicts = ["ok" if max(errs[m][1] for m in pair) < 0.10 else "no"
                            for pair in (("smr2", "adaptive"), ("smr1", "pert2"))]
                marks = [" <- COV_LIMIT" if cov == COV_LIMIT else "", " <- warning" if cov == SMR1_COV_WARNING else ""]
                print(f"{cov:5.2f} " + " ".join(f"{e[0]:7.2%} / {e[1]:7.2%}" for e in errs.values())
                      + f"   {verdicts[0]:>2}{marks[0]:13} {verdicts[1]:>2}{marks[1]}", flush=True)


if __name__ == "__main__":
    main()

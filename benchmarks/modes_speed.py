"""Time to the first 10 modes: the four-bolt frame and a generated 20 000-dof bolted frame.

Run from the repository root: ``python benchmarks/modes_speed.py``. Target (issue 2): under 2 s
for the first 10 modes of the 20 000-dof frame on the 2-core reference machine. Assembly is
timed apart; each time is the best of ``--repeat`` runs.
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np
from timing import best_of

from workbench.model.assembly import assemble
from workbench.model.frame_file import read_frame
from workbench.model.generate import multibay_for_dofs
from workbench.model.modal import DENSE_LIMIT, model_modes

REPO = Path(__file__).resolve().parents[1]




def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeat", type=int, default=3)
    parser.add_argument("--dofs", type=int, default=20000)
    args = parser.parse_args()

    rows = []
    four = read_frame(REPO / "frames" / "four_bolt.toml")
    t_asm, model = best_of(args.repeat, lambda: assemble(four))
    t_modes, modes = best_of(args.repeat, lambda: model_modes(model, 10))
    solver = "dense LAPACK" if model.size <= DENSE_LIMIT else "sparse shift-invert"
    rows.append(("four-bolt frame", model.size, len(four.joints), t_asm, t_modes, f"auto: {solver}"))

    big = multibay_for_dofs(args.dofs)
    t_asm, model = best_of(args.repeat, lambda: assemble(big))
    t_modes, modes_sparse = best_of(args.repeat, lambda: model_modes(model, 10, method="sparse"))
    rows.append((big.name, model.size, len(big.joints), t_asm, t_modes, "sparse shift-invert"))

    print(f"{'frame':42s} {'dofs':>7s} {'joints':>6s} {'assemble s':>10s} {'10 modes s':>10s}  solver")
    for name, dofs, joints, ta, tm, solver in rows:
        print(f"{name:42s} {dofs:7d} {joints:6d} {ta:10.3f} {tm:10.3f}  {solver}")
    verdict = "met" if rows[-1][4] < 2.0 else "MISSED"
    print(f"target: 10 modes of the {rows[-1][1]}-dof frame under 2 s: {verdict} ({rows[-1][4]:.2f} s)")
    print("first 10 frequencies of the large frame, Hz:", np.array2string(modes_sparse.frequency_hz, precision=3))


if __name__ == "__main__":
    main()

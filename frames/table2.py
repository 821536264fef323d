"""The paper's Table 2 reproduced with our frame, and the first frequencies of the five frames.

Reads frames/one_bolt_vertical.toml (joint A at its Table 4 modulus, 24 GPa), sets joint A to the
paper's nominal 11.5 GPa (Table 2 caption) and compares the first 9 eigenfrequencies with the
measured ones of ../shared/paper/table2_single_bolt_nominal.csv, modes paired by order.

    python frames/table2.py
"""

from __future__ import annotations

import time

import numpy as np

# build_frames sets one BLAS thread and the import path before numpy's first use
from build_frames import (
    CONFIGURATIONS,
    HERE,
    TABLE2_JOINT_MODULUS,
    frequencies,
    read_table2,
    rms_max_error,
    with_joint_modulus,
)

from workbench.model.assembly import assemble
from workbench.model.frame_file import read_frame
from workbench.model.modal import model_modes


def main() -> int:
    rows = read_table2()
    measured = np.array([float(r["f_exp_hz"]) for r in rows])
    paper_simu = np.array([float(r["f_simu_hz"]) for r in rows])

    frame = with_joint_modulus(read_frame(HERE / "one_bolt_vertical.toml"), TABLE2_JOINT_MODULUS)
    t0 = time.perf_counter()
    model = assemble(frame)
    t1 = time.perf_counter()
    ours = model_modes(model, measured.size, method="sparse").frequency_hz
    t2 = time.perf_counter()

    rel = ours / measured - 1.0
    rel_paper = paper_simu / measured - 1.0
    print(f"Table 2: one bolt on the left column, joint A at {TABLE2_JOINT_MODULUS / 1e9:g} GPa "
          f"(frames/one_bolt_vertical.toml, {model.size} dofs)")
    print(f"{'mode':>4} {'measured Hz':>12} {'ours Hz':>9} {'rel err':>8} {'paper Hz':>9} {'paper err':>9}")
    for k in range(measured.size):
        print(f"{k + 1:>4} {measured[k]:>12.2f} {ours[k]:>9.2f} {rel[k]:>+8.2%} {paper_simu[k]:>9.2f} "
              f"{rel_paper[k]:>+9.2%}")
    for label, model_hz in (("ours: ", ours), ("paper:", paper_simu)):
        rms, worst = rms_max_error(model_hz, measured)
        print(f"{label} RMS relative error {rms:.2%}, max {worst:.2%}")
    print(f"one model solve: assembly {1e3 * (t1 - t0):.1f} ms, 9 modes (sparse Lanczos) {1e3 * (t2 - t1):.1f} ms")

    print()
    print("First 10 eigenfrequencies (Hz) of the five frames, joints at their file moduli (Table 4):")
    print(f"{'frame':<20}" + "".join(f"{k:>8}" for k in range(1, 11)))
    for name in CONFIGURATIONS:
        f = frequencies(read_frame(HERE / f"{name}.toml"), 10)
        print(f"{name:<20}" + "".join(f"{v:>8.1f}" for v in f))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())

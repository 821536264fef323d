"""Two model-form figures the documentation quotes, printed from the bundled frames.

Run from the repository root: ``python benchmarks/model_form.py`` (about 5 s).

1. Shear and rotary inertia: the first 10 frequencies of each frame with Timoshenko beams against the
   Euler-Bernoulli ones the frame files use (frames/README.md quotes the largest drop).
2. The method named SMR2 evaluates the eigenvalue as a Rayleigh quotient; eq. (6) as printed
   (``phi^T K(gamma) phi``, the first-order vector unnormalised) is ``smr2(..., rayleigh=False)``: both
   against the exact tensor-Gauss reference (full solves), worst error over the first 10 modes.
"""

from __future__ import annotations

import dataclasses
from pathlib import Path

import numpy as np

from workbench.model.assembly import assemble
from workbench.model.frame_file import read_frame
from workbench.model.modal import model_modes
from workbench.uq.smr import smr2
from workbench.uq.stochastic import joint_model, quadrature_reference

REPO = Path(__file__).resolve().parents[1]
FRAMES = ("one_bolt_vertical", "one_bolt_horizontal", "two_bolt", "four_bolt")


def main() -> None:
    print("frame                 Timoshenko / Euler-Bernoulli - 1     SMR2 (Rayleigh)     eq. (6) as printed")
    print("                       lowest       highest                mean     std        mean     std")
    for name in FRAMES:
        frame = read_frame(REPO / "frames" / f"{name}.toml")
        euler = model_modes(assemble(frame), 10).frequency_hz
        timo = model_modes(assemble(dataclasses.replace(frame, beam_theory="timoshenko")), 10).frequency_hz
        drop = timo / euler - 1
        model, joints = assemble(frame), joint_model(frame)
        exact = quadrature_reference(model, joints, 10, points=6 if len(frame.joints) <= 2 else 4)
        errors = []
        for rayleigh in (True, False):
            got = smr2(model, joints, 10, rayleigh=rayleigh)
            errors += [np.max(np.abs(got.mean_hz / exact.mean_hz - 1)), np.max(np.abs(got.std_hz / exact.std_hz - 1))]
        print(f"{name:20s}  {drop.min():8.3%}  {drop.max():8.3%}            "
              + "   ".join(f"{e:7.3%}" for e in errors))


if __name__ == "__main__":
    main()

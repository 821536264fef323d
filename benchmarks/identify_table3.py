"""Moment matching (paper section 4.1, eq. 10-11) on the real Table 3 campaign, beside Table 4.

Run from the repository root: ``python benchmarks/identify_table3.py`` (a few seconds). Data: the
measured means and standard deviations of the first 9 eigenfrequencies of the one-bolt frame
(vertical joint) over 9 tightening levels, ``../shared/paper/table3_single_bolt_vertical_moments.csv``
(moments only: no per-test frequencies, so no interval). Model: ``frames/one_bolt_vertical.toml``
(our geometry, calibrated on Table 2; its joint file modulus, 24 GPa, is only the start). Forward
model: the adaptive SMR. Prints the identified E[Y] and CoV with the Gamma parameters of eq. (9),
the per-mode residuals of both moments, eps_E and eps_delta, and the same quantities for the
paper's Table 4 values on our frame, which shows where the difference comes from.
"""

from __future__ import annotations

import os

for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")  # small problems on 2 shared cores: one BLAS thread

import csv  # noqa: E402
from pathlib import Path  # noqa: E402

import numpy as np  # noqa: E402
from scipy.optimize import minimize_scalar  # noqa: E402

from workbench.extraction.records import MeasuredModes  # noqa: E402
from workbench.identify.moments import moment_matching  # noqa: E402
from workbench.model.assembly import assemble  # noqa: E402
from workbench.model.frame_file import read_frame  # noqa: E402
from workbench.model.joints import model_at_moduli  # noqa: E402
from workbench.uq.smr import adaptive  # noqa: E402
from workbench.uq.stochastic import JointModel  # noqa: E402

REPO = Path(__file__).resolve().parents[1]
TABLE3 = REPO.parent / "shared" / "paper" / "table3_single_bolt_vertical_moments.csv"
FRAME = REPO / "frames" / "one_bolt_vertical.toml"
PAPER_MEAN_PA, PAPER_COV = 24e9, 0.09  # Table 4, J_vert (alpha 123, beta 0.0081)
PAPER_NOMINAL_PA = 11.5e9  # Table 2's nominal fit, on which our frame was calibrated


def read_table3() -> MeasuredModes:
    with TABLE3.open() as handle:
        rows = list(csv.DictReader(handle))
    means = np.array([[float(r["mean_hz"]) for r in rows]])
    return MeasuredModes(means, modes=np.array([int(r["mode"]) for r in rows]),
                         published_std_hz=np.array([float(r["std_hz"]) for r in rows]), source=TABLE3.name)


def main() -> None:
    data = read_table3()
    model = assemble(read_frame(FRAME))
    fit = moment_matching(model, data)
    mean, cov = fit.mean_pa[0], fit.cov[0]

    print(f"Moment matching on Table 3 ({TABLE3.name}, modes {data.modes.min()}-{data.modes.max()}), "
          f"frame {FRAME.name}, forward model: {fit.method} SMR")
    print(f"{'':28s}{'ours':>12s}{'paper (Table 4)':>18s}")
    print(f"{'E[Y] (GPa)':28s}{mean / 1e9:12.2f}{PAPER_MEAN_PA / 1e9:18.2f}")
    print(f"{'CoV delta':28s}{cov:12.4f}{PAPER_COV:18.4f}")
    print(f"{'Gamma alpha = 1/cov^2':28s}{1 / cov**2:12.1f}{1 / PAPER_COV**2:18.1f}")
    print(f"{'Gamma beta = cov^2':28s}{cov**2:12.5f}{PAPER_COV**2:18.5f}")
    print(f"{'eq. (1) nominal Y (GPa)':28s}{fit.nominal.moduli_pa[0] / 1e9:12.2f}{PAPER_NOMINAL_PA / 1e9:18.2f}")
    print(f"{'eps_E (Hz^2), eq. (10)':28s}{fit.eps_E:12.2f}")
    print(f"{'eps_delta, eq. (11)':28s}{fit.eps_delta:12.3e}")
    print(f"forward evaluations {fit.evaluations} (+ {fit.nominal.evaluations} eigen-solves in the nominal fit), "
          f"sweeps {fit.sweeps} (converged: {fit.converged}), wall time {fit.wall_time_s:.1f} s")

    # the paper's Table 4 values run through our frame
    paper = adaptive(model_at_moduli(model, np.array([PAPER_MEAN_PA])),
                     JointModel(model.joint_names, np.array([PAPER_COV])), int(data.modes.max()))
    k = data.modes - 1
    paper_mean, paper_delta = paper.mean_hz[k], paper.std_hz[k] / paper.mean_hz[k]
    print()
    print("Per mode: measured (Table 3) vs SMR at our optimum, and at the paper's Table 4 values on our frame")
    print(f"{'mode':>4s} {'E[f] meas':>10s} {'ours':>9s} {'rel res':>8s} {'T4':>9s} {'rel res':>8s} |"
          f" {'delta meas':>10s} {'ours':>9s} {'res':>10s} {'T4':>9s} {'res':>10s} | {'ours d/cov':>10s}")
    for i, mode in enumerate(data.modes):
        measured = data.mean_hz[i]
        print(f"{mode:4d} {measured:10.2f} {fit.mean_hz[i]:9.2f} {fit.residual_mean_hz[i] / measured:+8.2%}"
              f" {paper_mean[i]:9.2f} {(measured - paper_mean[i]) / measured:+8.2%} |"
              f" {fit.measured_delta[i]:10.5f} {fit.delta[i]:9.5f} {fit.residual_delta[i]:+10.5f}"
              f" {paper_delta[i]:9.5f} {fit.measured_delta[i] - paper_delta[i]:+10.5f} | {fit.delta[i] / cov:10.4f}")
    eps_e_paper = float(np.sum((data.mean_hz - paper_mean) ** 2))
    eps_d_paper = float(np.sum((fit.measured_delta - paper_delta) ** 2))
    print(f"eps_E: ours {fit.eps_E:.2f} Hz^2, Table 4 on our frame {eps_e_paper:.2f} Hz^2; "
          f"eps_delta: ours {fit.eps_delta:.3e}, Table 4 on our frame {eps_d_paper:.3e}")

    # step 2 alone with the mean held at the paper's 24 GPa: which CoV would our frame give?
    at_paper = model_at_moduli(model, np.array([PAPER_MEAN_PA]))

    def eps_delta(c: float) -> float:
        m = adaptive(at_paper, JointModel(model.joint_names, np.array([c])), int(data.modes.max()))
        return float(np.sum((fit.measured_delta - m.std_hz[k] / m.mean_hz[k]) ** 2))

    step2 = minimize_scalar(eps_delta, bounds=(1e-3, 0.6), method="bounded", options={"xatol": 1e-5})
    print(f"step 2 alone on our frame with E[Y] held at the paper's 24 GPa: CoV {step2.x:.4f} "
          f"(eps_delta {step2.fun:.3e})")
    print()
    print("Why the numbers differ from Table 4 (our geometry, not the paper's):")
    print(f"- Mean: the paper's Figure 1 dimensions are unknown; our frame was calibrated on Table 2 with the\n"
          f"  joint at the paper's own nominal fit, 11.5 GPa, and Table 3's means are Table 2's frequencies.\n"
          f"  So eq. (1) and eq. (10) on our frame land there too ({fit.nominal.moduli_pa[0] / 1e9:.2f} and "
          f"{mean / 1e9:.2f} GPa), not at 24 GPa;\n  on our frame 24 GPa misfits the means (eps_E "
          f"{eps_e_paper:.0f} against {fit.eps_E:.0f} Hz^2).\n  The paper's own nominal (11.5 GPa) and "
          f"stochastic (24 GPa) means differ by 2x on its frame,\n  by a step its text does not explain.")
    print(f"- CoV: it follows the mean. A stiffer joint carries less of each mode's strain energy, so the\n"
          f"  frequencies feel a given CoV less (last column: delta_k / cov on our frame at {mean / 1e9:.1f} GPa).\n"
          f"  Step 2 with the mean held at 24 GPa gives CoV {step2.x:.3f} on our frame, near the paper's 0.09;\n"
          f"  at our {mean / 1e9:.1f} GPa it gives {cov:.3f}. The per-mode pattern is ours, not the real frame's:\n"
          f"  modes 2, 5 and 8 barely move on the real frame (delta about 1e-4) but do on ours, and modes 4\n"
          f"  and 9 move more on the real frame. So eq. (11) keeps a residual that no CoV removes.")


if __name__ == "__main__":
    main()

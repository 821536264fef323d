"""Accuracy of SMR1, SMR2, adaptive and Pert2 (the paper's section 4.3, Figure 11, and beyond).

Run from the repository root: ``python benchmarks/smr_accuracy.py`` (about 2 minutes). Prints
the tables and writes three figures to ``reports/``:

1. Figure 11 on our one-bolt frames (vertical joint 24 GPa CoV 0.09; horizontal 73.5 GPa CoV
   0.22): relative errors of mean and std of the first 10 eigenfrequencies against the stored
   10 000-sample Monte Carlo (``tests/reference/propagation_one_bolt.json``, seed in it) and against
   the exact tensor-Gauss reference. -> ``reports/figure11_smr_accuracy.png`` (against the exact
   reference, with the Monte Carlo itself as one more bar and its 3-standard-error band in grey)
2. The harder case: the four-bolt frame with CoVs up to 0.3, against the exact reference: where
   SMR1 fails and whether the adaptive strategy repairs it. -> ``reports/four_bolt_smr_accuracy.png``
3. The study behind the adaptive thresholds: SMR1's std error against the proximity factor (a
   symmetric portal whose column modes veer) and against the joint dispersion D_k (all frames).
   -> ``reports/adaptive_thresholds.png``
"""

from __future__ import annotations

import os

for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")  # small dense problems: one BLAS thread is fastest here

import json  # noqa: E402
import time  # noqa: E402
from pathlib import Path  # noqa: E402

import numpy as np  # noqa: E402

from workbench.model.assembly import assemble  # noqa: E402
from workbench.model.frame_file import read_frame  # noqa: E402
from workbench.model.generate import multibay_frame  # noqa: E402
from workbench.report.page import moment_error_figure, save_figure  # noqa: E402
from workbench.uq.smr import DISPERSION_THRESHOLD, PROXIMITY_THRESHOLD, adaptive, pert2, smr1, smr2  # noqa: E402
from workbench.uq.stochastic import JointModel, joint_model, quadrature_reference  # noqa: E402

REPO = Path(__file__).resolve().parents[1]
REFERENCE = REPO / "tests" / "reference" / "propagation_one_bolt.json"
METHODS = {"smr1": smr1, "smr2": smr2, "adaptive": adaptive, "pert2": pert2}


def percent(x: np.ndarray, ref: np.ndarray) -> np.ndarray:
    return 100.0 * (np.asarray(x) / np.asarray(ref) - 1.0)


def table(title: str, rows: dict[str, tuple[np.ndarray, np.ndarray]]) -> None:
    print(f"\n{title}")
    print(f"{'method':10s} {'max|mean err| %':>16s} {'max|std err| %':>15s}   std error per mode %")
    for name, (mean_err, std_err) in rows.items():
        print(f"{name:10s} {np.abs(mean_err).max():16.3f} {np.abs(std_err).max():15.2f}   "
              + " ".join(f"{e:+.2f}" for e in std_err))


def figure11() -> None:
    ref = json.loads(REFERENCE.read_text())
    panels, bands = {}, {}
    for name, data in ref["frames"].items():
        model = assemble(read_frame(REPO / "frames" / f"{name}.toml"))
        joints = joint_model(model.frame)
        mc, quad = data["mc"], data["quadrature"]
        results = {m: f(model, joints, 10) for m, f in METHODS.items()}
        vs_mc = {m: (percent(r.mean_hz, mc["mean_hz"]), percent(r.std_hz, mc["std_hz"])) for m, r in results.items()}
        vs_exact = {m: (percent(r.mean_hz, quad["mean_hz"]), percent(r.std_hz, quad["std_hz"]))
                    for m, r in results.items()}
        vs_exact["mc"] = (percent(mc["mean_hz"], quad["mean_hz"]), percent(mc["std_hz"], quad["std_hz"]))
        joint = next(iter(data["joint"].values()))
        label = f"{name} (E = {joint['youngs_modulus'] / 1e9:g} GPa, CoV {joint['cov']:g})"
        table(f"{label}: against Monte Carlo, {ref['samples']} samples, seed {ref['seed']}", vs_mc)
        table(f"{label}: against the exact quadrature reference", vs_exact)
        print("   MC standard error of the std, %: "
              + " ".join(f"{100 * s / m:.2f}" for s, m in zip(mc["se_std_hz"], mc["std_hz"])))
        refined = results["adaptive"].refined
        print(f"   adaptive refined modes {[int(k) + 1 for k in np.flatnonzero(refined)]}")
        panels[label] = ({m: e[0] for m, e in vs_exact.items()}, {m: e[1] for m, e in vs_exact.items()})
        bands[label] = (300 * np.array(mc["se_mean_hz"]) / np.array(mc["mean_hz"]),
                        300 * np.array(mc["se_std_hz"]) / np.array(mc["std_hz"]))
    path = save_figure(moment_error_figure(panels, bands), REPO / "reports" / "figure11_smr_accuracy.png")
    print(f"\nwritten {path.relative_to(REPO)} (errors against the exact reference, Monte Carlo included; "
          "grey: 3 standard errors of the Monte Carlo)")


def four_bolt() -> list[tuple[float, float, float]]:
    model = assemble(read_frame(REPO / "frames" / "four_bolt.toml"))
    groups = [j.group for j in model.frame.joints]
    panels, points = {}, []
    for cov_v, cov_h in ((0.09, 0.22), (0.15, 0.30), (0.30, 0.30)):
        joints = JointModel(model.joint_names, np.array([cov_v if g == "vertical" else cov_h for g in groups]))
        start = time.perf_counter()
        exact = quadrature_reference(model, joints, 10, points=7)
        t_exact = time.perf_counter() - start
        results = {m: f(model, joints, 10) for m, f in METHODS.items()}
        errors = {m: (percent(r.mean_hz, exact.mean_hz), percent(r.std_hz, exact.std_hz)) for m, r in results.items()}
        label = f"four-bolt, CoV vertical {cov_v:g}, horizontal {cov_h:g}"
        table(f"{label}: against the exact reference ({7 ** 4} solves, {t_exact:.0f} s)", errors)
        first = results["smr1"]
        print(f"   proximity factor {np.round(first.proximity, 1).tolist()}")
        print(f"   dispersion D_k   {np.round(first.dispersion, 4).tolist()}")
        print(f"   adaptive refined modes {[int(k) + 1 for k in np.flatnonzero(results['adaptive'].refined)]}")
        panels[label] = ({m: e[0] for m, e in errors.items()}, {m: e[1] for m, e in errors.items()})
        points += list(zip(first.proximity, first.dispersion, errors["smr1"][1]))
    path = save_figure(moment_error_figure(panels), REPO / "reports" / "four_bolt_smr_accuracy.png")
    print(f"\nwritten {path.relative_to(REPO)}")
    return points


def thresholds(points: list[tuple[float, float, float]]) -> None:
    import matplotlib.pyplot as plt

    portal = assemble(multibay_frame(1, 1, element_length=0.01))
    veer = []
    for cov in (0.01, 0.02, 0.03, 0.05, 0.1):
        joints = JointModel(portal.joint_names, np.full(len(portal.joint_names), cov))
        exact = quadrature_reference(portal, joints, 10)
        first = smr1(portal, joints, 10)
        err = percent(first.std_hz, exact.std_hz)
        veer += list(zip(first.proximity, first.dispersion, err))
    for name in ("one_bolt_vertical", "one_bolt_horizontal"):
        model = assemble(read_frame(REPO / "frames" / f"{name}.toml"))
        joints = joint_model(model.frame)
        exact = quadrature_reference(model, joints, 10)
        first = smr1(model, joints, 10)
        points += list(zip(first.proximity, first.dispersion, percent(first.std_hz, exact.std_hz)))
    pts, veer = np.array(points), np.array(veer)
    kappa = np.abs(pts[:, 2]) / 100 / pts[:, 1]
    print("\nAdaptive thresholds")
    print(f"   well-separated modes (one-bolt and four-bolt frames): |SMR1 std error| / D_k = kappa in "
          f"[{kappa.min():.2f}, {kappa.max():.2f}]; D threshold {DISPERSION_THRESHOLD} keeps "
          f"{kappa.max():.2f} * D under {100 * kappa.max() * DISPERSION_THRESHOLD:.2f} %")
    close = veer[np.abs(veer[:, 2]) / 100 > 2.0 * veer[:, 1]]
    fit = np.median(np.abs(close[:, 2]) / 100 * close[:, 0] ** 2) if len(close) else float("nan")
    print(f"   veering pair of the symmetric portal: |error| ~ {fit:.1f} / PF^2; PF threshold "
          f"{PROXIMITY_THRESHOLD:g} keeps it under {100 * fit / PROXIMITY_THRESHOLD**2:.2f} %")
    fig, (a, b) = plt.subplots(1, 2, figsize=(11, 4))
    a.loglog(veer[:, 0], np.abs(veer[:, 2]), "o", color="tab:orange", label="symmetric portal (veering pair)")
    a.loglog(pts[:, 0], np.abs(pts[:, 2]), ".", color="tab:blue", label="one-, four-bolt frames")
    a.axvline(PROXIMITY_THRESHOLD, color="k", ls=":")
    a.set_xlabel("proximity factor PF_k")
    a.set_ylabel("|SMR1 std error| (%)")
    a.legend(fontsize=8)
    b.loglog(pts[:, 1], np.abs(pts[:, 2]), ".", color="tab:blue", label="one-, four-bolt frames")
    b.loglog(veer[:, 1], np.abs(veer[:, 2]), "o", color="tab:orange", label="symmetric portal (veering pair)")
    d = np.logspace(-4, -1, 10)
    b.loglog(d, 100 * 1.9 * d, "k--", lw=0.8, label="1.9 D")
    b.axvline(DISPERSION_THRESHOLD, color="k", ls=":")
    b.set_xlabel("joint dispersion D_k")
    b.legend(fontsize=8)
    fig.tight_layout()
    path = save_figure(fig, REPO / "reports" / "adaptive_thresholds.png")
    print(f"written {path.relative_to(REPO)}")


def main() -> None:
    figure11()
    points = four_bolt()
    thresholds(points)


if __name__ == "__main__":
    main()

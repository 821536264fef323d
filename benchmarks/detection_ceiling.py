"""How often *any* gap test could see each validation case (the detection ceiling), beside what the diagnosis
saw; and how narrow a model-form error may be before a plain as-built error reads as a gap.

Run from the repository root: ``python benchmarks/detection_ceiling.py [--seed 22]`` (about a minute on 2
cores). It reads the seed's run in ``reports/diagnosis_validation_seed<S>`` (its verdicts) and rebuilds, for
every case whose primary effect acts on the frequencies (singles and out-of-vocabulary; the damping and
amplitude channels are left out), the effect's own shift ``delta`` of the modes in the band: the
nuisance-free article with the effect against the one without, at the intensity the case calibrated
(`workbench.proving.cases`), paired as the footprint pairs them (`workbench.proving.footprint`).

**Ceiling.** A test that knew that shift's exact shape in advance (no search over candidates, no measurement
error, no joint scatter) and tested along it one-sided at the diagnosis's level (``GAP_LEVEL`` = 1 %) sees it
with probability ``1 - Phi(z_0.99 - sqrt(lambda))``, ``lambda = delta^T C^-1 delta`` (Neyman-Pearson: no test
at that level does better). Four model-form covariances ``C``:

- **before 24**: the diagnosis's discrepancy up to seed 23 at its least (`workbench.diagnose.observations`:
  0.2 % per mode, 0.4 % common; a campaign's own scatter only widens it);
- **before 25**: the same plus the frame's geometry, each member end's x and y known to ``GEOMETRY_SD``
  (0.5 mm; seed 24; here with the proving ground's sensitivities, the diagnosis uses its own model's);
- **stated**: since seed 25, the per-mode floor at ``MODEL_FLOOR`` (0.1 %), the common shift, the geometry,
  and each member's second moment of area and area known to ``SECOND_MOMENT_SD`` (1 %) and ``AREA_SD``
  (0.5 %), independently (the proving ground's flat bars' width and thickness sensitivities turned into I and
  A ones: ``dlog I = db + 3 dt``, ``dlog A = db + dt``);
- **floor 0.15 %**: the first with a per-mode floor of 0.15 %;
- **generator**: the proving ground's as-built law itself (each material's E and density, each member's width
  and thickness, 0.3 %; each member end's x and y by a spread drawn between 0 and 1 mm; linearised), plus the
  frequencies' error floor 1e-4: what a test that knew the generator's nuisance law (an inverse crime) could do.

**False alarms.** The share of as-built residuals alone (no effect, no measurement error: the least a campaign
holds) beyond the 99 % chi-square quantile under the first three covariances, for three as-built laws: the
materials and sections alone (the generator up to seed 23); and with each member end 0.5 mm or 1 mm off in x
and y (a member's length off by 0.17 % or 0.33 % on a 0.42 m frame: "a few tenths of a percent on dimensions").
Two more laws step outside the generator's family, as another simulator would: the sections twice as far off
(0.6 %) with the ends 1 mm off; and the ends 0.5 mm off plus a per-mode error of 0.1 % or 0.15 % of no
structure (another code's elements, mesh and joints). A discrepancy narrower than the as-built errors a test may
meet reads them as gaps.

The sensitivities are forward differences on the proving ground's own articles. No number here sets a
threshold; it says how far one could go, and at what risk.
"""

from __future__ import annotations

import argparse
import csv
import math
from concurrent.futures import ProcessPoolExecutor
from functools import cache
from pathlib import Path

import numpy as np
from scipy.stats import chi2 as chi2_law
from scipy.stats import norm

from workbench.diagnose.decision import GAP_LEVEL
from workbench.diagnose.observations import (
    AREA_SD,
    COMMON_SD,
    GEOMETRY_SD,
    MODEL_FLOOR,
    RELATIVE_FLOOR,
    SECOND_MOMENT_SD,
)
from workbench.model.frame import Frame, member_ends
from workbench.proving.article import Article
from workbench.proving.campaigns import CampaignSettings
from workbench.proving.cases import FAINT, CaseSpec, calibrated_primary, reached_level
from workbench.proving.footprint import FOOTPRINT_MODES, article_frequencies, paired_shift
from workbench.proving.frames import FRAME_NAMES, proving_frame
from workbench.proving.geometry import moved_article
from workbench.proving.mechanisms import NONE
from workbench.proving.nuisances import built_frame
from workbench.workflow.proving_validation import validation_specs

REPO = Path(__file__).resolve().parents[1]
Z = float(norm.ppf(1.0 - GAP_LEVEL))


def effect_shift(spec: CaseSpec) -> tuple[np.ndarray, str, float] | None:
    """The case's primary effect's relative shift of the modes in the band, its channel's rung, footprint."""
    frame = proving_frame(spec.frame)
    settings = spec.settings()
    base = Article(frame)
    mech, x, fp = calibrated_primary(spec)
    if mech.channel != "frequency":
        return None
    reference = base if mech.nominal is None else Article(mech.nominal(frame, x), shear=False, rotary_inertia=False)
    delta = paired_shift(article_frequencies(reference), article_frequencies(mech.build(base, x), FOOTPRINT_MODES + 4),
                         settings.f_max_hz)
    return delta, reached_level(fp, "frequency"), fp


def _shift(article: Article, f0: np.ndarray) -> np.ndarray:
    """Relative shift of the reference modes ``f0`` (Hz) in ``article``."""
    return paired_shift(f0, article_frequencies(article, FOOTPRINT_MODES + 4))


def _band_shift(frame: Frame, f0: np.ndarray) -> np.ndarray:
    """Relative shift of the reference modes ``f0`` (Hz) in ``frame``'s article."""
    return _shift(Article(frame), f0)


@cache
def tolerance_sensitivities(frame_name: str, step: float = 1e-4) -> tuple[np.ndarray, np.ndarray]:
    """``(J_built, J_ends)``: d(relative band frequencies) per standard deviation of the generator's as-built
    error (each material's E and density, each member's width and thickness:
    `workbench.proving.nuisances.built_frame`), and per metre of each member end's x and y
    (`workbench.proving.geometry.moved_article`), by forward differences of ``step`` on the proving ground's
    article."""
    frame = proving_frame(frame_name)
    base = Article(frame)
    f0 = article_frequencies(base)
    f0 = f0[f0 <= CampaignSettings().f_max_hz]
    unit = {"materials": {n: {"youngs_modulus_factor": 1.0, "density_factor": 1.0} for n in frame.materials},
            "sections": {m.name: {"width_factor": 1.0, "thickness_factor": 1.0} for m in frame.members}}
    nuisances = CampaignSettings().nuisances
    built = []
    for group, names, sd in (("materials", list(frame.materials), nuisances.material_sd),
                             ("sections", [m.name for m in frame.members], nuisances.section_sd)):
        for name in names:
            for key in unit[group][name]:
                record = {g: {n: dict(v) for n, v in unit[g].items()} for g in unit}
                record[group][name][key] += step
                built.append(sd * _band_shift(built_frame(frame, record), f0) / step)
    ends = [_shift(moved_article(base, {name: (step * (axis == 0), step * (axis == 1))}), f0) / step
            for name in member_ends(frame) for axis in range(2)]
    return np.array(built).T, np.array(ends).T


def covariances(frame_name: str, m: int) -> dict[str, np.ndarray]:
    """The model-form covariances the module docstring compares, over a frame's first ``m`` band modes."""
    built, ends = (j[:m] for j in tolerance_sensitivities(frame_name))
    ones, eye = np.ones((m, m)), np.eye(m)
    before = 0.002 ** 2 * eye + COMMON_SD ** 2 * ones  # the per-mode floor up to seed 24
    spread = CampaignSettings().nuisances.geometry_sd_range
    mean_square = (spread[0] ** 2 + spread[0] * spread[1] + spread[1] ** 2) / 3.0  # E[sd^2], sd uniform
    sections = _section_columns(frame_name, built)
    return {
        "before 24": before,
        "before 25": before + GEOMETRY_SD ** 2 * ends @ ends.T,
        "stated": (MODEL_FLOOR ** 2 * eye + COMMON_SD ** 2 * ones + GEOMETRY_SD ** 2 * ends @ ends.T
                   + sections @ sections.T),
        "floor 0.15 %": 0.0015 ** 2 * eye + COMMON_SD ** 2 * ones,
        "generator": built @ built.T + mean_square * ends @ ends.T + RELATIVE_FLOOR ** 2 * eye,
    }


def _section_columns(frame_name: str, built: np.ndarray) -> np.ndarray:
    """The stated sections' columns: the generator's per-sd width and thickness columns of each member turned
    into per-``SECOND_MOMENT_SD`` second-moment and per-``AREA_SD`` area ones (module docstring)."""
    per_unit = built[:, 2 * len(proving_frame(frame_name).materials):] / CampaignSettings().nuisances.section_sd
    width, thickness = per_unit[:, 0::2], per_unit[:, 1::2]
    # db = (3 dlogA - dlogI) / 2, dt = (dlogI - dlogA) / 2
    return np.hstack([SECOND_MOMENT_SD * (thickness - width) / 2, AREA_SD * (3 * width - thickness) / 2])


def false_alarms(frame_name: str, draws: int, seed: int = 7) -> dict[str, dict[str, float]]:
    """Share of as-built residuals alone (no effect, no measurement error) beyond the 99 % chi-square quantile
    under each test covariance, for the as-built laws of the module docstring."""
    built, ends = tolerance_sensitivities(frame_name)
    m = built.shape[0]
    tests = covariances(frame_name, m)
    laws = {"sections only": built @ built.T}
    for sd in (5e-4, 1e-3):
        laws[f"+ ends {1e3 * sd:.1f} mm"] = laws["sections only"] + sd ** 2 * ends @ ends.T
    laws["sections x2, ends 1 mm"] = 4 * built @ built.T + 1e-6 * ends @ ends.T
    for sd in (1e-3, 1.5e-3):
        laws[f"ends 0.5 mm, {100 * sd:.2f} %"] = laws["+ ends 0.5 mm"] + sd ** 2 * np.eye(m)
    rng = np.random.default_rng(seed)
    q = chi2_law.ppf(1.0 - GAP_LEVEL, m)
    out: dict[str, dict[str, float]] = {}
    for law, cov in laws.items():
        r = rng.standard_normal((draws, m)) @ np.linalg.cholesky(cov + 1e-14 * np.eye(m)).T
        out[law] = {t: float(np.mean(np.einsum("gi,ij,gj->g", r, np.linalg.inv(c), r) > q))
                    for t, c in tests.items() if t != "generator"}
    return out


def ceiling(lam: float) -> float:
    """Power of the one-sided known-direction test at ``GAP_LEVEL`` with non-centrality ``lam``."""
    return float(1.0 - norm.cdf(Z - math.sqrt(max(lam, 0.0))))


def _one(spec: CaseSpec) -> dict | None:
    got = effect_shift(spec)
    if got is None:
        return None
    delta, rung, fp = got
    m = min(delta.size, tolerance_sensitivities(spec.frame)[0].shape[0])  # a nominal (stocky) may hold another count
    ceilings = {k: ceiling(float(delta[:m] @ np.linalg.solve(c, delta[:m])))
                for k, c in covariances(spec.frame, m).items()}
    return {"case": spec.case, "kind": spec.kind, "rung": rung, "footprint": fp, **ceilings}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--seed", type=int, default=22)
    parser.add_argument("--draws", type=int, default=20000, help="as-built draws per frame for the false alarms")
    parser.add_argument("--workers", type=int, default=2)
    args = parser.parse_args()
    print(f"false alarms at {GAP_LEVEL:.0%} on as-built residuals alone, the worst frame of {len(FRAME_NAMES)}")
    alarms = [false_alarms(name, args.draws) for name in FRAME_NAMES]
    for law in alarms[0]:
        print(f"  law {law:22s} " + "  ".join(f"{t}: {max(a[law][t] for a in alarms):6.1%}" for t in alarms[0][law]))
    run = REPO / "reports" / f"diagnosis_validation_seed{args.seed}" / "cases.csv"
    rows = {int(r["case"]): r for r in csv.DictReader(run.open())}
    specs = [s for s in validation_specs(len(rows), args.seed)
             if s.kind != NONE and not s.secondary and s.case in rows]
    with ProcessPoolExecutor(args.workers) as pool:
        results = [r for r in pool.map(_one, specs) if r is not None]
    names = [k for k in results[0] if k not in ("case", "kind", "rung", "footprint")]
    print(f"seed {args.seed}: {len(results)} cases whose primary effect moves the frequencies; mean ceiling of a "
          f"known-shape test at {GAP_LEVEL:.0%} under each covariance, and the share the run took for a gap")
    print(f"  {'':8s} {'rung':7s} {'cases':>5s} " + " ".join(f"{n:>13s}" for n in names) + f" {'run: a gap':>11s}")
    for group in ("single", "outside"):
        for rung in ("small", "medium", "large"):
            sel = [r for r in results if r["rung"] == rung and (r["kind"] == "outside_vocabulary") == (group == "outside")]
            if sel:
                seen = sum(rows[r["case"]]["verdict"] != "none" for r in sel) / len(sel)
                print(f"  {group:8s} {rung:7s} {len(sel):5d} "
                      + " ".join(f"{np.mean([r[n] for r in sel]):13.1%}" for n in names) + f" {seen:11.1%}")
        sel = [r for r in results if r["rung"] != FAINT and (r["kind"] == "outside_vocabulary") == (group == "outside")]
        seen = sum(rows[r["case"]]["verdict"] != "none" for r in sel) / len(sel)
        print(f"  {group:8s} {'all':7s} {len(sel):5d} "
              + " ".join(f"{np.mean([r[n] for r in sel]):13.1%}" for n in names) + f" {seen:11.1%}")


if __name__ == "__main__":
    main()

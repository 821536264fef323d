"""How often the damping channel's chi-square rejects at its stated 1 % when nothing but chance is there.

Run from the repository root: ``python benchmarks/damping_null_calibration.py`` (about 40 s). Not a test
(`tests/test_diagnose_damping_null.py` checks the two-level case at a looser tolerance); it measures the
damping channel's calibration for ``reports/diagnosis.md``.

Until seed 21 the diagnosis added the damping model's error (``DAMPING_MODEL_SD`` of the typical damping
ratio) to each excitation level's mean on its own, as if it were drawn anew per level. A mode's damping model
error is the same at every level (the model is linear), so on a campaign with two levels that chi-square
counted it twice. `workbench.diagnose.observations.damping_chi2` now reads the means under their covariance,
one model error per mode shared by the levels (`damping_whiten`): the levels' mean against the measurement and
the model error, the levels' differences against the measurement alone.
Here the null is simulated directly (independent of the diagnosis's fits): per mode a shared model error of
``DAMPING_MODEL_SD`` of the typical damping ratio, per level a measurement error of the stated standard error;
the baseline is known (no parameter fitted). Printed: the share of draws beyond the 99 % quantile for the
chi-square as the diagnosis computes it (``damping_chi2``) and for the former per-level chi-square (written
out here), both read with one degree of freedom per mean, with Wilson 95 % intervals;
the levels' line in amplitude alone (`damping_levels_chi2`, the standard errors known here, so chi-square rather
than the diagnosis's F); and the same for the drop a one-parameter candidate (a joint's damping, one-sided) reads as its evidence
against chi-square with one degree of freedom (one-sided: about half the stated level is right). Both take the
model error's scale from the measured median damping ratio, as the diagnosis does. Last, the targeted test's
family-wise p-value over six damping candidates (three joints, two forms) with the baseline fitted as the
diagnosis fits it, by min-p (`workbench.diagnose.family.damping_null`, since seed 22) and by Bonferroni.
"""

from __future__ import annotations

import numpy as np
from scipy.stats import chi2 as chi2_law

from workbench.diagnose.family import damping_null
from workbench.diagnose.fitting import damping_fit
from workbench.diagnose.observations import (
    DAMPING_MODEL_SD,
    Discrepancy,
    Observations,
    damping_chi2,
    damping_levels_chi2,
    damping_whiten,
)
from workbench.workflow.proving_validation import wilson

DRAWS = 10000
SEED = 20261202


def _observations(damping: np.ndarray, se: np.ndarray) -> Observations:
    n_cond, n_modes = damping.shape
    f = np.tile(np.linspace(50.0, 900.0, n_modes), (n_cond, 1))
    cov = np.zeros((n_cond, n_modes, n_modes))
    return Observations(np.arange(1.0, n_cond + 1.0), f, f * 1e-4, cov, damping, se, Discrepancy())


def main() -> None:
    rng = np.random.default_rng(SEED)
    zeta, n_modes, se_rel = 0.006, 10, 0.02
    share = rng.uniform(0.0, 1.0, n_modes)  # a candidate's direction (a joint's energy share), fixed
    for n_cond in (1, 2, 4):
        rejected = {"damping_chi2": 0, "per level (old)": 0}
        drop_rejected = {"damping_chi2": 0, "per level (old)": 0}
        levels_rejected = 0
        model = DAMPING_MODEL_SD * zeta
        limit_all, limit_drop = (chi2_law.ppf(0.99, k) for k in (n_cond * n_modes, 1))
        for _ in range(DRAWS):
            shared = model * rng.standard_normal(n_modes)
            measured = zeta + shared[None, :] + se_rel * zeta * rng.standard_normal((n_cond, n_modes))
            se = np.full((n_cond, n_modes), se_rel * zeta)
            obs = _observations(measured, se)
            base = np.full_like(measured, zeta)
            # the diagnosis's chi-square and its best non-negative multiple of the share
            computed = damping_chi2(obs, base)
            a, b = damping_whiten(obs, np.broadcast_to(share, measured.shape)), damping_whiten(obs, measured - base)
            eta = max(0.0, float(np.sum(a * b) / np.sum(a * a)))
            computed_drop = computed - damping_chi2(obs, base + eta * share)
            levels, q = damping_levels_chi2(obs, base)
            levels_rejected += bool(q) and levels > chi2_law.ppf(0.99, q)
            # the former chi-square: the model error added to every level's mean on its own
            r = measured - base
            old_var = se**2 + (DAMPING_MODEL_SD * float(np.median(measured))) ** 2
            old_chi2 = float(np.sum(r**2 / old_var))
            eta_o = max(0.0, float(np.sum(r * share / old_var) / np.sum(share**2 / old_var)))
            old_drop = old_chi2 - float(np.sum((r - eta_o * share) ** 2 / old_var))
            rejected["damping_chi2"] += computed > limit_all
            rejected["per level (old)"] += old_chi2 > limit_all
            drop_rejected["damping_chi2"] += computed_drop > limit_drop
            drop_rejected["per level (old)"] += old_drop > limit_drop
        for name in rejected:
            a, b = wilson(int(rejected[name]), DRAWS), wilson(int(drop_rejected[name]), DRAWS)
            print(
                f"{n_cond} level(s), {name:15s}: omnibus rejects {100 * a['rate']:.2f} % "
                f"[{100 * a['ci95'][0]:.2f}, {100 * a['ci95'][1]:.2f}], a candidate's drop {100 * b['rate']:.2f} % "
                f"[{100 * b['ci95'][0]:.2f}, {100 * b['ci95'][1]:.2f}] (stated: 1 %)"
            )

        if n_cond > 1:
            c = wilson(int(levels_rejected), DRAWS)
            print(f"{n_cond} level(s), the levels' line alone (damping_levels_chi2, chi-square): rejects "
                  f"{100 * c['rate']:.2f} % [{100 * c['ci95'][0]:.2f}, {100 * c['ci95'][1]:.2f}] (stated: 1 %)")


def family_calibration(draws: int = 2000) -> None:
    """The targeted test's family-wise p-value under no effect, the baseline fitted (level and trend) as the
    diagnosis fits it: three joints' shares in both forms, read by min-p (`damping_null`) and by Bonferroni.
    """
    rng = np.random.default_rng(SEED + 1)
    n_modes, zeta, se_rel = 10, 0.006, 0.02
    f = np.linspace(50.0, 900.0, n_modes)
    hysteretic = [rng.uniform(0.0, 1.0, n_modes) for _ in range(3)]
    shares = [s for h in hysteretic for s in (h, h * f / f.mean())]
    mask = np.ones(n_modes, bool)

    def law(drop: np.ndarray) -> np.ndarray:
        return chi2_law.sf(drop, 1)

    minp = bonferroni = 0
    for _ in range(draws):
        shared = DAMPING_MODEL_SD * zeta * rng.standard_normal(n_modes)
        measured = zeta + shared[None, :] + se_rel * zeta * rng.standard_normal((2, n_modes))
        obs = _observations(measured, np.full_like(measured, se_rel * zeta))
        base = damping_chi2(obs, damping_fit(obs, None, mask)[0])
        p_one = float(min(law(np.array(max(base - damping_chi2(obs, damping_fit(obs, s, mask)[0]), 0.0)))
                          for s in shares))
        minp += damping_null(obs, shares, law, draws=4000).adjusted(p_one) <= 0.01
        bonferroni += min(1.0, p_one * len(shares)) <= 0.01
    for name, hits in (("min-p (damping_null)", minp), ("Bonferroni", bonferroni)):
        w = wilson(int(hits), draws)
        print(f"2 levels, 6 damping candidates, baseline fitted, {name:20s}: rejects {100 * w['rate']:.2f} % "
              f"[{100 * w['ci95'][0]:.2f}, {100 * w['ci95'][1]:.2f}] (stated: 1 %)")


if __name__ == "__main__":
    main()
    family_calibration()

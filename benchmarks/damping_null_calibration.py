"""How often the damping channel's chi-square rejects at its stated 1 % when nothing but chance is there.

Run from the repository root: ``python benchmarks/damping_null_calibration.py`` (about 15 s). Not a test: it
measures a known flaw for the next change of the rules (``reports/diagnosis.md``, "Since seed 20").

`workbench.diagnose.observations.damping_chi2` adds the damping model's error (``DAMPING_MODEL_SD`` of the
typical damping ratio) to each excitation level's mean on its own, as if it were drawn anew per level. A mode's
damping model error is the same at every level (the model is linear), so on a campaign with two levels the
chi-square counts it twice: its law is about twice a chi-square of half the degrees of freedom, not the
chi-square the gap test reads it against. Here the null is simulated directly (independent of the diagnosis's
fits): per mode a shared model error of ``DAMPING_MODEL_SD`` of the typical damping ratio, per level a
measurement error of the stated standard error; the baseline is known (no parameter fitted), so the chi-square
has one degree of freedom per mean. Printed: the share of draws beyond the 99 % quantile, for the chi-square
as the diagnosis computes it and for the chi-square of the levels' mean (one error per mode), with Wilson 95 %
intervals; and the same for the drop a one-parameter candidate (a joint's damping, one-sided) reads as its
evidence against chi-square with one degree of freedom (one-sided: about half the stated level is right). Both
take the model error's scale from the measured median damping ratio, as the diagnosis does.
"""

from __future__ import annotations

import numpy as np
from scipy.stats import chi2 as chi2_law

from workbench.diagnose.observations import DAMPING_MODEL_SD, Discrepancy, Observations, damping_chi2, damping_variance
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
        rejected = {"as computed": 0, "levels' mean": 0}
        drop_rejected = {"as computed": 0, "levels' mean": 0}
        model = DAMPING_MODEL_SD * zeta
        limit_all, limit_mean, limit_drop = (chi2_law.ppf(0.99, k) for k in (n_cond * n_modes, n_modes, 1))
        for _ in range(DRAWS):
            shared = model * rng.standard_normal(n_modes)
            measured = zeta + shared[None, :] + se_rel * zeta * rng.standard_normal((n_cond, n_modes))
            se = np.full((n_cond, n_modes), se_rel * zeta)
            obs = _observations(measured, se)
            base = np.full_like(measured, zeta)
            r = measured - base
            variance = damping_variance(obs)  # the diagnosis's: its scale from the typical measured ratio
            computed = damping_chi2(obs, base)
            # the best non-negative multiple of the share, each formula's own least squares
            eta = max(0.0, float(np.sum(r * share / variance) / np.sum(share**2 / variance)))
            computed_drop = computed - damping_chi2(obs, base + eta * share)
            mean_var = variance[0] - se[0] ** 2 + se[0] ** 2 / n_cond  # one model error, the levels' mean error
            rm = r.mean(axis=0)
            mean_chi2 = float(np.sum(rm**2 / mean_var))
            eta_m = max(0.0, float(np.sum(rm * share / mean_var) / np.sum(share**2 / mean_var)))
            mean_drop = mean_chi2 - float(np.sum((rm - eta_m * share) ** 2 / mean_var))
            rejected["as computed"] += computed > limit_all
            rejected["levels' mean"] += mean_chi2 > limit_mean
            drop_rejected["as computed"] += computed_drop > limit_drop
            drop_rejected["levels' mean"] += mean_drop > limit_drop
        for name in rejected:
            a, b = wilson(int(rejected[name]), DRAWS), wilson(int(drop_rejected[name]), DRAWS)
            print(
                f"{n_cond} level(s), {name:12s}: omnibus rejects {100 * a['rate']:.2f} % "
                f"[{100 * a['ci95'][0]:.2f}, {100 * a['ci95'][1]:.2f}], a candidate's drop {100 * b['rate']:.2f} % "
                f"[{100 * b['ci95'][0]:.2f}, {100 * b['ci95'][1]:.2f}] (stated: 1 %)"
            )


if __name__ == "__main__":
    main()

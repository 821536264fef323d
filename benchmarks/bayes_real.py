"""The Bayesian identification, with and without its error terms, on real measured campaigns (issue 16).

Two public data sets (``../shared/data/real/``, `workbench.io.real_data`): UNESP-BERT (a clamped
two-bar beam with a two-bolt lap joint, band-limited random excitation at six levels, 0.05-0.30 V) and
the Brake-Reuss beam (stepped sine under force control at several levels). Each campaign's FRFs go
through the workbench's circle fit and MAC pairing; the nominal models are ``frames/unesp_bert.toml``
and ``frames/brake_reuss.toml``. Nobody tells the identification what varies between the tests: here
the excitation level, which softens the lap joint, not a random reassembly; so the joint's "CoV" is the
level-to-level spread of its modulus, and the discrepancy term shows how far the nominal model misses
each mode systematically.

Prints, per campaign and variant (error terms ``full`` and ``none``; moment matching beside them): the
joint's mean modulus and CoV with 95 % intervals, each mode's measurement error, the common error and
discrepancy scales, each mode's discrepancy, R-hat and ESS, wall time.

    python benchmarks/bayes_real.py [--steps 3000] [--max-steps 12000]
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

import numpy as np

from workbench.identify.bayes import bayes_identify
from workbench.identify.laplace import ERROR_TERMS
from workbench.identify.moments import moment_matching
from workbench.identify.pairing import pair_by_mac
from workbench.io.real_data import import_brake_reuss, import_unesp_bert
from workbench.model.structure import structure_of
from workbench.workflow.measured import measured_modes

REPO = Path(__file__).resolve().parents[1]
REAL = REPO.parent / "shared" / "data" / "real"


def campaigns():
    yield "UNESP-BERT, random, 6 levels", import_unesp_bert(REAL / "unesp-bert-bolted-beam",
                                                               REPO / "frames" / "unesp_bert.toml")
    yield "Brake-Reuss, force control", import_brake_reuss(REAL / "rice-brb-brake-reuss-beam",
                                                            REPO / "frames" / "brake_reuss.toml")


def interval(ci: np.ndarray, scale: float = 1.0, fmt: str = ".3g") -> str:
    return f"[{ci[0] * scale:{fmt}}, {ci[1] * scale:{fmt}}]"


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--steps", type=int, default=3000)
    parser.add_argument("--max-steps", type=int, default=12000)
    args = parser.parse_args(argv)
    for label, campaign in campaigns():
        model = structure_of(campaign.frame)
        data = pair_by_mac(model, measured_modes(campaign, None, "identify from"))
        print(f"\n{label}: {data.frequency_hz.shape[0]} tests, modes {list(map(int, data.modes))}, "
              f"mean {np.round(np.nanmean(data.frequency_hz, axis=0), 2).tolist()} Hz, level-to-level CoV "
              f"{np.round(np.nanstd(data.frequency_hz, axis=0, ddof=1) / np.nanmean(data.frequency_hz, axis=0), 5).tolist()}")
        try:
            fit = moment_matching(model, data, seed=0)
            print(f"  moments: E {fit.mean_pa[0] / 1e9:.2f} GPa, CoV {fit.cov[0]:.3f}"
                  + ("" if fit.cov_ci95 is None else f" {interval(fit.cov_ci95[0])}"))
        except ValueError as error:  # what the command would print, exit 2
            print(f"  moments: refused: {error}")
        for terms in ("full", "none"):
            t0 = time.perf_counter()
            try:
                post = bayes_identify(model, data, seed=0, steps=args.steps, max_steps=args.max_steps,
                                      errors=ERROR_TERMS[terms])
            except ValueError as error:
                print(f"  bayes, error terms {terms}: refused: {error}")
                continue
            wall = time.perf_counter() - t0
            print(f"  bayes, error terms {terms}: E {post.youngs_modulus[0] / 1e9:.2f} GPa "
                  f"{interval(post.youngs_modulus_ci95[0], 1e-9, '.2f')}, CoV {post.cov[0]:.3f} "
                  f"{interval(post.cov_ci95[0])}; max R-hat {post.rhat.max():.3f}, min ESS {post.ess.min():.0f}, "
                  f"{post.steps} steps, {wall:.0f} s, {'converged' if post.converged else 'NOT converged'}")
            print("    measurement error per mode (%): " + ", ".join(
                f"{m}: {100 * s:.3f} {interval(c, 100)}" for m, s, c in zip(post.modes, post.sigma, post.sigma_ci95)))
            for name, s, c in zip(post.error_names, post.error_scales, post.error_scales_ci95):
                print(f"    {name} (%): {100 * s:.3f} {interval(c, 100)}")
            if post.discrepancy is not None and post.discrepancy_ci95 is not None:
                print("    discrepancy per mode (%): " + ", ".join(
                    f"{m}: {100 * d:+.2f} {interval(c, 100, '+.2f')}"
                    for m, d, c in zip(post.modes, post.discrepancy, post.discrepancy_ci95)))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())

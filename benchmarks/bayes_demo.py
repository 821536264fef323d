"""Bayesian identification (workbench.identify.bayes) on two campaigns, posterior beside the truth.

(a) a synthetic 40-test one-bolt campaign drawn from the Gamma joint model (E = 24 GPa, CoV 0.09,
    exact frequencies + 0.05 % relative noise), started 3 times off (72 GPa);
(b) the bundled ``campaigns/two_bolt_table5`` (the virtual rig, Table 5 design), frequencies
    extracted from its FRFs by circle fit (`workbench.extraction.modes.extract_tests`), started from the
    frame file's moduli. Its truth, read from the truth JSON beside the campaign only here, is the
    sample mean and CoV of the rig's per-test joint moduli (the rig's preload law is not a Gamma law).

Prints posterior medians and equal-tailed 95 % intervals beside the truth, R-hat, ESS,
autocorrelation times and the wall time (target: < 60 s per identification on 2 cores).

    OPENBLAS_NUM_THREADS=1 python benchmarks/bayes_demo.py [--seed S] [--out DIR]
"""

from __future__ import annotations

import os

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import argparse  # noqa: E402
import json  # noqa: E402
import sys  # noqa: E402
import time  # noqa: E402
from pathlib import Path  # noqa: E402

import numpy as np  # noqa: E402

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO / "tests"))

from workbench.extraction.modes import extract_tests  # noqa: E402
from workbench.extraction.records import MeasuredModes  # noqa: E402
from workbench.identify.bayes import bayes_identify  # noqa: E402
from workbench.io.campaign import frf_set, load_campaign  # noqa: E402
from workbench.io.outputs import write_outputs  # noqa: E402
from workbench.model.assembly import assemble  # noqa: E402
from workbench.model.frame_file import read_frame  # noqa: E402
from workbench.model.modal import model_modes  # noqa: E402
from workbench.rig.simulate import truth_path  # noqa: E402
from workbench.uq.stochastic import track_modes  # noqa: E402
from workbench.workflow.posterior import POSTERIOR_FILE, posterior_netcdf  # noqa: E402


def gamma_campaign(n_tests: int, mean_pa: float, cov: float, noise: float, seed: int):
    frame = read_frame(REPO / "frames" / "one_bolt_vertical.toml")
    model = assemble(frame)
    rng = np.random.default_rng(seed)
    nominal = model_modes(model, 10)
    moduli = rng.gamma(1 / cov**2, mean_pa * cov**2, n_tests)
    f = np.empty((n_tests, 10))
    for t, y in enumerate(moduli):
        modes = model_modes(model, 14, np.array([y / frame.joints[0].youngs_modulus]))
        index, _ = track_modes(nominal, modes, model.mass)
        f[t] = modes.frequency_hz[index]
    f *= 1.0 + noise * rng.standard_normal(f.shape)
    data = MeasuredModes(f, modes=np.arange(1, 11), tests=tuple(range(1, n_tests + 1)),
                         source=f"synthetic one-bolt, {n_tests} tests")
    return model, data, moduli


def extracted(directory: Path):
    campaign = load_campaign(directory)
    sets = {t: frf_set(campaign, t) for t in campaign.test_ids}
    _, estimates = extract_tests({t: s.frequency_hz for t, s in sets.items()},
                                 {t: s.values for t, s in sets.items()}, campaign.quantity)
    f = np.array([[e.frequency_hz for e in estimates[t]] for t in campaign.test_ids])
    data = MeasuredModes(f, modes=np.arange(1, f.shape[1] + 1), tests=tuple(campaign.test_ids),
                         source=str(directory.name))
    return assemble(campaign.frame), data


def report(name: str, post, truth: dict[str, tuple[float, float]]) -> None:
    print(f"\n== {name}: {post.wall_time_s:.1f} s (walkers {post.walkers}, burn {post.burn}, steps {post.steps}, "
          f"acceptance {post.acceptance_fraction:.2f}, forward table error {post.forward_error:.1e})")
    print(f"{'group':<11}{'quantity':<10}{'truth':>10}{'median':>10}{'95 % interval':>24}  inside")
    for g, group in enumerate(post.groups):
        t_e, t_c = truth[group]
        lo, hi = post.youngs_modulus_ci95[g] / 1e9
        print(f"{group:<11}{'E (GPa)':<10}{t_e / 1e9:>10.2f}{post.youngs_modulus[g] / 1e9:>10.2f}"
              f"{f'[{lo:.2f}, {hi:.2f}]':>24}  {lo < t_e / 1e9 < hi}")
        lo, hi = post.cov_ci95[g]
        print(f"{group:<11}{'CoV':<10}{t_c:>10.3f}{post.cov[g]:>10.3f}{f'[{lo:.3f}, {hi:.3f}]':>24}  {lo < t_c < hi}")
    print("sigma_k (relative error per mode):", " ".join(f"{s:.1e}" for s in post.sigma))
    print(f"{'parameter':<26}{'R-hat':>8}{'ESS':>8}{'tau':>7}")
    for n, r, e, t in zip(post.parameter_names, post.rhat, post.ess, post.autocorr_time):
        print(f"{n:<26}{r:>8.3f}{e:>8.0f}{t:>7.1f}")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--out", type=Path, default=None, help="write posterior.nc of each run under DIR/<name>")
    args = parser.parse_args()

    model, data, moduli = gamma_campaign(40, 24e9, 0.09, 5e-4, seed=2024 + args.seed)
    post = bayes_identify(model, data, start=[72e9], seed=args.seed)
    print(f"(a) sample of the 40 drawn moduli: mean {moduli.mean() / 1e9:.2f} GPa, "
          f"CoV {moduli.std(ddof=1) / moduli.mean():.3f}")
    report("(a) synthetic one-bolt, 40 tests from Gamma(24 GPa, CoV 0.09), start 72 GPa", post,
           {"vertical": (24e9, 0.09)})
    if args.out:
        write_outputs(args.out / "one_bolt_synthetic", {POSTERIOR_FILE: posterior_netcdf(post)}, force=True)

    directory = REPO / "campaigns" / "two_bolt_table5"
    t0 = time.perf_counter()
    model, data = extracted(directory)
    print(f"\n(b) circle-fit extraction of {len(data.tests)} tests x {data.modes.size} modes: "
          f"{time.perf_counter() - t0:.1f} s (not part of the identification time)")
    truth_json = json.loads(truth_path(directory).read_text())
    y = np.array([[t["moduli_pa"]["A"], t["moduli_pa"]["B"]] for t in truth_json["tests"]])
    truth = {"vertical": (y[:, 0].mean(), y[:, 0].std(ddof=1) / y[:, 0].mean()),
             "horizontal": (y[:, 1].mean(), y[:, 1].std(ddof=1) / y[:, 1].mean())}
    post = bayes_identify(model, data, seed=args.seed)
    report("(b) two_bolt_table5 (extracted), truth = sample moments of the rig's moduli", post, truth)
    if args.out:
        write_outputs(args.out / "two_bolt_table5", {POSTERIOR_FILE: posterior_netcdf(post)}, force=True)


if __name__ == "__main__":
    main()

"""Do the diagnosis's verdicts hold when the same cases are measured another way?

The proving ground's fixed measurement is accelerance on 0.25 Hz lines (`workbench.proving.campaigns.CampaignSettings`;
the validation draws a lab's mix since seed 19, `workbench.proving.cases.drawn_measurements`); a lab may export
mobility (a vibrometer), receptance, or coarser lines. The cases here are measured the fixed way, then varied. For the chosen cases of a validation seed (the
same articles, effects and nuisances: only the measurement differs), each campaign is diagnosed blind as the
proving ground makes it and in each variant, and the verdict printed side by side; then, per variant, how many
verdicts are the right one (`workbench.proving.cases.expected_verdict`; a combined case counts its primary in the
verdict) and how many equal the accelerance verdict. The noise stays each curve's RMS over the band times
10^(-SNR/20) in the variant's quantity, so receptance puts the high modes nearer the noise, as a displacement
measurement does.

Run from the repository root: ``python benchmarks/measurement_variants.py [--seed 17] [--cases 1 16 ...]
[--variants receptance mobility lines_0.5]``. The default, 24 cases of seed 17 (20 named right at medium or
large footprint on accelerance, four without effect) in receptance and mobility, takes about 12 minutes on one
core.
"""

from __future__ import annotations

import argparse
import dataclasses

from workbench.diagnose.verdict import diagnose
from workbench.proving.campaigns import CampaignSettings
from workbench.proving.cases import case_campaign, expected_verdict
from workbench.workflow.measured import measured_modes
from workbench.workflow.proving_validation import validation_specs

DEFAULT_CASES = (1, 16, 18, 19, 20, 22, 25, 26, 27, 28, 29, 30, 31, 32, 33, 34, 51, 52, 53, 54, 0, 12, 24, 36)
BASE = CampaignSettings()


def variant(name: str) -> CampaignSettings:
    """The measurement settings a variant's name gives: a quantity, or ``lines_DF`` (line spacing, Hz)."""
    if name.startswith("lines_"):
        return dataclasses.replace(BASE, df_hz=float(name.removeprefix("lines_")))
    return dataclasses.replace(BASE, quantity=name)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seed", type=int, default=17)
    parser.add_argument("--cases", type=int, nargs="+", default=list(DEFAULT_CASES))
    parser.add_argument("--variants", nargs="+", default=["receptance", "mobility"])
    args = parser.parse_args()
    specs = {s.case: s for s in validation_specs(max(args.cases) + 1, args.seed, "fixed")}
    names = ["accelerance", *args.variants]
    right = dict.fromkeys(names, 0)
    agree = dict.fromkeys(args.variants, 0)
    print(f"{'case':>4s} {'frame':<21s} {'effect (level)':<36s} " + " ".join(f"{n:<32s}" for n in names))
    for case in args.cases:
        spec = specs[case]
        verdicts = []
        for name in names:
            campaign, _ = case_campaign(spec, BASE if name == "accelerance" else variant(name))
            result = diagnose(campaign.frame, measured_modes(campaign, None, "diagnose"))
            verdicts.append((result.verdict, result.where, result.confidence))
            right[name] += result.verdict == expected_verdict(spec.kind)
        for name, v in zip(args.variants, verdicts[1:]):
            agree[name] += v[:2] == verdicts[0][:2]
        label = f"{spec.kind} ({spec.level or '-'})"
        cells = [f"{v} {w or '-'} {c:.2f}" for v, w, c in verdicts]
        print(f"{case:4d} {spec.frame:<21s} {label:<36s} " + " ".join(f"{cell:<32s}" for cell in cells), flush=True)
    n = len(args.cases)
    print("right verdict: " + ", ".join(f"{k} {v}/{n}" for k, v in right.items()))
    print("same verdict and place as accelerance: " + ", ".join(f"{k} {v}/{n}" for k, v in agree.items()))


if __name__ == "__main__":
    main()

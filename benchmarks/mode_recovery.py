"""How many of a proving-ground article's modes the extraction measures, as the diagnosis sees them.

For every fourth case of a validation mix (`workbench.workflow.proving_validation.validation_specs`), the
campaign's FRFs go through the circle fit (`workbench.workflow.measured.measured_modes`, the diagnosis's own
call) and each true mode below the band's top, in each test, counts as measured when a usable estimate of
that test lies within ``max(0.3 zeta, 0.2 %)`` of it (the truth: the generator's own eigen-solution of each
test's article, which the extraction never sees). Prints, per campaign, the modes lost in its first test
(frequency, damping, distance to the nearest other mode), then the share measured over all tests, and how many
usable estimates lie near no true mode (an extraction that measured more by making modes up would show there).

Run: ``python benchmarks/mode_recovery.py [SEED [CASES]]`` (default the development mix, seed 9001, 100 cases:
25 campaigns, about 2 minutes).
"""

from __future__ import annotations

import sys

import numpy as np

from workbench.proving.cases import case_campaign
from workbench.workflow.measured import measured_modes
from workbench.workflow.proving_validation import validation_specs


def main(seed: int = 9001, cases: int = 100) -> None:
    found = total = spurious = estimates = 0
    for spec in validation_specs(cases, seed, "fixed")[::4]:
        campaign, truth = case_campaign(spec)
        measured = measured_modes(campaign, None, "diagnose").frequency_hz
        lost = []
        for t, test in enumerate(truth["tests"]):
            f_true, zeta = np.array(test["frequency_hz"]), np.array(test["damping_ratio"])
            inside = f_true <= truth["f_max_hz"]
            row = measured[t][np.isfinite(measured[t])]
            for x in row:  # each usable estimate: near a true mode of its test?
                k = int(np.argmin(np.abs(f_true / x - 1.0)))
                spurious += bool(np.abs(f_true[k] / x - 1.0) >= max(0.3 * zeta[k], 0.002))
                estimates += 1
            for k in np.nonzero(inside)[0]:
                near = row.size > 0 and np.min(np.abs(row / f_true[k] - 1.0)) < max(0.3 * zeta[k], 0.002)
                found, total = found + bool(near), total + 1
                if not near and t == 0:
                    gap = np.min(np.abs(np.delete(f_true, k) / f_true[k] - 1.0))
                    lost.append(f"{f_true[k]:.0f} Hz ({100 * zeta[k]:.2f} %, next mode {100 * gap:.1f} % away)")
        in_band = int(np.sum(np.array(truth["tests"][0]["frequency_hz"]) <= truth["f_max_hz"]))
        print(f"case {spec.case:3d} {truth['frame']:22s} {in_band:2d} modes in band; lost in test 1: "
              f"{', '.join(lost) or '-'}", flush=True)
    print(f"measured: {found} of {total} (test, mode) pairs below the band's top, {100 * found / total:.1f} %; "
          f"usable estimates near no true mode: {spurious} of {estimates}")


if __name__ == "__main__":
    main(*(int(a) for a in sys.argv[1:3]))

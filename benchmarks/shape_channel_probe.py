"""Would mode shapes tell a named effect from an impostor? A probe for the diagnosis's next channel.

Run from the repository root: ``python benchmarks/shape_channel_probe.py [--seed 13] CASE ...`` (about 10 s a
case; default: seed 13's cases 34, 94, 106, 62 and 98).

For each proving-ground case of a validation seed's mix: the campaign is simulated and diagnosed blind as
`workbench validate-diagnosis` does, then the measured shapes (each mode's modal constants, made real and averaged
over the tests, `workbench.workflow.report_inputs.shape_comparison`) are compared by MAC with the nominal model's
and with the named candidate's model at its fitted parameters. Printed per measured mode: ``1 - MAC`` against
each (the pairing is by mode order, as the report's shape table does: a mode near 1 is one the sensors barely see
or a pairing the order gets wrong, on both models alike). The diagnosis does not use shapes today; where the named effect is right, its model should bring the
shapes closer, and where it is an impostor of another mechanism (an out-of-vocabulary crack or moved column named
a mass), it need not.
"""

from __future__ import annotations

import argparse
from dataclasses import replace

import numpy as np

from workbench.diagnose.verdict import diagnose, diagnosis_record
from workbench.model.frame import Frame
from workbench.model.structure import response_dofs, structure_of
from workbench.proving.cases import case_campaign
from workbench.rig.effects import EFFECTS, NONE, UNEXPLAINED, apply_effect
from workbench.workflow.measured import measured_modes
from workbench.workflow.proving_validation import validation_specs
from workbench.workflow.report_inputs import ShapeComparison, shape_comparison


def _paired(shapes: ShapeComparison) -> np.ndarray:
    """``1 - MAC`` of each measured mode with the model mode it is paired with."""
    return 1.0 - np.array([shapes.mac[k, shapes.paired[k]] for k in range(shapes.mac.shape[0])])


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("cases", nargs="*", type=int, default=[34, 94, 106, 62, 98])
    parser.add_argument("--seed", type=int, default=13)
    parser.add_argument("--mix", type=int, default=200, help="cases in the seed's mix (default 200)")
    args = parser.parse_args()
    specs = {s.case: s for s in validation_specs(args.mix, args.seed, "fixed")}
    np.set_printoptions(precision=4, suppress=True, linewidth=140)
    for case in args.cases:
        spec = specs[case]
        campaign, truth = case_campaign(spec)
        measured = measured_modes(campaign, None, "diagnose")
        sensors = measured.sensors or tuple(response_dofs(structure_of(campaign.frame))[2])
        result = diagnose(campaign.frame, measured)
        mechanism = (truth["primary"] or {}).get("mechanism", "")
        print(f"case {case} ({spec.frame}): {spec.kind} {mechanism} {spec.level} -> {result.verdict} {result.where}")
        nominal = shape_comparison(campaign, measured, sensors)
        if nominal is None:
            print("  no modal constants")
            continue
        print("  1 - MAC, nominal model:  ", _paired(nominal))
        if result.verdict in (NONE.name, UNEXPLAINED):
            continue
        entry = next(r for r in diagnosis_record(campaign.name, result)["ranking"]
                     if (r["effect"], r["where"]) == (result.verdict, result.where))
        assert isinstance(campaign.frame, Frame)  # the proving ground writes frame files
        named = apply_effect(campaign.frame, EFFECTS[result.verdict].from_fit(result.where, entry["parameters"]))
        candidate = shape_comparison(replace(campaign, frame=named), measured, sensors)
        if candidate is not None:
            print("  1 - MAC, named candidate:", _paired(candidate))


if __name__ == "__main__":
    main()

"""The diagnosis's candidate forms against mechanisms of the proving ground (another discretisation, another
code, nuisances on): a tie across a member and a dashpot across a joint, each named, placed and sized."""

from __future__ import annotations

import pytest

from workbench.diagnose.verdict import diagnose
from workbench.proving.cases import CaseSpec, case_campaign
from workbench.workflow.measured import measured_modes


def _diagnosed(spec: CaseSpec):
    campaign, truth = case_campaign(spec)
    return diagnose(campaign.frame, measured_modes(campaign, None, "diagnose")), truth


def test_a_tie_across_a_column_is_a_force_locked_in_between_its_ends():
    # a wire tie too short between the column's ends compresses it; the column's sway is not softened (the tie
    # turns with it), so a force carried by the frame misses the sway mode by five times its shift
    result, truth = _diagnosed(CaseSpec(0, 1, "one_bolt_horizontal", "axial_prestress", "large", "misfit_tie",
                                        "left_column"))
    assert (result.verdict, result.where) == ("axial_prestress", "left_column")
    named = next(c for c in result.ranking if c.effect == "axial_prestress")
    assert named.parameters["reaction"] == "chord"
    rod = truth["primary"]["parameters"]
    tie_force = rod["rod_axial_stiffness"] * rod["misfit_m"]  # the rod is far softer axially than the column
    assert named.parameters["axial_force"] == pytest.approx(tie_force, rel=0.1)


def test_a_dashpot_across_a_joint_is_named_as_viscous_joint_damping():
    result, _ = _diagnosed(CaseSpec(0, 1, "two_bolt", "joint_damping", "large", "joint_dashpot", "B"))
    assert (result.verdict, result.where) == ("joint_damping", "B")
    damping = [c for c in result.ranking if c.effect == "joint_damping" and c.where == "B"]
    assert damping[0].form == "viscous"

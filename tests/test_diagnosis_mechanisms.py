"""The diagnosis's candidate forms against mechanisms of the proving ground (another discretisation, another
code, nuisances on): a tie across a member, a dashpot across a joint and a clamp whose compliance couples
translation and rotation, each named, placed and sized."""

from __future__ import annotations

import numpy as np
import pytest

from workbench.diagnose.baseline import baseline
from workbench.diagnose.observations import observations
from workbench.diagnose.verdict import diagnose
from workbench.model.assembly import assemble
from workbench.model.structure import structure_modes
from workbench.proving.cases import CaseSpec, case_campaign
from workbench.rig.effects import Effect, apply_effect
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


@pytest.mark.slow
def test_a_dashpot_across_a_joint_is_named_as_viscous_joint_damping():
    result, _ = _diagnosed(CaseSpec(0, 1, "two_bolt", "joint_damping", "large", "joint_dashpot", "B"))
    assert (result.verdict, result.where) == ("joint_damping", "B")
    damping = [c for c in result.ranking if c.effect == "joint_damping" and c.where == "B"]
    assert damping[0].form == "viscous"


@pytest.mark.slow
def test_a_clamp_that_gives_way_in_rotation_and_translation_is_a_two_dof_support():
    # the proving ground's clamp: translational springs below the node and a rotational one, a 3x3 stiffness with
    # translation-rotation coupling, loosened as a whole. One spring at a time fits it worse than the rotational
    # and horizontal springs of that support fitted together, whose second parameter is charged in the score
    campaign, _ = case_campaign(CaseSpec(0, 1, "two_bolt", "support_compliance", "large", "coupled_support",
                                         "base_right"))
    measured = measured_modes(campaign, None, "diagnose")
    result = diagnose(campaign.frame, measured)
    assert (result.verdict, result.where) == ("support_compliance", "base_right")
    support = [c for c in result.ranking if c.effect == "support_compliance" and c.where == "base_right"]
    assert support[0].form == "rz+ux" and set(support[0].parameters) == {"rz", "ux"}
    rotation = next(c for c in support if c.form == "rz")
    assert support[0].heldout_score < rotation.heldout_score - 6.0  # "strong" on the BIC scale, the charge paid
    # the two springs' changes are added at first order: the frame with both springs, solved exactly, agrees
    # with the verdict's prediction to within the model floor (0.2 %) on every mode
    base = baseline(campaign.frame, observations(measured))
    both = apply_effect(campaign.frame, Effect("support_compliance", "base_right", support[0].parameters))
    exact = base.frequency(structure_modes(assemble(both), base.count).frequency_hz)
    assert result.best_hz is not None and np.nanmax(np.abs(result.best_hz / exact - 1.0)) < 2e-3

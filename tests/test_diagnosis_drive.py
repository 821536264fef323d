"""The shaker's drive as the diagnosis models it: a spring and the mass that moves with the drive point's dof.

Where the reference force is measured at the shaker, the stinger and the armature are part of what is measured:
the drive point's dynamic stiffness is ``k - omega^2 m`` on the drive's direction (the suspension's spring, the
moving mass). The closed forms check the model (Rayleigh's first-order share of ``omega^2``, a mass on one dof
against the same mass on both translations); the diagnosis is checked on the proving ground's stinger, a rod of
beam elements to an armature node on a suspension spring, which shares none of the candidate's code.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest
import scipy.sparse as sp

from workbench.diagnose.verdict import diagnose
from workbench.extraction.records import MeasuredModes
from workbench.model.assembly import assemble
from workbench.model.frame import DOF_NAMES, Frame
from workbench.model.frame_file import frame_to_toml
from workbench.model.modal import model_modes
from workbench.proving.article import Article
from workbench.proving.footprint import article_frequencies
from workbench.proving.frames import proving_frame
from workbench.proving.mechanisms import matrix3, vocabulary_mechanism
from workbench.rig.effects import ADDED_MASS, STINGER_STIFFNESS, apply_effect


def _drive_share(frame: Frame, changed: Frame) -> float:
    """The share of the fundamental's ``omega^2`` that ``changed`` takes from ``frame``."""
    before, after = (model_modes(assemble(f), 1).frequency_hz[0] for f in (frame, changed))
    return 1.0 - (after / before) ** 2


def test_a_moving_mass_takes_the_share_rayleigh_says_and_less_than_a_point_mass():
    """A small mass ``m`` on the drive dof ``d`` of the mass-normalised fundamental ``phi`` takes the share
    ``m phi_d^2`` of ``omega^2`` (first order); the same mass on both translations takes
    ``m (phi_x^2 + phi_y^2)``, at least as much.
    """
    frame = proving_frame("two_bolt")
    drive = frame.excitation
    assert drive is not None
    model = assemble(frame)
    phi = model.expand(model_modes(model, 1).shapes)[:, 0]
    node = model.mesh.point_node[drive.point]
    along, across = 3 * node + DOF_NAMES.index(drive.dof), 3 * node + 1 - DOF_NAMES.index(drive.dof)
    mass = 1e-3
    changed = apply_effect(frame, STINGER_STIFFNESS.effect(drive.point, dof=drive.dof, moving_mass=mass))
    moving = _drive_share(frame, changed)
    assert moving == pytest.approx(mass * phi[along] ** 2, rel=0.01)
    point = _drive_share(frame, apply_effect(frame, ADDED_MASS.effect(drive.point, mass=mass)))
    assert point == pytest.approx(mass * (phi[along] ** 2 + phi[across] ** 2), rel=0.01)
    assert point >= moving > 0.0
    # the fundamental hardly moves the drive point across the drive: the mass matrix says it is on one dof only
    added = sp.coo_matrix(assemble(changed).mass - model.mass)
    added.eliminate_zeros()
    assert added.nnz == 1 and added.data[0] == pytest.approx(mass)
    assert added.row[0] == added.col[0] == model.dof(drive.point, drive.dof)


def test_a_drive_with_neither_spring_nor_mass_is_refused():
    frame = proving_frame("two_bolt")
    assert frame.excitation is not None
    with pytest.raises(ValueError, match="stiffness, its moving_mass or both"):
        apply_effect(frame, STINGER_STIFFNESS.effect(frame.excitation.point, dof="ux"))


def test_a_frame_file_has_no_key_for_a_moving_mass():
    frame = proving_frame("two_bolt")
    drive = frame.excitation
    assert drive is not None
    changed = apply_effect(frame, STINGER_STIFFNESS.effect(drive.point, stiffness=1e3, moving_mass=0.002))
    with pytest.raises(ValueError, match="moving mass"):
        frame_to_toml(changed)
    assert "[[springs]]" in frame_to_toml(apply_effect(frame, STINGER_STIFFNESS.effect(drive.point, stiffness=1e3)))


@pytest.mark.parametrize("frame_name", ["two_bolt", "four_bolt"])
def test_the_diagnosis_names_a_stinger_whose_rod_and_armature_load_the_drive(frame_name):
    """The proving ground's stinger on a soft suspension (100 N/m) with a small modal shaker's armature (20 g):
    the steel rod and the armature move with the drive point and lower the frequencies as a mass there would, on
    the drive's direction only. The diagnosis names the stinger at the drive point in its two forms, its moving
    mass within 10 % of the rod's and the armature's: the lumped mass also takes up what differs between the
    article's elements and the model's, which the fit weighs more since the per-mode floor is 0.1 % (seed 25;
    6-8 % here, 5 % with the floor at 0.2 %).
    """
    armature = 0.02
    frame = replace(proving_frame(frame_name), beam_theory="timoshenko")
    frame = replace(frame, joints=tuple(replace(j, cov=0.0) for j in frame.joints))
    mechanism = vocabulary_mechanism(frame, STINGER_STIFFNESS.name, np.random.default_rng(4), variant="stinger_rod")
    suspension = 1e2
    truth = mechanism.parameters(suspension)
    rod = 7850.0 * np.pi * truth["rod_diameter_m"] ** 2 / 4 * truth["rod_length_m"]  # steel, as the rod is
    article = mechanism.build(Article(frame), suspension)
    shaker = article.attachments[-1]
    assert shaker.anchor == "_armature"
    article = replace(article, attachments=(*article.attachments[:-1],
                                            replace(shaker, mass=matrix3(np.diag([armature, armature, 0.0])))))
    exact = article_frequencies(article, 12)[:8]
    rng = np.random.default_rng(5)
    result = diagnose(frame, MeasuredModes(exact[None, :] * (1 + 2e-4 * rng.standard_normal((6, 8)))))
    assert frame.excitation is not None
    assert (result.verdict, result.where) == (STINGER_STIFFNESS.name, frame.excitation.point)
    named = next(c for c in result.ranking if c.effect == result.verdict)
    assert "moving_mass" in named.form and "stiffness" in named.form  # a candidate only with its spring
    assert named.parameters["moving_mass"] == pytest.approx(rod + armature, rel=0.1)

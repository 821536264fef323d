"""The frame's geometry: member ends moved (model), drawn as built (proving ground), carried to the modes
(the diagnosis's discrepancy), against the inverse-square law of a beam's bending frequencies."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
from conftest import CLAMP, REPO, straight_beam
from test_diagnosis import ONE_BOLT, _data, _deterministic

from workbench.cli import main
from workbench.diagnose.baseline import Baseline
from workbench.diagnose.geometry import geometry_columns, section_columns
from workbench.diagnose.observations import AREA_SD, GEOMETRY_SD, SECOND_MOMENT_SD, Allowance
from workbench.diagnose.verdict import diagnose, diagnosis_record
from workbench.model.assembly import assemble
from workbench.model.frame import member_ends, member_length, moved_frame, points_on_member
from workbench.model.modal import model_modes
from workbench.proving.article import Article
from workbench.proving.campaigns import CampaignSettings, _build
from workbench.proving.frames import proving_frame
from workbench.proving.nuisances import NuisanceSettings, streams
from workbench.rig.effects import Effect


def test_moved_frame_keeps_every_point_and_joint_at_its_fraction_of_the_member():
    frame = proving_frame("asymmetric_four_bolt")
    rng = np.random.default_rng(3)
    offsets = {n: tuple(1e-3 * rng.standard_normal(2)) for n in member_ends(frame)}
    moved, ratio = moved_frame(frame, offsets)
    for member in frame.members:
        old, new = member_length(frame, member), member_length(moved, member)
        assert abs(ratio[member.name] - new / old) < 1e-12
        assert abs(new / old - 1.0) > 1e-5  # every member did change
        before = points_on_member(frame.points, member)
        after = points_on_member(moved.points, member)
        assert before.keys() <= after.keys()  # nothing fell off its member
        for name, s in before.items():
            assert abs(after[name] / new - s / old) < 1e-9, name
    for j_old, j_new in zip(frame.joints, moved.joints):
        r = ratio[j_old.member]
        np.testing.assert_allclose(j_new.span, np.array(j_old.span) * r, rtol=1e-12)


def _cantilever_baseline(length: float) -> Baseline:
    frame = straight_beam(length, [{"point": "a", **CLAMP}])
    model = assemble(frame)
    modes = model_modes(model, 6)
    return Baseline(frame, model, modes, np.arange(6), np.ones(6), 6)


def test_geometry_columns_follow_the_inverse_square_law_of_a_cantilever():
    length, sd = 0.8, 5e-4
    base = _cantilever_baseline(length)
    columns = geometry_columns(base, sd)  # columns: a.x, a.y, b.x, b.y
    assert columns.shape == (6, 4)
    model = base.model
    ux = model.expand(base.modes.shapes)[0::3]
    axial = np.linalg.norm(ux, axis=0) > 1e-6 * np.linalg.norm(base.modes.shapes, axis=0)
    # f ~ 1 / L^2 in bending, 1 / L along the axis: a longer beam (free end moved along +x) is lower
    expected = np.where(axial, -1.0, -2.0) * sd / length
    np.testing.assert_allclose(columns[:, 2], expected, rtol=2e-3)
    np.testing.assert_allclose(columns[:, 0], -expected, rtol=2e-3)  # the clamp moved along +x: shorter
    assert np.all(np.abs(columns[:, [1, 3]]) < 1e-3 * np.abs(expected)[:, None])  # across the axis: second order


def test_section_columns_follow_a_beams_square_root_law():
    # bending: f ~ sqrt(E I / (rho A)), so dlog f = (dlog I - dlog A) / 2; along the axis f ~ sqrt(E A / (rho A))
    # moves with neither
    base = _cantilever_baseline(0.8)
    i_sd, a_sd = 0.01, 0.005
    columns = section_columns(base, i_sd, a_sd)  # columns: the one member's I, then its A
    assert columns.shape == (6, 2)
    ux = base.model.expand(base.modes.shapes)[0::3]
    axial = np.linalg.norm(ux, axis=0) > 1e-6 * np.linalg.norm(base.modes.shapes, axis=0)
    np.testing.assert_allclose(columns[~axial, 0], 0.5 * i_sd, rtol=1e-3)
    np.testing.assert_allclose(columns[~axial, 1], -0.5 * a_sd, rtol=1e-3)
    assert np.all(np.abs(columns[axial]) < 1e-6)
    assert section_columns(base, 0.0, 0.0) is None


def test_members_sharing_a_section_are_toleranced_apart():
    # the portal's three members share one section: a column's change must stay with its member, the beam
    # moving the modes it bends and not a leg's
    frame = _deterministic(ONE_BOLT)
    assert len({m.section for m in frame.members}) < len(frame.members)
    model = assemble(frame)
    modes = model_modes(model, 6)
    columns = section_columns(Baseline(frame, model, modes, np.arange(6), np.ones(6), 6))
    n = len(frame.members)
    assert columns.shape == (6, 2 * n)
    # the members' I columns add up to the whole frame's I changed at once (linear to the step)
    scaled = replace(frame, sections={k: replace(s, second_moment=s.second_moment * 1.0001)
                                      for k, s in frame.sections.items()})
    whole = model_modes(assemble(scaled), 6).frequency_hz / modes.frequency_hz - 1.0
    np.testing.assert_allclose(columns[:, :n].sum(axis=1) * 1e-4 / 0.01, whole, rtol=2e-3, atol=1e-9)
    assert np.ptp(columns[:, :n], axis=1).max() > 1e-3  # the members do not move the modes alike


def test_as_built_geometry_is_drawn_after_the_other_draws_of_the_article():
    article = Article(proving_frame("two_bolt"))
    on = CampaignSettings()
    off = replace(on, nuisances=replace(NuisanceSettings(), geometry_sd_range=(0.0, 0.0)))
    with_geometry, without = _build(article, on, streams(11)), _build(article, off, streams(11))
    assert with_geometry.record["manufacturing"]["materials"] == without.record["manufacturing"]["materials"]
    assert with_geometry.record["manufacturing"]["sections"] == without.record["manufacturing"]["sections"]
    assert with_geometry.record["damping"] == without.record["damping"]
    np.testing.assert_array_equal(with_geometry.snr_db, without.snr_db)
    offsets = with_geometry.record["manufacturing"]["geometry"]["point_offsets_m"]
    assert set(offsets) == set(member_ends(article.frame))
    sd = with_geometry.record["manufacturing"]["geometry"]["geometry_sd_m"]
    assert 0.0 <= sd <= 1e-3
    assert max(abs(v) for xy in offsets.values() for v in xy) < 6 * sd + 1e-15
    assert "geometry" not in without.record["manufacturing"]


def test_a_frame_whose_ends_are_known_worse_reads_its_gap_against_a_wider_allowance():
    # the rig's article (other code than the proving ground) with a softer joint: the same data read with the
    # member ends exact, at the default 0.5 mm, and at 2 mm; a wider positive term can only lower the chi-square
    frame = _deterministic(ONE_BOLT)
    data = _data(frame, Effect("joint_stiffness_shift", "A", {"factor": 0.8}), seed=3)
    chi2 = []
    for sd in (0.0, GEOMETRY_SD, 2e-3):
        result = diagnose(frame, data, allowance=Allowance(geometry_sd_m=sd))
        record = diagnosis_record("c", result)["discrepancy"]
        assert record["geometry_sd_m"] == sd
        assert (record["geometry_largest_mode_sd"] == 0.0) == (sd == 0.0)
        chi2.append(result.gaps["frequency"]["chi2"])
    assert chi2[0] > chi2[1] > chi2[2], chi2


def test_the_geometry_sd_is_refused_in_one_line_when_it_is_no_length(tmp_path, capsys):
    campaign = REPO / "campaigns" / "four_bolt_table6"
    for bad in ("-1e-3", "nan", "1"):
        assert main(["diagnose", str(campaign), f"--geometry-sd-m={bad}", "--out", str(tmp_path / "out")]) == 2
        err = capsys.readouterr().err
        assert "--geometry-sd-m: must be a standard deviation in metres" in err and err.count("\n") == 1
        assert not (tmp_path / "out").exists()


def test_sections_known_worse_read_the_gap_against_a_wider_allowance():
    # as the geometry's test: the same data with sections exact, at the default, and three times the default
    frame = _deterministic(ONE_BOLT)
    data = _data(frame, Effect("joint_stiffness_shift", "A", {"factor": 0.8}), seed=3)
    chi2 = []
    for sd in ((0.0, 0.0), (SECOND_MOMENT_SD, AREA_SD), (3 * SECOND_MOMENT_SD, 3 * AREA_SD)):
        result = diagnose(frame, data, allowance=Allowance(section_sd=sd))
        record = diagnosis_record("c", result)["discrepancy"]
        assert (record["section_second_moment_sd"], record["section_area_sd"]) == sd
        assert (record["section_largest_mode_sd"] == 0.0) == (sd == (0.0, 0.0))
        chi2.append(result.gaps["frequency"]["chi2"])
    assert chi2[0] > chi2[1] > chi2[2], chi2


def test_the_section_sd_is_refused_in_one_line_when_it_is_not_two_fractions(tmp_path, capsys):
    campaign = REPO / "campaigns" / "four_bolt_table6"
    for bad in ("0.01", "-0.01,0.005", "nan,0.005", "0.01,0.9", "a,b"):
        assert main(["diagnose", str(campaign), f"--section-sd={bad}", "--out", str(tmp_path / "out")]) == 2
        err = capsys.readouterr().err
        assert "--section-sd: must be two relative standard deviations" in err and err.count("\n") == 1
        assert not (tmp_path / "out").exists()


def test_a_validation_run_diagnoses_under_the_allowance_it_states():
    # `validate-diagnosis --geometry-sd-m 0 --section-sd 0,0`: every case's diagnosis takes the frame as exact,
    # and validation.json's levels say so
    from workbench.workflow.diagnosis import validate
    summary = validate(1, 4, allowance=Allowance(0.0, (0.0, 0.0)))  # one case (a quick one): levels are per run
    levels = summary["levels"]
    assert (levels["geometry_sd_m"], levels["section_second_moment_sd"], levels["section_area_sd"]) == (0, 0, 0)
    assert len(summary["results"]) == 1
    for result in summary["results"]:
        d = result.record["discrepancy"]
        assert d["geometry_sd_m"] == 0.0 and d["geometry_largest_mode_sd"] == 0.0
        assert d["section_largest_mode_sd"] == 0.0

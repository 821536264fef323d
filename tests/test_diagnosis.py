"""Gap diagnosis: each effect injected into exact data is found, placed and sized; none and unexplained hold."""

from __future__ import annotations

import csv
import io
import json
from dataclasses import replace

import numpy as np
import pytest
from conftest import REPO

from workbench.cli import main
from workbench.diagnose.observations import observations
from workbench.diagnose.verdict import GAP_RATIO, diagnose, diagnosis_record
from workbench.extraction.records import MeasuredModes
from workbench.model.assembly import assemble
from workbench.model.frame_file import read_frame
from workbench.model.modal import model_modes
from workbench.rig.effects import Effect, apply_effect

ONE_BOLT = REPO / "frames" / "one_bolt_vertical.toml"
TWO_BOLT = REPO / "frames" / "two_bolt.toml"


def _deterministic(path):
    frame = read_frame(path)
    return replace(frame, joints=tuple(replace(j, cov=0.0) for j in frame.joints))


def _data(frame, effect, seed=0, tests=6, noise=1e-4, count=8, amplitude=None, gamma_of=None):
    """Tests of the article ``apply_effect(frame, effect)`` with a common-mode joint scatter and noise."""
    rng = np.random.default_rng(seed)
    article = assemble(apply_effect(frame, effect))
    rows = []
    real = np.array([j.name in {k.name for k in frame.joints} for j in article.frame.joints])
    for t in range(tests):
        gamma = np.where(real, np.exp(0.01 * rng.standard_normal(real.size)), 1.0)  # a damaged zone does not scatter
        if gamma_of is not None:
            gamma = np.where(real, gamma * gamma_of(t), 1.0)
        f = model_modes(article, count, gamma).frequency_hz
        rows.append(f * (1 + noise * rng.standard_normal(count)))
    return MeasuredModes(np.array(rows), amplitude=amplitude)


def test_correlated_scatter_is_not_read_as_a_gap():
    # Tests whose frequencies move together (a joint scattering from test to test): the errors of
    # the means are correlated across modes. Weighted by their covariance, a chance scatter stays
    # under the gap threshold; weighted by the standard errors alone, it crosses it often.
    rng = np.random.default_rng(3)
    direction = np.linspace(1, 3, 8) * 1e-3
    full, diagonal = [], []
    for _ in range(300):
        common = rng.standard_normal((12, 1)) * direction + 2e-5 * rng.standard_normal((12, 8))
        obs = observations(MeasuredModes(100.0 * (1 + common)))
        r = np.full(8, 100.0) / obs.frequency_hz[0] - 1  # the model is the truth
        full.append(float(r @ np.linalg.inv(obs.frequency_cov[0]) @ r) / 8)
        diagonal.append(float(np.sum((r / (obs.frequency_se[0] / obs.frequency_hz[0])) ** 2)) / 8)
    assert np.mean(np.array(full) > GAP_RATIO) < 0.01
    assert np.mean(np.array(diagonal) > GAP_RATIO) > 0.05


def test_global_joint_shift_scales_every_joint():
    frame = read_frame(TWO_BOLT)
    shifted = apply_effect(frame, Effect("joint_stiffness_shift", None, {"factor": 0.5}))
    assert [j.youngs_modulus for j in shifted.joints] == [0.5 * j.youngs_modulus for j in frame.joints]
    one = apply_effect(frame, Effect("joint_stiffness_shift", "B", {"factor": 0.5}))
    assert [j.youngs_modulus for j in one.joints] == [frame.joints[0].youngs_modulus,
                                                      0.5 * frame.joints[1].youngs_modulus]


# each case takes 20-30 s: one stays in the default suite, the others run in CI's slow step
SLOW = pytest.mark.slow
CASES = [
    pytest.param(Effect("support_compliance", "base_left", {"rz": 900.0}), "rz", 900.0, 0.02,
                 id="support_compliance"),
    pytest.param(Effect("joint_stiffness_shift", "A", {"factor": 0.6}), "factor", 0.6, 0.02,
                 id="joint_stiffness_shift", marks=SLOW),
    pytest.param(Effect("axial_prestress", "beam", {"axial_force": 300.0}), "axial_force", 300.0, 0.05,
                 id="axial_prestress", marks=SLOW),
    pytest.param(Effect("stinger_stiffness", "drive", {"stiffness": 2e4, "dof": "ux"}), "stiffness", 2e4, 0.05,
                 id="stinger_stiffness", marks=SLOW),
]


@pytest.mark.parametrize("effect,name,value,tolerance", CASES)
def test_injected_effect_is_named_placed_and_sized(effect, name, value, tolerance):
    frame = _deterministic(ONE_BOLT)
    result = diagnose(frame, _data(frame, effect))
    assert (result.verdict, result.where) == (effect.type, effect.where)
    best = result.ranking[0]
    assert best.parameters[name] == pytest.approx(value, rel=tolerance)
    assert result.shrinkage > 0.9
    # the contract's definition, on the ranking's own numbers
    baseline_error = result.baseline.heldout_freq_rms_rel_error
    assert result.shrinkage == pytest.approx(1 - best.heldout_freq_rms_rel_error / baseline_error)


@SLOW
def test_added_mass_on_a_member_is_found_between_mesh_nodes():
    frame = _deterministic(ONE_BOLT)
    effect = Effect("added_mass", "right_column", {"mass": 0.05, "position": 0.437})
    result = diagnose(frame, _data(frame, effect))
    assert result.verdict == "added_mass"
    best = result.ranking[0]
    assert best.where == "right_column"
    assert best.parameters["position"] == pytest.approx(0.437, abs=0.01)
    assert best.parameters["mass"] == pytest.approx(0.05, rel=0.05)


@SLOW
def test_amplitude_softening_needs_two_amplitudes_and_is_told_from_a_shift():
    frame = _deterministic(ONE_BOLT)
    amplitude = np.array([1.0, 5.0] * 4)
    data = _data(frame, Effect(), tests=8, amplitude=amplitude, gamma_of=lambda t: 1 - 0.03 * amplitude[t])
    result = diagnose(frame, data)
    assert (result.verdict, result.where) == ("amplitude_softening", "A")
    assert result.ranking[0].parameters["slope"] == pytest.approx(0.03, rel=0.05)
    shift = next(c for c in result.ranking if c.effect == "joint_stiffness_shift" and c.where == "A")
    assert shift.heldout_chi2 > 10 * result.ranking[0].heldout_chi2


@SLOW
def test_no_effect_is_none_and_an_outside_effect_is_unexplained():
    frame = _deterministic(ONE_BOLT)
    assert diagnose(frame, _data(frame, Effect(), seed=5)).verdict == "none"
    crack = Effect("outside_vocabulary", "beam", {"span": [0.25, 0.29], "stiffness_factor": 0.3})
    result = diagnose(frame, _data(frame, crack))
    assert result.verdict == "unexplained"
    assert result.where is None and result.shrinkage == 0.0
    # localisation points at the cracked member's stiffness among the first regions
    assert "beam" in [r.region for r in result.localisation[:3]]


@SLOW
def test_joint_damping_is_found_on_damping_alone():
    frame = _deterministic(TWO_BOLT)
    model = assemble(frame)
    modes = model_modes(model, 8)
    from workbench.model.assembly import joint_energies

    rest, per_joint = joint_energies(model, modes.shapes)
    share_b = per_joint[1] / (rest + per_joint.sum(axis=0))
    data = _data(frame, Effect(), seed=2)
    rng = np.random.default_rng(0)
    zeta = 0.004 + 0.08 * share_b
    damping = zeta * (1 + 0.01 * rng.standard_normal(data.frequency_hz.shape))
    result = diagnose(frame, replace(data, damping_ratio=damping))
    assert (result.verdict, result.where) == ("joint_damping", "B")
    assert result.ranking[0].parameters["eta"] == pytest.approx(0.08, rel=0.05)


def test_record_follows_the_contract():
    frame = _deterministic(ONE_BOLT)
    result = diagnose(frame, _data(frame, Effect("joint_stiffness_shift", "A", {"factor": 1.5})))
    record = diagnosis_record("test", result)
    assert set(record) >= {"campaign", "baseline", "localization", "ranking", "verdict"}
    assert set(record["baseline"]) >= {"freq_rms_rel_error", "modes"}
    assert set(record["baseline"]["modes"][0]) == {"mode", "measured_hz", "model_hz", "rel_error"}
    m = record["baseline"]["modes"][0]
    assert m["rel_error"] == pytest.approx(m["model_hz"] / m["measured_hz"] - 1)
    scores = [r["score"] for r in record["localization"]]
    assert scores == sorted(scores, reverse=True) and all(0 <= s <= 1 for s in scores)
    for entry in record["ranking"]:
        assert set(entry) >= {"effect", "where", "parameters", "freq_rms_rel_error", "heldout_freq_rms_rel_error"}
    held = [e["heldout_chi2"] for e in record["ranking"]]
    assert held == sorted(held)
    assert set(record["verdict"]) == {"effect", "where", "shrinkage"}
    json.dumps(record)  # JSON-ready


def test_bad_data_is_refused_in_one_line():
    with pytest.raises(ValueError, match="frequency_hz"):
        MeasuredModes(np.full((3, 4), np.nan))
    with pytest.raises(ValueError, match="amplitude"):
        MeasuredModes(np.ones((3, 4)), amplitude=np.array([1.0, 2.0]))
    with pytest.raises(ValueError, match="damping_ratio"):
        MeasuredModes(np.ones((3, 4)), damping_ratio=np.ones((2, 4)))


@SLOW
def test_diagnose_command_writes_json_and_html(tmp_path, capsys):
    out = tmp_path / "diag"
    assert main(["diagnose", str(REPO / "campaigns" / "paper_table3_one_bolt_vertical"), "--out", str(out)]) == 0
    record = json.loads((out / "diagnosis.json").read_text())
    # the verdict must follow from the record's own ranking and gates (it used to be checked against
    # every possible answer, a test that could not fail)
    from workbench.diagnose.verdict import MIN_SHRINKAGE

    verdict, ranking = record["verdict"], record["ranking"]
    if verdict["effect"] == "none":
        assert verdict["where"] is None and verdict["shrinkage"] == 0.0
    elif verdict["effect"] == "unexplained":
        assert verdict["where"] is None and verdict["shrinkage"] == 0.0 and ranking
    else:
        assert (verdict["effect"], verdict["where"]) == (ranking[0]["effect"], ranking[0]["where"])
        assert verdict["shrinkage"] >= MIN_SHRINKAGE
        assert ranking[0]["heldout_freq_rms_rel_error"] < record["baseline"]["freq_rms_rel_error"]
    assert record["synthetic"] is False
    page = (out / "index.html").read_text()
    assert "Real measured data" in page and "http" not in page.split("<body>")[1]
    capsys.readouterr()
    assert main(["diagnose", str(tmp_path / "missing"), "--out", str(tmp_path / "o2")]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "missing" in err[0]
    assert not (tmp_path / "o2").exists() or not any((tmp_path / "o2").iterdir())


@SLOW
def test_one_blind_rig_case_from_frfs_through_the_circle_fit():
    from workbench.workflow.rig_cases import run_case

    result = run_case(read_frame(TWO_BOLT), "joint_stiffness_shift", seed=11)
    assert result.effect_right and result.place_right
    assert result.shrinkage > 0.6


def test_every_effect_of_the_registry_is_drawn_in_its_place():
    from workbench.rig.effects import EFFECTS
    from workbench.workflow.rig_cases import draw_effect

    frame = read_frame(TWO_BOLT)
    for name, kind in EFFECTS.items():
        effect = draw_effect(frame, name, np.random.default_rng(0))
        assert effect.type == name and set(effect.parameters) <= set(kind.keys)
        apply_effect(frame, effect)  # a place and parameters the frame accepts
    with pytest.raises(ValueError, match="unknown type"):
        draw_effect(frame, "unexplained", np.random.default_rng(0))


def test_validation_reports_progress_and_writes_its_files(monkeypatch, tmp_path):
    import workbench.workflow.diagnosis as workflow
    from workbench.workflow.rig_cases import CaseResult

    def fake_case(frame, kind, seed):
        right = kind == "none"
        return CaseResult(seed, kind, None, {"x": 1.0}, kind, "none", None, 0.0, right, None, 0.5, {})

    monkeypatch.setattr(workflow, "run_case", fake_case)
    calls = []
    summary = workflow.validate(3, 2, TWO_BOLT, progress=lambda *a: calls.append(a))
    assert calls == [("validation cases", 1, 3), ("validation cases", 2, 3), ("validation cases", 3, 3)]
    assert [r.seed for r in summary["results"]] == [200_006, 200_007, 200_008]
    assert summary["none_right"] == "1/1" and summary["cases"] == 3
    files = workflow.validation_files(summary)
    assert "results" not in json.loads(files["summary.json"])
    rows = list(csv.reader(io.StringIO(files["cases.csv"])))
    assert len(rows) == 4 and rows[1][:3] == ["200006", "none", ""]
    assert json.loads(rows[1][3]) == {"x": 1.0}


@pytest.mark.slow
def test_blind_validation_meets_the_issue_targets():
    from workbench.workflow.diagnosis import validate

    summary = validate(40, 1, TWO_BOLT)
    assert summary["top1_accuracy"] >= 0.85
    assert summary["place_accuracy"] >= 0.80
    assert summary["shrinkage_right_verdicts"]["median"] >= 0.60
    assert summary["none_right"].split("/")[0] == summary["none_right"].split("/")[1]
    assert summary["outside_right"].split("/")[0] == summary["outside_right"].split("/")[1]


def test_a_damping_gap_alone_never_names_a_frequency_effect():
    # issue 14: frequencies within scatter, damping well off; the best-ranked candidate is a
    # frequency effect that fits the noise. It may not be named: only a damping candidate, or unexplained.
    from workbench.diagnose.fitting import CandidateFit
    from workbench.diagnose.observations import Observations
    from workbench.diagnose.verdict import _verdict

    modes = 4
    f = np.full((1, modes), 100.0)
    obs = Observations(np.array([1.0]), f, np.full((1, modes), 0.01), np.tile(np.eye(modes) * 1e-8, (1, 1, 1)),
                       np.full((1, modes), 0.02), np.full((1, modes), 1e-4))

    def fit(effect, channel, chi2, heldout_f, heldout_d, rms_f, rms_d):
        return CandidateFit(effect, "A", {}, channel, chi2, heldout_f + heldout_d, heldout_f, heldout_d,
                            rms_f, rms_f, rms_d, rms_d, 1, chi2)

    baseline = fit("baseline", "frequency", 400.0 * modes, 1.0, 400.0 * modes, 1e-4, 0.01)
    shift = fit("joint_stiffness_shift", "frequency", 1.0, 0.5, 400.0 * modes, 5e-5, 0.01)
    damping = fit("joint_damping", "damping", 3.0, 1.0, 3.0, 1e-4, 1e-4)
    verdict, where, _, _, _, _ = _verdict(obs, f.copy(), baseline, [shift, damping],
                                          {("joint_stiffness_shift", "A"): f, ("joint_damping", "A"): f})
    assert (verdict, where) == ("joint_damping", "A")
    verdict, _, _, _, _, partial = _verdict(obs, f.copy(), baseline, [shift], {("joint_stiffness_shift", "A"): f})
    assert verdict == "unexplained" and partial is None  # nothing on the channel with the gap
    # a frequency gap the best candidate only narrows (held-out error 20 % smaller, under the 30 % to
    # be named): unexplained, with it as the partial explanation
    off = f * 1.001
    weak = fit("joint_stiffness_shift", "frequency", 500.0, 450.0, 0.0, 8e-4, 0.01)
    base_f = fit("baseline", "frequency", 800.0, 800.0, 0.0, 1e-3, 0.01)
    verdict, _, _, _, _, partial = _verdict(obs, off, base_f, [weak], {("joint_stiffness_shift", "A"): off})
    assert verdict == "unexplained"
    assert partial == {"effect": "joint_stiffness_shift", "where": "A", "shrinkage": pytest.approx(0.2)}

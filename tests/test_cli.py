"""The ``workbench`` command line: outputs as the contract says, exit 2 with one line on bad input."""

from __future__ import annotations

import csv
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from workbench.cli import main
from workbench.io.outputs import write_frame
from workbench.model.assembly import assemble
from workbench.model.generate import multibay_frame
from workbench.model.modal import model_modes


@pytest.fixture
def frame_file(tmp_path):
    frame = multibay_frame(1, 1, element_length=0.05)
    path = tmp_path / "frame.toml"
    write_frame(frame, path)
    return frame, path


def test_modes_writes_the_nominal_frequencies(frame_file, tmp_path, capsys):
    frame, path = frame_file
    assert main(["modes", str(path), "--count", "4", "--out", str(tmp_path / "out")]) == 0
    with open(tmp_path / "out" / "modes.csv", newline="") as f:
        rows = list(csv.DictReader(f))
    assert [r["mode"] for r in rows] == ["1", "2", "3", "4"] and list(rows[0]) == ["mode", "frequency_hz"]
    expected = model_modes(assemble(frame), 4).frequency_hz
    np.testing.assert_allclose([float(r["frequency_hz"]) for r in rows], expected, rtol=1e-14)
    assert "4 modes" in capsys.readouterr().out


def test_existing_output_is_replaced_only_with_force(frame_file, tmp_path, capsys):
    _, path = frame_file
    out = tmp_path / "out"
    assert main(["modes", str(path), "--count", "2", "--out", str(out)]) == 0
    before = (out / "modes.csv").read_text()
    assert main(["modes", str(path), "--count", "3", "--out", str(out)]) == 2
    err = capsys.readouterr().err
    assert "from an earlier run; pass --force" in err and err.count("\n") == 1
    assert (out / "modes.csv").read_text() == before
    assert main(["modes", str(path), "--count", "3", "--out", str(out), "--force"]) == 0
    assert len((out / "modes.csv").read_text().splitlines()) == 4
    assert not [p for p in out.iterdir() if p.name.startswith(".")]  # no temporary left behind


@pytest.mark.parametrize("args, message", [
    (["modes", "{missing}", "--out", "{out}"], "cannot read the frame file"),
    (["modes", "{bad}", "--out", "{out}"], "materials.al.density: must be positive"),
    (["modes", "{good}", "--count", "0", "--out", "{out}"], "--count: must be a positive integer"),
    (["modes", "{good}", "--count", "100000", "--out", "{out}"], "count: asked for 100000 modes"),
    (["modes", "{good}"], "the following arguments are required: --out"),
])
def test_bad_input_exits_2_with_one_line(frame_file, tmp_path, capsys, args, message):
    _, good = frame_file
    bad = tmp_path / "bad.toml"
    bad.write_text(good.read_text().replace("density = 2700.0", "density = -1.0").replace(
        "[materials.aluminium]", "[materials.al]").replace('material = "aluminium"', 'material = "al"'))
    paths = {"missing": tmp_path / "nope.toml", "bad": bad, "good": good, "out": tmp_path / "out"}
    assert main([a.format(**paths) for a in args]) == 2
    err = capsys.readouterr().err
    assert message in err and err.count("\n") == 1 and "Traceback" not in err
    assert not (tmp_path / "out").exists()


def test_console_entry_point_runs_as_a_module(frame_file, tmp_path):
    _, path = frame_file
    done = subprocess.run([sys.executable, "-m", "workbench.cli", "modes", str(path), "--out", str(tmp_path / "o")],
                          capture_output=True, text=True)
    assert done.returncode == 0, done.stderr
    assert (tmp_path / "o" / "modes.csv").exists()


def test_propagate_writes_moments_and_run_record(tmp_path):
    import json

    from workbench.uq.smr import adaptive
    from workbench.uq.stochastic import joint_model

    frame = multibay_frame(1, 1, element_length=0.05)
    path = tmp_path / "frame.toml"
    write_frame(frame, path)
    out = tmp_path / "out"
    assert main(["propagate", str(path), "--method", "adaptive", "--count", "4", "--out", str(out)]) == 0
    with open(out / "moments.csv", newline="") as f:
        rows = list(csv.DictReader(f))
    assert list(rows[0]) == ["mode", "mean_hz", "std_hz"] and len(rows) == 4
    model = assemble(frame)
    expected = adaptive(model, joint_model(frame), 4)
    np.testing.assert_allclose([float(r["std_hz"]) for r in rows], expected.std_hz, rtol=1e-12)
    run = json.loads((out / "run.json").read_text())
    assert run["method"] == "adaptive" and run["samples"] == 0 and run["wall_time_s"] > 0


def test_propagate_monte_carlo_is_seeded(tmp_path):
    frame = multibay_frame(1, 1, element_length=0.05)
    path = tmp_path / "frame.toml"
    write_frame(frame, path)
    texts = []
    for name in ("a", "b"):
        assert main(["propagate", str(path), "--method", "mc", "--samples", "30", "--seed", "9", "--count", "3",
                     "--out", str(tmp_path / name)]) == 0
        texts.append((tmp_path / name / "moments.csv").read_text())
    assert texts[0] == texts[1]


def test_propagate_refuses_a_frame_without_random_joints(tmp_path, capsys):
    frame = multibay_frame(1, 1, element_length=0.05)
    frame = frame.__class__(**{**frame.__dict__, "joints": ()})
    path = tmp_path / "frame.toml"
    write_frame(frame, path)
    assert main(["propagate", str(path), "--method", "smr1", "--out", str(tmp_path / "o")]) == 2
    assert "no joint has a cov > 0" in capsys.readouterr().err
    assert main(["propagate", str(path), "--method", "smr9", "--out", str(tmp_path / "o")]) == 2


def test_extract_finds_the_modes_the_rig_put_in(tmp_path):
    """Rig campaign -> workbench extract -> modes.csv against the rig's truth."""
    import json

    from conftest import REPO

    from workbench.io.campaign import Factor
    from workbench.model.frame_file import read_frame
    from workbench.rig.simulate import RigSettings, simulate_campaign, write_with_truth

    frame = read_frame(REPO / "frames" / "one_bolt_vertical.toml")
    factor = Factor("bolt_A", "tightening", {"1": "hand-tight", "3": "6000 N"}, "A")
    campaign, truth = simulate_campaign(frame, (factor,), [{"bolt_A": "1"}, {"bolt_A": "3"}], RigSettings(), seed=4)
    directory = tmp_path / "c"
    truth_file = write_with_truth(campaign, truth, directory)
    assert truth_file.parent == tmp_path  # beside the campaign, not inside
    assert main(["extract", str(directory), "--count", "9", "--out", str(tmp_path / "x")]) == 0
    with open(tmp_path / "x" / "modes.csv", newline="") as f:
        rows = list(csv.DictReader(f))
    assert list(rows[0])[:4] == ["test_id", "mode", "frequency_hz", "damping_ratio"] and len(rows) == 18
    truth = json.loads(truth_file.read_text())
    for test in truth["tests"]:
        got = np.array([float(r["frequency_hz"]) for r in rows if r["test_id"] == str(test["test_id"])])
        true = np.array(test["frequency_hz"][:9])
        np.testing.assert_allclose(got, true, rtol=1e-3)
    assert (tmp_path / "x" / "quality.csv").exists()


def test_extract_refuses_a_campaign_without_frfs(tmp_path, capsys):
    from conftest import REPO

    table3 = REPO / "campaigns" / "paper_table3_one_bolt_vertical"
    assert main(["extract", str(table3), "--out", str(tmp_path / "x")]) == 2
    assert "has no FRFs" in capsys.readouterr().err


def test_identify_moments_writes_the_contract_record(tmp_path):
    import json

    from conftest import REPO

    out = tmp_path / "id"
    assert main(["identify", str(REPO / "campaigns" / "paper_table3_one_bolt_vertical"), "--method", "moments",
                 "--out", str(out)]) == 0
    record = json.loads((out / "identification.json").read_text())
    assert set(record) == {"campaign", "method", "joints", "modes_used", "wall_time_s"}
    joint = record["joints"]["A"]
    assert set(joint) == {"youngs_modulus", "cov", "youngs_modulus_ci95", "cov_ci95"}
    assert 5e9 < joint["youngs_modulus"] < 30e9 and 0.01 < joint["cov"] < 0.3
    assert joint["cov_ci95"] is None  # published moments alone give no interval
    assert record["modes_used"] == list(range(1, 10))


def test_an_estimate_at_its_bound_fails_unless_allowed_and_then_is_flagged(tmp_path, capsys):
    # frequencies scattered 40 times more than Table 3's: no CoV inside the search interval explains them
    import json
    import shutil

    from conftest import REPO

    campaign = tmp_path / "scattered"
    shutil.copytree(REPO / "campaigns" / "paper_table3_one_bolt_vertical", campaign)
    lines = (campaign / "moments.csv").read_text().splitlines()
    header = lines[0].split(",")
    rows = [line.split(",") for line in lines[1:]]
    for row in rows:
        row[header.index("std_hz")] = repr(40 * float(row[header.index("std_hz")]))
    (campaign / "moments.csv").write_text("\n".join([lines[0], *(",".join(r) for r in rows)]) + "\n")
    before = {p.name: p.read_bytes() for p in campaign.iterdir()}
    out = tmp_path / "id"
    assert main(["identify", str(campaign), "--method", "moments", "--out", str(out)]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "joint 'A'" in err and "upper bound" in err and "--allow-bounds" in err
    assert not out.exists()
    assert main(["identify", str(campaign), "--method", "moments", "--out", str(out), "--allow-bounds"]) == 0
    joint = json.loads((out / "identification.json").read_text())["joints"]["A"]
    assert joint["at_bound"] is True and joint["cov"] == pytest.approx(0.4, rel=0.01)
    assert "warning" in capsys.readouterr().err
    assert {p.name: p.read_bytes() for p in campaign.iterdir()} == before


def test_the_bound_rule_reads_the_posterior_boxes_too():
    from types import SimpleNamespace

    from conftest import REPO

    from workbench.identify.likelihood import COV_BOUNDS, MODULUS_BOUNDS_PA
    from workbench.identify.record import bound_failures, identification_record
    from workbench.model.frame_file import read_frame

    frame = read_frame(REPO / "frames" / "two_bolt.toml")
    first, second = frame.joint_names[:2]
    entries = {first: {"youngs_modulus": 1.005e8, "cov": 0.1}, second: {"youngs_modulus": 3e10, "cov": 0.1}}
    entries.update({name: {"youngs_modulus": 3e10, "cov": 0.1} for name in frame.joint_names[2:]})
    fit = SimpleNamespace(joint_records=lambda: {k: dict(v) for k, v in entries.items()},
                          mean_box_pa=MODULUS_BOUNDS_PA, cov_box=COV_BOUNDS)
    record = identification_record("c", "bayes", frame, fit, [1, 2], 1.0)
    assert record["joints"][first]["at_bound"] is True and "at_bound" not in record["joints"][second]
    [failure] = bound_failures(record, fit)
    assert repr(first) in failure and "lower bound 1e+08 Pa" in failure


def test_identify_bayes_refuses_published_moments(tmp_path, capsys):
    from conftest import REPO

    assert main(["identify", str(REPO / "campaigns" / "paper_table3_one_bolt_vertical"), "--method", "bayes",
                 "--out", str(tmp_path / "id")]) == 2
    err = capsys.readouterr().err
    assert "only published moments" in err and err.count("\n") == 1
    assert not (tmp_path / "id").exists()


def test_demo_without_the_bundled_campaigns_exits_2_with_one_line(tmp_path, capsys):
    out = tmp_path / "demo"
    assert main(["demo", "--campaigns", str(tmp_path / "nowhere"), "--out", str(out)]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "bundled campaigns are not there" in err and "--campaigns" in err
    assert not out.exists()


@pytest.mark.slow
def test_demo_runs_the_main_job_from_the_repository_root(tmp_path):
    """`workbench demo` as the README runs it (fewer samples): one report, its time printed last."""
    from conftest import REPO

    out = tmp_path / "demo"
    done = subprocess.run([sys.executable, "-m", "workbench.cli", "demo", "--out", str(out), "--samples", "100",
                           "--steps", "400"], cwd=REPO, capture_output=True, text=True, timeout=600)
    assert done.returncode == 0, done.stderr
    names = sorted(p.name for p in out.iterdir())
    tables = [n for n in names if n != "index.html"]
    assert "index.html" in names and tables and all(n.startswith("tables_") and n.endswith(".csv") for n in tables)
    assert done.stdout.strip().endswith(" s") and "demo report written to" in done.stdout
    text = (out / "index.html").read_text(encoding="utf-8")
    # the page links every table it wrote beside itself, and nothing else sits there
    assert all(f'href="{n}"' in text for n in tables)
    for name in ("one_bolt_vertical_sweep", "one_bolt_horizontal_sweep", "two_bolt_table5", "four_bolt_table6"):
        assert name in text
    assert "SYNTHETIC - virtual test rig" in text and 'src="http' not in text
    # the demo replaces its own report without --force: a second run gets past the check of the output set, where
    # any other command refuses an earlier run's set (tests/test_bad_input.py), and fails here on the campaigns it is
    # pointed to, leaving the first report whole (a second whole demo cost 80 s of CI's slow step for this line)
    missing = tmp_path / "no_campaigns"
    again = subprocess.run([sys.executable, "-m", "workbench.cli", "demo", "--out", str(out), "--campaigns",
                            str(missing)], cwd=REPO, capture_output=True, text=True, timeout=600)
    assert again.returncode == 2 and again.stdout == "", again.stderr
    assert str(missing) in again.stderr and "--force" not in again.stderr and "--out" not in again.stderr
    assert (out / "index.html").read_text(encoding="utf-8") == text


def _modes_campaign(directory: Path, seed: int) -> Path:
    """The one-bolt sweep's campaign with modes.csv in place of its FRFs: frequencies drawn from the
    joint's Gamma law (test_bayes.synthetic), 0.05 % noise."""
    import shutil

    from conftest import REPO
    from test_bayes import ONE_BOLT, synthetic

    shutil.copytree(REPO / "campaigns" / "one_bolt_vertical_sweep", directory, ignore=shutil.ignore_patterns("frf.*"))
    _, data, _ = synthetic(ONE_BOLT, [24e9], [0.09], 9, 5e-4, seed, count=4)
    rows = [f"{t + 1},{k + 1},{float(f)!r},0.002" for t in range(9) for k, f in enumerate(data.frequency_hz[t])]
    (directory / "modes.csv").write_text("test_id,mode,frequency_hz,damping_ratio\n" + "\n".join(rows) + "\n")
    return directory


@pytest.mark.slow
def test_identify_bayes_fails_on_unconverged_chains_unless_allowed_and_then_reports_them(tmp_path, capsys):
    import json

    campaign = _modes_campaign(tmp_path / "c", 5)
    before = {p.name: p.read_bytes() for p in campaign.iterdir()}
    out = tmp_path / "id"
    short = ["--steps", "40", "--max-steps", "40"]  # far too short for 10 parameters: R-hat and ESS miss them
    assert main(["identify", str(campaign), "--method", "bayes", *short, "--out", str(out)]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "have not converged in 40 steps" in err and "--allow-bounds" in err
    assert not out.exists()
    assert main(["identify", str(campaign), "--method", "bayes", *short, "--allow-bounds", "--errors", "sensitivity",
                 "--out", str(out)]) == 0
    record = json.loads((out / "identification.json").read_text())
    assert record["diagnostics"]["converged"] is False and record["diagnostics"]["rhat_max"] > 1.01
    errors = record["errors"]
    assert set(errors) == {"measurement", "common_error", "discrepancy_scale", "discrepancy", "sensitivity"}
    assert list(errors["discrepancy"]) == list(errors["sensitivity"]) == ["mode1", "mode2", "mode3", "mode4"]
    for entry in (errors["common_error"], errors["discrepancy_scale"], *errors["measurement"].values()):
        assert 0 < entry["ci95"][0] <= entry["value"] <= entry["ci95"][1]
    for entry in (*errors["discrepancy"].values(), *errors["sensitivity"].values()):
        assert entry["ci95"][0] <= entry["value"] <= entry["ci95"][1]
    assert {p.name: p.read_bytes() for p in campaign.iterdir()} == before


def test_identify_leaves_out_a_mode_found_in_one_test_with_a_warning(tmp_path, capsys):
    """One mode the circle fit lost in all tests but one does not cost the campaign: it is left out with a
    warning, and the identification equals the one from the campaign without that mode."""
    import json

    campaign = _modes_campaign(tmp_path / "c", 6)
    lines = (campaign / "modes.csv").read_text().splitlines()
    full = [line for line in lines[1:] if line.split(",")[1] != "3"]
    kept = [line for line in lines[1:] if line.split(",")[1] != "3" or line.split(",")[0] == "1"]
    (campaign / "modes.csv").write_text("\n".join([lines[0], *kept]) + "\n")  # mode 3 in test 1 only
    assert main(["identify", str(campaign), "--method", "moments", "--out", str(tmp_path / "a")]) == 0
    err = capsys.readouterr().err
    assert "modes [3] were extracted in fewer than 2 tests: left out" in err
    record = json.loads((tmp_path / "a" / "identification.json").read_text())
    assert record["modes_used"] == [1, 2, 4]
    # against the campaign that never had mode 3 (renumbered: its modes are 1, 2, 4 of the model)
    (campaign / "modes.csv").write_text("\n".join([lines[0], *full]) + "\n")
    assert main(["identify", str(campaign), "--method", "moments", "--out", str(tmp_path / "b")]) == 0
    without = json.loads((tmp_path / "b" / "identification.json").read_text())
    assert without["modes_used"] == [1, 2, 4]
    assert record["joints"] == without["joints"]


def test_identify_tolerances_are_checked_before_any_work(tmp_path, capsys):
    campaign = _modes_campaign(tmp_path / "c", 6)
    for bad, says in ((["--method", "bayes", "--tolerances", "0.003,x"], "--tolerances: '0.003,x': could not convert"),
                      (["--method", "bayes", "--tolerances", "0.5"], "section_sd 0.5 is not in (0, 0.1]"),
                      (["--method", "moments", "--tolerances", "0.003"], "--tolerances needs --method bayes"),
                      (["--method", "bayes", "--errors", "sensitivity", "--tolerances", "0.003"],
                       "without the sensitivity term")):
        out = tmp_path / "id"
        assert main(["identify", str(campaign), *bad, "--out", str(out)]) == 2
        err = capsys.readouterr().err
        assert err.count("\n") == 1 and says in err, (bad, err)
        assert not out.exists()


@pytest.mark.slow
def test_identify_bayes_with_tolerances_reports_each_manufacturing_factor(tmp_path):
    import json

    from workbench.model.frame_file import read_frame

    campaign = _modes_campaign(tmp_path / "c", 7)
    out = tmp_path / "id"
    assert main(["identify", str(campaign), "--method", "bayes", "--steps", "40", "--max-steps", "40",
                 "--allow-bounds", "--tolerances", "0.003,0.01", "--out", str(out)]) == 0
    factors = json.loads((out / "identification.json").read_text())["errors"]["manufacturing"]
    frame = read_frame(campaign / "frame.toml")
    expected = [f"{m}.{q}" for m in frame.materials for q in ("youngs_modulus", "density")] + \
        [f"{m.name}.{q}" for m in frame.members for q in ("width", "thickness")]
    assert list(factors) == expected
    for entry in factors.values():  # log factors within a few prior sds of the drawing
        assert entry["ci95"][0] <= entry["value"] <= entry["ci95"][1] and abs(entry["value"]) < 0.05

"""`workbench extract` writes what the contract promises: modes.csv with its optional interval and flag
columns, shapes.csv with every sensor's modal constant, quality.csv; checked against the rig's truth
(frequencies and damping of each test) and against the model's own mode shapes at the test's moduli,
and read back as a campaign's modes.csv."""

from __future__ import annotations

import csv
import shutil

import numpy as np
import pytest
from conftest import REPO
from scipy.stats import binomtest

from workbench.cli import main
from workbench.extraction.circlefit import FLAGS
from workbench.io.campaign import Factor, load_campaign
from workbench.model.assembly import assemble
from workbench.model.frame_file import read_frame
from workbench.model.joints import model_at_moduli
from workbench.model.modal import mac, model_modes
from workbench.rig.simulate import RigSettings, simulate_campaign, write_with_truth


@pytest.fixture(scope="module")
def extracted(tmp_path_factory):
    tmp = tmp_path_factory.mktemp("extract")
    frame = read_frame(REPO / "frames" / "one_bolt_vertical.toml")
    factor = Factor("bolt_A", "tightening", {"1": "hand-tight", "2": "1800 N", "3": "6000 N"}, "A")
    campaign, truth = simulate_campaign(frame, (factor,), [{"bolt_A": v} for v in "123"], RigSettings(), seed=21)
    write_with_truth(campaign, truth, tmp / "c")
    assert main(["extract", str(tmp / "c"), "--count", "8", "--out", str(tmp / "x")]) == 0
    tables = {}
    for name in ("modes", "shapes", "quality"):
        with open(tmp / "x" / f"{name}.csv", newline="") as f:
            tables[name] = list(csv.DictReader(f))
    return tmp, frame, truth, tables


def test_modes_csv_has_the_contract_columns_and_intervals_that_hold_the_truth(extracted):
    _, _, truth, tables = extracted
    rows = tables["modes"]
    assert list(rows[0]) == ["test_id", "mode", "frequency_hz", "damping_ratio", "frequency_hz_ci95_low",
                             "frequency_hz_ci95_high", "damping_ratio_ci95_low", "damping_ratio_ci95_high", "flags"]
    inside_f, inside_z = [], []
    for test in truth["tests"]:
        mine = [r for r in rows if r["test_id"] == str(test["test_id"])]
        assert [int(r["mode"]) for r in mine] == list(range(1, 9))
        for r, f_true, z_true in zip(mine, test["frequency_hz"], test["damping_ratio"]):
            lo, f, hi = (float(r[k]) for k in ("frequency_hz_ci95_low", "frequency_hz", "frequency_hz_ci95_high"))
            zlo, z, zhi = (float(r[k]) for k in ("damping_ratio_ci95_low", "damping_ratio", "damping_ratio_ci95_high"))
            assert lo <= f <= hi and zlo <= z <= zhi
            assert all(flag in FLAGS for flag in r["flags"].split(";") if flag)
            inside_f.append(lo <= f_true <= hi)
            inside_z.append(zlo <= z_true <= zhi)
    # 24 intervals each: a 95 % interval that holds the truth fewer than 19 times is refused at 1 %
    for inside in (inside_f, inside_z):
        assert binomtest(sum(inside), len(inside), 0.95, alternative="less").pvalue > 0.01, sum(inside)


def test_shapes_csv_are_the_models_modes_at_the_tests_moduli(extracted):
    _, frame, truth, tables = extracted
    rows = tables["shapes"]
    assert list(rows[0]) == ["test_id", "mode", "sensor", "modal_constant_re", "modal_constant_im"]
    sensors = [s.name for s in frame.sensors]
    model = assemble(frame)
    dofs = np.array([model.dof(s.point, s.dof) for s in frame.sensors])
    drive = model.dof(frame.excitation.point, frame.excitation.dof)
    flags = {(r["test_id"], r["mode"], r["curve"]): r["flags"] for r in tables["quality"]}
    compared = 0
    for test in truth["tests"]:
        moved = model_at_moduli(model, np.array([test["moduli_pa"]["A"]]))
        modes = model_modes(moved, 8)
        expected = modes.shapes[dofs] * modes.shapes[drive]  # (sensors, modes), 1/kg
        got = np.zeros((len(sensors), 8), complex)
        usable = np.zeros((len(sensors), 8), bool)
        for r in rows:
            if r["test_id"] == str(test["test_id"]):
                i, k = sensors.index(r["sensor"]), int(r["mode"]) - 1
                got[i, k] = complex(float(r["modal_constant_re"]), float(r["modal_constant_im"]))
                # a curve whose circle is lost in noise or is no circle gives no constant to trust
                raised = set(flags[(r["test_id"], r["mode"], r["sensor"])].split(";"))
                usable[i, k] = not {"weak", "poor_circle"} & raised
        for k in range(8):
            if usable[:, k].sum() < 2:
                continue
            compared += 1
            # the rig's damping is proportional (real modes): the constants are the model's phi_s phi_e
            assert mac(got[usable[:, k], k:k + 1], expected[usable[:, k], k:k + 1])[0, 0] > 0.99, (test["test_id"], k)
            # the scale: each curve's constant is 2 zeta w D, so it carries that curve's damping error
            scale = np.linalg.norm(got[usable[:, k], k]) / np.linalg.norm(expected[usable[:, k], k])
            assert scale == pytest.approx(1.0, abs=0.1), (test["test_id"], k)
    assert compared >= 20  # of 24 test-modes


def test_modes_csv_with_its_optional_columns_reads_back_as_a_campaigns_modes(extracted, tmp_path):
    tmp, _, _, tables = extracted
    shutil.copytree(tmp / "c", tmp_path / "c")
    shutil.copy(tmp / "x" / "modes.csv", tmp_path / "c" / "modes.csv")
    campaign = load_campaign(tmp_path / "c")
    assert list(campaign.modes.columns) == ["test_id", "mode", "frequency_hz", "damping_ratio"]
    assert len(campaign.modes) == len(tables["modes"])

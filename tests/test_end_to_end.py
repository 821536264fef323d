"""The whole chain in one fast run: frame -> rig campaign -> extract -> identify -> report -> diagnose.

Each stage is the command a user runs, reading the files the stage before wrote; the checks are the
properties that tie the stages together (modes found where the rig put them, the identified joint
near the rig's law, a self-contained page, a contract diagnosis), not numbers of this code's own.
"""

from __future__ import annotations

import csv
import json

import numpy as np
import pytest
from conftest import REPO

from workbench.cli import main
from workbench.io.campaign import Factor, write_campaign
from workbench.model.frame_file import read_frame
from workbench.rig.simulate import RigSettings, simulate_campaign

PRELOADS_N = ("300", "1000", "2500", "6000")


@pytest.fixture(scope="module")
def chain(tmp_path_factory):
    root = tmp_path_factory.mktemp("chain")
    frame = read_frame(REPO / "frames" / "one_bolt_vertical.toml")
    factors = (Factor("bolt_A", "tightening", {k: f"preload {k} N" for k in PRELOADS_N}, "A"),)
    settings = RigSettings(f_max_hz=300.0, df_hz=0.25, mode_count=4)
    campaign, truth = simulate_campaign(frame, factors, [{"bolt_A": k} for k in PRELOADS_N], settings, seed=11)
    write_campaign(campaign, root / "campaign")
    return root, truth


def _run(*args: str) -> None:
    assert main(list(args)) == 0


def test_extract_finds_the_rig_modes(chain):
    root, truth = chain
    _run("extract", str(root / "campaign"), "--out", str(root / "extract"))
    with open(root / "extract" / "modes.csv") as handle:
        rows = list(csv.DictReader(handle))
    found = {(r["test_id"], int(r["mode"])): float(r["frequency_hz"]) for r in rows}
    for test, record in zip(sorted({r["test_id"] for r in rows}, key=int), truth["tests"]):
        true_hz = np.asarray(record["frequency_hz"])
        got = np.array([found.get((test, k + 1), np.nan) for k in range(true_hz.size)])
        seen = np.isfinite(got)
        assert seen.sum() >= 3
        np.testing.assert_allclose(got[seen], true_hz[: seen.size][seen], rtol=2e-3)


@pytest.mark.slow
def test_identify_report_and_diagnose_read_what_the_stage_before_wrote(chain):
    root, truth = chain
    _run("identify", str(root / "campaign"), "--method", "moments", "--out", str(root / "identify"))
    record = json.loads((root / "identify" / "identification.json").read_text())
    joint = record["joints"]["A"]
    assert 0.01 < joint["cov"] < 1.0 and 1e9 < joint["youngs_modulus"] < 1e12
    _run("report", str(root / "campaign"), "--no-bayes", "--samples", "40", "--out", str(root / "report"))
    page = (root / "report" / "index.html").read_text(encoding="utf-8")
    assert page.startswith("<!DOCTYPE html>") and "http://" not in page and "https://" not in page
    _run("diagnose", str(root / "campaign"), "--out", str(root / "diagnose"))
    diagnosis = json.loads((root / "diagnose" / "diagnosis.json").read_text())
    assert {"verdict", "baseline"} <= set(diagnosis)
    assert diagnosis["verdict"]["effect"]

"""The frame files of the paper's configurations: they load, hold the paper's joints, and the
calibrated one-bolt frame reproduces the measured Table 2 (issue 2 targets: RMS <= 2 %, max <= 4 %)."""

from __future__ import annotations

import csv
from dataclasses import replace

import numpy as np
import pytest
from conftest import REPO, shared_path

from workbench.model.assembly import assemble
from workbench.model.frame_file import frame_to_toml, read_frame
from workbench.model.modal import model_modes
from workbench.model.paper_frames import paper_frame

FRAMES = REPO / "frames"
JOINTS = {
    "monolithic": {},
    "one_bolt_vertical": {"A": "vertical"},
    "one_bolt_horizontal": {"B": "horizontal"},
    "two_bolt": {"A": "vertical", "B": "horizontal"},
    "four_bolt": {"L1": "vertical", "L2": "horizontal", "L3": "horizontal", "L4": "vertical"},
}
TABLE4 = {"vertical": (24e9, 0.09), "horizontal": (73.5e9, 0.22)}


@pytest.mark.parametrize("name", list(JOINTS))
def test_configuration_holds_the_papers_joints(name):
    frame = read_frame(FRAMES / f"{name}.toml")
    assert {j.name: j.group for j in frame.joints} == JOINTS[name]
    for joint in frame.joints:
        assert (joint.youngs_modulus, joint.cov) == TABLE4[joint.group]
    assert frame.excitation.point == "drive" and frame.points["drive"][1] == pytest.approx(0.115)
    assert len(frame.sensors) >= 3


def test_joints_lower_frequencies_below_the_monolithic_frame():
    mono = model_modes(assemble(read_frame(FRAMES / "monolithic.toml")), 10).frequency_hz
    four = model_modes(assemble(read_frame(FRAMES / "four_bolt.toml")), 10).frequency_hz
    vertical = model_modes(assemble(read_frame(FRAMES / "one_bolt_vertical.toml")), 10).frequency_hz
    assert np.all(vertical <= mono * (1 + 1e-12)) and np.all(four < mono)


def test_calibrated_one_bolt_frame_reproduces_table2():
    path = shared_path("paper", "table2_single_bolt_nominal.csv")
    with open(path, newline="") as f:
        measured = np.array([float(r["f_exp_hz"]) for r in csv.DictReader(f)])
    frame = read_frame(FRAMES / "one_bolt_vertical.toml")
    at_nominal = replace(frame, joints=tuple(replace(j, youngs_modulus=11.5e9) for j in frame.joints))
    ours = model_modes(assemble(at_nominal), measured.size).frequency_hz
    error = ours / measured - 1
    assert np.sqrt(np.mean(error**2)) <= 0.02
    assert np.abs(error).max() <= 0.04


@pytest.mark.parametrize("name", list(JOINTS))
def test_files_are_the_builders_output(name):
    # frames/*.toml are written by workbench.model.paper_frames (python frames/build_frames.py), which the proving
    # ground builds its bundled frames from: a file edited by hand, or a builder changed without them, fails here
    assert frame_to_toml(paper_frame(name)) == (FRAMES / f"{name}.toml").read_text(encoding="utf-8")

"""A matrix model through `propagate`: a frame written as Matrix Market and as OP4 files (through
scipy.io and pyyeti, not the frame's own assembly) gives the frame's moments by every method, and
the CLI takes it wherever it takes a frame file."""

from __future__ import annotations

import csv
from pathlib import Path

import numpy as np
import pytest

from workbench.cli import main
from workbench.io.matrix_export import write_matrix_model
from workbench.model.assembly import assemble
from workbench.model.frame_file import read_frame
from workbench.model.matrix_file import read_matrix_model
from workbench.model.structure import structure_energies, structure_frf, structure_modes
from workbench.uq.smr import propagate
from workbench.uq.stochastic import joint_model

REPO = Path(__file__).resolve().parents[1]
FRAME = REPO / "frames" / "four_bolt.toml"


@pytest.fixture(scope="module")
def exported(tmp_path_factory):
    root = tmp_path_factory.mktemp("matrix")
    frame = assemble(read_frame(FRAME))
    paths = {fmt: write_matrix_model(frame, root / fmt, fmt) for fmt in ("matrix-market", "op4")}
    return frame, paths


@pytest.mark.parametrize("fmt", ["matrix-market", "op4"])
def test_both_formats_give_the_frame_modes_and_joint_energies(exported, fmt):
    frame, paths = exported
    model = read_matrix_model(paths[fmt])
    assert model.joint_names == frame.joint_names and model.groups == frame.groups
    expected = structure_modes(frame, 10)
    got = structure_modes(model, 10)
    np.testing.assert_allclose(got.frequency_hz, expected.frequency_hz, rtol=1e-6)
    # lambda_kj (eq. 5) as quadratic forms on each joint's rows against the frame's element energies
    rest_f, joints_f = structure_energies(frame, expected.shapes)
    rest_m, joints_m = structure_energies(model, expected.shapes)
    scale = expected.eigenvalues
    np.testing.assert_allclose(rest_m / scale, rest_f / scale, atol=1e-6)
    np.testing.assert_allclose(joints_m / scale, joints_f / scale, atol=1e-6)
    # a joint's form on its own rows is the form on the whole matrix
    x = expected.shapes[:, :3]
    whole = np.einsum("ik,ik->k", x, model.stiffness_joints[1] @ x)
    np.testing.assert_allclose(structure_energies(model, x)[1][1], whole, rtol=1e-12)


@pytest.mark.parametrize("method", ["smr1", "smr2", "adaptive", "pert2", "mc"])
def test_every_method_gives_the_frame_moments(exported, method):
    frame, paths = exported
    model = read_matrix_model(paths["op4"])
    a = propagate(frame, joint_model(frame), method, 10, samples=300, seed=3)
    b = propagate(model, joint_model(model), method, 10, samples=300, seed=3)
    np.testing.assert_allclose(b.nominal_hz, a.nominal_hz, rtol=1e-6)
    np.testing.assert_allclose(b.mean_hz, a.mean_hz, rtol=1e-6)
    np.testing.assert_allclose(b.std_hz, a.std_hz, rtol=1e-5)


def test_the_frf_at_the_sensors_is_the_frame_frf(exported):
    frame, paths = exported
    model = read_matrix_model(paths["matrix-market"])
    axis = np.linspace(5.0, 400.0, 200)
    a = structure_frf(frame, structure_modes(frame, 12), axis, "mobility")
    b = structure_frf(model, structure_modes(model, 12), axis, "mobility")
    assert a.responses == b.responses
    np.testing.assert_allclose(np.abs(b.values), np.abs(a.values), rtol=1e-5)


def _moments(path: Path) -> np.ndarray:
    with open(path) as f:
        return np.array([[float(r["mean_hz"]), float(r["std_hz"])] for r in csv.DictReader(f)])


def test_the_command_line_propagates_a_matrix_model(exported, tmp_path):
    _, paths = exported
    for name, source in (("frame", FRAME), ("matrix", paths["matrix-market"])):
        assert main(["propagate", str(source), "--method", "smr2", "--out", str(tmp_path / name)]) == 0
    np.testing.assert_allclose(_moments(tmp_path / "matrix" / "moments.csv"),
                               _moments(tmp_path / "frame" / "moments.csv"), rtol=1e-6)

"""A campaign whose ``frame`` is a matrix model (CONTRACTS.md sections 2 and 4): loaded, written,
exported to and imported from UFF, extracted and identified exactly as the same campaign on the
frame file the matrices were exported from."""

from __future__ import annotations

import csv
import json
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from workbench.cli import main
from workbench.io.campaign import Factor, load_campaign, write_campaign
from workbench.io.matrix_export import write_matrix_model
from workbench.io.uff import export_frfs
from workbench.model.assembly import assemble
from workbench.model.frame_file import read_frame
from workbench.model.matrix_file import read_matrix_model
from workbench.model.matrix_model import MatrixModel
from workbench.rig.simulate import RigSettings, simulate_campaign

REPO = Path(__file__).resolve().parents[1]


@pytest.fixture(scope="module")
def campaigns(tmp_path_factory):
    """The same rig campaign twice: on the two-bolt frame file, and on that frame's matrices (OP4)."""
    root = tmp_path_factory.mktemp("campaigns")
    frame = read_frame(REPO / "frames" / "two_bolt.toml")
    factors = (Factor("bolt_A", "tightening", {"1": "hand-tight", "3": "6000 N"}, "A"),
               Factor("bolt_B", "tightening", {"1": "hand-tight", "3": "6000 N"}, "B"))
    design = [{"bolt_A": a, "bolt_B": b} for a in "13" for b in "13"]
    campaign, _ = simulate_campaign(frame, factors, design, RigSettings(), seed=11)
    write_campaign(campaign, root / "frame")
    model = read_matrix_model(write_matrix_model(assemble(frame), root / "matrices", "op4"))
    matrix = replace(campaign, frame=model, frame_file="model/model.toml")
    write_campaign(matrix, root / "matrix")
    return root / "frame", root / "matrix"


def test_a_matrix_campaign_is_written_with_its_model_and_loads_back(campaigns):
    _, matrix = campaigns
    assert sorted(p.name for p in (matrix / "model").iterdir()) == ["dofs.csv", "model.op4", "model.toml"]
    loaded = load_campaign(matrix)
    assert isinstance(loaded.frame, MatrixModel) and loaded.frame_file == "model/model.toml"
    assert loaded.frame.joint_names == ("A", "B") and len(loaded.frame.sensors) > 1


def _rows(path: Path) -> list[dict[str, str]]:
    with open(path, newline="") as f:
        return list(csv.DictReader(f))


@pytest.mark.slow
def test_extract_and_identify_give_the_frame_campaign_results(campaigns, tmp_path):
    frame, matrix = campaigns
    for name, source in (("f", frame), ("m", matrix)):
        assert main(["extract", str(source), "--count", "6", "--out", str(tmp_path / f"x{name}")]) == 0
        assert main(["identify", str(source), "--method", "moments", "--count", "6",
                     "--out", str(tmp_path / f"i{name}")]) == 0
    assert _rows(tmp_path / "xm" / "modes.csv") == _rows(tmp_path / "xf" / "modes.csv")
    a = json.loads((tmp_path / "if" / "identification.json").read_text())["joints"]
    b = json.loads((tmp_path / "im" / "identification.json").read_text())["joints"]
    for joint in ("A", "B"):
        for key in ("youngs_modulus", "cov"):
            assert b[joint][key] == pytest.approx(a[joint][key], rel=1e-6)


def test_uff_export_and_import_keep_the_matrix_model_nodes(campaigns, tmp_path):
    _, matrix = campaigns
    campaign = load_campaign(matrix)
    uff = export_frfs(campaign, tmp_path / "frfs.uff")
    model_toml = matrix / "model" / "model.toml"
    out = tmp_path / "imported"
    assert main(["import", str(uff), "--frame", str(model_toml), "--out", str(out)]) == 0
    back = load_campaign(out)
    assert isinstance(back.frame, MatrixModel) and (out / "model.toml").is_file() and (out / "model.op4").is_file()
    assert back.frf is not None and campaign.frf is not None
    keys = ["test_id", "sensor", "frequency_hz"]
    want = campaign.frf.astype({"test_id": str}).sort_values(keys).reset_index(drop=True)
    got = back.frf.astype({"test_id": str}).sort_values(keys).reset_index(drop=True)
    assert got[["test_id", "sensor"]].equals(want[["test_id", "sensor"]])
    for column in ("frequency_hz", "real", "imag"):
        np.testing.assert_allclose(got[column], want[column], rtol=1e-12, atol=0)

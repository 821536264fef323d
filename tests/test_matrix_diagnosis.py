"""The diagnosis on a matrix model (CONTRACTS.md section 3): the scikit-fem bracket of
examples/bolted_bracket, its tests made here with scipy (the mass added to the matrices by hand,
the joints scattered, noise on), never through the workbench's effects. The verdict names the
effect and the node, or the joint; the geometric effects are never candidates."""

from __future__ import annotations

import importlib.util
import json
from pathlib import Path

import numpy as np
import pytest
import scipy.sparse as sp
import scipy.sparse.linalg as spla

from workbench.cli import main
from workbench.diagnose.verdict import diagnose, diagnosis_record
from workbench.extraction.records import MeasuredModes
from workbench.model.matrix_file import read_matrix_model
from workbench.rig.effects import Effect, apply_matrix_effect

REPO = Path(__file__).resolve().parents[1]
GEOMETRIC = {"support_compliance", "shear_deformation", "axial_prestress"}


@pytest.fixture(scope="module")
def bracket(tmp_path_factory):
    """The bracket's model with deterministic joints (its file says CoV 0.15; these tests scatter 1 %)."""
    spec = importlib.util.spec_from_file_location("bracket_build", REPO / "examples" / "bolted_bracket" / "build.py")
    example = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(example)
    out = tmp_path_factory.mktemp("bracket")
    found, nodes, comps = example.matrices()
    example.write_model(out, found, nodes, comps)
    toml = out / "model_mtx" / "model.toml"
    toml.write_text(toml.read_text().replace("cov = 0.15", "cov = 0.0"))
    return read_matrix_model(toml), found, out


def _tests(found, mass=None, joint_factor=(1.0, 1.0), count=7, tests=8, seed=0):
    """Modes of ``tests`` assemblies by scipy's eigsh: joints scattered by 1 % about ``joint_factor``
    times the file's means, 0.01 % noise."""
    rng = np.random.default_rng(seed)
    m = found["M"] if mass is None else found["M"] + mass
    rows = []
    for _ in range(tests):
        g = np.array(joint_factor) * np.exp(0.01 * rng.standard_normal(2))
        k = found["K0"] + g[0] * found["KA"] + g[1] * found["KB"]
        lam = np.sort(spla.eigsh(k, k=count, M=m, sigma=0.0, which="LM", return_eigenvectors=False))
        rows.append(np.sqrt(lam) / (2 * np.pi) * (1 + 1e-4 * rng.standard_normal(count)))
    return MeasuredModes(np.array(rows), source="scipy tests")


@pytest.mark.slow
def test_a_mass_on_a_node_is_named_there(bracket):
    model, found, _ = bracket
    node = int(model.sensors[0].node)  # the arm's tip, where the shaker's sensor block sits
    rows = [model.dofs.find(node, c) for c in ("ux", "uy", "uz")]
    added = sp.csr_matrix((np.full(3, 0.15), (rows, rows)), shape=found["M"].shape)  # 150 g
    result = diagnose(model, _tests(found, mass=added))
    record = diagnosis_record("bracket + 150 g", result)
    assert not GEOMETRIC & {c["effect"] for c in record["ranking"]}
    assert record["verdict"]["effect"] == "added_mass"
    assert record["verdict"]["where"] == f"node {node}"
    assert record["ranking"][0]["parameters"]["mass"] == pytest.approx(0.15, rel=0.05)


@pytest.mark.slow
def test_a_softer_joint_is_named_and_the_nominal_model_gives_none(bracket):
    model, found, _ = bracket
    soft = diagnosis_record("bracket, joint B at 0.8", diagnose(model, _tests(found, joint_factor=(1.0, 0.8))))
    assert (soft["verdict"]["effect"], soft["verdict"]["where"]) == ("joint_stiffness_shift", "B")
    nominal = diagnosis_record("bracket", diagnose(model, _tests(found, seed=3)))
    assert nominal["verdict"]["effect"] == "none"


def test_matrix_effects_refuse_what_a_matrix_model_cannot_hold(bracket):
    model, _, _ = bracket
    with pytest.raises(ValueError, match="frame's geometry"):
        apply_matrix_effect(model, Effect("axial_prestress", "arm", {"axial_force": 100.0}))
    with pytest.raises(ValueError, match="not a node"):
        apply_matrix_effect(model, Effect("added_mass", "node 999999", {"mass": 1.0}))
    with pytest.raises(ValueError, match="not the excitation"):
        apply_matrix_effect(model, Effect("stinger_stiffness", f"node {model.sensors[3].node}", {"stiffness": 1e5}))


def test_a_matrix_models_drive_takes_its_moving_mass_on_the_excitation_dof_only(bracket):
    model, _, _ = bracket
    node = f"node {int(model.dofs.nodes[model.excitation])}"
    changed = apply_matrix_effect(model, Effect("stinger_stiffness", node, {"moving_mass": 0.01}))
    added = sp.csr_matrix(changed.mass - model.mass)
    assert added.nnz == 1 and added[model.excitation, model.excitation] == pytest.approx(0.01)
    assert (changed.stiffness_rest - model.stiffness_rest).count_nonzero() == 0


@pytest.mark.slow
def test_diagnose_runs_on_a_matrix_campaign(bracket, tmp_path):
    model, found, out = bracket
    campaign = tmp_path / "campaign"
    campaign.mkdir()
    for f in (out / "model_mtx").iterdir():
        (campaign / f.name).write_bytes(f.read_bytes())
    measured = _tests(found, joint_factor=(0.85, 1.0))
    lines = ["test_id,mode,frequency_hz,damping_ratio"]
    for t, row in enumerate(measured.frequency_hz):
        lines += [f"t{t},{k + 1},{f!r},0.01" for k, f in enumerate(row)]
    (campaign / "modes.csv").write_text("\n".join(lines) + "\n")
    (campaign / "design.csv").write_text("test_id,assembly\n" + "".join(f"t{t},{t}\n" for t in range(8)))
    levels = ", ".join(f'"{t}" = "assembly {t}"' for t in range(8))
    (campaign / "campaign.toml").write_text('name = "bracket"\nframe = "model.toml"\nsynthetic = true\n\n'
                                            f'[factors.assembly]\nkind = "other"\nlevels = {{ {levels} }}\n')
    assert main(["diagnose", str(campaign), "--out", str(tmp_path / "d")]) == 0
    record = json.loads((tmp_path / "d" / "diagnosis.json").read_text())
    assert (record["verdict"]["effect"], record["verdict"]["where"]) == ("joint_stiffness_shift", "A")
    assert (tmp_path / "d" / "index.html").is_file()

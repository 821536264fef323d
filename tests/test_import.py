"""`workbench import` (CONTRACTS.md section 3): a campaign from files as test software exports them.

The files here are written with pyuff directly, or as plain CSV, from the FRFs of the campaign in
../shared/examples (written by another program): not by the workbench's own exporter, so the import
is judged on files it did not make. The imported campaign then goes through `extract`, whose modes
are compared with the example's truth.
"""

from __future__ import annotations

import csv
import gc
import json
import shutil
import warnings

import numpy as np
import pytest
from conftest import EXAMPLE, REPO, digest, error_lines, run_cli, shared_path, tree

pyuff = pytest.importorskip("pyuff")

DIRECTIONS = {"ux": 1, "uy": 2, "rz": 6}


@pytest.fixture(scope="module")
def example():
    """The example's frame, its FRF rows by test (every sensor, up to 130 Hz: two modes) and its truth."""
    source = shared_path(EXAMPLE)
    rows: dict[str, list] = {}
    with (source / "frf.csv").open() as f:
        for r in csv.DictReader(f):
            if float(r["frequency_hz"]) <= 130.0:
                rows.setdefault(r["test_id"], []).append(r)
    truth = json.loads(shared_path(EXAMPLE + ".truth.json").read_text())
    return source / "frame.toml", rows, truth


def _write_uff(path, frame_path, rows, binary: bool):
    """One test's FRFs as a lab's software would export them: pyuff, the frame's node numbers (index + 1)."""
    import tomllib

    frame = tomllib.loads(frame_path.read_text())
    points = list(frame["points"])
    excitation = frame["excitation"]
    dsets = []
    for sensor in frame["sensors"]:
        mine = [r for r in rows if r["sensor"] == sensor["name"]]
        f = np.array([float(r["frequency_hz"]) for r in mine])
        h = np.array([float(r["real"]) + 1j * float(r["imag"]) for r in mine])
        dsets.append(pyuff.prepare_58(binary=int(binary), func_type=4, rsp_node=points.index(sensor["point"]) + 1,
                                      rsp_dir=DIRECTIONS[sensor["dof"]],
                                      ref_node=points.index(excitation["point"]) + 1,
                                      ref_dir=DIRECTIONS[excitation["dof"]], abscissa_spacing=1,
                                      abscissa_spec_data_type=18, ordinate_spec_data_type=12,
                                      orddenom_spec_data_type=13, data=h, x=f, id1="lab export"))
    # pyuff's binary writer erases the first header in "overwrite" mode and leaves its file handle to the
    # garbage collector (a ResourceWarning): append to an empty file and collect it here
    path.write_bytes(b"")
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", ResourceWarning)
        pyuff.UFF(str(path)).write_sets(dsets, mode="add")
        gc.collect()


@pytest.mark.parametrize("binary", [False, True], ids=["ascii", "binary"])
def test_uff_exports_import_and_extract_to_the_truth(tmp_path, example, binary):
    frame_path, rows, truth = example
    files = []
    for tid, test_rows in rows.items():
        files.append(tmp_path / f"run_{tid}.uff")
        _write_uff(files[-1], frame_path, test_rows, binary)
    (tmp_path / "design.csv").write_text("test_id,bolt_A\n" + "".join(
        f"run_{t['test_id']},{t['levels']['bolt_A']}\n" for t in truth["tests"]))
    before = digest([p for p in tree(tmp_path) if not p.name.startswith(".")])
    code, err = run_cli(["import", *map(str, files), "--frame", str(frame_path), "--design",
                         str(tmp_path / "design.csv"), "--out", str(tmp_path / "campaign")])
    assert code == 0, err
    assert digest([p for p in tree(tmp_path) if "campaign" not in p.parts and not p.name.startswith(".")]) == before
    toml = (tmp_path / "campaign" / "campaign.toml").read_text()
    assert 'quantity = "accelerance"' in toml and 'joint = "A"' in toml and "synthetic = false" in toml
    assert (tmp_path / "campaign" / "frame.toml").read_bytes() == frame_path.read_bytes()
    code, err = run_cli(["extract", str(tmp_path / "campaign"), "--out", str(tmp_path / "modes")])
    assert code == 0, err
    with (tmp_path / "modes" / "modes.csv").open() as f:
        found = {(r["test_id"], int(r["mode"])): float(r["frequency_hz"]) for r in csv.DictReader(f)}
    for test in truth["tests"]:
        for mode, exact in enumerate(test["frequency_hz"][:2], start=1):
            assert found[(f"run_{test['test_id']}", mode)] == pytest.approx(exact, rel=1e-3)


def test_csv_files_need_the_quantity_and_become_one_test_each(tmp_path, example):
    frame_path, rows, _ = example
    files = []
    for tid, test_rows in rows.items():
        files.append(tmp_path / f"t{tid}.csv")
        files[-1].write_text("sensor,frequency_hz,real,imag\n" + "".join(
            f"{r['sensor']},{r['frequency_hz']},{r['real']},{r['imag']}\n" for r in test_rows))
    args = ["import", *map(str, files), "--frame", str(frame_path), "--out", str(tmp_path / "c")]
    code, err = run_cli(args)
    assert code == 2 and "--quantity" in error_lines(err)[0]
    code, err = run_cli([*args, "--quantity", "accelerance"])
    assert code == 0, err
    design = (tmp_path / "c" / "design.csv").read_text().splitlines()
    assert design == ["test_id,test", *(f"t{tid},t{tid}" for tid in rows)]
    code, err = run_cli([*args, "--quantity", "accelerance"])  # its own earlier import: only with --force
    assert code == 2 and "--force" in err
    assert run_cli([*args, "--quantity", "accelerance", "--force"])[0] == 0


def test_import_never_replaces_a_campaign_it_did_not_write(tmp_path, example):
    frame_path, rows, _ = example
    real = tmp_path / "table5"
    shutil.copytree(REPO / "campaigns" / "paper_table3_one_bolt_vertical", real)
    (tmp_path / "a.csv").write_text("sensor,frequency_hz,real,imag\ns1,1.0,0.1,0.2\ns1,2.0,0.1,0.2\n")
    before = digest(tree(real))
    code, err = run_cli(["import", str(tmp_path / "a.csv"), "--frame", str(frame_path), "--quantity", "mobility",
                         "--out", str(real), "--force"])
    assert code == 2 and "campaign or model folder" in err
    assert digest(tree(real)) == before

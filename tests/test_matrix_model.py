"""Matrix models (CONTRACTS.md section 4): Matrix Market and OUTPUT4 files read to the same model, whose
frequencies match an independent dense eigen-solution, and every broken file refused in one line."""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest
import scipy.io as sio
import scipy.linalg as sla
import scipy.sparse as sp

from workbench.model import matrix_io
from workbench.model.assembly import assemble
from workbench.model.frame_file import read_frame
from workbench.model.matrix_file import is_matrix_model, read_matrix_model
from workbench.model.matrix_io import load_op4
from workbench.model.modal import model_modes
from workbench.model.structure import structure_modes

REPO = Path(__file__).resolve().parents[1]
N = 8  # dofs of the spring-mass chain
OP4_NAMES = {"mass": "MAA", "stiffness_rest": "KRR", "A": "KJA", "B": "KJB"}


# --- the fixture: a spring-mass chain with two joint springs ---------------------------------------

def chain_matrices() -> dict[str, np.ndarray]:
    """Masses on a line, springs between neighbours and to the ground at node 1; joints A and B are
    the springs 3-4 and 6-7 at their mean. The mass has neighbour coupling (a consistent-mass-like,
    non-diagonal matrix) so that a reader that drops off-diagonal entries is caught."""
    masses = 0.5 + 0.1 * np.arange(N)
    mass = np.diag(masses) + np.diag(np.full(N - 1, 0.02), 1) + np.diag(np.full(N - 1, 0.02), -1)
    springs = 1.0e4 * (1.0 + 0.3 * np.arange(N - 1))

    def spring(i: int, k: float) -> np.ndarray:
        a = np.zeros((N, N))
        a[i, i] = a[i + 1, i + 1] = k
        a[i, i + 1] = a[i + 1, i] = -k
        return a

    rest = sum(spring(i, k) for i, k in enumerate(springs) if i not in (2, 5))
    rest[0, 0] += 2.0e4  # ground spring
    return {"mass": mass, "stiffness_rest": rest, "A": spring(2, springs[2]), "B": spring(5, springs[5])}


def toml_text(data: dict) -> str:
    def value(v: object) -> str:
        if isinstance(v, str):
            return json.dumps(v)
        if isinstance(v, bool):
            return str(v).lower()
        if isinstance(v, float) and not math.isfinite(v):
            return "nan" if math.isnan(v) else ("inf" if v > 0 else "-inf")
        if isinstance(v, list):
            return "[" + ", ".join(value(x) for x in v) + "]"
        return repr(v)

    lines = [f"{k} = {value(v)}" for k, v in data.items() if not isinstance(v, (dict, list)) or
             (isinstance(v, list) and not any(isinstance(x, dict) for x in v))]
    for k, v in data.items():
        if isinstance(v, dict):
            lines += ["", f"[{k}]"] + [f"{kk} = {value(vv)}" for kk, vv in v.items()]
        elif isinstance(v, list) and any(isinstance(x, dict) for x in v):
            for table in v:
                lines += ["", f"[[{k}]]"] + [f"{kk} = {value(vv)}" for kk, vv in table.items()]
    return "\n".join(lines) + "\n"


def dofs_text(rows: list[tuple] | None = None, header: str = "index,node,component,x,y,z") -> str:
    rows = rows if rows is not None else [(i, i + 1, "ux", 0.1 * i, 0.0, 0.0) for i in range(N)]
    return header + "\n" + "".join(",".join(str(c) for c in r) + "\n" for r in rows)


def model_data(fmt: str) -> dict:
    op4 = fmt == "op4"
    data: dict = {"name": "spring-mass chain", "format": fmt}
    if op4:
        data["file"] = "model.op4"
    data |= {"mass": "Maa" if op4 else "M.mtx", "stiffness_rest": "KRR" if op4 else "K0.mtx", "dofs": "dofs.csv",
             "joints": [{"name": "A", "stiffness": "kja" if op4 else "KA.mtx", "youngs_modulus": 24e9, "cov": 0.09,
                         "group": "vertical"},
                        {"name": "B", "stiffness": "KJB" if op4 else "KB.mtx", "youngs_modulus": 73.5e9}],
             "excitation": {"node": 2, "component": "ux"},
             "sensors": [{"name": "s1", "node": 5, "component": "ux"}, {"name": "s8", "node": 8, "component": "ux"}],
             "damping": {"ratios": [0.01, 0.004]}}
    return data


MTX_FILES = {"mass": "M.mtx", "stiffness_rest": "K0.mtx", "A": "KA.mtx", "B": "KB.mtx"}


def write_model(root: Path, fmt: str = "matrix-market", *, binary: bool = True, layout: str = "dense",
                matrices: dict[str, np.ndarray] | None = None, data: dict | None = None) -> Path:
    """The chain as a model in ``root``: Matrix Market (one .mtx per matrix) or one op4 file
    (``layout`` dense, or bigmat / nonbigmat sparse columns; ASCII or binary)."""
    root.mkdir(parents=True, exist_ok=True)
    matrices = chain_matrices() if matrices is None else matrices
    if fmt == "op4":
        load_op4().write(str(root / "model.op4"), {OP4_NAMES[k]: a for k, a in matrices.items()},
                         binary=binary, sparse=layout)
    else:
        for key, a in matrices.items():
            sio.mmwrite(str(root / MTX_FILES[key]), sp.coo_matrix(a), precision=17)
    (root / "dofs.csv").write_text(dofs_text())
    path = root / "model.toml"
    path.write_text(toml_text(model_data(fmt) if data is None else data))
    return path


def dense_frequencies(matrices: dict[str, np.ndarray], gamma=(1.0, 1.0)) -> np.ndarray:
    k = matrices["stiffness_rest"] + gamma[0] * matrices["A"] + gamma[1] * matrices["B"]
    return np.sqrt(sla.eigh(k, matrices["mass"], eigvals_only=True)) / (2 * np.pi)


# --- valid models -----------------------------------------------------------------------------------

OP4_VARIANTS = [(binary, layout) for binary in (True, False) for layout in ("dense", "bigmat", "nonbigmat")]


@pytest.mark.parametrize("binary,layout", OP4_VARIANTS,
                         ids=[f"{'binary' if b else 'ascii'}-{s}" for b, s in OP4_VARIANTS])
def test_op4_and_matrix_market_give_the_dense_frequencies(tmp_path, binary, layout):
    expected = dense_frequencies(chain_matrices())
    for fmt in ("matrix-market", "op4"):
        model = read_matrix_model(write_model(tmp_path / fmt, fmt, binary=binary, layout=layout))
        got = structure_modes(model, N).frequency_hz
        np.testing.assert_allclose(got, expected, rtol=1e-10)
    gamma = np.array([0.6, 1.7])
    np.testing.assert_allclose(structure_modes(model, N, gamma).frequency_hz,
                               dense_frequencies(chain_matrices(), gamma), rtol=1e-10)


def test_the_record_holds_what_the_file_says(tmp_path):
    model = read_matrix_model(write_model(tmp_path))
    m = chain_matrices()
    assert model.name == "spring-mass chain" and model.format == "matrix-market" and model.size == N
    assert model.joint_names == ("A", "B") and model.groups == ("vertical", "B")
    np.testing.assert_array_equal(model.youngs_moduli, [24e9, 73.5e9])
    np.testing.assert_array_equal(model.covs, [0.09, 0.0])
    assert model.excitation == 1 and model.sensor_dofs == {"s1": 4, "s8": 7}
    assert model.damping_ratio(3) == (0.01, 0.004, 0.004)
    np.testing.assert_array_equal(model.dofs.nodes, np.arange(1, N + 1))
    np.testing.assert_allclose(model.dofs.coordinates[:, 0], 0.1 * np.arange(N))
    np.testing.assert_array_equal(model.mass.toarray(), m["mass"])
    gamma = np.array([0.5, 2.0])
    np.testing.assert_array_equal(model.stiffness(gamma).toarray(),
                                  m["stiffness_rest"] + 0.5 * m["A"] + 2.0 * m["B"])
    with pytest.raises(ValueError, match="gamma: expected 2 values"):
        model.stiffness(np.ones(3))
    with pytest.raises(ValueError, match="finite and positive"):
        model.stiffness(np.array([1.0, -1.0]))


def test_rows_in_any_order_and_no_coordinates(tmp_path):
    path = write_model(tmp_path)
    rows = [(i, i + 1, "ux") for i in range(N)][::-1]
    (tmp_path / "dofs.csv").write_text(dofs_text(rows, "index,node,component"))
    model = read_matrix_model(path)
    assert model.dofs.coordinates is None and model.dofs.find(3, "ux") == 2


def test_sparse_and_dense_solvers_agree(tmp_path):
    model = read_matrix_model(write_model(tmp_path))
    dense = structure_modes(model, 4, method="dense").frequency_hz
    np.testing.assert_allclose(structure_modes(model, 4, method="sparse").frequency_hz, dense, rtol=1e-9)


def test_is_matrix_model_tells_models_from_frames(tmp_path):
    path = write_model(tmp_path)
    assert is_matrix_model(path)
    assert not is_matrix_model(REPO / "frames" / "two_bolt.toml")
    assert not is_matrix_model(tmp_path / "absent.toml")
    data = model_data("matrix-market")
    del data["format"]
    path.write_text(toml_text(data))
    assert is_matrix_model(path)  # so that the missing key is reported by the matrix-model reader
    with pytest.raises(ValueError, match="format: required key is missing"):
        read_matrix_model(path)


@pytest.mark.parametrize("fmt", ["matrix-market", "op4"])
def test_a_frame_exported_as_matrices_has_the_frame_frequencies(tmp_path, fmt):
    frame = read_frame(REPO / "frames" / "two_bolt.toml")
    fm = assemble(frame)
    matrices = {"mass": fm.mass, "stiffness_rest": fm.stiffness_rest, "A": fm.stiffness_joints[0],
                "B": fm.stiffness_joints[1]}
    if fmt == "op4":
        load_op4().write(str(tmp_path / "model.op4"), {OP4_NAMES[k]: a for k, a in matrices.items()},
                         binary=True, sparse="bigmat")
    else:
        for key, a in matrices.items():
            sio.mmwrite(str(tmp_path / MTX_FILES[key]), a, precision=17)
    names = ("ux", "uy", "rz")
    xy = fm.mesh.node_xy[fm.free_dofs // 3]
    (tmp_path / "dofs.csv").write_text(dofs_text(
        [(i, d // 3 + 1, names[d % 3], x, y, 0.0) for i, (d, (x, y)) in enumerate(zip(fm.free_dofs, xy))]))
    data = model_data(fmt)
    data["joints"][1]["youngs_modulus"] = frame.joints[1].youngs_modulus
    data["excitation"] = {"node": int(fm.free_dofs[0] // 3 + 1), "component": names[fm.free_dofs[0] % 3]}
    data["sensors"] = []
    (tmp_path / "model.toml").write_text(toml_text(data))
    model = read_matrix_model(tmp_path / "model.toml")
    for gamma in (None, np.array([0.7, 1.4])):
        expected = model_modes(fm, 10, gamma).frequency_hz
        np.testing.assert_allclose(structure_modes(model, 10, gamma).frequency_hz, expected, rtol=1e-6)


# --- refusals -----------------------------------------------------------------------------------------

def edit_toml(change):
    def mutate(root: Path, fmt: str) -> None:
        data = model_data(fmt)
        change(data)
        (root / "model.toml").write_text(toml_text(data))
    return mutate


def edit_matrix(key: str, change):
    def mutate(root: Path, fmt: str) -> None:
        matrices = chain_matrices()
        matrices[key] = change(matrices[key].copy())
        write_model(root, fmt, matrices=matrices)
    return mutate


def edit_dofs(rows: list[tuple], header: str = "index,node,component,x,y,z"):
    return edit_file("dofs.csv", dofs_text(rows, header))


def edit_file(name: str, text: str | bytes):
    def mutate(root: Path, fmt: str) -> None:
        target = root / name
        target.write_bytes(text) if isinstance(text, bytes) else target.write_text(text)
    return mutate


def setitem(path: tuple, value):
    def change(data: dict) -> None:
        target = data
        for key in path[:-1]:
            target = target[key]
        if value is DELETE:
            del target[path[-1]]
        else:
            target[path[-1]] = value
    return change


DELETE = object()


def write_complex_joint(root: Path, fmt: str) -> None:
    m = chain_matrices()
    load_op4().write(str(root / "model.op4"), {"MAA": m["mass"], "KRR": m["stiffness_rest"],
                                               "KJA": m["A"] * (1 + 1e-3j), "KJB": m["B"]})


def non_square(a):
    return a[:, :-1]


def asymmetric(a):
    a[0, 1] += 1e-6 * np.abs(a).max()
    return a


def indefinite_mass(a):
    a[3, 4] = a[4, 3] = 2.0  # diagonal stays positive, the 2 x 2 block |0.8 2; 2 0.9| is indefinite
    return a


def with_value(i, j, v):
    def change(a):
        a[i, j] = v
        a[j, i] = v
        return a
    return change


def negative_joint(a):
    return -a


SPLIT_DOFS = [(i, i + 1, "ux", 0.1 * i, 0.0, 0.0) for i in range(N)]

# (id, format, mutation, file the message starts with, fragment)
REFUSALS = [
    ("missing-mass", "matrix-market", edit_toml(setitem(("mass",), DELETE)), "model.toml",
     "model.toml: mass: required key is missing"),
    ("missing-dofs", "matrix-market", edit_toml(setitem(("dofs",), DELETE)), "model.toml",
     "dofs: required key is missing"),
    ("unknown-key", "matrix-market", edit_toml(setitem(("masss",), "M.mtx")), "model.toml",
     "masss: unknown key"),
    ("unknown-format", "matrix-market", edit_toml(setitem(("format",), "hdf5")), "model.toml",
     "format: 'hdf5' is not one of matrix-market, op4"),
    ("missing-matrix-file", "matrix-market", edit_toml(setitem(("joints", 1, "stiffness"), "KX.mtx")), "model.toml",
     "joints[1].stiffness: file 'KX.mtx' not found"),
    ("missing-dofs-file", "matrix-market", edit_toml(setitem(("dofs",), "nodes.csv")), "model.toml",
     "dofs: file 'nodes.csv' not found"),
    ("op4-without-file", "op4", edit_toml(setitem(("file",), DELETE)), "model.toml",
     "file: required key is missing"),
    ("mtx-with-file", "matrix-market", edit_toml(setitem(("file",), "model.op4")), "model.toml",
     "file: only used with format = \"op4\""),
    ("op4-name-absent", "op4", edit_toml(setitem(("joints", 0, "stiffness"), "KJC")), "model.op4",
     "joints[0].stiffness ('KJC'): no matrix of that name in the file (it holds: maa, krr, kja, kjb)"),
    ("non-square-mtx", "matrix-market", edit_matrix("stiffness_rest", non_square), "K0.mtx",
     "stiffness_rest: not square (8 x 7)"),
    ("non-square-op4", "op4", edit_matrix("A", non_square), "model.op4", "joints[0].stiffness ('kja'): not square"),
    ("size-vs-dofs", "matrix-market", edit_dofs(SPLIT_DOFS + [(8, 9, "ux", 0, 0, 0)]),
     "M.mtx", "mass: 8 x 8, but dofs.csv has 9 rows"),
    ("size-vs-dofs-op4", "op4", edit_dofs(SPLIT_DOFS + [(8, 9, "ux", 0, 0, 0)]),
     "model.op4", "mass ('Maa'): 8 x 8, but dofs.csv has 9 rows"),
    ("asymmetric", "matrix-market", edit_matrix("stiffness_rest", asymmetric), "K0.mtx",
     "stiffness_rest: not symmetric: entry (0, 1) differs from its transpose by 1e-06 of the largest entry"),
    ("asymmetric-op4", "op4", edit_matrix("mass", asymmetric), "model.op4", "mass ('Maa'): not symmetric"),
    ("mass-indefinite", "matrix-market", edit_matrix("mass", indefinite_mass), "M.mtx",
     "mass: not positive definite: pivot"),
    ("mass-massless-dof", "matrix-market", edit_matrix("mass", with_value(5, 5, 0.0)), "M.mtx",
     "mass: not positive definite: diagonal entry of row 5 (node 6 ux) is 0"),
    ("joint-not-semidefinite", "matrix-market", edit_matrix("B", negative_joint), "KB.mtx",
     "joints[1].stiffness: not positive semi-definite: largest eigenvalue"),
    ("joint-all-zero", "matrix-market", edit_matrix("A", np.zeros_like), "KA.mtx",
     "joints[0].stiffness: the matrix is all zeros"),
    ("nan-entry", "matrix-market", edit_matrix("stiffness_rest", with_value(2, 2, math.nan)), "K0.mtx",
     "stiffness_rest: 1 non-finite entries (NaN or inf), the first at row 2, column 2"),
    ("inf-entry-op4", "op4", edit_matrix("mass", with_value(0, 1, math.inf)), "model.op4",
     "mass ('Maa'): 2 non-finite entries"),
    ("dofs-missing-column", "matrix-market", edit_file("dofs.csv", "index,node\n0,1\n"), "dofs.csv",
     "missing column(s) component"),
    ("dofs-unknown-column", "matrix-market", edit_dofs(SPLIT_DOFS, "index,node,component,x,y,w"),
     "dofs.csv", "unknown column(s) w"),
    ("dofs-partial-xyz", "matrix-market", edit_dofs([r[:4] for r in SPLIT_DOFS], "index,node,component,x"),
     "dofs.csv", "coordinates need all of x, y, z; missing y, z"),
    ("dofs-index-twice", "matrix-market", edit_dofs([(0, 1, "ux", 0, 0, 0)] + SPLIT_DOFS[:-1]),
     "dofs.csv", "line 3: index 0 already given on line 2"),
    ("dofs-index-range", "matrix-market", edit_dofs(SPLIT_DOFS[:-1] + [(8, 9, "ux", 0, 0, 0)]),
     "dofs.csv", "line 9: index 8 is outside 0..7"),
    ("dofs-component", "matrix-market", edit_dofs(SPLIT_DOFS[:-1] + [(7, 8, "uw", 0, 0, 0)]),
     "dofs.csv", "line 9: component 'uw' is not one of ux, uy, uz, rx, ry, rz"),
    ("dofs-node-not-integer", "matrix-market", edit_dofs([(0, 1.5, "ux", 0, 0, 0)] + SPLIT_DOFS[1:]),
     "dofs.csv", "line 2: node '1.5' is not an integer"),
    ("dofs-same-dof-twice", "matrix-market", edit_dofs(SPLIT_DOFS[:-1] + [(7, 7, "ux", 0, 0, 0)]),
     "dofs.csv", "line 9: node 7 component ux already given on line 8"),
    ("dofs-empty", "matrix-market", edit_file("dofs.csv", ""), "dofs.csv", "empty file"),
    ("excitation-node", "matrix-market", edit_toml(setitem(("excitation", "node"), 99)), "model.toml",
     "excitation.node: node 99 component 'ux' is not in dofs.csv (no dof of node 99)"),
    ("sensor-component", "matrix-market", edit_toml(setitem(("sensors", 1, "component"), "uz")), "model.toml",
     "sensors[1].node: node 8 component 'uz' is not in dofs.csv (node 8 has ux)"),
    ("sensor-bad-component", "matrix-market", edit_toml(setitem(("sensors", 0, "component"), "z")), "model.toml",
     "sensors[0].component: 'z' is not one of ux, uy, uz, rx, ry, rz"),
    ("sensor-duplicate", "matrix-market", edit_toml(setitem(("sensors", 1, "name"), "s1")), "model.toml",
     "sensors[1].name: duplicate sensor name 's1'"),
    ("cov-negative", "matrix-market", edit_toml(setitem(("joints", 0, "cov"), -0.1)), "model.toml",
     "joints[0].cov: must not be negative, got -0.1"),
    ("modulus-zero", "matrix-market", edit_toml(setitem(("joints", 1, "youngs_modulus"), 0.0)), "model.toml",
     "joints[1].youngs_modulus: must be positive, got 0"),
    ("modulus-nan", "matrix-market", edit_toml(setitem(("joints", 1, "youngs_modulus"), math.nan)), "model.toml",
     "joints[1].youngs_modulus: must be finite, got nan"),
    ("joint-duplicate", "matrix-market", edit_toml(setitem(("joints", 1, "name"), "A")), "model.toml",
     "joints[1].name: duplicate joint name 'A'"),
    ("damping", "matrix-market", edit_toml(setitem(("damping", "ratios"), [0.01, 1.5])), "model.toml",
     "damping.ratios[1]: must be below 1, got 1.5"),
    ("not-toml", "matrix-market", edit_file("model.toml", "name = \n"), "model.toml", "not valid TOML"),
    ("mtx-not-matrix-market", "matrix-market", edit_file("KA.mtx", "hello\n"), "KA.mtx",
     "joints[0].stiffness: not a Matrix Market file"),
    ("mtx-header-lies", "matrix-market",
     edit_file("K0.mtx", "%%MatrixMarket matrix coordinate real general\n8 8 1000000000000\n1 1 1\n"), "K0.mtx",
     "the header declares 1000000000000 entries but the file holds"),
    ("mtx-complex", "matrix-market",
     edit_file("K0.mtx", "%%MatrixMarket matrix coordinate complex general\n8 8 1\n1 1 1 0\n"), "K0.mtx",
     "stiffness_rest: a complex matrix; expected real entries"),
    ("op4-file-directory", "op4", edit_toml(setitem(("file",), ".")), "model.toml",
     "file: '.' is a directory, expected a file"),
    ("op4-complex", "op4", write_complex_joint, "model.op4", "joints[0].stiffness ('kja'): a complex matrix"),
    ("mtx-pattern", "matrix-market",
     edit_file("KA.mtx", "%%MatrixMarket matrix coordinate pattern symmetric\n8 8 1\n3 3\n"), "KA.mtx",
     "joints[0].stiffness: a pattern matrix; expected real entries"),
    ("dofs-short-row", "matrix-market", edit_dofs(SPLIT_DOFS[:-1] + [(7, 8, "ux", 0, 0)]), "dofs.csv",
     "line 9: 5 fields, the header has 6"),
    ("excitation-float-node", "matrix-market", edit_toml(setitem(("excitation", "node"), 2.0)), "model.toml",
     "excitation.node: expected an integer node number, got number 2.0"),
    ("mtx-cut-mid-number", "matrix-market",  # scipy 1.17's reader crashed the process on this one
     edit_file("K0.mtx", "%%MatrixMarket matrix coordinate real symmetric\n%\n8 8 13\n1 1 3.0000000000000000e"),
     "K0.mtx", "stiffness_rest: line 4: '1 1 3.0000000000000000e' is not a coordinate entry (row column value)"),
    ("mtx-hex-value", "matrix-market",  # scipy's reader reads a number's prefix and drops the rest
     edit_file("KB.mtx", "%%MatrixMarket matrix coordinate real general\n8 8 1\n6 6 0x10\n"),
     "KB.mtx", "joints[1].stiffness: line 3: '6 6 0x10' is not a coordinate entry"),
    ("mtx-truncated", "matrix-market",
     edit_file("KB.mtx", "%%MatrixMarket matrix coordinate real general\n8 8 4\n6 6 1\n7 7 1\n"),
     "KB.mtx", "joints[1].stiffness: unreadable Matrix Market data (ValueError: Truncated file"),
    ("op4-corrupt", "op4", edit_file("model.op4", b"\x00\x01" * 20), "model.op4", "file: not a readable OUTPUT4 file"),
]


@pytest.mark.parametrize("fmt,mutate,where,fragment", [r[1:] for r in REFUSALS], ids=[r[0] for r in REFUSALS])
def test_a_broken_model_is_refused_in_one_line(tmp_path, fmt, mutate, where, fragment):
    path = write_model(tmp_path, fmt)
    mutate(tmp_path, fmt)
    with pytest.raises(ValueError) as caught:
        read_matrix_model(path)
    message = str(caught.value)
    assert "\n" not in message
    assert message.startswith(str(tmp_path / where) + ":"), message
    assert fragment in message, message


def test_a_truncated_op4_file_is_refused(tmp_path):
    path = write_model(tmp_path, "op4", binary=True, layout="bigmat")
    data = (tmp_path / "model.op4").read_bytes()
    (tmp_path / "model.op4").write_bytes(data[: len(data) - 40])
    with pytest.raises(ValueError, match=r"model\.op4: file: not a readable OUTPUT4 file"):
        read_matrix_model(path)


def test_an_op4_name_given_twice_is_ambiguous(tmp_path):
    path = write_model(tmp_path, "op4")
    m = chain_matrices()
    load_op4().write(str(tmp_path / "model.op4"), ["MAA", "KRR", "KJA", "KJB", "KJB"],
                     [m["mass"], m["stiffness_rest"], m["A"], m["B"], m["B"]])
    with pytest.raises(ValueError, match=r"joints\[1\]\.stiffness \('KJB'\): 2 matrices of that name"):
        read_matrix_model(path)


def test_large_joint_supports_take_the_factorisation_path(tmp_path, monkeypatch):
    """Above DENSE_EIGEN_LIMIT rows the semi-definiteness test factors A + 1e-9 lambda_max I: it must
    accept a semi-definite joint and refuse one whose smallest eigenvalue is -1e-6 of the largest."""
    monkeypatch.setattr(matrix_io, "DENSE_EIGEN_LIMIT", 0)
    read_matrix_model(write_model(tmp_path / "good"))
    matrices = chain_matrices()
    largest = sla.eigvalsh(matrices["A"])[-1]
    matrices["A"][0, 0] -= 1e-6 * largest  # a node outside the spring: eigenvalue -1e-6 lambda_max
    with pytest.raises(ValueError, match=r"KA\.mtx: joints\[0\]\.stiffness: not positive semi-definite"):
        read_matrix_model(write_model(tmp_path / "bad", matrices=matrices))


def test_an_asymmetry_below_the_tolerance_is_accepted_and_symmetrised(tmp_path):
    matrices = chain_matrices()
    matrices["stiffness_rest"][0, 1] *= 1 + 1e-12
    model = read_matrix_model(write_model(tmp_path, matrices=matrices))
    k = model.stiffness_rest.toarray()
    np.testing.assert_array_equal(k, k.T)


def test_the_checks_leave_their_matrices_alone():
    """Stored zeros (an assembly's pattern) survive the checks: they must not compact the caller's arrays."""
    joint = chain_matrices()["A"]
    a = sp.csr_matrix(joint + np.eye(N))  # then the diagonal back to the joint's: six stored zeros
    for row in range(N):
        a.data[a.indptr[row] + list(a.indices[a.indptr[row]:a.indptr[row + 1]]).index(row)] = joint[row, row]
    assert a.nnz == 4 + 6 and np.array_equal(a.toarray(), joint)
    before = (a.data.copy(), a.indices.copy(), a.indptr.copy())
    checked = matrix_io.checked_matrix(a, "KA")
    matrix_io.check_semidefinite(checked, "KA")
    for got, kept in zip((a.data, a.indices, a.indptr), before):
        np.testing.assert_array_equal(got, kept)
    np.testing.assert_array_equal(checked.indptr, before[2])

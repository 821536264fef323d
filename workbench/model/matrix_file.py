"""Reading the matrix model file (``model.toml`` and its files, CONTRACTS.md section 4).

`read_matrix_model` validates everything the contract lists and raises `MatrixModelError` (a
ValueError) with one line naming the file, the key or matrix, and the problem. The cheap checks come
first (the TOML, dofs.csv, the excitation and sensors), the matrices last; within them, the header
before the data. Paths in the file are relative to its directory. Nothing is written.
"""

from __future__ import annotations

import csv
import math
import tomllib
from pathlib import Path
from typing import Any, NoReturn

import numpy as np
import scipy.sparse as sp

from workbench.model.frame import DEFAULT_DAMPING_RATIO
from workbench.model.matrix_io import (
    MatrixModelError,
    check_positive_definite,
    check_semidefinite,
    checked_matrix,
    read_mtx,
    read_op4,
)
from workbench.model.matrix_model import COMPONENTS, DofTable, MatrixJoint, MatrixModel, MatrixSensor

__all__ = ["FORMATS", "MatrixModelError", "read_matrix_model", "is_matrix_model", "read_dofs", "model_files"]

FORMATS = ("matrix-market", "op4")
_TOP_KEYS = {"name", "description", "format", "file", "mass", "stiffness_rest", "dofs", "joints", "excitation",
             "sensors", "damping"}
_TOP_REQUIRED = {"name", "format", "mass", "stiffness_rest", "dofs"}
# Keys only a matrix model has: a frame file (section 1) has none of them, and always has members.
_MATRIX_ONLY_KEYS = {"format", "mass", "stiffness_rest", "dofs"}
_DOF_COLUMNS = ("index", "node", "component")
_XYZ = ("x", "y", "z")


class _Table:
    """One TOML table of the model file; every error names the file and the key."""

    def __init__(self, source: str, where: str, table: Any, allowed: set[str], required: set[str]) -> None:
        self.source, self.where = source, where
        if not isinstance(table, dict):
            self.fail("", f"expected a table, got {_kind(table)}")
        unknown = sorted(set(table) - allowed)
        if unknown:
            self.fail(unknown[0], f"unknown key (allowed: {', '.join(sorted(allowed))})")
        for key in sorted(required):
            if key not in table:
                self.fail(key, "required key is missing")
        self.table: dict[str, Any] = table

    def fail(self, key: str, problem: str) -> NoReturn:
        field = ".".join(k for k in (self.where, key) if k)
        raise MatrixModelError(" ".join(f"{self.source}: {field or '(top)'}: {problem}".split()))

    def string(self, key: str, default: str | None = None) -> str:
        value = self.table.get(key, default)
        if not isinstance(value, str) or not value.strip():
            self.fail(key, f"expected a non-empty string, got {_kind(value)}")
        return value

    def number(self, key: str, default: float | None = None, *, positive: bool = False,
               below: float | None = None) -> float:
        return _number(self, key, self.table.get(key, default), positive=positive, below=below)

    def integer(self, key: str) -> int:
        value = self.table.get(key)
        if isinstance(value, bool) or not isinstance(value, int):
            self.fail(key, f"expected an integer node number, got {_kind(value)}")
        return value

    def tables(self, key: str) -> list[dict[str, Any]]:
        value = self.table.get(key, [])
        if not isinstance(value, list) or not all(isinstance(t, dict) for t in value):
            self.fail(key, f"expected an array of tables [[{key}]], got {_kind(value)}")
        return value


def _kind(value: Any) -> str:
    if isinstance(value, bool):
        return f"boolean {str(value).lower()}"
    if isinstance(value, (str, int, float)):
        return f"{'string' if isinstance(value, str) else 'number'} {value!r}"
    return "nothing" if value is None else type(value).__name__


def _number(t: _Table, key: str, value: Any, *, positive: bool = False, below: float | None = None) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        t.fail(key, f"expected a number, got {_kind(value)}")
    value = float(value)
    if not math.isfinite(value):
        t.fail(key, f"must be finite, got {value}")
    if positive and value <= 0.0:
        t.fail(key, f"must be positive, got {value:g}")
    if value < 0.0:
        t.fail(key, f"must not be negative, got {value:g}")
    if below is not None and value >= below:
        t.fail(key, f"must be below {below:g}, got {value:g}")
    return value


def is_matrix_model(path: str | Path) -> bool:
    """Whether ``path`` is a matrix model file (section 4) rather than a frame file (section 1).

    True for a TOML file with a ``format`` key, or with ``mass``, ``stiffness_rest`` or ``dofs`` and
    no ``members``: those keys belong to matrix models only, so a matrix model that lacks one of its
    required keys still reaches `read_matrix_model` and gets its message. False for anything else,
    unreadable files included (the frame reader then reports the problem).
    """
    try:
        data = tomllib.loads(Path(path).read_text(encoding="utf-8"))
    except (OSError, UnicodeDecodeError, tomllib.TOMLDecodeError):
        return False
    return "format" in data or (bool(_MATRIX_ONLY_KEYS & set(data)) and "members" not in data)


def read_matrix_model(path: str | Path) -> MatrixModel:
    """Read and validate a matrix model (CONTRACTS.md section 4).

    Parameters
    ----------
    path : the ``model.toml`` file; the files it names are relative to its directory. Only read.

    Returns
    -------
    MatrixModel
        Matrices on the rows of dofs.csv (mass kg, stiffnesses N/m), joints at their mean parameter.

    Raises
    ------
    MatrixModelError
        A ValueError with one line naming the file, the key or matrix, and the problem.
    """
    path = Path(path)
    try:
        data = tomllib.loads(path.read_text(encoding="utf-8"))
    except OSError as exc:
        raise MatrixModelError(f"{path}: cannot read the matrix model file: {exc.strerror or exc}") from None
    except UnicodeDecodeError:
        raise MatrixModelError(f"{path}: not a UTF-8 text file") from None
    except tomllib.TOMLDecodeError as exc:
        raise MatrixModelError(" ".join(f"{path}: not valid TOML: {exc}".split())) from None
    top = _Table(str(path), "", data, _TOP_KEYS, _TOP_REQUIRED)
    name = top.string("name")
    description = top.string("description") if "description" in data else ""
    fmt = top.string("format")
    if fmt not in FORMATS:
        top.fail("format", f"{fmt!r} is not one of {', '.join(FORMATS)}")
    if fmt == "matrix-market" and "file" in data:
        top.fail("file", "only used with format = \"op4\" (Matrix Market has one file per matrix)")
    if fmt == "op4" and "file" not in data:
        top.fail("file", "required key is missing (format = \"op4\" reads every matrix from one file)")
    joints, joint_files = _joints(top)
    sources = {"mass": top.string("mass"), "stiffness_rest": top.string("stiffness_rest"), **joint_files}
    dofs = read_dofs(_existing(top, "dofs", top.string("dofs")))
    excitation = _excitation(top, dofs)
    sensors = _sensors(top, dofs)
    damping = _damping(top)
    matrices = _matrices(top, fmt, sources, dofs)
    return MatrixModel(name, matrices["mass"], matrices["stiffness_rest"],
                       tuple(matrices[key] for key in joint_files), joints, dofs, excitation, sensors, damping,
                       description, fmt, str(path))


def model_files(path: str | Path) -> dict[str, Path]:
    """The files a valid ``model.toml`` names (dofs, matrices or the op4 file): name as written -> path.

    For copying a model beside a campaign: the names are relative to the model file's directory.
    """
    path = Path(path)
    data = tomllib.loads(path.read_text(encoding="utf-8"))
    names = [data["dofs"]] + ([data["file"]] if data.get("format") == "op4" else
                              [data["mass"], data["stiffness_rest"]] + [j["stiffness"] for j in data.get("joints", [])])
    return {str(name): path.parent / str(name) for name in names}


def _existing(top: _Table, key: str, name: str) -> Path:
    """The file named by ``key``, relative to the model file's directory; refused when absent."""
    target = Path(top.source).parent / name
    if target.is_dir():
        top.fail(key, f"{name!r} is a directory, expected a file ({target})")
    if not target.is_file():
        top.fail(key, f"file {name!r} not found ({target})")
    return target


def _joints(top: _Table) -> tuple[tuple[MatrixJoint, ...], dict[str, str]]:
    joints: list[MatrixJoint] = []
    files: dict[str, str] = {}
    for i, table in enumerate(top.tables("joints")):
        t = _Table(top.source, f"joints[{i}]", table, {"name", "stiffness", "youngs_modulus", "cov", "group"},
                   {"name", "stiffness", "youngs_modulus"})
        jname = t.string("name")
        if any(j.name == jname for j in joints):
            t.fail("name", f"duplicate joint name {jname!r}")
        files[f"joints[{i}].stiffness"] = t.string("stiffness")
        group = t.string("group") if "group" in table else jname
        joints.append(MatrixJoint(jname, t.number("youngs_modulus", positive=True), t.number("cov", 0.0), group))
    return tuple(joints), files


def _dof_of(t: _Table, dofs: DofTable) -> tuple[int, str, int]:
    node = t.integer("node")
    component = t.string("component")
    if component not in COMPONENTS:
        t.fail("component", f"{component!r} is not one of {', '.join(COMPONENTS)}")
    row = dofs.find(node, component)
    if row is None:
        present = dofs.node_components(node)
        t.fail("node", f"node {node} component {component!r} is not in dofs.csv ("
                       + (f"node {node} has {', '.join(present)})" if present else f"no dof of node {node})"))
    return node, component, row


def _excitation(top: _Table, dofs: DofTable) -> int | None:
    if "excitation" not in top.table:
        return None
    return _dof_of(_Table(top.source, "excitation", top.table["excitation"], {"node", "component"},
                          {"node", "component"}), dofs)[2]


def _sensors(top: _Table, dofs: DofTable) -> tuple[MatrixSensor, ...]:
    sensors: list[MatrixSensor] = []
    for i, table in enumerate(top.tables("sensors")):
        t = _Table(top.source, f"sensors[{i}]", table, {"name", "node", "component"}, {"name", "node", "component"})
        sname = t.string("name")
        if any(s.name == sname for s in sensors):
            t.fail("name", f"duplicate sensor name {sname!r}")
        sensors.append(MatrixSensor(sname, *_dof_of(t, dofs)))
    return tuple(sensors)


def _damping(top: _Table) -> tuple[float, ...]:
    if "damping" not in top.table:
        return (DEFAULT_DAMPING_RATIO,)
    t = _Table(top.source, "damping", top.table["damping"], {"ratios"}, {"ratios"})
    values = t.table["ratios"]
    if not isinstance(values, list) or not values:
        t.fail("ratios", f"expected a non-empty list of damping ratios, got {_kind(values)}")
    return tuple(_number(t, f"ratios[{k}]", v, below=1.0) for k, v in enumerate(values))


def _matrices(top: _Table, fmt: str, sources: dict[str, str], dofs: DofTable) -> dict[str, sp.csr_matrix]:
    """Every matrix, read and checked: square, one row per dof, finite, symmetric, mass definite, joints
    semi-definite.
    """
    n = dofs.size
    wheres: dict[str, str] = {}
    if fmt == "op4":
        op4_path = _existing(top, "file", top.string("file"))
        raw = read_op4(op4_path, sources, n)
        wheres = {key: f"{op4_path}: {key} ({name!r})" for key, name in sources.items()}
    else:
        raw = {}
        for key, name in sources.items():
            target = _existing(top, key, name)
            wheres[key] = f"{target}: {key}"
            raw[key] = read_mtx(target, wheres[key], n)
    matrices = {key: checked_matrix(a, wheres[key]) for key, a in raw.items()}
    check_positive_definite(matrices["mass"], wheres["mass"], dofs.label)
    for key in sources:
        if key.startswith("joints["):
            check_semidefinite(matrices[key], wheres[key])
    return matrices


def _dof_rows(path: Path) -> tuple[list[str], list[tuple[int, list[str]]]]:
    """Header and (line number, cells) of each non-blank row of dofs.csv."""
    lines: list[tuple[int, list[str]]] = []
    try:
        # utf-8-sig: spreadsheet programs start their CSV exports with a byte-order mark
        with path.open(newline="", encoding="utf-8-sig") as handle:
            reader = csv.reader(handle)
            for row in reader:
                lines.append((reader.line_num, row))
    except (OSError, UnicodeDecodeError, csv.Error) as exc:
        raise MatrixModelError(" ".join(f"{path}: cannot read the dof table: {exc}".split())) from None
    lines = [(num, [c.strip() for c in row]) for num, row in lines if any(c.strip() for c in row)]
    if not lines:
        raise MatrixModelError(f"{path}: empty file: expected columns {', '.join(_DOF_COLUMNS)}")
    return lines[0][1], lines[1:]


def _dof_columns(path: Path, header: list[str]) -> tuple[str, ...]:
    def bad(problem: str) -> NoReturn:
        raise MatrixModelError(f"{path}: {problem} (expected {', '.join(_DOF_COLUMNS)} and optionally x, y, z)")

    if len(set(header)) != len(header):
        bad(f"duplicated column {next(c for c in header if header.count(c) > 1)!r}")
    missing = [c for c in _DOF_COLUMNS if c not in header]
    if missing:
        bad(f"missing column(s) {', '.join(missing)}")
    unknown = [c for c in header if c not in _DOF_COLUMNS + _XYZ]
    if unknown:
        bad(f"unknown column(s) {', '.join(unknown)}")
    xyz = [c for c in _XYZ if c in header]
    if xyz and len(xyz) != 3:
        bad(f"coordinates need all of x, y, z; missing {', '.join(c for c in _XYZ if c not in header)}")
    return tuple(header)


def read_dofs(path: Path) -> DofTable:
    """Read and validate ``dofs.csv``: ``index`` 0..n-1 each once, integer ``node``, known ``component``.

    Parameters
    ----------
    path : the CSV file (columns ``index, node, component`` and optionally ``x, y, z`` in m).

    Returns
    -------
    DofTable
        Rows in matrix order (by ``index``).
    """
    header, rows = _dof_rows(path)
    columns = _dof_columns(path, header)
    n = len(rows)
    if n == 0:
        raise MatrixModelError(f"{path}: no rows: a matrix model needs at least one dof")
    nodes = np.zeros(n, np.int64)
    components = [""] * n
    xyz = np.zeros((n, 3)) if "x" in columns else None
    seen: dict[tuple[int, str], int] = {}
    line_of_index: dict[int, int] = {}
    for line, cells in rows:
        if len(cells) != len(columns):
            raise MatrixModelError(f"{path}: line {line}: {len(cells)} fields, the header has {len(columns)}")
        cell = dict(zip(columns, cells))
        index = _integer(path, line, "index", cell["index"])
        if not 0 <= index < n:
            raise MatrixModelError(f"{path}: line {line}: index {index} is outside 0..{n - 1} "
                                   f"(one row per matrix row, from 0)")
        if index in line_of_index:
            raise MatrixModelError(f"{path}: line {line}: index {index} already given on line {line_of_index[index]}")
        line_of_index[index] = line
        node = _integer(path, line, "node", cell["node"])
        component = cell["component"]
        if component not in COMPONENTS:
            raise MatrixModelError(f"{path}: line {line}: component {component!r} is not one of "
                                   f"{', '.join(COMPONENTS)}")
        if (node, component) in seen:
            raise MatrixModelError(f"{path}: line {line}: node {node} component {component} already given "
                                   f"on line {seen[node, component]}")
        seen[node, component] = line
        nodes[index], components[index] = node, component
        if xyz is not None:
            xyz[index] = [_coordinate(path, line, c, cell[c]) for c in _XYZ]
    return DofTable(nodes, tuple(components), xyz)


def _integer(path: Path, line: int, column: str, text: str) -> int:
    try:
        return int(text)
    except ValueError:
        raise MatrixModelError(f"{path}: line {line}: {column} {text!r} is not an integer") from None


def _coordinate(path: Path, line: int, column: str, text: str) -> float:
    try:
        value = float(text)
    except ValueError:
        raise MatrixModelError(f"{path}: line {line}: {column} {text!r} is not a number (m)") from None
    if not math.isfinite(value):
        raise MatrixModelError(f"{path}: line {line}: {column} must be finite, got {text}")
    return value

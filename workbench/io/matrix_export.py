"""A frame written as a matrix model (CONTRACTS.md section 4): the same structure for another program.

The assembled frame's matrices on its free dofs, one per joint at its mean modulus, in Matrix Market
files or one Nastran OUTPUT4 file, with ``dofs.csv`` and ``model.toml``. Node ``n + 1`` is the
frame's mesh node ``n`` (the contract's nodes are integers; the frame's named points are mesh nodes),
its components ``ux``, ``uy`` and ``rz``; sensors and the excitation keep their names. What it is
for: checking a matrix-model path against the frame it came from (both must give the same modes),
and handing a frame to a user's own FE tools.
"""

from __future__ import annotations

import io
import tempfile
from pathlib import Path

import numpy as np
import scipy.io as sio
import scipy.sparse as sp

from workbench.io.outputs import csv_text, write_outputs
from workbench.model.assembly import Model
from workbench.model.frame import DOF_NAMES
from workbench.model.frame_file import toml_string
from workbench.model.matrix_file import FORMATS
from workbench.model.matrix_io import load_op4

__all__ = ["matrix_model_files", "write_matrix_model"]

OP4_FILE = "model.op4"


def _mtx(matrix: sp.spmatrix) -> bytes:
    buffer = io.BytesIO()
    sio.mmwrite(buffer, sp.coo_matrix(matrix), symmetry="symmetric", precision=17)
    return buffer.getvalue()


def _op4(matrices: dict[str, sp.spmatrix]) -> bytes:
    # pyyeti writes to a path only; the bytes go through write_outputs like every other file
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / OP4_FILE
        load_op4().write(str(path), {k: sp.csc_matrix(a) for k, a in matrices.items()}, binary=True, sparse="bigmat")
        return path.read_bytes()


def _node(model: Model, point: str, dof: str) -> tuple[int, str]:
    model.dof(point, dof)  # refuses a fixed support dof
    return model.mesh.point_node[point] + 1, dof


def matrix_model_files(model: Model, fmt: str = "matrix-market") -> dict[str, str | bytes]:
    """The files of ``model`` as a matrix model: name -> content (``model.toml`` names the others).

    Parameters
    ----------
    model : an assembled frame.
    fmt : ``"matrix-market"`` (``M.mtx``, ``K0.mtx``, ``K_<joint>.mtx``) or ``"op4"`` (``model.op4``
        holding ``MAA``, ``KAA`` and ``KJ<n>``, one per joint in the frame's order).
    """
    if fmt not in FORMATS:
        raise ValueError(f"format: {fmt!r} is not one of {', '.join(FORMATS)}")
    frame = model.frame
    names = {"mass": "MAA", "stiffness_rest": "KAA"} if fmt == "op4" else {"mass": "M.mtx", "stiffness_rest": "K0.mtx"}
    joint_names = [f"KJ{i + 1}" if fmt == "op4" else f"K_{j.name}.mtx" for i, j in enumerate(frame.joints)]
    matrices = {names["mass"]: model.mass, names["stiffness_rest"]: model.stiffness_rest,
                **dict(zip(joint_names, model.stiffness_joints))}
    files: dict[str, str | bytes] = ({OP4_FILE: _op4(matrices)} if fmt == "op4"
                                     else {name: _mtx(a) for name, a in matrices.items()})
    nodes = model.free_dofs // 3
    xy = model.mesh.node_xy[nodes]
    files["dofs.csv"] = csv_text(["index", "node", "component", "x", "y", "z"],
                                 ((i, int(n) + 1, DOF_NAMES[d % 3], float(x), float(y), 0.0)
                                  for i, (n, d, (x, y)) in enumerate(zip(nodes, model.free_dofs, xy))))
    lines = [f"name = {toml_string(frame.name)}", f"description = {toml_string('exported from ' + frame.source)}",
             f"format = {toml_string(fmt)}"]
    if fmt == "op4":
        lines.append(f"file = {toml_string(OP4_FILE)}")
    lines += [f"mass = {toml_string(names['mass'])}", f"stiffness_rest = {toml_string(names['stiffness_rest'])}",
              'dofs = "dofs.csv"']
    for joint, file in zip(frame.joints, joint_names):
        lines += ["", "[[joints]]", f"name = {toml_string(joint.name)}", f"stiffness = {toml_string(file)}",
                  f"youngs_modulus = {joint.youngs_modulus!r}", f"cov = {joint.cov!r}",
                  f"group = {toml_string(joint.group)}"]
    if frame.excitation is not None:
        node, comp = _node(model, frame.excitation.point, frame.excitation.dof)
        lines += ["", "[excitation]", f"node = {node}", f"component = {toml_string(comp)}"]
    for sensor in frame.sensors:
        node, comp = _node(model, sensor.point, sensor.dof)
        lines += ["", "[[sensors]]", f"name = {toml_string(sensor.name)}", f"node = {node}",
                  f"component = {toml_string(comp)}"]
    ratios = ", ".join(repr(float(r)) for r in np.atleast_1d(frame.damping_ratios))
    lines += ["", "[damping]", f"ratios = [{ratios}]"]
    files["model.toml"] = "\n".join(lines) + "\n"
    return files


def write_matrix_model(model: Model, directory: str | Path, fmt: str = "matrix-market",
                       force: bool = False) -> Path:
    """Write ``model`` as a matrix model into ``directory`` (all files or none); returns ``model.toml``'s path."""
    write_outputs(directory, matrix_model_files(model, fmt), force=force)
    return Path(directory) / "model.toml"

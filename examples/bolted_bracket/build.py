"""A 3-D bolted bracket built with scikit-fem, written as a matrix model (Matrix Market and OP4) and
a synthetic 30-test campaign on it: a model that is not a planar frame, made by another FE code.

The bracket is an L of steel bars meshed with trilinear hexahedra: a column clamped at its base and
an arm across its top, wider than the column and overhanging it on one side (so that bending in
and out of the L's plane and torsion couple, and one shaker excites them all). Two bolted joints
are zones through a whole cross-section whose equivalent modulus is random: ``A`` in the column,
``B`` in the arm. Each joint's stiffness is assembled over its zone at its mean modulus, so that
``K(gamma) = K_rest + gamma_A K_A + gamma_B K_B`` (CONTRACTS.md section 4).

The campaign is made here, with scipy and numpy only, not by the workbench: for each of 30 tests,
joint moduli drawn from Gamma laws (true means and CoVs in ``truth.json``, not the model file's),
modes by scipy's shift-invert Lanczos on the scikit-fem matrices, accelerances at six sensors by
modal superposition of 20 modes with 1 % modal damping, complex noise at 40 dB, on a logarithmic
frequency axis (0.2 % steps, about ten lines per half-power band). The workbench then has to find
the modes by circle fit and the joints by moment matching, as it would on a lab's export.

Run from the repository root::

    python examples/bolted_bracket/build.py --out out/bolted_bracket

It writes ``model_mtx/`` and ``model_op4/`` (the same model in both formats), ``campaign/`` (a
section-2 campaign whose ``frame`` is ``model.toml``), and ``truth.json`` beside it.
"""

from __future__ import annotations

import argparse
import json
import shutil
from pathlib import Path

import numpy as np
import pandas as pd
import scipy.io as sio
import scipy.sparse as sp
import scipy.sparse.linalg as spla
import skfem
from pyyeti.nastran import op4
from skfem.helpers import dot
from skfem.models.elasticity import lame_parameters, linear_elasticity

# geometry, m
COLUMN_HEIGHT, ARM_LENGTH, BAR, STEP = 0.60, 0.60, 0.04, 0.02
ARM_WIDTH = 2 * BAR  # the arm overhangs the column on one side
STEEL_E, STEEL_NU, STEEL_RHO = 210e9, 0.3, 7850.0
JOINT_E = 70e9  # the file's mean equivalent modulus of both joint zones, Pa
JOINTS = {"A": ("z", 0.30, 0.34), "B": ("x", 0.30, 0.34)}  # axis and span of each joint's zone, m
# the campaign's truth: the joints' real laws differ from the file's means
TRUE_MEAN_RATIO = {"A": 0.85, "B": 1.10}
TRUE_COV = {"A": 0.10, "B": 0.20}
TESTS, MODES_SUMMED, DAMPING, SNR_DB = 30, 20, 0.01, 40.0
SENSORS = [("s1", (ARM_LENGTH, ARM_WIDTH, COLUMN_HEIGHT), "uz"), ("s2", (ARM_LENGTH, ARM_WIDTH, COLUMN_HEIGHT), "uy"),
           ("s3", (ARM_LENGTH / 2, ARM_WIDTH, COLUMN_HEIGHT), "uz"), ("s4", (0.0, 0.0, COLUMN_HEIGHT / 2), "ux"),
           ("s5", (0.0, 0.0, COLUMN_HEIGHT / 2), "uy"), ("s6", (ARM_LENGTH, 0.0, COLUMN_HEIGHT), "uz")]
EXCITATION = ((ARM_LENGTH, ARM_WIDTH, COLUMN_HEIGHT), "uz")
COMPONENTS = ("ux", "uy", "uz")


def bracket_mesh() -> skfem.MeshHex:
    """The L: a box of hexahedra with the elements outside the column and the arm removed."""
    x = np.linspace(0.0, ARM_LENGTH, round(ARM_LENGTH / STEP) + 1)
    y = np.linspace(0.0, ARM_WIDTH, round(ARM_WIDTH / STEP) + 1)
    z = np.linspace(0.0, COLUMN_HEIGHT, round(COLUMN_HEIGHT / STEP) + 1)
    mesh = skfem.MeshHex.init_tensor(x, y, z)
    cx, cy, cz = mesh.p[:, mesh.t].mean(axis=1)
    column = (cx < BAR) & (cy < BAR)
    arm = cz > COLUMN_HEIGHT - BAR
    return mesh.remove_elements(np.flatnonzero(~(column | arm)))


def joint_elements(mesh: skfem.MeshHex) -> dict[str, np.ndarray]:
    centre = mesh.p[:, mesh.t].mean(axis=1)
    axis = {"x": 0, "y": 1, "z": 2}
    out = {}
    for name, (along, lo, hi) in JOINTS.items():
        c = centre[axis[along]]
        zone = (c > lo) & (c < hi)
        out[name] = np.flatnonzero(zone & ((centre[2] < COLUMN_HEIGHT - BAR) if name == "A" else (centre[0] > BAR)))
    return out


@skfem.BilinearForm
def _mass(u, v, w):
    return STEEL_RHO * dot(u, v)


def matrices() -> tuple[dict[str, sp.csr_matrix], np.ndarray, np.ndarray]:
    """Mass, rest stiffness and joint stiffnesses on the free dofs; node and component of each free dof."""
    mesh = bracket_mesh()
    element = skfem.ElementVector(skfem.ElementHex1())
    zones = joint_elements(mesh)
    in_joint = np.concatenate(list(zones.values()))
    rest = np.setdiff1d(np.arange(mesh.t.shape[1]), in_joint)
    full = skfem.Basis(mesh, element)
    steel = linear_elasticity(*lame_parameters(STEEL_E, STEEL_NU))
    joint = linear_elasticity(*lame_parameters(JOINT_E, STEEL_NU))
    found = {"M": skfem.asm(_mass, full), "K0": skfem.asm(steel, skfem.Basis(mesh, element, elements=rest))}
    for name, elements in zones.items():
        found[f"K{name}"] = skfem.asm(joint, skfem.Basis(mesh, element, elements=elements))
    clamped = full.get_dofs(lambda p: np.isclose(p[2], 0.0)).all()
    free = np.setdiff1d(np.arange(full.N), clamped)
    # ElementVector numbers a node's components together: dof 3 n + c
    reduced = {k: sp.csr_matrix(a[free][:, free]) for k, a in found.items()}
    return reduced, free // 3, free % 3


def node_of(points: np.ndarray, where: tuple[float, float, float]) -> int:
    return int(np.argmin(np.linalg.norm(points.T - np.array(where), axis=1)))


def model_toml(fmt: str, sensor_nodes: list[int], excitation_node: int) -> str:
    names = ({"mass": "MAA", "stiffness_rest": "KAA", "A": "KJA", "B": "KJB"} if fmt == "op4" else
             {"mass": "M.mtx", "stiffness_rest": "K0.mtx", "A": "KA.mtx", "B": "KB.mtx"})
    lines = ['name = "bolted L-bracket, scikit-fem hexahedra"',
             'description = "examples/bolted_bracket/build.py: steel L, joints A (column) and B (arm)"',
             f'format = "{fmt}"'] + (['file = "model.op4"'] if fmt == "op4" else [])
    lines += [f'mass = "{names["mass"]}"', f'stiffness_rest = "{names["stiffness_rest"]}"', 'dofs = "dofs.csv"']
    for name in ("A", "B"):
        lines += ["", "[[joints]]", f'name = "{name}"', f'stiffness = "{names[name]}"',
                  f"youngs_modulus = {JOINT_E!r}", "cov = 0.15", f'group = "{name}"']
    lines += ["", "[excitation]", f"node = {excitation_node}", f'component = "{EXCITATION[1]}"']
    for (name, _, comp), node in zip(SENSORS, sensor_nodes):
        lines += ["", "[[sensors]]", f'name = "{name}"', f"node = {node}", f'component = "{comp}"']
    lines += ["", "[damping]", f"ratios = [{DAMPING}]"]
    return "\n".join(lines) + "\n"


def write_model(out: Path, found: dict[str, sp.csr_matrix], nodes: np.ndarray,
                comps: np.ndarray) -> tuple[dict[str, int], int]:
    """``model_mtx/`` and ``model_op4/`` in ``out``; returns each sensor's row and the excitation's."""
    points = bracket_mesh().p
    sensor_nodes = [node_of(points, where) for _, where, _ in SENSORS]
    excitation_node = node_of(points, EXCITATION[0])
    dofs = pd.DataFrame({"index": np.arange(nodes.size), "node": nodes + 1, "component": [COMPONENTS[c] for c in comps],
                         "x": points[0, nodes], "y": points[1, nodes], "z": points[2, nodes]})
    for fmt, folder in (("matrix-market", "model_mtx"), ("op4", "model_op4")):
        target = out / folder
        target.mkdir(parents=True)
        dofs.to_csv(target / "dofs.csv", index=False, float_format="%.17g")
        if fmt == "op4":
            op4.write(str(target / "model.op4"), {"MAA": found["M"], "KAA": found["K0"], "KJA": found["KA"],
                                                  "KJB": found["KB"]}, binary=True, sparse="bigmat")
        else:
            for key in ("M", "K0", "KA", "KB"):
                sio.mmwrite(str(target / f"{key}.mtx"), found[key], precision=17)
        (target / "model.toml").write_text(model_toml(fmt, [n + 1 for n in sensor_nodes], excitation_node + 1))
    row = {(int(n), int(c)): i for i, (n, c) in enumerate(zip(nodes, comps))}
    rows = {name: row[(node, COMPONENTS.index(comp))] for (name, _, comp), node in zip(SENSORS, sensor_nodes)}
    return rows, row[(excitation_node, COMPONENTS.index(EXCITATION[1]))]


def modes(stiffness: sp.csr_matrix, mass: sp.csr_matrix, count: int) -> tuple[np.ndarray, np.ndarray]:
    values, vectors = spla.eigsh(stiffness, k=count, M=mass, sigma=0.0, which="LM")
    order = np.argsort(values)
    return values[order], vectors[:, order]


def campaign(out: Path, found: dict[str, sp.csr_matrix], rows: dict[str, int], drive: int, seed: int) -> dict:
    rng = np.random.default_rng(seed)
    gammas = {j: TRUE_MEAN_RATIO[j] * rng.gamma(1 / TRUE_COV[j] ** 2, TRUE_COV[j] ** 2, TESTS) for j in ("A", "B")}
    top_hz = np.sqrt(modes(found["K0"] + found["KA"] + found["KB"], found["M"], 7)[0][-1]) / (2 * np.pi) * 1.12
    f = np.exp(np.arange(np.log(5.0), np.log(top_hz), 0.002))
    w = 2 * np.pi * f
    sensor_rows = np.array(list(rows.values()))
    tables, frequencies = [], []
    for t in range(TESTS):
        k = found["K0"] + gammas["A"][t] * found["KA"] + gammas["B"][t] * found["KB"]
        lam, phi = modes(k, found["M"], MODES_SUMMED)
        wr = np.sqrt(lam)
        frequencies.append((wr / (2 * np.pi))[:8].tolist())
        constants = phi[sensor_rows] * phi[drive]  # (n_sensors, modes)
        h = -w[None, :] ** 2 * (constants @ (1.0 / (wr[:, None] ** 2 - w[None, :] ** 2
                                                    + 2j * DAMPING * wr[:, None] * w[None, :])))
        sigma = np.sqrt(np.mean(np.abs(h) ** 2, axis=1, keepdims=True)) * 10 ** (-SNR_DB / 20)
        h = h + sigma * (rng.standard_normal(h.shape) + 1j * rng.standard_normal(h.shape)) / np.sqrt(2)
        for s, name in enumerate(rows):
            tables.append(pd.DataFrame({"test_id": f"t{t + 1:02d}", "sensor": name, "frequency_hz": f,
                                        "real": h[s].real, "imag": h[s].imag}))
    target = out / "campaign"
    shutil.copytree(out / "model_op4", target)
    pd.concat(tables).to_parquet(target / "frf.parquet", index=False)
    pd.DataFrame({"test_id": [f"t{t + 1:02d}" for t in range(TESTS)],
                  "assembly": [str(t + 1) for t in range(TESTS)]}).to_csv(target / "design.csv", index=False)
    levels = ", ".join(f'"{t + 1}" = "assembly {t + 1}"' for t in range(TESTS))
    (target / "campaign.toml").write_text(
        'name = "bolted L-bracket: 30 assemblies (synthetic, scikit-fem)"\n'
        'frame = "model.toml"\nquantity = "accelerance"\nsynthetic = true\n'
        'source = "examples/bolted_bracket/build.py: modes by scipy eigsh, modal FRFs, 40 dB noise"\n\n'
        f'[factors.assembly]\nkind = "other"\nlevels = {{ {levels} }}\n')
    sample = {j: {"youngs_modulus": float(JOINT_E * g.mean()), "cov": float(g.std(ddof=1) / g.mean())}
              for j, g in gammas.items()}
    return {"law": {j: {"youngs_modulus": JOINT_E * TRUE_MEAN_RATIO[j], "cov": TRUE_COV[j]} for j in gammas},
            "sample": sample, "frequency_hz": frequencies, "seed": seed}


def build(out: Path, seed: int = 2026) -> dict:
    """Write the two models, the campaign and ``truth.json`` into ``out`` (a new directory)."""
    out.mkdir(parents=True)
    found, nodes, comps = matrices()
    rows, drive = write_model(out, found, nodes, comps)
    truth = campaign(out, found, rows, drive, seed)
    (out / "truth.json").write_text(json.dumps(truth, indent=2) + "\n")
    return truth


if __name__ == "__main__":
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--out", type=Path, default=Path("out/bolted_bracket"), help="a new directory")
    parser.add_argument("--seed", type=int, default=2026)
    args = parser.parse_args()
    result = build(args.out, args.seed)
    print(f"written to {args.out}: sample joint laws {json.dumps(result['sample'])}")

"""The candidates on a matrix model: the effects that need no frame geometry (CONTRACTS.md section 3).

A matrix model has no members, supports or sections, so support compliance, shear deformation and
axial prestress are not candidates. What remains, each on a grid of its parameter like a frame's
(a `workbench.diagnose.curves.Sweep`, the model changed by `workbench.rig.effects.apply_matrix_effect`):

- each joint's modulus factor (0.1 to 10), and every joint at once;
- the shaker's drive at the excitation's dof: its spring, around the drive point's static stiffness, alone or
  with the mass moving with it (`workbench.diagnose.candidates.drive_sweeps`; the mass is no candidate alone,
  `workbench.diagnose.verdict.PAIRED_ONLY`);
- an added mass (on a node's translations) at the few nodes where a mass best explains the
  residual with the modes held fixed (`_mass_screen`), 5 cm apart when the dof table gives
  coordinates; a node is named ``"node N"``.

Amplitude softening and joint damping reuse the joint curves and the energy shares, as on a frame.
"""

from __future__ import annotations

import numpy as np

from workbench.diagnose.baseline import Baseline
from workbench.diagnose.candidates import GRID_POINTS, drive_sweeps, joint_sweeps
from workbench.diagnose.curves import Curve, Sweep, solve_sweeps
from workbench.diagnose.localise import node_translation
from workbench.diagnose.observations import Observations
from workbench.model.matrix_model import MatrixModel
from workbench.rig.effects import ADDED_MASS, TRANSLATIONS, node_name
from workbench.tasks import Mapper

__all__ = ["matrix_curves"]

MASS_PLACES = 3  # nodes given an added-mass curve
MASS_SPACING_M = 0.05  # between them, when the dof table has coordinates


def _stinger_sweeps(model: MatrixModel) -> list[Sweep]:
    if model.excitation is None:
        return []
    return drive_sweeps(model.stiffness(), model.excitation, node_name(model.dofs.nodes[model.excitation]), {},
                        _translating_mass(model))


def _translating_mass(model: MatrixModel) -> float:
    """The structure's mass as a rigid translation sees it, kg (the largest over x, y, z)."""
    best = 0.0
    for component in TRANSLATIONS:
        e = np.array([c == component for c in model.dofs.components], float)
        best = max(best, float(e @ (model.mass @ e)))
    return best


def _mass_screen(nodes: np.ndarray, translation: np.ndarray, masses: np.ndarray, residual: np.ndarray,
                 weight: np.ndarray) -> np.ndarray:
    """Each node's best weighted squared misfit (n_nodes,) for a mass there, modes held fixed.

    A mass ``m`` on a node whose mass-normalised translation is ``t_k`` in mode k moves that mode's
    frequency by ``(1 + m t_k)^(-1/2) - 1`` with the mode shape held (its Rayleigh quotient): the
    screen keeps the saturation of a heavy mass, which the linear sensitivity does not, and ranks
    hundreds of nodes at the cost of a few exact solves.
    """
    ok = ~np.isnan(residual)
    shift = (1.0 + masses[None, :, None] * translation[:, None, ok]) ** -0.5 - 1.0  # (nodes, masses, modes)
    misfit = np.sum(weight[ok] * (residual[ok] - shift) ** 2, axis=-1)
    return misfit.min(axis=1)


def _mass_sweeps(base: Baseline, model: MatrixModel, residual: np.ndarray, weight: np.ndarray) -> list[Sweep]:
    nodes, translation = node_translation(model, base.modes.shapes[:, base.pairing])
    total = _translating_mass(model)
    misfit = _mass_screen(nodes, translation, total * np.logspace(-3.5, 0, 60), residual, weight)
    coordinates = model.dofs.coordinates
    where: dict[int, np.ndarray] = {}
    if coordinates is not None:
        for row, node in enumerate(model.dofs.nodes):
            where.setdefault(int(node), coordinates[row])
    values = total * np.logspace(-3.5, 0, GRID_POINTS)
    chosen: list[int] = []
    grids: list[Sweep] = []
    for i in np.argsort(misfit):
        if len(chosen) == MASS_PLACES:
            break
        node = int(nodes[i])
        if where and any(np.linalg.norm(where[node] - where[c]) < MASS_SPACING_M for c in chosen):
            continue
        chosen.append(node)
        grids.append(Sweep(ADDED_MASS.name, node_name(node), values, 0, True))
    return grids


def matrix_curves(base: Baseline, obs: Observations, residual: np.ndarray, weight: np.ndarray,
                  mapper: Mapper | None = None) -> list[Curve]:
    """One curve per candidate and place a matrix model allows (module docstring), those that could be solved.

    ``residual`` (n_measured,) relative frequency residual of the baseline and ``weight`` its
    inverse relative variance, for the added mass's screen; ``mapper`` solves the grids
    (`workbench.diagnose.curves.solve_sweeps`).
    """
    model = base.frame
    if not isinstance(model, MatrixModel):
        raise TypeError("matrix_curves: the baseline is a frame's; use frame_curves")
    grids = _stinger_sweeps(model) + joint_sweeps(base) + _mass_sweeps(base, model, residual, weight)
    return solve_sweeps(base, grids, mapper)

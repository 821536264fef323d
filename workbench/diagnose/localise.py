"""Where the nominal model misses: regions scored by how much of the residual a change of them explains.

The relative frequency residuals are projected on the sensitivity of each mode to a relative
change of each region's stiffness (its share of the mode's strain energy,
``0.5 * phi^T K_R phi / lambda``) or mass (``-0.5 * phi^T M_R phi``): members, joints, support
springs, named points (a mass there, or a spring at the excitation point). A region's score is the
share of the weighted residual a one-parameter change of that region explains (a squared cosine,
0 to 1). Joints are also scored on the damping residuals against their energy share.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from workbench.diagnose.baseline import Baseline
from workbench.diagnose.observations import Observations
from workbench.model.assembly import Model, element_energies
from workbench.model.frame import Frame
from workbench.model.matrix_model import MatrixModel
from workbench.model.structure import structure_energies
from workbench.rig.effects import node_name

__all__ = ["Region", "explained", "energy_shares", "node_translation", "localise"]

NODE_REGIONS = 10  # nodes of a matrix model listed as places a mass may sit


@dataclass(frozen=True)
class Region:
    """A region of the frame and how much of the residual a change of it explains."""

    region: str
    kind: str  # member, joint, support, point
    mechanism: str  # stiffness, mass, damping
    score: float


def explained(direction: np.ndarray, residual: np.ndarray, weight: np.ndarray) -> float:
    """Share of the weighted residual a multiple of ``direction`` explains (squared cosine, 0 to 1).

    ``direction``, ``residual``, ``weight``: (n_modes,); NaN entries are left out.
    """
    ok = ~np.isnan(residual) & ~np.isnan(direction)
    a, r, w = direction[ok], residual[ok], weight[ok]
    denominator = float(np.sum(w * a * a) * np.sum(w * r * r))
    return float(np.sum(w * a * r) ** 2 / denominator) if denominator > 0 else 0.0


def energy_shares(base: Baseline) -> tuple[np.ndarray, np.ndarray]:
    """Each joint's share (n_joints, n_measured) of the measured modes' strain energy, and each
    member's outside its joints (n_members, n_measured; none on a matrix model).
    """
    model, shapes = base.model, base.modes.shapes[:, base.pairing]
    rest, per_joint = structure_energies(model, shapes)
    total = rest + per_joint.sum(axis=0)
    if not isinstance(model, Model):
        return per_joint / total, np.zeros((0, shapes.shape[1]))
    per_element = element_energies(model, shapes)
    outside = model.mesh.element_joint < 0
    members = np.array([per_element[outside & (model.mesh.element_member == i)].sum(axis=0)
                        for i in range(len(model.frame.members))])
    return per_joint / total, members / total


def _member_regions(base: Baseline, member_share: np.ndarray, shapes: np.ndarray, residual: np.ndarray,
                    weight: np.ndarray) -> list[Region]:
    """Each member's stiffness (strain energy outside joints) and mass (kinetic energy)."""
    frame, model = base.planar
    mesh = model.mesh
    regions = []
    lengths = mesh.element_lengths()
    for i, m in enumerate(frame.members):
        regions.append(Region(m.name, "member", "stiffness", explained(0.5 * member_share[i], residual, weight)))
        rho_a = frame.materials[m.material].density * frame.sections[m.section].area
        elements = np.flatnonzero(mesh.element_member == i)
        nodal = np.zeros(len(mesh.node_xy))
        np.add.at(nodal, mesh.connectivity[elements].ravel(), np.repeat(0.5 * rho_a * lengths[elements], 2))
        kinetic = nodal @ (shapes[0::3] ** 2 + shapes[1::3] ** 2)
        regions.append(Region(m.name, "member", "mass", explained(-0.5 * kinetic, residual, weight)))
    return regions


def _joint_regions(frame: Frame | MatrixModel, obs: Observations, joint_share: np.ndarray, residual: np.ndarray,
                   weight: np.ndarray, damping_residual: np.ndarray | None) -> list[Region]:
    """Each joint's stiffness, and its damping when damping was measured."""
    regions = []
    for j, joint in enumerate(frame.joint_names):
        regions.append(Region(joint, "joint", "stiffness", explained(0.5 * joint_share[j], residual, weight)))
        if damping_residual is not None and obs.damping_se is not None:
            d_weight = 1.0 / np.nanmean(obs.damping_se ** 2, axis=0)
            centred = joint_share[j] - np.average(joint_share[j], weights=d_weight)
            regions.append(Region(joint, "joint", "damping", explained(centred, damping_residual, d_weight)))
    return regions


def _point_regions(base: Baseline, shapes: np.ndarray, lam: np.ndarray, residual: np.ndarray,
                   weight: np.ndarray) -> list[Region]:
    """Support springs, a mass at each named point, a spring at the excitation point."""
    frame, model = base.planar
    mesh = model.mesh
    regions = []
    for s in frame.supports:
        if s.rz is not None and not math.isinf(s.rz):
            phi = shapes[3 * mesh.point_node[s.point] + 2]
            score = explained(0.5 * s.rz * phi ** 2 / lam, residual, weight)
            regions.append(Region(s.point, "support", "stiffness", score))
    supported = {s.point for s in frame.supports}
    for name, node in mesh.point_node.items():
        if name in supported:
            continue
        translation = shapes[3 * node] ** 2 + shapes[3 * node + 1] ** 2
        regions.append(Region(name, "point", "mass", explained(-0.5 * translation, residual, weight)))
        if frame.excitation is not None and frame.excitation.point == name:
            phi = shapes[3 * node + ("ux", "uy", "rz").index(frame.excitation.dof)]
            regions.append(Region(name, "point", "stiffness", explained(0.5 * phi ** 2 / lam, residual, weight)))
    return regions


def node_translation(model: MatrixModel, shapes: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """A matrix model's nodes (n_nodes,) and each one's squared translation in each mode (n_nodes, n_modes)."""
    rows = np.array([c in ("ux", "uy", "uz") for c in model.dofs.components])
    nodes, owner = np.unique(model.dofs.nodes[rows], return_inverse=True)
    translation = np.zeros((nodes.size, shapes.shape[1]))
    np.add.at(translation, owner, shapes[rows] ** 2)
    return nodes, translation


def _node_regions(model: MatrixModel, shapes: np.ndarray, lam: np.ndarray, residual: np.ndarray,
                  weight: np.ndarray) -> list[Region]:
    """A mass at the `NODE_REGIONS` nodes that explain the most, a spring at the excitation's node."""
    nodes, translation = node_translation(model, shapes)
    scores = np.array([explained(-0.5 * t, residual, weight) for t in translation])
    regions = [Region(node_name(nodes[i]), "point", "mass", float(scores[i]))
               for i in np.argsort(scores)[::-1][:NODE_REGIONS]]
    if model.excitation is not None:
        phi = shapes[model.excitation]
        regions.append(Region(node_name(model.dofs.nodes[model.excitation]), "point", "stiffness",
                              explained(0.5 * phi ** 2 / lam, residual, weight)))
    return regions


def localise(base: Baseline, obs: Observations, predicted_hz: np.ndarray,
             damping_residual: np.ndarray | None = None,
             shares: tuple[np.ndarray, np.ndarray] | None = None) -> list[Region]:
    """Regions scored by the share of the residual their stiffness, mass or damping explains, best first.

    Parameters
    ----------
    base : the baseline (its modes and pairing).
    obs : the observations.
    predicted_hz : (n_cond, n_measured) the model's predicted means, Hz.
    damping_residual : (n_measured,) measured minus baseline damping ratio, or None.
    shares : `energy_shares` of the baseline when the caller has them already.

    Returns
    -------
    One `Region` per region and kind (its best mechanism), by decreasing score.
    """
    residual = (obs.frequency_hz / predicted_hz - 1.0).mean(axis=0)
    weight = 1.0 / np.nanmean((obs.frequency_se / obs.frequency_hz) ** 2, axis=0)
    lam = base.modes.eigenvalues[base.pairing]
    joint_share, member_share = shares if shares is not None else energy_shares(base)
    regions = _joint_regions(base.frame, obs, joint_share, residual, weight, damping_residual)
    if isinstance(base.model, Model):
        shapes = base.model.expand(base.modes.shapes)[:, base.pairing]
        regions += (_member_regions(base, member_share, shapes, residual, weight)
                    + _point_regions(base, shapes, lam, residual, weight))
    else:
        regions += _node_regions(base.model, base.modes.shapes[:, base.pairing], lam, residual, weight)
    best: dict[tuple[str, str], Region] = {}
    for r in regions:  # one entry per region: its best mechanism
        if (r.region, r.kind) not in best or r.score > best[(r.region, r.kind)].score:
            best[(r.region, r.kind)] = r
    return sorted(best.values(), key=lambda r: -r.score)

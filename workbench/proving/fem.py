"""The article's finite element model: mesh, element properties, node terms, prestress, free-dof system.

`discretise` turns an `workbench.proving.article.Article` into the proving ground's own `System`
(`workbench.proving.beams`): Timoshenko elements at most a third of the frame's ``element_length`` long and
at least 12 per member (three times the workbench's count at least), a node at every named point, joint and
zone end, hinge and anchor; a bolted joint is its member's zone ``span`` whose Young's modulus is the
joint's in this test; locked-in axial forces come from a static solve of the rods' length misfits.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, field

import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spla

from workbench.model.frame import DOF_NAMES, FIXED, member_length, points_on_member
from workbench.proving.article import Anchor, Article
from workbench.proving.beams import (
    BarSet,
    BeamSet,
    System,
    assemble,
    bar_axial_forces,
    bar_matrices,
    bar_misfit_loads,
    beam_axial_forces,
    beam_geometric,
    beam_matrices,
    beam_misfit_loads,
)

__all__ = ["Discrete", "discretise", "MIN_ELEMENTS_PER_MEMBER", "REFINEMENT"]

MIN_ELEMENTS_PER_MEMBER = 12
REFINEMENT = 3  # elements at most element_length / 3: three times the workbench's count
_DEFAULT_KAPPA, _DEFAULT_NU = 5.0 / 6.0, 0.33  # a rectangle; aluminium, when the frame file gives none


@dataclass(frozen=True)
class Discrete:
    """A discretised article: its `System` and what locates things in it.

    Attributes
    ----------
    system : the free-dof matrices, sensors and excitation.
    node_xy : (n_nodes, 2) m. point_node : frame point -> node.
    element_member : (e,) member index of each beam element, -1 for a rod's.
    axial_force : (e,) locked-in axial force of each beam element, N (tension positive).
    """

    system: System
    node_xy: np.ndarray
    point_node: dict[str, int]
    element_member: np.ndarray
    axial_force: np.ndarray = field(repr=False)

    def member_axial_force(self, member_index: int) -> float:
        """Mean locked-in axial force along a member, N."""
        return float(self.axial_force[self.element_member == member_index].mean())


@dataclass
class _Mesh:
    """Nodes and elements while they are built (mutable scratch, never returned)."""

    xy: list[tuple[float, float]]
    point_node: dict[str, int]
    stations: dict[str, list[tuple[float, int]]]
    twin: dict[int, int]  # hinge's right-hand node -> its left-hand node (shared translations)
    elements: list[tuple[int, int, int, float]]  # start node, end node, member index (-1: rod), midpoint s
    rod_of_element: list[int]  # rod index, -1 for members


def _member_stations(article: Article, member_name: str) -> list[tuple[float, str | None, float | None]]:
    """Where a member needs nodes: (s, point name or None, hinge stiffness or None), sorted, merged."""
    frame = article.frame
    member = frame.member(member_name)
    length = member_length(frame, member)
    out: list[tuple[float, str | None, float | None]] = [
        (s, name, None) for name, s in points_on_member(frame.points, member).items()]
    out += [(s, None, None) for j in frame.joints if j.member == member_name for s in j.span]
    out += [(s, None, None) for z in article.zones if z.member == member_name for s in z.span]
    out += [(h.station, None, h.stiffness) for h in article.hinges if h.member == member_name]
    for anchor in _anchors(article):
        if isinstance(anchor, tuple) and anchor[0] == member_name:
            out.append((float(anchor[1]), None, None))
    out.sort(key=lambda t: (t[0], t[1] is None))
    merged: list[tuple[float, str | None, float | None]] = []
    for s, name, hinge in out:
        if not -1e-9 * length <= s <= length * (1 + 1e-9):
            raise ValueError(f"article: station {s} m is not on member {member_name!r} (length {length:.6g} m)")
        if merged and s - merged[-1][0] <= 1e-9 * max(length, 1.0):
            # one station: a named point wins, a hinge is kept
            old = merged[-1]
            merged[-1] = (old[0], old[1] or name, old[2] if old[2] is not None else hinge)
            continue
        merged.append((s, name, hinge))
    return merged


def _anchors(article: Article) -> list[Anchor]:
    anchors: list[Anchor] = [a.anchor for a in article.attachments]
    anchors += [x for r in article.rods for x in (r.start, r.end)]
    anchors += [x for d in article.dashpots for x in (d.a, d.b)]
    return anchors


def _mesh_members(article: Article) -> _Mesh:
    """Nodes at the frame's points and every station; each interval cut into equal elements (module docstring)."""
    frame = article.frame
    mesh = _Mesh(list(frame.points.values()), {n: i for i, n in enumerate(frame.points)}, {}, {}, [], [])
    for extra in article.nodes:
        mesh.point_node[extra.name] = len(mesh.xy)
        mesh.xy.append(extra.xy)
    for mi, member in enumerate(frame.members):
        length = member_length(frame, member)
        x0 = np.array(frame.points[member.start], float)
        direction = (np.array(frame.points[member.end], float) - x0) / length
        h = min(frame.element_length / REFINEMENT, length / MIN_ELEMENTS_PER_MEMBER)
        placed: list[tuple[float, int]] = []
        previous: tuple[float, int] | None = None
        for s, name, hinge in _member_stations(article, member.name):
            node = mesh.point_node[name] if name is not None else _new_node(mesh, x0 + s * direction)
            placed.append((s, node))
            if previous is not None:
                _chain(mesh, previous, (s, node), h, x0, direction, mi)
            previous = (s, node)
            if hinge is not None:  # the elements beyond start from a twin sharing the translations
                twin = _new_node(mesh, x0 + s * direction)
                mesh.twin[twin] = node
                previous = (s, twin)
        mesh.stations[member.name] = placed
    return mesh


def _new_node(mesh: _Mesh, xy: np.ndarray) -> int:
    mesh.xy.append((float(xy[0]), float(xy[1])))
    return len(mesh.xy) - 1


def _chain(mesh: _Mesh, a: tuple[float, int], b: tuple[float, int], h: float, x0: np.ndarray,
           direction: np.ndarray, member: int) -> None:
    """Equal elements, none longer than ``h``, from station ``a`` to station ``b`` of a member."""
    (s0, n0), (s1, n1) = a, b
    count = max(1, math.ceil((s1 - s0) / h - 1e-9))
    nodes = [n0] + [_new_node(mesh, x0 + (s0 + (s1 - s0) * k / count) * direction) for k in range(1, count)] + [n1]
    for k in range(count):
        mesh.elements.append((nodes[k], nodes[k + 1], member, s0 + (s1 - s0) * (k + 0.5) / count))
        mesh.rod_of_element.append(-1)


def _node_of(mesh: _Mesh, anchor: Anchor) -> int:
    if isinstance(anchor, str):
        if anchor not in mesh.point_node:
            raise KeyError(f"article: {anchor!r} is neither a point of the frame nor an extra node")
        return mesh.point_node[anchor]
    member, s = anchor
    for station, node in mesh.stations[member]:
        if abs(station - s) <= 1e-9 * max(abs(s), 1.0):
            return node
    raise KeyError(f"article: no node at {s} m on member {member!r}")


def _mesh_rods(article: Article, mesh: _Mesh) -> None:
    """Beam chains of the rods (bars are kept apart: `_bars`)."""
    for ri, rod in enumerate(article.rods):
        if rod.bar:
            continue
        a, b = _node_of(mesh, rod.start), _node_of(mesh, rod.end)
        xa, xb = np.array(mesh.xy[a]), np.array(mesh.xy[b])
        nodes = [a] + [_new_node(mesh, xa + (xb - xa) * k / rod.elements) for k in range(1, rod.elements)] + [b]
        for k in range(rod.elements):
            mesh.elements.append((nodes[k], nodes[k + 1], -1, 0.0))
            mesh.rod_of_element.append(ri)


def _dof_table(mesh: _Mesh) -> np.ndarray:
    """(n_nodes, 3) global dof numbers; a hinge's twin shares its partner's ux, uy."""
    table = np.empty((len(mesh.xy), 3), int)
    count = 0
    for n in range(len(mesh.xy)):
        if n in mesh.twin:
            table[n, :2] = table[mesh.twin[n], :2]
            table[n, 2] = count
            count += 1
        else:
            table[n] = count + np.arange(3)
            count += 3
    return table


def _member_properties(article: Article, mesh: _Mesh, moduli: Mapping[str, float],
                       factor: float) -> dict[str, np.ndarray]:
    """Per element E, G, A, I, kappa, density and added inertia of the members' elements (rods get NaN)."""
    frame = article.frame
    n = len(mesh.elements)
    p = {k: np.full(n, np.nan) for k in ("E", "nu", "rho", "A", "I", "kappa")}
    p["mu_add"], p["rot_add"] = np.zeros(n), np.zeros(n)
    member_index = np.array([e[2] for e in mesh.elements])
    mid = np.array([e[3] for e in mesh.elements])
    for mi, member in enumerate(frame.members):
        on = member_index == mi
        mat, sec = frame.materials[member.material], frame.sections[member.section]
        p["E"][on], p["rho"][on], p["A"][on], p["I"][on] = mat.youngs_modulus, mat.density, sec.area, sec.second_moment
        p["nu"][on] = mat.poisson_ratio if mat.poisson_ratio is not None else _DEFAULT_NU
        p["kappa"][on] = sec.shear_coefficient if sec.shear_coefficient else _DEFAULT_KAPPA
        for j in frame.joints:
            if j.member == member.name:
                p["E"][on & (mid > j.span[0]) & (mid < j.span[1])] = moduli.get(j.name, j.youngs_modulus)
        for z in article.zones:
            if z.member == member.name:
                inside = on & (mid > z.span[0]) & (mid < z.span[1])
                p["E"][inside] *= z.stiffness_factor
                p["A"][inside] *= z.area_factor
                p["I"][inside] *= z.inertia_factor
                p["mu_add"][inside] += z.mass_per_length
                p["rot_add"][inside] += z.rotary_per_length
    p["E"] = p["E"] * factor
    return p


def _beams(article: Article, mesh: _Mesh, dofs: np.ndarray, moduli: Mapping[str, float], factor: float) -> BeamSet:
    p = _member_properties(article, mesh, moduli, factor)
    for k, ri in enumerate(mesh.rod_of_element):
        if ri >= 0:
            rod = article.rods[ri]
            p["E"][k], p["nu"][k], p["rho"][k] = rod.youngs_modulus * factor, rod.poisson_ratio, rod.density
            p["A"][k], p["I"][k], p["kappa"][k] = rod.area, rod.second_moment, rod.shear_coefficient
    conn = np.array([(e[0], e[1]) for e in mesh.elements], int)
    xy = np.array(mesh.xy, float)
    d = xy[conn[:, 1]] - xy[conn[:, 0]]
    length = np.hypot(d[:, 0], d[:, 1])
    shear = p["kappa"] * p["E"] / (2.0 * (1.0 + p["nu"])) * p["A"] if article.shear else np.full(length.size, np.inf)
    rotary = p["rho"] * p["I"] + p["rot_add"] if article.rotary_inertia else np.zeros(length.size)
    return BeamSet(np.concatenate([dofs[conn[:, 0]], dofs[conn[:, 1]]], axis=1), length, d[:, 0] / length,
                   d[:, 1] / length, p["E"] * p["A"], p["E"] * p["I"], shear, p["rho"] * p["A"] + p["mu_add"], rotary)


def _bars(article: Article, mesh: _Mesh, dofs: np.ndarray, factor: float) -> tuple[BarSet, np.ndarray]:
    """The pin-ended rods as bars, and each one's stress-free strain."""
    rods = [r for r in article.rods if r.bar]
    ends = np.array([(_node_of(mesh, r.start), _node_of(mesh, r.end)) for r in rods], int).reshape(-1, 2)
    xy = np.array(mesh.xy, float)
    d = xy[ends[:, 1]] - xy[ends[:, 0]]
    length = np.hypot(d[:, 0], d[:, 1])
    bars = BarSet(np.concatenate([dofs[ends[:, 0], :2], dofs[ends[:, 1], :2]], axis=1), length,
                  d[:, 0] / np.where(length > 0, length, 1), d[:, 1] / np.where(length > 0, length, 1),
                  np.array([r.youngs_modulus * r.area * factor for r in rods]),
                  np.array([r.density * r.area for r in rods]))
    return bars, np.array([r.misfit for r in rods]) / np.where(length > 0, length, 1)


def _node_terms(article: Article, mesh: _Mesh, dofs: np.ndarray,
                size: int) -> tuple[sp.csr_matrix, sp.csr_matrix, sp.csr_matrix, set[int]]:
    """Stiffness, mass and damping at nodes (supports, masses, springs, attachments, dashpots) and fixed dofs."""
    frame = article.frame
    blocks: dict[str, list[tuple[np.ndarray, np.ndarray]]] = {"k": [], "m": [], "c": []}
    fixed: set[int] = set()
    for support in frame.supports:
        node = dofs[mesh.point_node[support.point]]
        for i, name in enumerate(DOF_NAMES):
            stiffness = support.stiffness(name)
            if stiffness == FIXED:
                fixed.add(int(node[i]))
            elif stiffness is not None:
                blocks["k"].append((node[i:i + 1], np.array([[stiffness]])))
    for pm in frame.masses:
        node = dofs[mesh.point_node[pm.point]]
        blocks["m"].append((node, np.diag([pm.mass, pm.mass, pm.rotary_inertia])))
    for spring in frame.springs:
        if spring.mass:  # a frame file has none; the generator's drive is its own (mechanisms.py)
            raise ValueError(f"{frame.source}: the spring at {spring.point!r}: a moving mass is the diagnosis's only")
        i = DOF_NAMES.index(spring.dof)
        blocks["k"].append((dofs[mesh.point_node[spring.point], i:i + 1], np.array([[spring.stiffness]])))
    for att in article.attachments:
        node = dofs[_node_of(mesh, att.anchor)]
        for key, value in (("k", att.stiffness), ("m", att.mass), ("c", att.damping)):
            if value is not None:
                blocks[key].append((node, np.array(value, float)))
        fixed |= {int(node[DOF_NAMES.index(d)]) for d in att.fixed}
    for dash in article.dashpots:
        i = DOF_NAMES.index(dash.dof)
        pair = np.array([dofs[_node_of(mesh, dash.a), i], dofs[_node_of(mesh, dash.b), i]])
        blocks["c"].append((pair, dash.coefficient * np.array([[1.0, -1.0], [-1.0, 1.0]])))
    for hinge_twin, left in mesh.twin.items():
        k_hinge = _hinge_stiffness(article, mesh, left)
        pair = np.array([dofs[left, 2], dofs[hinge_twin, 2]])
        blocks["k"].append((pair, k_hinge * np.array([[1.0, -1.0], [-1.0, 1.0]])))
    out = []
    for key in ("k", "m", "c"):
        total = sp.csr_matrix((size, size))
        for where, block in blocks[key]:
            total = total + assemble(block[None], where[None], size)
        out.append(total)
    return out[0], out[1], out[2], fixed


def _hinge_stiffness(article: Article, mesh: _Mesh, left: int) -> float:
    for member, placed in mesh.stations.items():
        for s, node in placed:
            if node == left:
                return next(h.stiffness for h in article.hinges if h.member == member and abs(h.station - s) < 1e-9)
    raise KeyError("article: a hinge lost its station")


def discretise(article: Article, joint_moduli: Mapping[str, float] | None = None,
               modulus_factor: float = 1.0) -> Discrete:
    """The article's finite element system (module docstring).

    Parameters
    ----------
    joint_moduli : joint name -> the zone's Young's modulus in this test, Pa (default: the frame's means).
    modulus_factor : multiplies every member's, joint's and rod's modulus (the lab's temperature).

    Returns
    -------
    Discrete
        Free-dof matrices with the geometric stiffness of the locked-in axial forces.
    """
    frame = article.frame
    moduli = dict(joint_moduli or {})
    mesh = _mesh_members(article)
    _mesh_rods(article, mesh)
    dofs = _dof_table(mesh)
    size = int(dofs.max()) + 1
    beams = _beams(article, mesh, dofs, moduli, modulus_factor)
    bars, bar_strain = _bars(article, mesh, dofs, modulus_factor)
    kb, mb = beam_matrices(beams)
    kr, mr, _ = bar_matrices(bars)
    k_node, m_node, c_node, fixed = _node_terms(article, mesh, dofs, size)
    stiffness = assemble(kb, beams.dofs, size) + assemble(kr, bars.dofs, size) + k_node
    mass = assemble(mb, beams.dofs, size) + assemble(mr, bars.dofs, size) + m_node
    free = np.setdiff1d(np.arange(size), np.array(sorted(fixed), int))
    index = np.full(size, -1)
    index[free] = np.arange(free.size)
    member_index = np.array([e[2] for e in mesh.elements])
    beam_strain = np.array([article.rods[r].misfit / _rod_length(article, mesh, r) if r >= 0 else 0.0
                            for r in mesh.rod_of_element])
    given = np.array([frame.members[m].axial_force if m >= 0 else 0.0 for m in member_index])
    axial = given.copy()
    if np.any(beam_strain) or np.any(bar_strain) or np.any(given):
        geometric, axial = _prestress(stiffness, beams, bars, beam_strain, bar_strain, given, free, size)
        stiffness = stiffness + geometric
    sensors = [int(index[dofs[mesh.point_node[s.point], DOF_NAMES.index(s.dof)]]) for s in frame.sensors]
    if article.excitation is not None:
        anchor, dof = article.excitation
        excitation = int(index[dofs[_node_of(mesh, anchor), DOF_NAMES.index(dof)]])
    elif frame.excitation is not None:
        exc = frame.excitation
        excitation = int(index[dofs[mesh.point_node[exc.point], DOF_NAMES.index(exc.dof)]])
    else:
        excitation = -1
    placed = frame.excitation is not None or article.excitation is not None
    if min(sensors, default=0) < 0 or (placed and excitation < 0):
        raise ValueError(f"article {frame.name!r}: a sensor or the excitation sits on a fixed dof")
    restrict = sp.csr_matrix((np.ones(free.size), (np.arange(free.size), free)), shape=(free.size, size))
    reduced = [(restrict @ a @ restrict.T).tocsr() for a in (stiffness, mass, c_node)]
    damping = reduced[2] if reduced[2].nnz else None
    system = System(reduced[0], reduced[1], damping, np.array(sensors, int), excitation)
    return Discrete(system, np.array(mesh.xy, float), dict(mesh.point_node), member_index, axial)


def _rod_length(article: Article, mesh: _Mesh, ri: int) -> float:
    rod = article.rods[ri]
    a, b = np.array(mesh.xy[_node_of(mesh, rod.start)]), np.array(mesh.xy[_node_of(mesh, rod.end)])
    return float(np.hypot(*(b - a)))


def _prestress(stiffness: sp.csr_matrix, beams: BeamSet, bars: BarSet, beam_strain: np.ndarray,
               bar_strain: np.ndarray, given: np.ndarray, free: np.ndarray,
               size: int) -> tuple[sp.csr_matrix, np.ndarray]:
    """Geometric stiffness of the locked-in axial forces: misfits solved statically, plus the members' given forces.

    The misfit loads are self-equilibrated; the linear static solve ``K u = f`` on the free dofs spreads them
    over whatever path the frame offers, and each element's force is ``EA (elongation / L - misfit strain)``.
    """
    load = np.zeros(size)
    np.add.at(load, beams.dofs, beam_misfit_loads(beams, beam_strain))
    np.add.at(load, bars.dofs, bar_misfit_loads(bars, bar_strain))
    u = np.zeros(size)
    if np.any(load):
        kff = stiffness[free][:, free].tocsc()
        u[free] = spla.spsolve(kff, load[free])
    beam_force = beam_axial_forces(beams, u, beam_strain) + given
    bar_force = bar_axial_forces(bars, u, bar_strain)
    _, _, kg_bar = bar_matrices(bars, bar_force)
    geometric = assemble(beam_geometric(beams, beam_force), beams.dofs, size) + assemble(kg_bar, bars.dofs, size)
    return geometric, beam_force

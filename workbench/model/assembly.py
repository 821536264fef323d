"""Meshing and assembly: global mass, rest stiffness and joint-zone stiffnesses of a frame.

The stiffness is split as in the paper, eq. (3)-(4):

    K(gamma) = K_rest + sum_j gamma_j K_j,

where ``K_j`` is the stiffness of joint ``j``'s zone at the joint's mean modulus, so that
``gamma_j = Y_j / E[Y_j]`` is the normalised random modulus of eq. (8)-(9) and ``gamma = 1`` is the
nominal model. Supports that are ``fixed`` remove their dof; every other matrix is on the free dofs.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
import scipy.sparse as sp

from workbench.model import elements
from workbench.model.frame import DOF_NAMES, Frame, Joint, member_length, points_on_member
from workbench.model.pattern import JointPattern

__all__ = ["Mesh", "ElementData", "Model", "mesh_frame", "assemble", "element_energies", "joint_energies",
           "strain_energy"]


@dataclass(frozen=True)
class Mesh:
    """Finite-element mesh of a frame.

    Attributes
    ----------
    node_xy : (n_nodes, 2) node coordinates, m.
    connectivity : (n_elements, 2) node indices of each element, from the member's start to its end.
    element_member : (n_elements,) index of the element's member in ``frame.members``.
    element_joint : (n_elements,) index in ``frame.joints`` of the joint zone holding the element, or -1.
    point_node : node index of every named point.
    """

    node_xy: np.ndarray
    connectivity: np.ndarray
    element_member: np.ndarray
    element_joint: np.ndarray
    point_node: dict[str, int]

    @property
    def dof_count(self) -> int:
        return 3 * len(self.node_xy)

    def element_lengths(self) -> np.ndarray:
        d = np.diff(self.node_xy[self.connectivity], axis=1)[:, 0]
        return np.hypot(d[:, 0], d[:, 1])


@dataclass(frozen=True)
class ElementData:
    """Per-element quantities for strain energies computed from deformations.

    Attributes (all shape (n_elements,) unless said)
    ----------
    dofs : (n_elements, 6) global dofs (ux, uy, rz at start, then end).
    length : m.  cos, sin : direction cosines.
    axial : EA / L, N/m.  bending : EI / ((1 + phi) L), N.m.  phi : Timoshenko shear parameter.
    """

    dofs: np.ndarray
    length: np.ndarray
    cos: np.ndarray
    sin: np.ndarray
    axial: np.ndarray
    bending: np.ndarray
    phi: np.ndarray


@dataclass(frozen=True)
class Model:
    """Assembled matrices of a frame on its free dofs (fixed support dofs removed).

    Attributes
    ----------
    frame, mesh : what was assembled.
    mass : (n, n) sparse mass matrix, kg.
    stiffness_rest : (n, n) sparse stiffness outside the joint zones, supports springs, grounded
        springs and the geometric stiffness of member axial forces, N/m.
    stiffness_joints : one (n, n) sparse matrix per joint of ``frame.joints``, at its mean modulus.
    free_dofs : (n,) global dof number (3 * node + {0: ux, 1: uy, 2: rz}) of each free dof.
    elements : per-element data for `element_energies`.
    spring_stiffness : (n,) diagonal of the support and grounded springs, N/m or N.m/rad.
    stiffness_geometric : (n, n) geometric stiffness of the members' axial forces.
    """

    frame: Frame
    mesh: Mesh
    mass: sp.csr_matrix
    stiffness_rest: sp.csr_matrix
    stiffness_joints: tuple[sp.csr_matrix, ...]
    free_dofs: np.ndarray
    elements: ElementData
    spring_stiffness: np.ndarray
    stiffness_geometric: sp.csr_matrix
    _position: np.ndarray = field(init=False, repr=False, compare=False)
    _pattern: JointPattern = field(init=False, repr=False, compare=False)

    def __post_init__(self) -> None:
        position = np.full(self.mesh.dof_count, -1)
        position[self.free_dofs] = np.arange(self.free_dofs.size)
        object.__setattr__(self, "_position", position)
        object.__setattr__(self, "_pattern", JointPattern.of(self.stiffness_rest, tuple(self.stiffness_joints)))

    @property
    def size(self) -> int:
        return int(self.free_dofs.size)

    @property
    def joint_names(self) -> tuple[str, ...]:
        return self.frame.joint_names

    @property
    def joints(self) -> tuple[Joint, ...]:
        """The frame's joints (name, mean modulus, cov, group), in the order of ``stiffness_joints``."""
        return self.frame.joints

    @property
    def groups(self) -> tuple[str, ...]:
        """Each joint's group (its own name when the file gives none)."""
        return tuple(j.group for j in self.frame.joints)

    @property
    def source(self) -> str:
        """The frame file's path, for messages."""
        return self.frame.source

    def damping_ratio(self, mode_count: int) -> tuple[float, ...]:
        """Modal damping ratios of the first `mode_count` modes (the frame's ``[damping]``)."""
        return self.frame.damping_ratio(mode_count)

    def stiffness(self, gamma: np.ndarray | None = None) -> sp.csr_matrix:
        """``K(gamma) = K_rest + sum_j gamma_j K_j`` (eq. 4); ``gamma = None`` means all ones."""
        return self._pattern.stiffness(gamma, self.joint_names)

    def dof(self, point: str, dof: str) -> int:
        """Index in the free-dof system of ``dof`` (ux, uy, rz) at the named ``point``."""
        if point not in self.mesh.point_node:
            raise KeyError(f"{self.frame.source}: no point named {point!r}")
        index = self._position[3 * self.mesh.point_node[point] + DOF_NAMES.index(dof)]
        if index < 0:
            raise ValueError(f"{self.frame.source}: {dof} at point {point!r} is a fixed support dof")
        return int(index)

    def expand(self, vectors: np.ndarray) -> np.ndarray:
        """Free-dof vectors (n, ...) to all dofs (3 * n_nodes, ...), zero on fixed dofs."""
        out = np.zeros((self.mesh.dof_count,) + vectors.shape[1:], dtype=vectors.dtype)
        out[self.free_dofs] = vectors
        return out


def mesh_frame(frame: Frame) -> Mesh:
    """Mesh every member into elements no longer than ``frame.element_length``.

    Nodes are placed at the member's ends, at every named point lying on it (so members meeting
    there are rigidly connected) and at joint span ends, then each interval is divided evenly.
    """
    node_xy: list[tuple[float, float]] = []
    point_node: dict[str, int] = {}
    for name, xy in frame.points.items():
        point_node[name] = len(node_xy)
        node_xy.append(xy)

    conn: list[tuple[int, int]] = []
    elem_member: list[int] = []
    elem_joint: list[int] = []
    for mi, member in enumerate(frame.members):
        length = member_length(frame, member)
        x0 = np.array(frame.points[member.start])
        direction = (np.array(frame.points[member.end]) - x0) / length
        # (station along the member, node or None for a new node)
        stations: list[tuple[float, int | None]] = [
            (s, point_node[name]) for name, s in points_on_member(frame.points, member).items()]
        zones = [(ji, j) for ji, j in enumerate(frame.joints) if j.member == member.name]
        for _, joint in zones:
            stations.extend((s, None) for s in joint.span)
        stations.sort(key=lambda t: (t[0], t[1] is None))
        merged: list[tuple[float, int | None]] = []
        for s, node in stations:
            if merged and s - merged[-1][0] <= 1e-9 * max(length, 1.0):
                # one station: a named point wins over a span end a rounding error away, on
                # either side (dropping the point would disconnect the members meeting there)
                if merged[-1][1] is None and node is not None:
                    merged[-1] = (s, node)
                continue
            merged.append((s, node))
        previous = None
        for s, node in merged:
            if node is None:
                node = len(node_xy)
                node_xy.append(tuple(x0 + s * direction))
            if previous is not None:
                s_prev, n_prev = previous
                count = max(1, math.ceil((s - s_prev) / frame.element_length - 1e-9))
                chain = [n_prev]
                for k in range(1, count):
                    chain.append(len(node_xy))
                    node_xy.append(tuple(x0 + (s_prev + (s - s_prev) * k / count) * direction))
                chain.append(node)
                mid = s_prev + (s - s_prev) * (np.arange(count) + 0.5) / count
                owner = np.full(count, -1)
                for ji, joint in zones:
                    owner[(mid > joint.span[0]) & (mid < joint.span[1])] = ji
                conn.extend(zip(chain[:-1], chain[1:]))
                elem_member.extend([mi] * count)
                elem_joint.extend(owner.tolist())
            previous = (s, node)
    return Mesh(np.array(node_xy, float), np.array(conn, int), np.array(elem_member, int),
                np.array(elem_joint, int), point_node)


def _element_properties(frame: Frame, mesh: Mesh) -> dict[str, np.ndarray]:
    members = frame.members
    mats = [frame.materials[m.material] for m in members]
    secs = [frame.sections[m.section] for m in members]
    em = mesh.element_member
    prop = {
        "E": np.array([m.youngs_modulus for m in mats])[em],
        "rho": np.array([m.density for m in mats])[em],
        "A": np.array([s.area for s in secs])[em],
        "I": np.array([s.second_moment for s in secs])[em],
    }
    joint_e = np.array([j.youngs_modulus for j in frame.joints] + [np.nan])
    in_joint = mesh.element_joint >= 0
    prop["E"] = np.where(in_joint, joint_e[mesh.element_joint], prop["E"])
    if frame.beam_theory == "timoshenko":
        prop["nu"] = np.array([m.poisson_ratio for m in mats])[em]
        prop["kappa"] = np.array([s.shear_coefficient for s in secs])[em]
    return prop


def _element_data(frame: Frame, mesh: Mesh) -> tuple[ElementData, dict[str, np.ndarray]]:
    d = np.diff(mesh.node_xy[mesh.connectivity], axis=1)[:, 0]
    length = np.hypot(d[:, 0], d[:, 1])
    p = _element_properties(frame, mesh)
    phi = (elements.shear_parameter(length, p["I"], p["A"], p["kappa"], p["nu"])
           if frame.beam_theory == "timoshenko" else np.zeros_like(length))
    data = ElementData(_element_dofs(mesh), length, d[:, 0] / length, d[:, 1] / length,
                       p["E"] * p["A"] / length, p["E"] * p["I"] / ((1.0 + phi) * length), phi)
    return data, p


def _element_dofs(mesh: Mesh) -> np.ndarray:
    n = mesh.connectivity
    return np.concatenate([3 * n[:, :1] + np.arange(3), 3 * n[:, 1:] + np.arange(3)], axis=1)


def _assemble(matrices: np.ndarray, dofs: np.ndarray, index: np.ndarray) -> sp.csr_matrix:
    """Element matrices (n_el, 6, 6) summed straight onto the free dofs: ``index`` maps a mesh dof
    to its free dof, -1 where fixed (reducing each assembled matrix by fancy indexing afterwards
    cost O(mesh dofs) per joint matrix: most of the assembly at 200 joints and 1M dofs).
    """
    rows = index[np.repeat(dofs, 6, axis=1)].ravel()
    cols = index[np.tile(dofs, (1, 6))].ravel()
    keep = (rows >= 0) & (cols >= 0)
    size = int(index.max()) + 1
    a = sp.csr_matrix((matrices.ravel()[keep], (rows[keep], cols[keep])), shape=(size, size))
    a.sum_duplicates()
    return a


def _geometric(frame: Frame, mesh: Mesh, data: ElementData, index: np.ndarray) -> sp.csr_matrix:
    """Geometric stiffness of the members' axial forces (``Member.axial_force`` and ``locked_force``), free dofs.

    A force locked in between a member's own ends (``locked_force``) is carried back by its chord: the chord's
    string stiffness of the opposite force is added, so that the member bows under it between its ends but
    its sway as a whole is not softened (no P-delta: a tie inside a tube does not buckle the tube).
    """
    force = np.array([m.axial_force + m.locked_force for m in frame.members])[mesh.element_member]
    t = elements.rotation(data.cos, data.sin)
    kg = _assemble(elements.to_global(elements.geometric_local(data.length, force), t), data.dofs, index)
    locked = [m for m in frame.members if m.locked_force != 0.0]
    if not locked:
        return kg
    ends = np.array([[mesh.point_node[m.start], mesh.point_node[m.end]] for m in locked])
    chord = mesh.node_xy[ends[:, 1]] - mesh.node_xy[ends[:, 0]]
    length = np.hypot(chord[:, 0], chord[:, 1])
    string = elements.string_local(length, -np.array([m.locked_force for m in locked]))
    string = elements.to_global(string, elements.rotation(chord[:, 0] / length, chord[:, 1] / length))
    dofs = np.hstack([3 * ends[:, :1] + np.arange(3), 3 * ends[:, 1:] + np.arange(3)])
    return kg + _assemble(string, dofs, index)


def _deformations(model: Model, shapes: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Stretch and the two end rotations relative to the chord of every element, (n_el, n_shapes)."""
    e = model.elements
    u = model.expand(np.atleast_2d(shapes.T).T)[e.dofs]  # (n_el, 6, n_shapes)
    dx, dy = u[:, 3] - u[:, 0], u[:, 4] - u[:, 1]
    stretch = e.cos[:, None] * dx + e.sin[:, None] * dy
    chord = (-e.sin[:, None] * dx + e.cos[:, None] * dy) / e.length[:, None]
    return stretch, u[:, 2] - chord, u[:, 5] - chord


def element_energies(model: Model, shapes: np.ndarray, others: np.ndarray | None = None) -> np.ndarray:
    """``x^T K_e y`` of each element for the columns of ``shapes`` (x) and ``others`` (y, default x).

    Shape (n_elements, n_shapes): twice the strain energy of each element when ``others`` is None.
    Computed from each element's deformations (stretch and end rotations relative to the chord),
    not from the assembled matrix: for a bending mode of a frame with stiff axial dofs, ``phi^T K
    phi`` on the assembled ``K`` loses about 1e-7 to cancellation, this does not. Joint elements
    are at their joint's mean modulus (gamma = 1). Shapes are on the model's free dofs.
    """
    e = model.elements
    sx, ax, bx = _deformations(model, shapes)
    sy, ay, by = (sx, ax, bx) if others is None else _deformations(model, others)
    phi = e.phi[:, None]
    bending = (4.0 + phi) * (ax * ay + bx * by) + (2.0 - phi) * (ax * by + bx * ay)
    return e.axial[:, None] * sx * sy + e.bending[:, None] * bending


def joint_energies(model: Model, shapes: np.ndarray, others: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
    """``x^T K_rest y`` and ``x^T K_j y`` for every joint, from `element_energies`.

    Returns
    -------
    rest : (n_shapes,) everything outside the joint zones: elements, springs, geometric stiffness.
    joints : (n_joints, n_shapes) each joint zone at its mean modulus (``lambda_kj`` of eq. 5).
    """
    x = np.atleast_2d(shapes.T).T
    y = x if others is None else np.atleast_2d(others.T).T
    per_element = element_energies(model, x, None if others is None else y)
    n_joints = len(model.frame.joints)
    owner = model.mesh.element_joint
    sums = np.zeros((n_joints + 1, per_element.shape[1]))
    np.add.at(sums, owner + 1, per_element)  # row 0: elements outside the joints
    rest = sums[0] + np.einsum("ik,i,ik->k", x, model.spring_stiffness, y)
    if model.stiffness_geometric.nnz:
        rest = rest + np.einsum("ik,ik->k", x, model.stiffness_geometric @ y)
    return rest, sums[1:]


def strain_energy(model: Model, shapes: np.ndarray, gamma: np.ndarray | None = None) -> np.ndarray:
    """``phi^T K(gamma) phi`` for each shape (n_shapes,), accurate to rounding (see `element_energies`)."""
    rest, joints = joint_energies(model, shapes)
    weight = np.ones(len(joints)) if gamma is None else np.asarray(gamma, float)
    return rest + weight @ joints


def assemble(frame: Frame) -> Model:
    """Assemble the mass, rest stiffness and joint stiffnesses of ``frame`` (eq. 3-4).

    Returns
    -------
    Model
        Matrices on the free dofs; ``Model.stiffness(gamma)`` gives ``K(gamma)``.
    """
    mesh = mesh_frame(frame)
    n = mesh.dof_count
    data, p = _element_data(frame, mesh)
    t = elements.rotation(data.cos, data.sin)
    k_el = elements.to_global(elements.stiffness_local(data.length, p["E"], p["A"], p["I"], data.phi), t)
    m_el = elements.to_global(elements.mass_local(data.length, p["rho"], p["A"], p["I"], data.phi,
                                                  frame.beam_theory == "timoshenko"), t)
    diag_k, diag_m = np.zeros(n), np.zeros(n)
    fixed = np.zeros(n, bool)
    for support in frame.supports:
        node = mesh.point_node[support.point]
        for i, dof in enumerate(DOF_NAMES):
            value = support.stiffness(dof)
            if value == math.inf:
                fixed[3 * node + i] = True
            elif value is not None:
                diag_k[3 * node + i] += value
    for spring in frame.springs:
        diag_k[3 * mesh.point_node[spring.point] + DOF_NAMES.index(spring.dof)] += spring.stiffness
        diag_m[3 * mesh.point_node[spring.point] + DOF_NAMES.index(spring.dof)] += spring.mass
    for pm in frame.masses:
        node = mesh.point_node[pm.point]
        diag_m[3 * node: 3 * node + 3] += (pm.mass, pm.mass, pm.rotary_inertia)
    free = np.flatnonzero(~fixed)
    index = np.full(n, -1)
    index[free] = np.arange(free.size)

    # the elements grouped by joint once (rest first, as -1), each joint a slice of them
    order = np.argsort(mesh.element_joint, kind="stable")
    bounds = np.searchsorted(mesh.element_joint[order], np.arange(-1, len(frame.joints) + 1))
    group = [order[bounds[j]:bounds[j + 1]] for j in range(len(frame.joints) + 1)]
    k_geo = _geometric(frame, mesh, data, index)
    k_geo.eliminate_zeros()
    k_rest = _assemble(k_el[group[0]], data.dofs[group[0]], index) + sp.diags(diag_k[free]) + k_geo
    k_joints = tuple(_assemble(k_el[g], data.dofs[g], index) for g in group[1:])
    mass = _assemble(m_el, data.dofs, index) + sp.diags(diag_m[free])
    return Model(frame, mesh, mass.tocsr(), k_rest.tocsr(), k_joints, free, data, diag_k[free], k_geo)

"""Which candidates the diagnosis fits: each effect of the registry at each place the frame allows.

Every effect of `workbench.rig.effects.EFFECTS` that is a candidate, at each place of the kind it
names, gets a grid of its parameter (a `workbench.diagnose.curves.Sweep`, solved by
`workbench.diagnose.curves.solve_sweeps`, on a `workbench.tasks.Mapper`'s workers): a support's rotational
stiffness (clamped supports from a hundredth of the beam's EI / L up), the stinger's stiffness
(around the drive point's static stiffness) and the mass that moves with the drive (a candidate only
with the spring: `workbench.diagnose.verdict.PAIRED_ONLY`), each member's
axial force (-0.6 to 2 Euler loads carried through the frame, -1.5 to 2 locked in between the
member's own ends), each joint's modulus factor (0.1 to 10, and every joint at once), the shear
coefficient (Euler-Bernoulli frames), and an added mass. Amplitude softening and joint damping
(hysteretic or viscous) reuse the joint curves and the energy shares (`workbench.diagnose.verdict`).

**Mass position.** A first-order screen (`workbench.diagnose.localise.explained` of each mesh
node's translation) picks the few best places; around each, nearby nodes are fitted on a coarse
exact grid, and the best one's position along its member is refined between mesh nodes by a
bounded scalar search, before the full grid.
"""

from __future__ import annotations

import math

import numpy as np
import scipy.linalg
import scipy.sparse as sp
from scipy.optimize import linear_sum_assignment, minimize_scalar
from scipy.sparse.linalg import splu

from workbench.diagnose.baseline import Baseline
from workbench.diagnose.curves import Curve, Sweep, solve_sweeps
from workbench.diagnose.fitting import fit_curve
from workbench.diagnose.localise import explained
from workbench.diagnose.observations import Observations
from workbench.model.assembly import Mesh
from workbench.model.frame import Frame, member_length
from workbench.model.structure import structure_modes
from workbench.rig.effects import (
    ADDED_MASS,
    AXIAL_PRESTRESS,
    JOINT_STIFFNESS_SHIFT,
    SHEAR_DEFORMATION,
    STINGER_STIFFNESS,
    SUPPORT_COMPLIANCE,
)
from workbench.tasks import Mapper

__all__ = ["GRID_POINTS", "drive_sweeps", "frame_curves", "joint_sweeps", "mass_scale", "members_at"]

GRID_POINTS = 33
RITZ_EXTRA = 20  # Ritz basis of the mass screen: this many modes beyond the measured ones


def _bending(frame: Frame, member_index: int) -> float:
    m = frame.members[member_index]
    return frame.materials[m.material].youngs_modulus * frame.sections[m.section].second_moment


def _reference_bending(frame: Frame, point: str) -> tuple[float, float]:
    """EI (N.m2) and length (m) of the first member that starts or ends at ``point``."""
    for i, m in enumerate(frame.members):
        if point in (m.start, m.end):
            return _bending(frame, i), member_length(frame, m)
    return _bending(frame, 0), member_length(frame, frame.members[0])


def _support_sweeps(base: Baseline) -> list[Sweep]:
    """Each support's rotational spring and, where held, each translational one, softened from the file's.

    A real clamp gives way in translation as well as in rotation (a bolted foot slides and rocks on its
    plate): each held dof is one form of the support's compliance, and two of them at once one more
    (`workbench.diagnose.verdict`, by `workbench.diagnose.combined.form_pairs`). A fixed dof starts from a stiffness far
    above the member's (its ``EI / L`` in rotation, ``EI / L^3`` in translation, up to the axial ``EA / L``).
    """
    frame, _ = base.planar
    grids = []
    for s in frame.supports:
        ei, length = _reference_bending(frame, s.point)
        for dof, reference, decades in (("rz", ei / length, (-2, 3)), ("ux", ei / length ** 3, (-1, 6)),
                                        ("uy", ei / length ** 3, (-1, 6))):
            held = getattr(s, dof)
            if held is None:
                continue
            values = (reference * np.logspace(*decades, GRID_POINTS) if math.isinf(held)
                      else held * np.logspace(-3, 0, GRID_POINTS))
            grids.append(Sweep(SUPPORT_COMPLIANCE.name, s.point, values, values.size - 1, True, swept=dof))
    return grids


def mass_scale(mass: sp.spmatrix) -> float:
    """The scale (kg) of a frame's mass grids (added masses, the drive's moving mass): the free mass matrix's
    diagonal summed over every third free dof.

    It is not the frame's mass: where supports remove dofs the stride drifts off ``ux`` (on the proving ground's
    portals it sums mostly ``uy`` and some ``rz``: 0.50 kg on the two-bolt frame, whose rigid translation along x
    sees 1.16 kg). The grids it scales are the ones the validations ran with; a grid up to the frame's
    translating mass would be another rule, to be judged on a fresh seed.
    """
    return float(mass.diagonal()[0::3].sum())


def drive_sweeps(stiffness: sp.spmatrix, dof: int, where: str, fixed: dict, total_mass: float) -> list[Sweep]:
    """The shaker's drive in its two forms at the drive point, each on the excitation's dof only (frames and
    matrix models).

    Its spring (the stinger's axial stiffness in series with the shaker's suspension), from a ten-thousandth to
    ten times the drive point's static stiffness; and the mass that moves with the drive point (the armature and
    the stinger, guided across), which shows where the reference force is measured at the shaker, from 3e-4 to 1
    times ``total_mass``. The drive point's dynamic stiffness ``k - omega^2 m`` is both at once
    (`workbench.diagnose.combined.form_pairs`): a soft suspension leaves the mass alone, which lowers the
    frequencies as an added mass does, but on the drive's direction only.

    Parameters
    ----------
    stiffness : (n, n) the model's stiffness matrix, N/m (its free dofs).
    dof : the excitation's index among them.
    where : the drive point's name (a frame's point, a matrix model's ``"node N"``).
    fixed : further parameters of both forms (a frame's ``{"dof": "ux"}``).
    total_mass : the mass grid's top, kg (`mass_scale`; a matrix model's translating mass).

    Returns
    -------
    [the spring's grid (N/m), the moving mass's grid (kg)].
    """
    unit = np.zeros(stiffness.shape[0])
    unit[dof] = 1.0
    k_static = 1.0 / float(splu(stiffness.tocsc()).solve(unit)[dof])
    springs = k_static * np.logspace(-4, 1, GRID_POINTS)
    masses = total_mass * np.logspace(-3.5, 0, GRID_POINTS)
    return [Sweep(STINGER_STIFFNESS.name, where, springs, 0, True, dict(fixed)),
            Sweep(STINGER_STIFFNESS.name, where, masses, 0, True, dict(fixed), swept="moving_mass")]


def _stinger_sweeps(base: Baseline) -> list[Sweep]:
    frame, model = base.planar
    excitation = frame.excitation
    if excitation is None:
        return []
    return drive_sweeps(model.stiffness(), model.dof(excitation.point, excitation.dof), excitation.point,
                        {"dof": excitation.dof}, mass_scale(model.mass))


def _axial_sweeps(base: Baseline) -> list[Sweep]:
    """Each member's axial force in its two forms, from its pin-ended Euler load ``pi^2 EI / L^2``.

    Carried through the frame (a load, a support's reaction: the member's sway is softened, P-delta) or
    locked in between the member's own ends (a tie, a misfit rod, a tightening sequence: its chord carries the
    force back, so only its bowing between the ends is softened, and it takes more compression before it
    buckles). The two move the sway modes by factors of ten apart for the same bending modes.
    """
    frame, _ = base.planar
    grids = []
    for i, m in enumerate(frame.members):
        euler = math.pi ** 2 * _bending(frame, i) / member_length(frame, m) ** 2
        for reaction, lowest in (("frame", -0.6), ("chord", -1.5)):
            values = np.unique(np.concatenate([np.linspace(lowest, 0.0, 10), np.linspace(0.0, 2.0, 16)])) * euler
            grids.append(Sweep(AXIAL_PRESTRESS.name, m.name, values, int(np.flatnonzero(values == 0.0)[0]), False,
                                {"reaction": reaction}))
    return grids


def joint_sweeps(base: Baseline) -> list[Sweep]:
    """Each joint's modulus factor from 0.1 to 10, and every joint's at once (frames and matrix models)."""
    values = np.logspace(-1, 1, 2 * (GRID_POINTS // 2) + 1)
    grids = [Sweep(JOINT_STIFFNESS_SHIFT.name, j, values, values.size // 2, True) for j in base.frame.joint_names]
    if len(base.frame.joint_names) > 1:  # every joint at once (where null): the file's joint model itself is off
        grids.append(Sweep(JOINT_STIFFNESS_SHIFT.name, None, values, values.size // 2, True))
    return grids


def _shear_sweeps(base: Baseline) -> list[Sweep]:
    frame, _ = base.planar
    if frame.beam_theory == "timoshenko":
        return []
    kappa = next((s.shear_coefficient for s in frame.sections.values() if s.shear_coefficient), 5.0 / 6.0)
    values = kappa * np.logspace(-1.5, 2, GRID_POINTS)
    return [Sweep(SHEAR_DEFORMATION.name, None, values, values.size - 1, True)]


def frame_curves(base: Baseline, obs: Observations, residual: np.ndarray, weight: np.ndarray,
                 mapper: Mapper | None = None) -> list[Curve]:
    """One curve per frame-level candidate and place the frame allows (module docstring), those that could be
    solved.

    ``residual`` (n_measured,) relative frequency residual of the baseline and ``weight`` its
    inverse relative variance, for the added mass's screen; ``mapper`` solves the grids (`solve_sweeps`).
    """
    grids = (_support_sweeps(base) + _stinger_sweeps(base) + _axial_sweeps(base) + joint_sweeps(base)
             + _shear_sweeps(base) + _mass_sweeps(base, obs, residual, weight))
    return solve_sweeps(base, grids, mapper)


def _best_near(base: Baseline, obs: Observations, node: int, coarse: np.ndarray, reach_m: float,
               basis: tuple[np.ndarray, np.ndarray]) -> tuple[tuple[str, dict] | None, float]:
    """The place within ``reach_m`` of ``node`` whose coarse mass curve fits best, and its cost."""
    frame, model = base.planar
    mesh = model.mesh
    near = [place for n in range(len(mesh.node_xy)) if np.hypot(*(mesh.node_xy[n] - mesh.node_xy[node])) <= reach_m
            and (place := _place(frame, mesh, n)) is not None]
    best, best_cost = None, np.inf
    for where, fixed in near:
        cost = _mass_cost(base, obs, where, fixed, coarse, basis)
        if cost < best_cost:
            best, best_cost = (where, fixed), cost
    return best, best_cost


def _mass_sweeps(base: Baseline, obs: Observations, residual: np.ndarray, weight: np.ndarray,
                 keep: int = 3, reach_m: float = 0.03) -> list[Sweep]:
    """Added-mass grids at the few positions whose mass sensitivity best fits the residual.

    The first-order screen ranks every mesh node; around each of the ``keep`` best (5 cm apart),
    the nodes within ``reach_m`` are fitted on a coarse exact grid and the best one gets the
    full grid: the screen is linear, a mass of 10 % of the frame is not.
    """
    frame, model = base.planar
    mesh = model.mesh
    shapes = model.expand(base.modes.shapes)[:, base.pairing]
    translation = shapes[0::3] ** 2 + shapes[1::3] ** 2  # (n_nodes, n_measured): -0.5 m T per kg
    scores = np.array([explained(-0.5 * translation[node], residual, weight) for node in range(len(mesh.node_xy))])
    total_mass = mass_scale(model.mass)
    coarse = total_mass * np.logspace(-3.5, 0, 13)
    basis = _ritz_basis(base)
    chosen: list[int] = []
    grids: list[Sweep] = []
    for node in np.argsort(scores)[::-1]:
        if len(chosen) == keep:
            break
        if _place(frame, mesh, int(node)) is None or any(
                np.hypot(*(mesh.node_xy[node] - mesh.node_xy[c])) < 0.05 for c in chosen):
            continue
        chosen.append(int(node))
        best, best_cost = _best_near(base, obs, node, coarse, reach_m, basis)
        if best is not None and "position" in best[1]:
            best = _refine_position(base, obs, best[0], best[1]["position"], coarse, frame, basis)[0]
        elif best is not None:  # a named point: the mass may sit a few mm off it, along a member through it
            for member, position in _positions_of_point(frame, best[0]):
                refined, cost = _refine_position(base, obs, member, position, coarse, frame, basis)
                if cost < best_cost:
                    best, best_cost = refined, cost
        if best is not None:
            values = total_mass * np.logspace(-3.5, 0, GRID_POINTS)
            grids.append(Sweep(ADDED_MASS.name, best[0], values, 0, True, dict(best[1])))
    return grids


def _mass_cost(base: Baseline, obs: Observations, where: str, fixed: dict, masses: np.ndarray,
               basis: tuple[np.ndarray, np.ndarray]) -> float:
    """Frequency chi-square of the best mass (over the grid ``masses``, kg) at a place, on the Ritz screen."""
    curve = _ritz_mass_curve(base, where, fixed, masses, basis)
    return np.inf if curve is None else fit_curve(base, obs, curve, np.ones(obs.frequency_hz.shape[1], bool))[2]


def _ritz_basis(base: Baseline) -> tuple[np.ndarray, np.ndarray]:
    """Eigenvalues (n_basis,) and all-dof shapes (3 n_nodes, n_basis) of the nominal model's first modes: the
    Ritz basis of the mass screen (the measured count, plus `RITZ_EXTRA`).
    """
    frame, model = base.planar
    modes = structure_modes(model, min(base.count + RITZ_EXTRA, model.size - 2))
    return modes.eigenvalues, model.expand(modes.shapes)


def _translations_at(base: Baseline, where: str, fixed: dict, shapes: np.ndarray) -> np.ndarray | None:
    """(2, n_basis) the basis's x and y translations at a mass's place: a named point's node, or along a member
    linearly between the nodes of the element that holds the position.
    """
    frame, model = base.planar
    mesh = model.mesh
    if where in frame.points:
        node = mesh.point_node[where]
        return shapes[[3 * node, 3 * node + 1]]
    member = next((i for i, m in enumerate(frame.members) if m.name == where), None)
    if member is None:
        return None
    m = frame.members[member]
    x0, x1 = np.asarray(frame.points[m.start]), np.asarray(frame.points[m.end])
    xy = x0 + float(fixed.get("position", 0.5)) * (x1 - x0)
    for a, b in mesh.connectivity[mesh.element_member == member]:
        pa, pb = mesh.node_xy[a], mesh.node_xy[b]
        t = float(np.dot(xy - pa, pb - pa) / np.dot(pb - pa, pb - pa))
        if -1e-9 <= t <= 1 + 1e-9:
            return ((1 - t) * shapes[[3 * a, 3 * a + 1]] + t * shapes[[3 * b, 3 * b + 1]])
    return None


def _ritz_mass_curve(base: Baseline, where: str, fixed: dict, masses: np.ndarray,
                     basis: tuple[np.ndarray, np.ndarray]) -> Curve | None:
    """Frequencies of the frame with a point mass on the grid ``masses`` (kg), by Rayleigh-Ritz on the nominal
    modes: ``K_r = diag(lambda)``, ``M_r = I + m U^T U`` with ``U`` the basis's translations at the place.

    A screen only: it ranks places and positions (tens of them, each on a grid of masses) at a dense
    eigen-solve of the basis's size instead of a solve of the frame; the place it picks gets exact solves
    (`sweep`). Upper bounds of the exact frequencies, within a small fraction of the shift for the masses the
    screen has to tell apart.
    """
    eigenvalues, shapes = basis
    u = _translations_at(base, where, fixed, shapes)
    if u is None:
        return None
    n = base.count
    out = np.empty((masses.size, n))
    gram = u.T @ u
    for i, mass in enumerate(masses):
        lam, vec = scipy.linalg.eigh(np.diag(eigenvalues), np.eye(eigenvalues.size) + mass * gram)
        rows, cols = linear_sum_assignment(-(vec[:n] ** 2))  # each nominal mode to the Ritz mode it dominates
        out[i, rows] = np.sqrt(np.maximum(lam[cols], 0.0)) / (2 * np.pi)
    return Curve(ADDED_MASS.name, where, ADDED_MASS.parameter or "mass", masses, out, True, dict(fixed))


def _refine_position(base: Baseline, obs: Observations, member: str, position: float, masses: np.ndarray,
                     frame: Frame, basis: tuple[np.ndarray, np.ndarray]) -> tuple[tuple[str, dict], float]:
    """Position of a mass between mesh nodes: a bounded scalar search within one element each side."""
    step = frame.element_length / member_length(frame, frame.member(member))
    lo, hi = max(position - step, 0.005), min(position + step, 0.995)
    res = minimize_scalar(lambda x: _mass_cost(base, obs, member, {"position": float(x)}, masses, basis),
                          bounds=(lo, hi), method="bounded", options={"xatol": 1e-4, "maxiter": 12})
    return (member, {"position": round(float(res.x), 4)}), float(res.fun)


def members_at(frame: Frame, name: str | None) -> list[tuple[str, float | None]]:
    """Members a frame name stands on, with its position along each (fraction of the length from the start).

    A member is itself (position None); a point, every member whose segment holds it; a joint, its member.
    """
    if name is None:
        return []
    if any(m.name == name for m in frame.members):
        return [(name, None)]
    if name in frame.points:
        x, y = frame.points[name]
        out: list[tuple[str, float | None]] = []
        for m in frame.members:
            (x0, y0), (x1, y1) = frame.points[m.start], frame.points[m.end]
            length = math.hypot(x1 - x0, y1 - y0)
            off = abs((x1 - x0) * (y - y0) - (y1 - y0) * (x - x0)) / length
            along = ((x - x0) * (x1 - x0) + (y - y0) * (y1 - y0)) / length
            if off < 1e-9 * length and -1e-9 * length <= along <= length * (1 + 1e-9):
                out.append((m.name, along / length))
        return out
    return [(j.member, None) for j in frame.joints if j.name == name]


def _positions_of_point(frame: Frame, point: str) -> list[tuple[str, float]]:
    return [(m, p) for m, p in members_at(frame, point) if p is not None]


def _place(frame: Frame, mesh: Mesh, node: int) -> tuple[str, dict] | None:
    """A mesh node as a named point, or as a member and a position along it (None on a support)."""
    supported = {s.point for s in frame.supports}
    for name, n in mesh.point_node.items():
        if n == node:
            return (None if name in supported else (name, {}))
    member = int(mesh.element_member[np.flatnonzero((mesh.connectivity == node).any(axis=1))[0]])
    m = frame.members[member]
    x0 = np.asarray(frame.points[m.start])
    position = float(np.hypot(*(mesh.node_xy[node] - x0)) / member_length(frame, m))
    return m.name, {"position": round(position, 4)}

"""The `Frame` record and its parts: what a frame file (``frame.toml``, CONTRACTS.md section 1) holds.

A frame is a planar set of straight beams (members) joined rigidly where they meet, with bolted
joints as zones of a member whose Young's modulus is random (paper section 2.2.2, Figure 3c).
`workbench.model.frame_file` reads, validates and writes the file; this module holds the records.

One optional key extends the contract: ``axial_force`` (N, tension positive) on a member, the
locked-in axial load whose geometric stiffness the gap diagnosis needs.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, replace

import numpy as np

__all__ = [
    "DOF_NAMES",
    "BEAM_THEORIES",
    "DEFAULT_DAMPING_RATIO",
    "DEFAULT_ELEMENT_LENGTH",
    "FIXED",
    "FrameFileError",
    "Material",
    "Section",
    "Member",
    "Joint",
    "Support",
    "PointMass",
    "GroundSpring",
    "DofRef",
    "Sensor",
    "Frame",
    "member_length",
    "locate_point",
    "points_on_member",
    "member_ends",
    "moved_frame",
]

DOF_NAMES = ("ux", "uy", "rz")
BEAM_THEORIES = ("euler-bernoulli", "timoshenko")
DEFAULT_ELEMENT_LENGTH = 0.01  # m
DEFAULT_DAMPING_RATIO = 0.005
FIXED = math.inf  # a support dof of infinite stiffness is removed from the system
# Relative to the frame's size: how far a point may sit from a member and still be on it.
_ON_MEMBER_TOLERANCE = 1e-9


class FrameFileError(ValueError):
    """A frame file breaks the contract; the message is one line: ``file: field: problem``."""


@dataclass(frozen=True)
class Material:
    """A material: Young's modulus (Pa), density (kg/m3), Poisson's ratio (Timoshenko beams only)."""

    name: str
    youngs_modulus: float  # Pa
    density: float  # kg/m3
    poisson_ratio: float | None = None


@dataclass(frozen=True)
class Section:
    """A cross-section: area (m2), second moment of area in the frame's plane (m4), shear coefficient."""

    name: str
    area: float  # m2
    second_moment: float  # m4
    shear_coefficient: float | None = None


@dataclass(frozen=True)
class Member:
    """A straight beam from point ``start`` to point ``end``, of one material and one section."""

    name: str
    start: str
    end: str
    material: str
    section: str
    axial_force: float = 0.0  # N, tension positive (extension of the contract)
    # N, tension positive: a force locked in between the member's own ends (a tie, tendon or misfit rod
    # across it), which its chord carries back; not in the frame file (the diagnosis's candidate only)
    locked_force: float = 0.0


@dataclass(frozen=True)
class Joint:
    """A bolted joint: the zone ``span`` of a member whose modulus is random (mean, coefficient of variation).

    Joints of one ``group`` share their random modulus law (default: the joint's own name).
    """

    name: str
    member: str
    span: tuple[float, float]  # m from the member's start
    youngs_modulus: float  # Pa, mean of the zone's modulus
    cov: float = 0.0
    group: str = ""

    def __post_init__(self) -> None:
        if not self.group:
            object.__setattr__(self, "group", self.name)


@dataclass(frozen=True)
class Support:
    """Support conditions at a point; each dof is None (free), `math.inf` (fixed) or N/m, N.m/rad."""

    point: str
    ux: float | None = None
    uy: float | None = None
    rz: float | None = None

    def stiffness(self, dof: str) -> float | None:
        return getattr(self, dof)


@dataclass(frozen=True)
class PointMass:
    """A lumped mass at a point."""

    point: str
    mass: float  # kg
    rotary_inertia: float = 0.0  # kg.m2


@dataclass(frozen=True)
class GroundSpring:
    """A spring from one dof of a point to the ground, and a mass that moves with that dof only.

    The pair is a shaker's drive on the structure where the reference force is measured at the shaker: its
    suspension (the spring) and its armature and stinger (the mass, guided across the drive direction), a
    dynamic stiffness ``k - omega^2 m`` at the drive point. A frame file gives the spring only.
    """

    point: str
    dof: str
    stiffness: float  # N/m or N.m/rad
    mass: float = 0.0  # kg (kg.m2 on rz) moving with the dof


@dataclass(frozen=True)
class DofRef:
    """One dof (ux, uy or rz) of a named point: the excitation."""

    point: str
    dof: str


@dataclass(frozen=True)
class Sensor:
    """A named measurement of one dof (ux, uy or rz) of a point."""

    name: str
    point: str
    dof: str


@dataclass(frozen=True)
class Frame:
    """A validated frame file. Immutable: change it with `dataclasses.replace`."""

    name: str
    points: dict[str, tuple[float, float]]
    materials: dict[str, Material]
    sections: dict[str, Section]
    members: tuple[Member, ...]
    joints: tuple[Joint, ...] = ()
    supports: tuple[Support, ...] = ()
    masses: tuple[PointMass, ...] = ()
    springs: tuple[GroundSpring, ...] = ()
    excitation: DofRef | None = None
    sensors: tuple[Sensor, ...] = ()
    damping_ratios: tuple[float, ...] = (DEFAULT_DAMPING_RATIO,)
    beam_theory: str = "euler-bernoulli"
    element_length: float = DEFAULT_ELEMENT_LENGTH  # m
    description: str = ""
    source: str = field(default="<frame>", compare=False)

    def member(self, name: str) -> Member:
        for m in self.members:
            if m.name == name:
                return m
        raise KeyError(f"{self.source}: members: no member named {name!r}")

    def joint(self, name: str) -> Joint:
        for j in self.joints:
            if j.name == name:
                return j
        known = ", ".join(j.name for j in self.joints) or "none"
        raise KeyError(f"{self.source}: joints: no joint named {name!r} (known: {known})")

    @property
    def joint_names(self) -> tuple[str, ...]:
        return tuple(j.name for j in self.joints)

    def damping_ratio(self, mode_count: int) -> tuple[float, ...]:
        """Modal damping ratios of the first `mode_count` modes; the last given value repeats."""
        r = self.damping_ratios
        return tuple(r[min(k, len(r) - 1)] for k in range(mode_count))


def member_length(frame: Frame, member: Member) -> float:
    """Length of `member` in m."""
    (x0, y0), (x1, y1) = frame.points[member.start], frame.points[member.end]
    return math.hypot(x1 - x0, y1 - y0)


def locate_point(
    points: dict[str, tuple[float, float]], member: Member, xy: tuple[float, float]
) -> float | None:
    """Distance in m along `member` from its start to `xy`, or None if `xy` is not on it."""
    start, end = points[member.start], points[member.end]
    s = _along(np.array([xy], float), np.array(start, float), np.array(end, float), _tolerance(points))[0]
    return None if np.isnan(s) else float(s)


def points_on_member(points: dict[str, tuple[float, float]], member: Member) -> dict[str, float]:
    """Every point lying on `member`: name -> distance in m from its start (`locate_point` for all at once).

    One pass over the points per member: meshing and checking a frame of thousands of points stays linear
    in the points per member (point by point, each with its own tolerance scan, it was quadratic).
    """
    names = list(points)
    xy = np.array([points[n] for n in names], float).reshape(-1, 2)
    s = _along(xy, np.array(points[member.start], float), np.array(points[member.end], float), _tolerance(points))
    return {name: float(v) for name, v in zip(names, s) if not np.isnan(v)}


def _tolerance(points: dict[str, tuple[float, float]]) -> float:
    """How far off a member a point may lie, m: relative to the frame's largest coordinate."""
    coordinates = np.abs(np.array(list(points.values()), float))
    return _ON_MEMBER_TOLERANCE * max(1.0, float(coordinates.max()) if coordinates.size else 1.0)


def _along(xy: np.ndarray, start: np.ndarray, end: np.ndarray, tol: float) -> np.ndarray:
    """(n,) distance of each point of ``xy`` (n, 2) along the segment from its start, m; NaN when off it."""
    d = end - start
    length = float(math.hypot(d[0], d[1]))
    rel = xy - start
    s = (rel[:, 0] * d[0] + rel[:, 1] * d[1]) / length
    off = np.abs(rel[:, 0] * d[1] - rel[:, 1] * d[0]) / length
    inside = (off <= tol) & (s >= -tol) & (s <= length + tol)
    return np.where(inside, np.clip(s, 0.0, length), np.nan)


def member_ends(frame: Frame) -> list[str]:
    """The points that start or end a member, in the frame's order of points."""
    ends = {n for m in frame.members for n in (m.start, m.end)}
    return [n for n in frame.points if n in ends]


def moved_frame(frame: Frame, offsets: dict[str, tuple[float, float]]) -> tuple[Frame, dict[str, float]]:
    """``frame`` with member ends moved by ``offsets`` (point name -> (dx, dy), m), and each member's new length
    over its old.

    A point on a member that ends no member (a sensor, the drive) keeps its fraction of that member's length,
    and so does each joint's span: the frame as built is the file's frame a little stretched, member by member.
    """
    ends = set(member_ends(frame))
    points = {n: (x + offsets.get(n, (0.0, 0.0))[0], y + offsets.get(n, (0.0, 0.0))[1]) if n in ends else (x, y)
              for n, (x, y) in frame.points.items()}
    ratio = {}
    for member in frame.members:
        length = member_length(frame, member)
        a, b = (np.array(points[n], float) for n in (member.start, member.end))
        ratio[member.name] = float(np.linalg.norm(b - a)) / length
        for name, s in points_on_member(frame.points, member).items():
            if name not in ends:
                xy = a + (s / length) * (b - a)
                points[name] = (float(xy[0]), float(xy[1]))
    joints = tuple(replace(j, span=(j.span[0] * ratio[j.member], j.span[1] * ratio[j.member])) for j in frame.joints)
    return replace(frame, points=points, joints=joints), ratio

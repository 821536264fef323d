"""Mechanisms outside the diagnosis's vocabulary: gaps that no candidate of ``workbench/rig/effects.py`` explains.

=================  ===========================================================================
two_cracks         two edge cracks (rotational springs at two stations), their compliance from the
                   crack depth ratio ``x`` (Dimarogonas and Paipetis' flexibility of a cracked
                   rectangular section: ``c = 5.346 h F(a / h) / (E I)``);
thicker_member     one member's thickness times ``1 + x`` (A and mass times ``1 + x``, I times ``(1 + x)^3``);
moved_column       the outermost column built ``x`` m further out than drawn (geometry: its beam longer);
corner_gusset      a plate of thickness ``x`` (m) welded across a corner between the two members;
elastic_contact    a spring of ``x`` N/m across a member at one station (the frame leaning on a stop).
=================  ===========================================================================

Each is a `workbench.proving.mechanisms.Mechanism` of effect ``outside_vocabulary``; its ``where`` names the
member or point it sits on, for the record only (the right verdict is ``unexplained``).
"""

from __future__ import annotations

import math
from dataclasses import replace
from typing import Any

import numpy as np

from workbench.model.frame import Frame, member_length, points_on_member
from workbench.proving.article import Article, Attachment, Hinge, Rod, Zone
from workbench.proving.mechanisms import OUTSIDE, Mechanism, free_station, matrix3, section_depth

__all__ = ["OUTSIDE_VARIANTS", "outside_mechanism", "crack_compliance"]

OUTSIDE_VARIANTS = ("two_cracks", "thicker_member", "moved_column", "corner_gusset", "elastic_contact")


def crack_compliance(depth_ratio: float, depth: float, bending_rigidity: float) -> float:
    """Rotational compliance of an open edge crack, rad/(N.m): ``5.346 h F(a/h) / EI`` (Dimarogonas & Paipetis).

    Parameters
    ----------
    depth_ratio : crack depth over section depth, in [0, 0.8]. depth : section depth h, m. bending_rigidity : EI, N.m2.
    """
    a = depth_ratio
    f = (1.8624 * a**2 - 3.95 * a**3 + 16.375 * a**4 - 37.226 * a**5 + 76.81 * a**6 - 126.9 * a**7
         + 172.0 * a**8 - 143.97 * a**9 + 66.56 * a**10)
    return 5.346 * depth * f / bending_rigidity


def _members(frame: Frame) -> list[str]:
    return [m.name for m in frame.members]


def _two_cracks(frame: Frame, rng: np.random.Generator) -> Mechanism:
    names = _members(frame)
    first = names[int(rng.integers(len(names)))]
    second = first if rng.random() < 0.5 else names[int(rng.integers(len(names)))]
    s1 = free_station(frame, first, rng, clearance=0.03)
    s2 = free_station(frame, second, rng, clearance=0.03)
    for _ in range(50):  # two cracks on one member stay apart
        if second != first or abs(s2 - s1) > 0.05:
            break
        s2 = free_station(frame, second, rng, clearance=0.03)
    ratio = float(rng.uniform(0.6, 1.0))  # the second crack is the shallower

    def rigidity(member: str) -> tuple[float, float]:
        m = frame.member(member)
        return (frame.materials[m.material].youngs_modulus * frame.sections[m.section].second_moment,
                section_depth(frame, member))

    def build(article: Article, x: float) -> Article:
        hinges = []
        for member, s, depth_ratio in ((first, s1, x), (second, s2, x * ratio)):
            ei, h = rigidity(member)
            hinges.append(Hinge(member, s, 1.0 / crack_compliance(depth_ratio, h, ei)))
        return replace(article, hinges=article.hinges + tuple(hinges))

    def parameters(x: float) -> dict[str, Any]:
        return {"cracks": [{"member": first, "station_m": s1, "depth_ratio": x},
                           {"member": second, "station_m": s2, "depth_ratio": x * ratio}]}

    return Mechanism(OUTSIDE, "two_cracks", first, (0.005, 0.7), build, parameters)


def _thicker_member(frame: Frame, rng: np.random.Generator) -> Mechanism:
    member = _members(frame)[int(rng.integers(len(frame.members)))]
    length = member_length(frame, frame.member(member))

    def build(article: Article, x: float) -> Article:
        zone = Zone(member, (0.0, length), area_factor=1.0 + x, inertia_factor=(1.0 + x) ** 3)
        return replace(article, zones=article.zones + (zone,))

    def parameters(x: float) -> dict[str, Any]:
        return {"member": member, "thickness_factor": 1.0 + x}

    return Mechanism(OUTSIDE, "thicker_member", member, (1e-4, 1.0), build, parameters)


def _columns(frame: Frame) -> list[str]:
    """Vertical members, the outermost (largest x) first."""
    vertical = [m for m in frame.members if abs(frame.points[m.start][0] - frame.points[m.end][0]) < 1e-9]
    return [m.name for m in sorted(vertical, key=lambda m: -frame.points[m.start][0])]


def _move_column(frame: Frame, column: str, dx: float) -> Frame:
    """``frame`` with the points of ``column`` moved by ``dx`` m along x; joints at a moved end follow it."""
    moved = set(points_on_member(frame.points, frame.member(column)))
    points = {n: ((xy[0] + dx, xy[1]) if n in moved else xy) for n, xy in frame.points.items()}
    joints = []
    for j in frame.joints:
        m = frame.member(j.member)
        old, new = member_length(frame, m), math.dist(points[m.start], points[m.end])
        if j.member != column and m.end in moved and m.start not in moved and (j.span[0] + j.span[1]) > old:
            j = replace(j, span=(j.span[0] + new - old, j.span[1] + new - old))  # a zone at the moved end
        joints.append(j)
    return replace(frame, points=points, joints=tuple(joints))


def _moved_column(frame: Frame, rng: np.random.Generator) -> Mechanism:
    columns = _columns(frame)
    if not columns:
        raise ValueError(f"{frame.name}: no vertical member to move")
    column = columns[0]
    xs = [xy[0] for xy in frame.points.values()]
    outward = 1.0 if frame.points[frame.member(column).start][0] >= np.mean(xs) else -1.0

    def build(article: Article, x: float) -> Article:
        return replace(article, frame=_move_column(article.frame, column, outward * x))

    def parameters(x: float) -> dict[str, Any]:
        return {"member": column, "moved_m": outward * x}

    return Mechanism(OUTSIDE, "moved_column", column, (1e-5, 0.08), build, parameters)


def _corners(frame: Frame) -> list[tuple[str, str, str]]:
    """(point, member a, member b): points where two non-parallel members end."""
    out = []
    for point in frame.points:
        ends = [m for m in frame.members if point in (m.start, m.end)]
        for i, a in enumerate(ends):
            for b in ends[i + 1:]:
                da = np.subtract(frame.points[a.end], frame.points[a.start])
                db = np.subtract(frame.points[b.end], frame.points[b.start])
                if abs(da[0] * db[1] - da[1] * db[0]) > 1e-6 * np.linalg.norm(da) * np.linalg.norm(db):
                    out.append((point, a.name, b.name))
    return out


def _leg(frame: Frame, member: str, corner: str, distance: float) -> tuple[str, float]:
    m = frame.member(member)
    return (member, distance) if m.start == corner else (member, round(member_length(frame, m) - distance, 6))


def _corner_gusset(frame: Frame, rng: np.random.Generator) -> Mechanism:
    corners = _corners(frame)
    if not corners:
        raise ValueError(f"{frame.name}: no corner for a gusset")
    point, a, b = corners[int(rng.integers(len(corners)))]
    thickness, width = float(rng.uniform(1e-3, 3e-3)), 0.03  # m: a plate as wide as the members

    def legs(x: float) -> tuple[tuple[str, float], tuple[str, float]]:
        return _leg(frame, a, point, x), _leg(frame, b, point, x)

    def build(article: Article, x: float) -> Article:
        # the plate as a diagonal strip between its legs' ends, x from the corner along each member
        start, end = legs(x)
        rod = Rod("gusset", start, end, 70e9, 2700.0, width * thickness, width * thickness**3 / 12, 5.0 / 6.0,
                  0.33, elements=3)
        return replace(article, rods=article.rods + (rod,))

    def parameters(x: float) -> dict[str, Any]:
        return {"corner": point, "legs_m": x, "thickness_m": thickness}

    shortest = min(member_length(frame, frame.member(n)) for n in (a, b))
    return Mechanism(OUTSIDE, "corner_gusset", point, (1e-3, min(0.1, 0.3 * shortest)), build, parameters)


def _elastic_contact(frame: Frame, rng: np.random.Generator) -> Mechanism:
    member = _members(frame)[int(rng.integers(len(frame.members)))]
    s = free_station(frame, member, rng, clearance=0.03)
    m = frame.member(member)
    d = np.subtract(frame.points[m.end], frame.points[m.start]) / member_length(frame, m)
    normal = np.array([-d[1], d[0], 0.0])

    def build(article: Article, x: float) -> Article:
        k = x * np.outer(normal, normal)
        return replace(article, attachments=article.attachments + (Attachment((member, s), stiffness=matrix3(k)),))

    def parameters(x: float) -> dict[str, Any]:
        return {"member": member, "station_m": s, "stiffness": x}

    return Mechanism(OUTSIDE, "elastic_contact", member, (1.0, 1e7), build, parameters)


_FACTORIES = {"two_cracks": _two_cracks, "thicker_member": _thicker_member, "moved_column": _moved_column,
              "corner_gusset": _corner_gusset, "elastic_contact": _elastic_contact}


def outside_mechanism(frame: Frame, rng: np.random.Generator, variant: str | None = None) -> Mechanism:
    """An out-of-vocabulary mechanism on ``frame`` (module docstring), its variant drawn unless given."""
    name = variant or OUTSIDE_VARIANTS[int(rng.integers(len(OUTSIDE_VARIANTS)))]
    if name not in _FACTORIES:
        raise ValueError(f"outside_mechanism: {name!r} is not one of {', '.join(OUTSIDE_VARIANTS)}")
    return _FACTORIES[name](frame, rng)


"""The proving ground's effects: each produced by a mechanism other than the diagnosis's candidate form.

The diagnosis fits parametrised enrichments of the nominal model (``workbench/rig/effects.py``: one
rotational support spring, a point mass, Timoshenko sections, a grounded spring at the drive point, a given
axial force, a joint modulus factor, a softening linear in the amplitude, a damping ratio per joint energy
share). Data made by those very forms would flatter it. Here each effect of the vocabulary comes from
another physical mechanism (`Mechanism`, one scalar intensity ``x``, built on an `Article`):

======================  ==========================================================================
support_compliance      ``coupled_support``: the clamp's compliance sits below the node: translational
                        springs at an offset plus a rotational spring, a full 3x3 stiffness matrix with
                        translation-rotation coupling that gives the nominal first frequency when tight;
                        ``x``: the clamp loosened, the whole matrix over ``1 + x``.
added_mass              ``spread_mass``: a block spread over 2-6 cm of a member (kg/m and its own rotary
                        inertia); or ``eccentric_mass``: a mass mounted 15-40 mm off the member's axis
                        (a 3x3 mass matrix coupling translation and rotation). ``x``: the mass, kg.
shear_deformation       ``stocky_sections``: every section thicker (``x``: thickness factor); the
                        article is Timoshenko, the nominal file of the same sections Euler-Bernoulli.
stinger_stiffness       ``stinger_rod``: a steel rod (beam elements with mass) from the drive point to a
                        shaker armature (a mass on a suspension spring, guided across), the force put
                        in at the armature (the shaker's drive is the reference); ``x``: the
                        suspension's stiffness, N/m.
axial_prestress         ``misfit_tie`` / ``misfit_strut``: a wire tie too short (member compressed) or a
                        carbon strut too long (member stretched) between the member's ends; the misfit
                        ``x`` (m) is solved statically and the geometric stiffness built from the solved
                        axial forces of every element.
joint_stiffness_shift   ``joint_hinge``: a rotational spring at the middle of the joint (softer), or
                        ``joint_subzone``: the joint's central part softer or stiffer; not the modulus of
                        the whole zone.
amplitude_softening     ``sublinear_softening``: ``Y(a) = Y (1 - drop ((a - 1) / 4) ** p)`` with p < 1 and
                        a law per bolt (the others soften less); zero at the lowest amplitude.
joint_damping           ``joint_dashpot``: a rotational dashpot across the joint's span (a non-proportional
                        damping matrix; FRFs by a direct solve per line).
======================  ==========================================================================

Out-of-vocabulary mechanisms are in `workbench.proving.outside`. The intensity is calibrated to a
footprint on the frequencies (or damping) by `workbench.proving.footprint`.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, replace
from typing import Any

import numpy as np
from scipy.optimize import brentq

from workbench.model.frame import FIXED, Frame, Support, member_length, points_on_member
from workbench.proving.article import (
    Article,
    Attachment,
    Dashpot,
    ExtraNode,
    Hinge,
    Matrix3,
    Rod,
    Softening,
    Zone,
)
from workbench.proving.beams import solve_modes
from workbench.proving.fem import discretise

__all__ = ["EFFECTS", "OUTSIDE", "NONE", "Mechanism", "VARIANTS", "vocabulary_mechanism", "free_station",
           "section_depth", "joint_bending_rigidity", "matrix3"]

NONE = "none"
OUTSIDE = "outside_vocabulary"
# the diagnosis's vocabulary (CONTRACTS.md section 3), without none and unexplained
EFFECTS = ("support_compliance", "added_mass", "shear_deformation", "stinger_stiffness", "axial_prestress",
           "joint_stiffness_shift", "amplitude_softening", "joint_damping")
VARIANTS: dict[str, tuple[str, ...]] = {
    "support_compliance": ("coupled_support",),
    "added_mass": ("spread_mass", "eccentric_mass"),
    "shear_deformation": ("stocky_sections",),
    "stinger_stiffness": ("stinger_rod",),
    "axial_prestress": ("misfit_tie", "misfit_strut"),
    "joint_stiffness_shift": ("joint_hinge", "joint_subzone_soft", "joint_subzone_stiff"),
    "amplitude_softening": ("sublinear_softening",),
    "joint_damping": ("joint_dashpot",),
}


@dataclass(frozen=True)
class Mechanism:
    """A hidden effect with one scalar intensity ``x``.

    Attributes
    ----------
    effect : the vocabulary name it stands for (`EFFECTS`), or ``outside_vocabulary``.
    name : the mechanism (module docstring). where : the frame name the truth gives (or None: global).
    bounds : ``(lo, hi)`` of ``x``; the footprint grows with ``x`` over it.
    build : ``build(article, x)``, the article with the effect.
    parameters : ``parameters(x)``, the truth's JSON-ready parameters (with the vocabulary's magnitude key).
    channel : what the footprint measures: ``frequency``, ``amplitude`` (the high-amplitude shift) or ``damping``.
    nominal : ``nominal(frame, x)``, the nominal frame file at ``x`` (stocky_sections only), else None.
    """

    effect: str
    name: str
    where: str | None
    bounds: tuple[float, float]
    build: Callable[[Article, float], Article]
    parameters: Callable[[float], dict[str, Any]]
    channel: str = "frequency"
    nominal: Callable[[Frame, float], Frame] | None = None


def section_depth(frame: Frame, member: str) -> float:
    """In-plane depth of a member's section as a rectangle, m: ``sqrt(12 I / A)``."""
    sec = frame.sections[frame.member(member).section]
    return math.sqrt(12.0 * sec.second_moment / sec.area)


def joint_bending_rigidity(frame: Frame, joint: str) -> float:
    """EI of a joint's zone at its mean modulus, N.m2."""
    j = frame.joint(joint)
    return j.youngs_modulus * frame.sections[frame.member(j.member).section].second_moment


def free_station(frame: Frame, member: str, rng: np.random.Generator, clearance: float = 0.02,
                 lo: float = 0.15, hi: float = 0.85) -> float:
    """A distance along ``member`` (m), between ``lo`` and ``hi`` of its length, ``clearance`` m from its
    named points and joint zones.
    """
    m = frame.member(member)
    length = member_length(frame, m)
    busy = list(points_on_member(frame.points, m).values())
    busy += [s for j in frame.joints if j.member == member for s in j.span]
    for _ in range(200):
        s = float(rng.uniform(lo * length, hi * length))
        inside = any(j.span[0] - clearance < s < j.span[1] + clearance for j in frame.joints if j.member == member)
        if not inside and all(abs(s - b) >= clearance for b in busy):
            return round(s, 4)
    raise ValueError(f"{frame.name}: member {member!r} has no free station {clearance} m clear of points and joints")


def _pick(names: list[str], rng: np.random.Generator) -> str:
    return names[int(rng.integers(len(names)))]


def _direction(frame: Frame, member: str) -> tuple[float, float]:
    m = frame.member(member)
    (x0, y0), (x1, y1) = frame.points[m.start], frame.points[m.end]
    length = math.hypot(x1 - x0, y1 - y0)
    return (x1 - x0) / length, (y1 - y0) / length


def matrix3(a: np.ndarray) -> Matrix3:
    """A (3, 3) array as the nested tuples an `Attachment` holds."""
    rows = [tuple(float(v) for v in row) for row in np.asarray(a, float).reshape(3, 3)]
    return (rows[0], rows[1], rows[2])  # type: ignore[return-value]


# ------------------------------------------------------------------------------------ support_compliance

def _first_frequency(article: Article) -> float:
    d = discretise(article, {j.name: j.youngs_modulus for j in article.frame.joints})
    return float(solve_modes(d.system.stiffness, d.system.mass, 1).frequency_hz[0])


def _clamp(frame: Frame, support: Support, rng: np.random.Generator) -> np.ndarray:
    """A clamp's 3x3 stiffness at a support: the compliance centre below the node (module docstring).

    A horizontal spring at depth h and a vertical one at e across, stiff (the nominal file says fixed: and
    1e7 N/m across already moves the bundled frames' mode 9 by 1.4 %), plus a rotational spring. Each offset
    spring is rank one and couples translation and rotation. The file's rz is a fitted figure (frames/README),
    so the rotational spring is set for the clamp to give the nominal first frequency (brentq).
    """
    k_r0 = support.rz if support.rz is not None and support.rz != FIXED else 1e6
    k_x, k_y = float(10 ** rng.uniform(8.0, 8.5)), float(10 ** rng.uniform(8.5, 9.0))
    h, e = float(rng.uniform(0.002, 0.008)), float(rng.uniform(-0.002, 0.002))
    # a spring along n at offset r moves with u + theta x r: g = (n_x, n_y, n_y r_x - n_x r_y)
    gx, gy = np.array([1.0, 0.0, h]), np.array([0.0, 1.0, e])
    coupled = k_x * np.outer(gx, gx) + k_y * np.outer(gy, gy)
    free = replace(frame, supports=tuple(s if s.point != support.point else Support(s.point) for s in frame.supports))
    target = _first_frequency(Article(frame))

    def gap(k_r: float) -> float:
        k = coupled + np.diag([0.0, 0.0, k_r])
        return _first_frequency(Article(free, attachments=(Attachment(support.point, stiffness=matrix3(k)),))) - target

    k_r = brentq(gap, 0.0, 4.0 * k_r0, xtol=1e-6 * k_r0) if gap(0.0) < 0 < gap(4.0 * k_r0) else k_r0
    return coupled + np.diag([0.0, 0.0, k_r])


def _coupled_support(frame: Frame, where: str | None, rng: np.random.Generator) -> Mechanism:
    supports = [s for s in frame.supports if any(v is not None for v in (s.ux, s.uy, s.rz))]
    support = next(s for s in supports if s.point == where) if where else supports[int(rng.integers(len(supports)))]
    tight = _clamp(frame, support, rng)
    k_r0 = support.rz if support.rz is not None and support.rz != FIXED else 1e6

    def build(article: Article, x: float) -> Article:
        frame_ = article.frame
        rest = tuple(s if s.point != support.point else Support(s.point) for s in frame_.supports)
        # a looser clamp: every term of the matrix falls together, translations and coupling too
        attachment = Attachment(support.point, stiffness=matrix3(tight / (1.0 + x)))
        return replace(article, frame=replace(frame_, supports=rest), attachments=article.attachments + (attachment,))

    def parameters(x: float) -> dict[str, Any]:
        k = tight / (1.0 + x)
        condensed = k[2, 2] - k[2, :2] @ np.linalg.solve(k[:2, :2], k[:2, 2])
        return {"rz": float(condensed), "rz_nominal": k_r0, "rz_translations_held": float(k[2, 2]),
                "ux": float(k[0, 0]), "uy": float(k[1, 1]), "stiffness_matrix": k.tolist()}

    return Mechanism("support_compliance", "coupled_support", support.point, (1e-4, 100.0), build, parameters)


# ------------------------------------------------------------------------------------------ added_mass

def _mass_place(frame: Frame, where: str | None, rng: np.random.Generator) -> tuple[str, float]:
    member = where if where in {m.name for m in frame.members} else _pick([m.name for m in frame.members], rng)
    return member, free_station(frame, member, rng, clearance=0.04)


def _spread_mass(frame: Frame, where: str | None, rng: np.random.Generator) -> Mechanism:
    member, s = _mass_place(frame, where, rng)
    width = float(rng.uniform(0.02, 0.06))
    span = (round(s - width / 2, 5), round(s + width / 2, 5))

    def build(article: Article, x: float) -> Article:
        # a block of length w: kg/m x / w, and its own rotary inertia x w^2 / 12 spread as x w / 12 per metre
        zone = Zone(member, span, mass_per_length=x / width, rotary_per_length=x * width / 12.0)
        return replace(article, zones=article.zones + (zone,))

    def parameters(x: float) -> dict[str, Any]:
        position = s / member_length(frame, frame.member(member))
        return {"mass": x, "member": member, "span": list(span), "position": position}

    return Mechanism("added_mass", "spread_mass", member, (1e-4, 2.0), build, parameters)


def _eccentric_mass(frame: Frame, where: str | None, rng: np.random.Generator) -> Mechanism:
    member, s = _mass_place(frame, where, rng)
    c, d = _direction(frame, member)
    offset = float(rng.uniform(0.015, 0.04)) * (1.0 if rng.random() < 0.5 else -1.0)
    dx, dy = -d * offset, c * offset  # across the member's axis
    size = 0.02  # m, the block's side: its own rotary inertia

    def build(article: Article, x: float) -> Article:
        # rigid offset: the block's displacement is (ux - dy rz, uy + dx rz)
        g = np.array([[1.0, 0.0, -dy], [0.0, 1.0, dx]])
        mass = x * g.T @ g + np.diag([0.0, 0.0, x * size**2 / 6.0])
        return replace(article, attachments=article.attachments + (Attachment((member, s), mass=matrix3(mass)),))

    def parameters(x: float) -> dict[str, Any]:
        return {"mass": x, "member": member, "station_m": s, "offset_m": [dx, dy],
                "position": s / member_length(frame, frame.member(member))}

    return Mechanism("added_mass", "eccentric_mass", member, (1e-4, 2.0), build, parameters)


# ----------------------------------------------------------------------------------- shear_deformation

def _thicker(frame: Frame, x: float) -> Frame:
    """Every section's in-plane thickness times ``x``: A times x, I times x^3."""
    sections = {k: replace(s, area=s.area * x, second_moment=s.second_moment * x**3) for k, s in frame.sections.items()}
    return replace(frame, sections=sections)


def _stocky_sections(frame: Frame, where: str | None, rng: np.random.Generator) -> Mechanism:
    def build(article: Article, x: float) -> Article:
        return replace(article, frame=_thicker(article.frame, x), shear=True, rotary_inertia=True)

    def nominal(f: Frame, x: float) -> Frame:
        return replace(_thicker(f, x), beam_theory="euler-bernoulli")

    def parameters(x: float) -> dict[str, Any]:
        depth = min(section_depth(_thicker(frame, x), m.name) / member_length(frame, m) for m in frame.members)
        return {"thickness_factor": x, "slenderness_depth_over_length": depth,
                "shear_coefficient": next((s.shear_coefficient for s in frame.sections.values()
                                           if s.shear_coefficient), 5.0 / 6.0)}

    return Mechanism("shear_deformation", "stocky_sections", None, (0.3, 8.0), build, parameters, nominal=nominal)


# ----------------------------------------------------------------------------------- stinger_stiffness

def _stinger_rod(frame: Frame, where: str | None, rng: np.random.Generator) -> Mechanism:
    if frame.excitation is None:
        raise ValueError(f"{frame.name}: no excitation to put a stinger on")
    point, dof = frame.excitation.point, frame.excitation.dof
    if dof == "rz":
        raise ValueError(f"{frame.name}: a stinger pushes along ux or uy, not rz")
    # piano wire 1.5-2 mm, 30-50 mm long: its first bending mode stays above 2.5 kHz, its bending
    # stiffness holds the drive point's rotation by a few N.m/rad only
    diameter, length = float(rng.uniform(1.5e-3, 2e-3)), float(rng.uniform(0.03, 0.05))
    armature = float(rng.uniform(0.0005, 0.002))  # kg, the coil's moving part not in the nominal's spring
    xs = np.array([xy[0] for xy in frame.points.values()])
    ys = np.array([xy[1] for xy in frame.points.values()])
    x0, y0 = frame.points[point]
    # the shaker stands outside the frame: away from the frame's centre along the driven direction
    sign = -1.0 if (x0 if dof == "ux" else y0) <= (xs.mean() if dof == "ux" else ys.mean()) else 1.0
    end = (x0 + sign * length, y0) if dof == "ux" else (x0, y0 + sign * length)
    area, inertia = math.pi * diameter**2 / 4, math.pi * diameter**4 / 64
    across = "uy" if dof == "ux" else "ux"

    def build(article: Article, x: float) -> Article:
        k = np.zeros((3, 3))
        axis = 0 if dof == "ux" else 1
        k[axis, axis] = x
        mass = np.diag([armature, armature, 0.0])
        rod = Rod("stinger", point, "_armature", 210e9, 7850.0, area, inertia, 0.9, 0.3, elements=4)
        # the reference is the shaker's drive: the force goes in at the armature, and the rod, the armature
        # and its suspension are part of what is measured (with a force sensor on the structure the stinger's
        # axial spring would be inside the measured force and not show)
        return replace(article, nodes=article.nodes + (ExtraNode("_armature", end),), rods=article.rods + (rod,),
                       attachments=article.attachments + (Attachment("_armature", matrix3(k), matrix3(mass),
                                                                     fixed=(across, "rz")),),
                       excitation=("_armature", dof))

    def parameters(x: float) -> dict[str, Any]:
        k_rod = 210e9 * area / length
        return {"stiffness": 1.0 / (1.0 / x + 1.0 / k_rod), "suspension_stiffness": x, "dof": dof,
                "rod_diameter_m": diameter, "rod_length_m": length, "armature_mass_kg": armature}

    return Mechanism("stinger_stiffness", "stinger_rod", point, (1e2, 2e6), build, parameters)


# ------------------------------------------------------------------------------------- axial_prestress

def _misfit(frame: Frame, where: str | None, rng: np.random.Generator, strut: bool) -> Mechanism:
    member = where or _pick([m.name for m in frame.members], rng)
    m = frame.member(member)
    length = member_length(frame, m)
    if strut:  # carbon tube 8 x 0.5 mm: light, and stiff enough in buckling for a few hundred N
        e, rho, area = 120e9, 1550.0, math.pi * (0.008**2 - 0.007**2) / 4
        capacity = math.pi**2 * e * math.pi * (0.008**4 - 0.007**4) / 64 / length**2  # pin-ended Euler load
    else:  # spring-steel wire, 1 mm, 1.5 GPa
        e, rho, area = 200e9, 7850.0, math.pi * 0.001**2 / 4
        capacity = 1.5e9 * area
    sign = 1.0 if strut else -1.0  # a strut too long pushes the ends apart: the member in tension
    # the rod takes nearly all the misfit (the member is far stiffer axially): 80 % of its capacity at most
    largest = 0.8 * capacity / (e * area / length)

    def build(article: Article, x: float) -> Article:
        rod = Rod("tie", m.start, m.end, e, rho, area, bar=True, misfit=sign * x)
        return replace(article, rods=article.rods + (rod,))

    def parameters(x: float) -> dict[str, Any]:
        return {"misfit_m": sign * x, "rod": "carbon strut" if strut else "steel wire tie",
                "rod_axial_stiffness": e * area / length, "rod_capacity_n": capacity}

    return Mechanism("axial_prestress", "misfit_strut" if strut else "misfit_tie", member, (1e-8, largest),
                     build, parameters)


# ------------------------------------------------------------------------------- joint_stiffness_shift

def _joint_mechanism(frame: Frame, where: str | None, rng: np.random.Generator, kind: str) -> Mechanism:
    joint = frame.joint(where or _pick(list(frame.joint_names), rng))
    a, b = joint.span
    width = b - a
    share = float(rng.uniform(0.3, 0.6))  # the central part under the bolt head that changes
    sub = (round(a + width * (1 - share) / 2, 6), round(b - width * (1 - share) / 2, 6))
    ei = joint_bending_rigidity(frame, joint.name)

    def factor(x: float) -> float:
        """The modulus factor of the whole zone with the same bending compliance."""
        if kind == "joint_hinge":
            return 1.0 / (1.0 + x)
        if kind == "joint_subzone_soft":
            return 1.0 / (1.0 + share * x)
        return 1.0 / ((1.0 - share) + share / (1.0 + x))

    def build(article: Article, x: float) -> Article:
        if kind == "joint_hinge":  # compliance x * width / EI added at the middle of the zone
            hinge = Hinge(joint.member, round((a + b) / 2, 6), ei / (x * width))
            return replace(article, hinges=article.hinges + (hinge,))
        zone_factor = 1.0 / (1.0 + x) if kind == "joint_subzone_soft" else 1.0 + x
        return replace(article, zones=article.zones + (Zone(joint.member, sub, stiffness_factor=zone_factor),))

    def parameters(x: float) -> dict[str, Any]:
        out: dict[str, Any] = {"factor": factor(x), "mechanism_intensity": x}
        if kind == "joint_hinge":
            out["hinge_stiffness"] = ei / (x * width)
        else:
            out["subzone_span"] = list(sub)
        return out

    return Mechanism("joint_stiffness_shift", kind, joint.name, (1e-4, 20.0), build, parameters)


# ------------------------------------------------------------------------------- amplitude_softening

def _softening(frame: Frame, where: str | None, rng: np.random.Generator) -> Mechanism:
    joint = where or _pick(list(frame.joint_names), rng)
    exponent = float(rng.uniform(0.4, 0.8))
    others = {j: (float(rng.uniform(0.0, 0.2)), float(rng.uniform(0.4, 0.8))) for j in frame.joint_names if j != joint}

    def laws(x: float) -> tuple[Softening, ...]:
        return (Softening(joint, x, exponent),) + tuple(Softening(j, x * r, p) for j, (r, p) in others.items())

    def build(article: Article, x: float) -> Article:
        return replace(article, softening=article.softening + laws(x))

    def parameters(x: float) -> dict[str, Any]:
        return {"s0": x / 4.0, "drop_at_high": x, "exponent": exponent,
                "per_joint": {s.joint: {"drop_at_high": s.drop, "exponent": s.exponent} for s in laws(x)}}

    return Mechanism("amplitude_softening", "sublinear_softening", joint, (1e-5, 0.6), build, parameters,
                     channel="amplitude")


# ------------------------------------------------------------------------------------ joint_damping

def _dashpot(frame: Frame, where: str | None, rng: np.random.Generator) -> Mechanism:
    joint = frame.joint(where or _pick(list(frame.joint_names), rng))

    def build(article: Article, x: float) -> Article:
        dash = Dashpot((joint.member, joint.span[0]), (joint.member, joint.span[1]), "rz", x)
        return replace(article, dashpots=article.dashpots + (dash,))

    def parameters(x: float) -> dict[str, Any]:
        return {"coefficient": x, "unit": "N.m.s/rad", "span": list(joint.span)}

    return Mechanism("joint_damping", "joint_dashpot", joint.name, (1e-6, 1e3), build, parameters, channel="damping")


_FACTORIES: dict[str, Callable[[Frame, str | None, np.random.Generator], Mechanism]] = {
    "coupled_support": _coupled_support,
    "spread_mass": _spread_mass,
    "eccentric_mass": _eccentric_mass,
    "stocky_sections": _stocky_sections,
    "stinger_rod": _stinger_rod,
    "misfit_tie": lambda f, w, r: _misfit(f, w, r, strut=False),
    "misfit_strut": lambda f, w, r: _misfit(f, w, r, strut=True),
    "joint_hinge": lambda f, w, r: _joint_mechanism(f, w, r, "joint_hinge"),
    "joint_subzone_soft": lambda f, w, r: _joint_mechanism(f, w, r, "joint_subzone_soft"),
    "joint_subzone_stiff": lambda f, w, r: _joint_mechanism(f, w, r, "joint_subzone_stiff"),
    "sublinear_softening": _softening,
    "joint_dashpot": _dashpot,
}


def vocabulary_mechanism(frame: Frame, effect: str, rng: np.random.Generator, where: str | None = None,
                         variant: str | None = None) -> Mechanism:
    """A mechanism for a vocabulary effect on ``frame``: its variant, place and details drawn from ``rng``.

    Parameters
    ----------
    effect : a name of `EFFECTS`.
    where : the place (support point, member, joint, ...) or None to draw one.
    variant : a name of ``VARIANTS[effect]`` or None to draw one.

    Raises
    ------
    ValueError
        An unknown effect or variant, or a frame without the place the effect needs.
    """
    if effect not in VARIANTS:
        raise ValueError(f"vocabulary_mechanism: {effect!r} is not one of {', '.join(VARIANTS)}")
    names = VARIANTS[effect]
    name = variant or names[int(rng.integers(len(names)))]
    if name not in names:
        raise ValueError(f"vocabulary_mechanism: {effect} has no variant {name!r} (variants: {', '.join(names)})")
    return _FACTORIES[name](frame, where, rng)

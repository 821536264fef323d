"""The vocabulary of sim-to-real effects (CONTRACTS.md section 3) as changes of a frame.

One definition serves both sides: the virtual rig (`workbench.rig.simulate`) injects an `Effect` into the
tested article, and the diagnosis (`workbench.diagnose.diagnosis`) fits the same parametrised enrichments
to a campaign. Frame-level effects change the frame (`apply_effect`); joint-level ones
(joint_stiffness_shift changes the frame too; amplitude_softening, joint_damping) act on the joint
physics of whoever uses them.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, replace
from typing import Any

from workbench.model.frame import Frame, GroundSpring, Joint, PointMass, member_length

__all__ = ["EFFECTS", "DAMAGE_JOINT", "Effect", "apply_effect", "set_member"]

DAMAGE_JOINT = "_damage"  # the joint zone that stands for an outside-vocabulary damaged zone

EFFECTS = ("none", "support_compliance", "added_mass", "shear_deformation", "stinger_stiffness",
           "axial_prestress", "joint_stiffness_shift", "amplitude_softening", "joint_damping",
           "outside_vocabulary")


@dataclass(frozen=True)
class Effect:
    """A gap between the nominal model and the tested article: injected by the rig, fitted by the diagnosis.

    ``type``: one of `EFFECTS`. ``where``: a name from the frame (support point, point or member,
    excitation point, member, joint) or None for a global effect. ``parameters`` by type:

    - support_compliance: new stiffnesses of the support's dofs, e.g. ``{"rz": 1500.0}``;
    - added_mass: ``{"mass": kg, "rotary_inertia": kg.m2 (0), "position": 0.5}`` at a point, or
      on a member at ``position`` (fraction of its length from its start);
    - shear_deformation: ``{"shear_coefficient": k}`` optional (Timoshenko, default the file's, else
      5/6); ``poisson_ratio`` (default 0.3) for materials whose file gives none;
    - stinger_stiffness: ``{"stiffness": N/m, "dof": the excitation dof}`` added at the point;
    - axial_prestress: ``{"axial_force": N}`` (tension positive) added to the member's;
    - joint_stiffness_shift: ``{"factor": f}`` times the joint's mean modulus (every joint's when
      ``where`` is None: the file's joint model itself is off);
    - amplitude_softening: ``{"s0": s, "ps_n": N}``: the joint's softening coefficient becomes s;
    - joint_damping: ``{"eta": e}`` added to the joint's damping per energy share;
    - outside_vocabulary: ``{"span": [a, b], "stiffness_factor": f}``: a cracked / thinned zone
      of the member, its EA and EI times f (``where`` a member);
    - none: nothing.
    """

    type: str = "none"
    where: str | None = None
    parameters: dict[str, Any] = field(default_factory=dict)

    def __post_init__(self) -> None:
        if self.type not in EFFECTS:
            raise ValueError(f"Effect: type {self.type!r} is not one of {', '.join(EFFECTS)}")


def set_member(frame: Frame, name: str, **changes) -> Frame:
    """Copy of ``frame`` with the named member's fields changed (KeyError if there is none)."""
    frame.member(name)
    return replace(frame, members=tuple(replace(m, **changes) if m.name == name else m for m in frame.members))


def apply_effect(frame: Frame, effect: Effect | None) -> Frame:
    """The true frame: ``frame`` with a frame-level effect applied (joint-level ones return it as is)."""
    if effect is None or effect.type == "none":
        return frame
    t, w, p = effect.type, effect.where, dict(effect.parameters)
    if t == "support_compliance":
        supports = [s for s in frame.supports if s.point == w]
        if not supports:
            raise ValueError(f"support_compliance: {w!r} is not a support point")
        bad = set(p) - {"ux", "uy", "rz"}
        if bad or not p:
            raise ValueError(f"support_compliance: parameters must be dof stiffnesses, got {p}")
        new = tuple(replace(s, **{k: float(v) for k, v in p.items()}) if s.point == w else s
                    for s in frame.supports)
        return replace(frame, supports=new)
    if t == "added_mass":
        mass, inertia = float(p["mass"]), float(p.get("rotary_inertia", 0.0))
        point = w
        if w not in frame.points:
            member = frame.member(w)
            s = float(p.get("position", 0.5))
            (x0, y0), (x1, y1) = frame.points[member.start], frame.points[member.end]
            xy = (x0 + s * (x1 - x0), y0 + s * (y1 - y0))
            size = member_length(frame, member)
            same = [n for n, q in frame.points.items() if math.hypot(q[0] - xy[0], q[1] - xy[1]) < 1e-9 * size]
            point = same[0] if same else f"{w}_added_mass"  # an existing point there carries the mass
            if not same:
                frame = replace(frame, points={**frame.points, point: xy})
        return replace(frame, masses=frame.masses + (PointMass(point, mass, inertia),))
    if t == "shear_deformation":
        sections = frame.sections
        if "shear_coefficient" in p:
            sections = {k: replace(v, shear_coefficient=float(p["shear_coefficient"])) for k, v in sections.items()}
        # Timoshenko needs G: a file written for Euler-Bernoulli may leave these out (rectangle, metal)
        sections = {k: v if v.shear_coefficient else replace(v, shear_coefficient=5.0 / 6.0) for k, v in sections.items()}
        nu = float(p.get("poisson_ratio", 0.3))
        materials = {k: v if v.poisson_ratio is not None else replace(v, poisson_ratio=nu)
                     for k, v in frame.materials.items()}
        return replace(frame, beam_theory="timoshenko", sections=sections, materials=materials)
    if t == "stinger_stiffness":
        dof = p.get("dof", frame.excitation.dof if frame.excitation else "ux")
        if w not in frame.points:
            raise ValueError(f"stinger_stiffness: {w!r} is not a point")
        return replace(frame, springs=frame.springs + (GroundSpring(w, dof, float(p["stiffness"])),))
    if t == "axial_prestress":
        return set_member(frame, w, axial_force=frame.member(w).axial_force + float(p["axial_force"]))
    if t == "joint_stiffness_shift":
        if w is not None:
            frame.joint(w)
        return replace(frame, joints=tuple(replace(x, youngs_modulus=x.youngs_modulus * float(p["factor"]))
                                           if w is None or x.name == w else x for x in frame.joints))
    if t in ("amplitude_softening", "joint_damping"):
        frame.joint(w)
        return frame
    if t == "outside_vocabulary":
        member = frame.member(w)
        a, b = (float(v) for v in p["span"])
        if not 0.0 <= a < b <= member_length(frame, member):
            raise ValueError(f"outside_vocabulary: span {p['span']} is not inside member {w!r}")
        for j in frame.joints:
            if j.member == w and a < j.span[1] and j.span[0] < b:
                raise ValueError(f"outside_vocabulary: span {p['span']} overlaps joint {j.name}")
        e = frame.materials[member.material].youngs_modulus * float(p["stiffness_factor"])
        # A zone of reduced modulus is exactly what a joint zone is; gamma stays 1 on it.
        return replace(frame, joints=frame.joints + (Joint(DAMAGE_JOINT, w, (a, b), e, 0.0, DAMAGE_JOINT),))
    raise ValueError(f"effect {t!r} is not handled")


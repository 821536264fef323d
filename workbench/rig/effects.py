"""The effects registry: the vocabulary of sim-to-real effects (CONTRACTS.md section 3), in one place.

Every effect name, its parameters, their units, the kind of place it sits at and whether it changes
the frame or the joint physics is written here once, as an `EffectKind` in `EFFECTS`; the virtual
rig (`workbench.rig.simulate`), the diagnosis's candidates (`workbench.diagnose.candidates`), the
blind rig cases (`workbench.workflow.rig_cases`) and the diagnosis page read it from here.

One definition serves both sides: the rig injects an `Effect` into the tested article, and the
diagnosis fits the same parametrised enrichments to a campaign. Frame-level effects change the
frame (`apply_effect`); joint-level ones (amplitude_softening, joint_damping) act on the joint
physics of whoever uses them (joint_stiffness_shift changes the frame's joint moduli).
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, field, replace
from typing import Any

import numpy as np
import scipy.sparse as sp

from workbench.model.frame import Frame, GroundSpring, Joint, PointMass, member_length
from workbench.model.matrix_model import MatrixModel

__all__ = ["EffectKind", "EFFECTS", "NONE", "SUPPORT_COMPLIANCE", "ADDED_MASS", "SHEAR_DEFORMATION",
           "STINGER_STIFFNESS", "AXIAL_PRESTRESS", "JOINT_STIFFNESS_SHIFT", "AMPLITUDE_SOFTENING", "JOINT_DAMPING",
           "OUTSIDE_VOCABULARY", "UNEXPLAINED", "DAMAGE_JOINT", "Effect", "apply_effect", "set_member",
           "MATRIX_EFFECTS", "node_name", "apply_matrix_effect"]

DAMAGE_JOINT = "_damage"  # the joint zone that stands for an outside-vocabulary damaged zone
UNEXPLAINED = "unexplained"  # the verdict on a gap no effect of the vocabulary explains; not injectable


@dataclass(frozen=True)
class EffectKind:
    """One effect of the vocabulary.

    Attributes
    ----------
    name : the effect's name in files, records and `Effect.type`.
    place : what an `Effect`'s ``where`` names: "support point", "point or member", "excitation point",
        "member", "joint" (None for every joint where the effect allows it), or None for a global effect.
    parameter : the key of `Effect.parameters` that carries its magnitude, or None.
    unit : the unit of ``parameter``.
    options : the further keys `Effect.parameters` accepts (documented on `Effect`).
    level : "frame" when `apply_effect` changes the frame, "joint" when it changes the joint physics
        (the rig's joint laws, the diagnosis's joint model), "none" for no effect.
    channel : the data it changes: "frequency" or "damping".
    candidate : the diagnosis fits it (``none`` and ``outside_vocabulary`` are verdicts it reaches by
        elimination, never candidates).
    fitted : the key under which the diagnosis reports the fitted magnitude (``parameter`` unless the
        diagnosis fits a related quantity: the softening slope at the tested preload).
    meaning : CONTRACTS.md section 3's one-line meaning.
    """

    name: str
    place: str | None
    parameter: str | None
    unit: str
    options: tuple[str, ...] = ()
    level: str = "frame"
    channel: str = "frequency"
    candidate: bool = True
    fitted: str | None = None
    meaning: str = ""

    @property
    def keys(self) -> tuple[str, ...]:
        """Every key `Effect.parameters` accepts for this effect."""
        return ((self.parameter,) if self.parameter else ()) + self.options

    @property
    def fitted_parameter(self) -> str | None:
        """The key of the diagnosis's fitted magnitude."""
        return self.fitted or self.parameter

    def effect(self, where: str | None = None, **parameters: Any) -> Effect:
        """An `Effect` of this kind; ``parameters`` in the order given (KeyError-free: checked here)."""
        unknown = set(parameters) - set(self.keys)
        if unknown:
            raise ValueError(f"{self.name}: unknown parameters {sorted(unknown)}; expected some of {list(self.keys)}")
        return Effect(self.name, where, dict(parameters))

    def from_fit(self, where: str | None, parameters: dict[str, Any]) -> Effect:
        """The `Effect` a diagnosis candidate's fitted ``parameters`` describe: its own keys only (a fit's record
        adds others, such as a two-dof form's label or a softening's slope).
        """
        return Effect(self.name, where, {k: v for k, v in parameters.items() if k in self.keys})


NONE = EffectKind("none", None, None, "", level="none", candidate=False,
                  meaning="no gap beyond measurement scatter: the nominal model already fits")
SUPPORT_COMPLIANCE = EffectKind("support_compliance", "support point", "rz", "N.m/rad", ("ux", "uy"),
                                meaning="a support is less stiff than modelled")
ADDED_MASS = EffectKind("added_mass", "point or member", "mass", "kg", ("rotary_inertia", "position"),
                        meaning="unmodelled mass (sensor, bracket, bolt)")
SHEAR_DEFORMATION = EffectKind("shear_deformation", None, "shear_coefficient", "1", ("poisson_ratio",),
                               meaning="shear and rotary inertia of thick members (Timoshenko)")
STINGER_STIFFNESS = EffectKind("stinger_stiffness", "excitation point", "stiffness", "N/m", ("dof", "moving_mass"),
                               meaning="the shaker's stinger adds a spring at the drive point")
AXIAL_PRESTRESS = EffectKind("axial_prestress", "member", "axial_force", "N", ("reaction",),
                             meaning="locked-in axial force in a member (tightening sequence), geometric stiffness")
JOINT_STIFFNESS_SHIFT = EffectKind("joint_stiffness_shift", "joint", "factor", "1",
                                   meaning="a joint's mean modulus differs from the frame file's")
# The rig softens by s0 exp(-P / ps_n) per unit of amplitude ratio; the diagnosis fits the slope at
# the tested preload, gamma(a) = 1 - slope * a.
AMPLITUDE_SOFTENING = EffectKind("amplitude_softening", "joint", "s0", "1 per amplitude ratio", ("ps_n",),
                                 level="joint", fitted="slope",
                                 meaning="a joint's modulus drops as excitation amplitude rises")
JOINT_DAMPING = EffectKind("joint_damping", "joint", "eta", "damping ratio per strain-energy share", level="joint",
                           channel="damping", meaning="damping concentrated in a joint")
OUTSIDE_VOCABULARY = EffectKind("outside_vocabulary", "member", "stiffness_factor", "1", ("span",), candidate=False,
                                meaning="a cracked or thinned zone of a member: a gap no candidate explains")

EFFECTS: dict[str, EffectKind] = {kind.name: kind for kind in (
    NONE, SUPPORT_COMPLIANCE, ADDED_MASS, SHEAR_DEFORMATION, STINGER_STIFFNESS, AXIAL_PRESTRESS,
    JOINT_STIFFNESS_SHIFT, AMPLITUDE_SOFTENING, JOINT_DAMPING, OUTSIDE_VOCABULARY)}


@dataclass(frozen=True)
class Effect:
    """A gap between the nominal model and the tested article: injected by the rig, fitted by the diagnosis.

    ``type``: a name of `EFFECTS`. ``where``: a name from the frame (support point, point or member,
    excitation point, member, joint) or None for a global effect. ``parameters`` by type:

    - support_compliance: new stiffnesses of the support's dofs, e.g. ``{"rz": 1500.0}``;
    - added_mass: ``{"mass": kg, "rotary_inertia": kg.m2 (0), "position": 0.5}`` at a point, or
      on a member at ``position`` (fraction of its length from its start);
    - shear_deformation: ``{"shear_coefficient": k}`` optional (Timoshenko, default the file's, else
      5/6); ``poisson_ratio`` (default 0.3) for materials whose file gives none;
    - stinger_stiffness: ``{"stiffness": N/m, "dof": the excitation dof}`` added at the point, and
      ``"moving_mass"`` (kg, default 0) moving with that dof only: the shaker's armature and stinger where the
      reference force is measured at the shaker (`workbench.model.frame.GroundSpring`); either may be left out;
    - axial_prestress: ``{"axial_force": N}`` (tension positive) added to the member's, carried through the
      frame; with ``"reaction": "chord"`` locked in between the member's own ends (``Member.locked_force``);
    - joint_stiffness_shift: ``{"factor": f}`` times the joint's mean modulus (every joint's when
      ``where`` is None: the file's joint model itself is off);
    - amplitude_softening: ``{"s0": s, "ps_n": N}``: the joint's softening coefficient becomes s;
    - joint_damping: ``{"eta": e}`` added to the joint's damping per energy share;
    - outside_vocabulary: ``{"span": [a, b], "stiffness_factor": f}``: a cracked / thinned zone
      of the member, its EA and EI times f (``where`` a member);
    - none: nothing.
    """

    type: str = NONE.name
    where: str | None = None
    parameters: dict[str, Any] = field(default_factory=dict)

    def __post_init__(self) -> None:
        if self.type not in EFFECTS:
            raise ValueError(f"Effect: type {self.type!r} is not one of {', '.join(EFFECTS)}")

    @property
    def kind(self) -> EffectKind:
        """The effect's entry in the registry."""
        return EFFECTS[self.type]

    @property
    def magnitude(self) -> float:
        """The value of the registry's ``parameter`` of the effect, in its unit (KeyError when not given)."""
        if self.kind.parameter is None:
            raise ValueError(f"Effect: {self.type!r} has no magnitude")
        return float(self.parameters[self.kind.parameter])


def set_member(frame: Frame, name: str, **changes: Any) -> Frame:
    """Copy of ``frame`` with the named member's fields changed (KeyError if there is none)."""
    frame.member(name)
    return replace(frame, members=tuple(replace(m, **changes) if m.name == name else m for m in frame.members))


def _support_compliance(frame: Frame, w: str | None, p: dict[str, Any]) -> Frame:
    supports = [s for s in frame.supports if s.point == w]
    if not supports:
        raise ValueError(f"support_compliance: {w!r} is not a support point")
    bad = set(p) - set(SUPPORT_COMPLIANCE.keys)
    if bad or not p:
        raise ValueError(f"support_compliance: parameters must be dof stiffnesses, got {p}")
    stiffness: dict[str, Any] = {k: float(v) for k, v in p.items()}
    new = tuple(replace(s, **stiffness) if s.point == w else s for s in frame.supports)
    return replace(frame, supports=new)


def _added_mass(frame: Frame, w: str, p: dict[str, Any]) -> Frame:
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


def _shear_deformation(frame: Frame, w: str | None, p: dict[str, Any]) -> Frame:
    sections = frame.sections
    if "shear_coefficient" in p:
        sections = {k: replace(v, shear_coefficient=float(p["shear_coefficient"])) for k, v in sections.items()}
    # Timoshenko needs G: a file written for Euler-Bernoulli may leave these out (rectangle, metal)
    sections = {k: v if v.shear_coefficient else replace(v, shear_coefficient=5.0 / 6.0) for k, v in sections.items()}
    nu = float(p.get("poisson_ratio", 0.3))
    materials = {k: v if v.poisson_ratio is not None else replace(v, poisson_ratio=nu)
                 for k, v in frame.materials.items()}
    return replace(frame, beam_theory="timoshenko", sections=sections, materials=materials)


def _stinger_stiffness(frame: Frame, w: str, p: dict[str, Any]) -> Frame:
    dof = p.get("dof", frame.excitation.dof if frame.excitation else "ux")
    if w not in frame.points:
        raise ValueError(f"stinger_stiffness: {w!r} is not a point")
    _drive_given(p)
    spring = GroundSpring(w, dof, float(p.get("stiffness", 0.0)), float(p.get("moving_mass", 0.0)))
    return replace(frame, springs=frame.springs + (spring,))


def _drive_given(p: dict[str, Any]) -> None:
    if "stiffness" not in p and "moving_mass" not in p:
        raise ValueError("stinger_stiffness: give its stiffness, its moving_mass or both")


def _axial_prestress(frame: Frame, w: str, p: dict[str, Any]) -> Frame:
    member, force = frame.member(w), float(p["axial_force"])
    reaction = p.get("reaction", "frame")
    if reaction == "chord":
        return set_member(frame, w, locked_force=member.locked_force + force)
    if reaction != "frame":
        raise ValueError(f"axial_prestress: reaction must be 'frame' or 'chord', got {reaction!r}")
    return set_member(frame, w, axial_force=member.axial_force + force)


def _joint_stiffness_shift(frame: Frame, w: str | None, p: dict[str, Any]) -> Frame:
    if w is not None:
        frame.joint(w)
    return replace(frame, joints=tuple(replace(x, youngs_modulus=x.youngs_modulus * float(p["factor"]))
                                       if w is None or x.name == w else x for x in frame.joints))


def _joint_level(frame: Frame, w: str | None, p: dict[str, Any]) -> Frame:
    if w is not None:  # None: every joint at once (a global softening); else the joint must exist
        frame.joint(w)
    return frame  # a joint-level effect's physics is the user's to change, not the frame's


def _outside_vocabulary(frame: Frame, w: str, p: dict[str, Any]) -> Frame:
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


# `where` is None only for global effects (shear, every joint's shift), whose appliers take None
_APPLY: dict[str, Callable[..., Frame]] = {
    SUPPORT_COMPLIANCE.name: _support_compliance,
    ADDED_MASS.name: _added_mass,
    SHEAR_DEFORMATION.name: _shear_deformation,
    STINGER_STIFFNESS.name: _stinger_stiffness,
    AXIAL_PRESTRESS.name: _axial_prestress,
    JOINT_STIFFNESS_SHIFT.name: _joint_stiffness_shift,
    AMPLITUDE_SOFTENING.name: _joint_level,
    JOINT_DAMPING.name: _joint_level,
    OUTSIDE_VOCABULARY.name: _outside_vocabulary,
}


def apply_effect(frame: Frame, effect: Effect | None) -> Frame:
    """The true frame: ``frame`` with a frame-level effect applied (joint-level ones return it as is).

    Raises
    ------
    ValueError
        The effect's place or parameters do not fit the frame.
    KeyError
        ``where`` names no member or joint of the frame.
    """
    if effect is None or effect.type == NONE.name:
        return frame
    apply = _APPLY.get(effect.type)
    if apply is None:
        raise ValueError(f"effect {effect.type!r} is not handled")
    return apply(frame, effect.where, dict(effect.parameters))


# CONTRACTS.md section 3: on a matrix model the effects that need a frame's geometry are no candidates
MATRIX_EFFECTS = (ADDED_MASS, STINGER_STIFFNESS, JOINT_STIFFNESS_SHIFT, AMPLITUDE_SOFTENING, JOINT_DAMPING)
TRANSLATIONS = ("ux", "uy", "uz")


def node_name(node: int) -> str:
    """A matrix model's place in records: ``"node 1042"``."""
    return f"node {int(node)}"


def _node_of(model: MatrixModel, where: str | None) -> int:
    text = (where or "").removeprefix("node ").strip()
    if not text.isdigit() or not model.dofs.node_components(int(text)):
        raise ValueError(f"{model.source}: {where!r} is not a node of the model (\"node N\", N in dofs.csv)")
    return int(text)


def apply_matrix_effect(model: MatrixModel, effect: Effect | None) -> MatrixModel:
    """A matrix model changed by a model-level effect of `MATRIX_EFFECTS` (joint-level ones return it as is).

    ``where``: a joint's name (None: every joint) for ``joint_stiffness_shift``; ``"node N"`` for
    ``added_mass`` (``mass`` kg on each translation the node has) and ``stinger_stiffness``
    (``stiffness`` N/m and ``moving_mass`` kg on the excitation's dof, which must be at that node; either may
    be left out).
    """
    if effect is None or effect.type == NONE.name:
        return model
    if effect.kind not in MATRIX_EFFECTS:
        raise ValueError(f"{model.source}: {effect.type} needs a frame's geometry; no candidate on a matrix model")
    p = effect.parameters
    if effect.type == JOINT_STIFFNESS_SHIFT.name:
        if effect.where is not None and effect.where not in model.joint_names:
            raise KeyError(f"{model.source}: no joint named {effect.where!r}")
        factor = np.array([float(p["factor"]) if effect.where in (None, n) else 1.0 for n in model.joint_names])
        return model.scaled(factor)
    if effect.type in (AMPLITUDE_SOFTENING.name, JOINT_DAMPING.name):
        if effect.where not in model.joint_names:
            raise KeyError(f"{model.source}: no joint named {effect.where!r}")
        return model
    node = _node_of(model, effect.where)
    if effect.type == ADDED_MASS.name:
        rows = [r for c in TRANSLATIONS if (r := model.dofs.find(node, c)) is not None]
        extra = sp.csr_matrix((np.full(len(rows), float(p["mass"])), (rows, rows)), shape=model.mass.shape)
        return replace(model, mass=(model.mass + extra).tocsr())
    if model.excitation is None or int(model.dofs.nodes[model.excitation]) != node:
        raise ValueError(f"{model.source}: stinger_stiffness at {effect.where!r}, which is not the excitation")
    _drive_given(p)
    at = ([model.excitation], [model.excitation])
    spring = sp.csr_matrix(([float(p.get("stiffness", 0.0))], at), shape=model.mass.shape)
    moving = sp.csr_matrix(([float(p.get("moving_mass", 0.0))], at), shape=model.mass.shape)
    return replace(model, stiffness_rest=(model.stiffness_rest + spring).tocsr(), mass=(model.mass + moving).tocsr())

"""Blind validation of the gap diagnosis on the virtual rig (``workbench validate-diagnosis``).

Each case is a campaign of the rig on a frame (default: the two-bolt frame) with one hidden
effect drawn from a seed: its type (in turn: each effect of the registry `workbench.rig.effects.EFFECTS`:
none, each effect of the vocabulary, and one outside it: a cracked zone of a member), its place
and its magnitude (`draw_effect`). The diagnosis sees only the campaign (its frame file and its
FRFs, through the circle fit); the truth stays here and only scores the verdict.

The article without effect matches its frame file: every test at full preload (level 3) with the
joint law's modulus there equal to the file's mean, no amplitude softening, no joint damping, a
constant 0.4 % modal damping; what remains is the rig's test-to-test scatter (2 % lognormal on
each joint, 1 K of temperature on the members) and 40 dB of FRF noise. The design: 4 tests at
the low and 4 at the high amplitude (paper 2.2.2), 8 tests a case.

Scoring: the verdict is right when it names the drawn effect (``none`` for no effect,
``unexplained`` for the outside effect). Its place is right when it is the drawn place, or, for an
added mass, on the same member (a point names every member it lies on).
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, replace
from typing import Any

import numpy as np

from workbench.diagnose.candidates import members_at
from workbench.diagnose.verdict import diagnose, diagnosis_record
from workbench.io.campaign import Campaign, Factor
from workbench.model.frame import Frame, member_length
from workbench.rig.effects import (
    ADDED_MASS,
    AMPLITUDE_SOFTENING,
    AXIAL_PRESTRESS,
    EFFECTS,
    JOINT_DAMPING,
    JOINT_STIFFNESS_SHIFT,
    NONE,
    OUTSIDE_VOCABULARY,
    SHEAR_DEFORMATION,
    STINGER_STIFFNESS,
    SUPPORT_COMPLIANCE,
    UNEXPLAINED,
    Effect,
)
from workbench.rig.simulate import JointLaw, RigSettings, simulate_campaign
from workbench.workflow.measured import measured_modes

__all__ = ["CASE_SETTINGS", "CASE_TYPES", "draw_effect", "case_campaign", "CaseResult", "run_case", "summarise"]

CASE_SETTINGS = RigSettings(law_shape={"s0": 0.0, "eta0": 0.0}, zeta_base=(0.004,), snr_db=40.0)
CASE_TYPES = tuple(EFFECTS)  # none, the eight of the vocabulary, outside_vocabulary
FULL_PRELOAD = "3"


def _euler(frame: Frame, member: str) -> float:
    m = frame.member(member)
    ei = frame.materials[m.material].youngs_modulus * frame.sections[m.section].second_moment
    return math.pi ** 2 * ei / member_length(frame, m) ** 2


class _Draw:
    """Random places and magnitudes on one frame, in the order the drawers call them (seeded)."""

    def __init__(self, frame: Frame, rng: np.random.Generator) -> None:
        self.frame, self.rng = frame, rng
        supported = {s.point for s in frame.supports}
        self.free_points = [p for p in frame.points if p not in supported]
        self.joints = [j.name for j in frame.joints]
        self.members = [m.name for m in frame.members]

    def log_uniform(self, lo: float, hi: float) -> float:
        return float(10 ** self.rng.uniform(math.log10(lo), math.log10(hi)))

    def pick(self, names: list[str]) -> str:
        return names[int(self.rng.integers(len(names)))]


def _support_compliance(d: _Draw) -> Effect:
    support = d.frame.supports[int(d.rng.integers(len(d.frame.supports)))]
    if support.rz is None:
        raise ValueError(f"{d.frame.source}: support at {support.point!r} has no rotational stiffness to soften")
    return SUPPORT_COMPLIANCE.effect(support.point, rz=support.rz * d.log_uniform(0.05, 0.5))


def _added_mass(d: _Draw) -> Effect:
    mass = d.log_uniform(0.02, 0.15)
    if d.rng.random() < 0.5:
        return ADDED_MASS.effect(d.pick(d.free_points), mass=mass)
    member = d.pick(d.members)
    return ADDED_MASS.effect(member, mass=mass, position=float(d.rng.uniform(0.15, 0.85)))


def _shear_deformation(d: _Draw) -> Effect:
    kappa = next((s.shear_coefficient for s in d.frame.sections.values() if s.shear_coefficient), 5 / 6)
    return SHEAR_DEFORMATION.effect(None, shear_coefficient=kappa * d.log_uniform(0.15, 1.0))


def _stinger_stiffness(d: _Draw) -> Effect:
    excitation = d.frame.excitation
    if excitation is None:
        raise ValueError(f"{d.frame.source}: the frame has no excitation point to put a stinger on")
    return STINGER_STIFFNESS.effect(excitation.point, stiffness=d.log_uniform(5e3, 5e4), dof=excitation.dof)


def _axial_prestress(d: _Draw) -> Effect:
    member = d.pick(d.members)
    sign = -1.0 if d.rng.random() < 0.5 else 1.0
    return AXIAL_PRESTRESS.effect(member, axial_force=sign * _euler(d.frame, member) * d.rng.uniform(0.05, 0.2))


def _joint_stiffness_shift(d: _Draw) -> Effect:
    factor = d.log_uniform(0.4, 0.8) if d.rng.random() < 0.5 else d.log_uniform(1.25, 2.0)
    return JOINT_STIFFNESS_SHIFT.effect(d.pick(d.joints), factor=factor)


def _amplitude_softening(d: _Draw) -> Effect:
    # ps_n far above the preload: the slope s0 acts fully at full preload
    return AMPLITUDE_SOFTENING.effect(d.pick(d.joints), s0=d.rng.uniform(0.01, 0.05), ps_n=1e12)


def _joint_damping(d: _Draw) -> Effect:
    return JOINT_DAMPING.effect(d.pick(d.joints), eta=d.rng.uniform(0.03, 0.15))


def _outside_vocabulary(d: _Draw) -> Effect:
    for _ in range(100):
        member = d.frame.member(d.pick(d.members))
        length = member_length(d.frame, member)
        width = d.rng.uniform(0.03, 0.06)
        a = d.rng.uniform(0.05, length - 0.05 - width)
        if all(not (j.member == member.name and a < j.span[1] + 0.01 and j.span[0] - 0.01 < a + width)
               for j in d.frame.joints):
            return OUTSIDE_VOCABULARY.effect(member.name, span=[round(a, 3), round(a + width, 3)],
                                             stiffness_factor=float(d.rng.uniform(0.2, 0.5)))
    raise ValueError(f"{d.frame.source}: no member has room for a damaged zone away from the joints")


_DRAWERS: dict[str, Callable[[_Draw], Effect]] = {
    NONE.name: lambda d: Effect(),
    SUPPORT_COMPLIANCE.name: _support_compliance,
    ADDED_MASS.name: _added_mass,
    SHEAR_DEFORMATION.name: _shear_deformation,
    STINGER_STIFFNESS.name: _stinger_stiffness,
    AXIAL_PRESTRESS.name: _axial_prestress,
    JOINT_STIFFNESS_SHIFT.name: _joint_stiffness_shift,
    AMPLITUDE_SOFTENING.name: _amplitude_softening,
    JOINT_DAMPING.name: _joint_damping,
    OUTSIDE_VOCABULARY.name: _outside_vocabulary,
}


def draw_effect(frame: Frame, kind: str, rng: np.random.Generator) -> Effect:
    """A hidden effect of type ``kind`` (a name of `EFFECTS`) with a random place and magnitude (module docstring)."""
    drawer = _DRAWERS.get(kind)
    if drawer is None:
        raise ValueError(f"draw_effect: unknown type {kind!r}")
    return drawer(_Draw(frame, rng))


def case_campaign(frame: Frame, effect: Effect, seed: int,
                  settings: RigSettings = CASE_SETTINGS) -> tuple[Campaign, dict[str, Any]]:
    """The rig's campaign of one case and its truth; the campaign's frame file is the nominal ``frame``.

    The nominal joints are deterministic (cov 0) at the modulus the rig's law gives at full
    preload, so that without an effect the file is the article.
    """
    nominal = replace(frame, joints=tuple(replace(j, cov=0.0) for j in frame.joints))
    preload = settings.level_preloads_n[FULL_PRELOAD]
    article = []
    for j in nominal.joints:  # the law is linear in the file's mean: scale it to hit the mean at full preload
        law = JointLaw.calibrated(j.youngs_modulus, settings.group_cov.get(j.group, 0.05), **settings.law_shape)
        article.append(replace(j, youngs_modulus=j.youngs_modulus ** 2 / float(law.modulus(preload))))
    rig_frame = replace(nominal, joints=tuple(article))
    factors = (Factor("amplitude", "amplitude", {"low": "low amplitude", "high": "high amplitude (5 x low)"}),)
    design = [{"amplitude": level} for level in ("low", "high") * 4]
    campaign, truth = simulate_campaign(rig_frame, factors, design, settings, seed=seed, effect=effect,
                                        name=f"blind case, seed {seed}")
    return replace(campaign, frame=nominal), truth


@dataclass(frozen=True)
class CaseResult:
    """One blind case: what was drawn, the verdict that is right, the diagnosis's, and their scores."""

    seed: int
    truth: str  # the drawn type
    truth_where: str | None
    truth_parameters: dict
    expected: str  # the verdict that is right
    verdict: str
    where: str | None
    shrinkage: float
    effect_right: bool
    place_right: bool | None  # None when the verdict has no place to check
    wall_time_s: float
    record: dict


def _expected(effect: Effect) -> str:
    """The verdict that is right: the effect when the diagnosis can name it; else none or unexplained."""
    if effect.kind.candidate:
        return effect.type
    return NONE.name if effect.type == NONE.name else UNEXPLAINED


def _place_right(frame: Frame, effect: Effect, where: str | None) -> bool | None:
    if not effect.kind.candidate:
        return None
    if effect.where is None:
        return where is None
    if effect.type == ADDED_MASS.name:
        return bool({m for m, _ in members_at(frame, effect.where)} & {m for m, _ in members_at(frame, where)})
    return where == effect.where


def run_case(frame: Frame, kind: str, seed: int) -> CaseResult:
    """Draw, simulate, diagnose blind (campaign only), score."""
    rng = np.random.default_rng(seed)
    effect = draw_effect(frame, kind, rng)
    campaign, _ = case_campaign(frame, effect, seed)
    assert isinstance(campaign.frame, Frame)  # the rig builds its campaigns on frame files
    result = diagnose(campaign.frame, measured_modes(campaign, None, "diagnose"))  # the truth is not passed
    expected = _expected(effect)
    right = result.verdict == expected
    return CaseResult(seed, effect.type, effect.where, dict(effect.parameters), expected, result.verdict, result.where,
                      result.shrinkage, right, _place_right(frame, effect, result.where) if right else None,
                      result.wall_time_s, diagnosis_record(campaign.name, result))


def _quantiles(x: np.ndarray) -> dict[str, float] | None:
    return None if x.size == 0 else {q: float(np.quantile(x, p)) for q, p in
                                     (("min", 0), ("p10", 0.1), ("median", 0.5), ("p90", 0.9), ("max", 1))}


def _right_of(results: list[CaseResult], kind: str) -> str:
    """``right/drawn`` for the cases of one drawn type."""
    return f"{sum(r.effect_right for r in results if r.truth == kind)}/{sum(r.truth == kind for r in results)}"


def summarise(results: list[CaseResult]) -> dict[str, Any]:
    """Confusion matrix (drawn type -> verdict), accuracy, place accuracy and shrinkage quantiles."""
    labels = list(CASE_TYPES) + [UNEXPLAINED]
    confusion = {t: {v: 0 for v in labels} for t in CASE_TYPES}
    for r in results:
        confusion[r.truth][r.verdict if r.verdict in labels else UNEXPLAINED] += 1
    right = [r for r in results if r.effect_right]
    placed = [r for r in right if r.place_right is not None]
    named = [r for r in results if EFFECTS[r.truth].candidate]
    shrink_right = np.array([r.shrinkage for r in named if r.effect_right])
    shrink_all = np.array([r.shrinkage if r.effect_right else 0.0 for r in named])
    return {
        "cases": len(results),
        "top1_accuracy": len(right) / max(len(results), 1),
        "place_accuracy": (sum(bool(r.place_right) for r in placed) / len(placed)) if placed else None,
        "place_checked": len(placed),
        "none_right": _right_of(results, NONE.name),
        "outside_right": _right_of(results, OUTSIDE_VOCABULARY.name),
        "shrinkage_right_verdicts": _quantiles(shrink_right),
        "shrinkage_all_effects": _quantiles(shrink_all),
        "confusion": confusion,
        "mean_wall_time_s": float(np.mean([r.wall_time_s for r in results])) if results else 0.0,
    }

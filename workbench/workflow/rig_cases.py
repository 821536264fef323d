"""Blind validation of the gap diagnosis on the virtual rig (``workbench validate-diagnosis``).

Each case is a campaign of the rig on a frame (default: the two-bolt frame) with one hidden
effect drawn from a seed: its type (in turn: none, each effect of the vocabulary, and one outside
it: a cracked zone of a member), its place and its magnitude (`draw_effect`). The diagnosis sees
only the campaign (its frame file and its FRFs, through the circle fit); the truth stays here and
only scores the verdict.

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
from dataclasses import dataclass, replace
from typing import Any

import numpy as np

from workbench.io.campaign import Factor
from workbench.workflow.measured import modal_data
from workbench.diagnose.diagnosis import diagnose, members_at
from workbench.rig.effects import EFFECTS, Effect
from workbench.model.frame import Frame, member_length
from workbench.rig.simulate import JointLaw, RigSettings, simulate_campaign

__all__ = ["CASE_SETTINGS", "draw_effect", "case_campaign", "CaseResult", "run_case", "summarise"]

CASE_SETTINGS = RigSettings(law_shape={"s0": 0.0, "eta0": 0.0}, zeta_base=(0.004,), snr_db=40.0)
CASE_TYPES = EFFECTS  # none, the eight of the vocabulary, outside_vocabulary
FULL_PRELOAD = "3"


def _euler(frame: Frame, member: str) -> float:
    m = frame.member(member)
    ei = frame.materials[m.material].youngs_modulus * frame.sections[m.section].second_moment
    return math.pi ** 2 * ei / member_length(frame, m) ** 2


def draw_effect(frame: Frame, kind: str, rng: np.random.Generator) -> Effect:
    """A hidden effect of type ``kind`` with a random place and magnitude (module docstring)."""
    supported = {s.point for s in frame.supports}
    free_points = [p for p in frame.points if p not in supported]
    joints = [j.name for j in frame.joints]
    members = [m.name for m in frame.members]

    def log_uniform(lo: float, hi: float) -> float:
        return float(10 ** rng.uniform(math.log10(lo), math.log10(hi)))

    if kind == "none":
        return Effect()
    if kind == "support_compliance":
        support = frame.supports[int(rng.integers(len(frame.supports)))]
        return Effect(kind, support.point, {"rz": support.rz * log_uniform(0.05, 0.5)})
    if kind == "added_mass":
        mass = log_uniform(0.02, 0.15)
        if rng.random() < 0.5:
            return Effect(kind, free_points[int(rng.integers(len(free_points)))], {"mass": mass})
        member = members[int(rng.integers(len(members)))]
        return Effect(kind, member, {"mass": mass, "position": float(rng.uniform(0.15, 0.85))})
    if kind == "shear_deformation":
        kappa = next((s.shear_coefficient for s in frame.sections.values() if s.shear_coefficient), 5 / 6)
        return Effect(kind, None, {"shear_coefficient": kappa * log_uniform(0.15, 1.0)})
    if kind == "stinger_stiffness":
        return Effect(kind, frame.excitation.point, {"stiffness": log_uniform(5e3, 5e4), "dof": frame.excitation.dof})
    if kind == "axial_prestress":
        member = members[int(rng.integers(len(members)))]
        sign = -1.0 if rng.random() < 0.5 else 1.0
        return Effect(kind, member, {"axial_force": sign * _euler(frame, member) * rng.uniform(0.05, 0.2)})
    if kind == "joint_stiffness_shift":
        factor = log_uniform(0.4, 0.8) if rng.random() < 0.5 else log_uniform(1.25, 2.0)
        return Effect(kind, joints[int(rng.integers(len(joints)))], {"factor": factor})
    if kind == "amplitude_softening":
        # ps_n far above the preload: the slope s0 acts fully at full preload
        return Effect(kind, joints[int(rng.integers(len(joints)))], {"s0": rng.uniform(0.01, 0.05), "ps_n": 1e12})
    if kind == "joint_damping":
        return Effect(kind, joints[int(rng.integers(len(joints)))], {"eta": rng.uniform(0.03, 0.15)})
    if kind == "outside_vocabulary":
        for _ in range(100):
            member = frame.member(members[int(rng.integers(len(members)))])
            length = member_length(frame, member)
            width = rng.uniform(0.03, 0.06)
            a = rng.uniform(0.05, length - 0.05 - width)
            if all(not (j.member == member.name and a < j.span[1] + 0.01 and j.span[0] - 0.01 < a + width)
                   for j in frame.joints):
                return Effect(kind, member.name, {"span": [round(a, 3), round(a + width, 3)],
                                                  "stiffness_factor": float(rng.uniform(0.2, 0.5))})
        raise ValueError(f"{frame.source}: no member has room for a damaged zone away from the joints")
    raise ValueError(f"draw_effect: unknown type {kind!r}")


def case_campaign(frame: Frame, effect: Effect, seed: int, settings: RigSettings = CASE_SETTINGS):
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


def _place_right(frame: Frame, effect: Effect, where: str | None) -> bool | None:
    if effect.type in ("none", "outside_vocabulary"):
        return None
    if effect.where is None:
        return where is None
    if effect.type == "added_mass":
        return bool({m for m, _ in members_at(frame, effect.where)} & {m for m, _ in members_at(frame, where)})
    return where == effect.where


def run_case(frame: Frame, kind: str, seed: int) -> CaseResult:
    """Draw, simulate, diagnose blind (campaign only), score."""
    from workbench.diagnose.diagnosis import diagnosis_record

    rng = np.random.default_rng(seed)
    effect = draw_effect(frame, kind, rng)
    campaign, _ = case_campaign(frame, effect, seed)
    result = diagnose(campaign.frame, modal_data(campaign))  # the truth is not passed
    expected = {"none": "none", "outside_vocabulary": "unexplained"}.get(effect.type, effect.type)
    right = result.verdict == expected
    return CaseResult(seed, effect.type, effect.where, dict(effect.parameters), expected, result.verdict, result.where,
                      result.shrinkage, right, _place_right(frame, effect, result.where) if right else None,
                      result.wall_time_s, diagnosis_record(campaign.name, result))


def summarise(results: list[CaseResult]) -> dict[str, Any]:
    """Confusion matrix (drawn type -> verdict), accuracy, place accuracy and shrinkage quantiles."""
    labels = list(CASE_TYPES) + ["unexplained"]
    confusion = {t: {v: 0 for v in labels} for t in CASE_TYPES}
    for r in results:
        confusion[r.truth][r.verdict if r.verdict in labels else "unexplained"] += 1
    right = [r for r in results if r.effect_right]
    placed = [r for r in right if r.place_right is not None]
    named = [r for r in results if r.truth not in ("none", "outside_vocabulary")]
    shrink_right = np.array([r.shrinkage for r in named if r.effect_right])
    shrink_all = np.array([r.shrinkage if r.effect_right else 0.0 for r in named])

    def quantiles(x: np.ndarray) -> dict[str, float] | None:
        return None if x.size == 0 else {q: float(np.quantile(x, p)) for q, p in
                                         (("min", 0), ("p10", 0.1), ("median", 0.5), ("p90", 0.9), ("max", 1))}

    return {
        "cases": len(results),
        "top1_accuracy": len(right) / max(len(results), 1),
        "place_accuracy": (sum(r.place_right for r in placed) / len(placed)) if placed else None,
        "place_checked": len(placed),
        "none_right": f"{sum(r.effect_right for r in results if r.truth == 'none')}/"
                      f"{sum(r.truth == 'none' for r in results)}",
        "outside_right": f"{sum(r.effect_right for r in results if r.truth == 'outside_vocabulary')}/"
                         f"{sum(r.truth == 'outside_vocabulary' for r in results)}",
        "shrinkage_right_verdicts": quantiles(shrink_right),
        "shrinkage_all_effects": quantiles(shrink_all),
        "confusion": confusion,
        "mean_wall_time_s": float(np.mean([r.wall_time_s for r in results])) if results else 0.0,
    }

"""Blind validation of the diagnosis on the proving ground: cases the diagnosis's own code did not make.

Each case (`workbench.proving.cases.case_mix`, without its joint-identification cases) is a campaign from the
proving ground: its own Timoshenko elements on a finer mesh, each effect by another mechanism than the
registry's form, nuisances on in every case, effects outside the vocabulary, combined effects and several
geometries. The diagnosis sees the campaign only (FRFs through the circle fit, the nominal frame file); the
truth is read afterwards. The decision's levels are frozen constants (`workbench.diagnose.decision`); they
were set on a development mix of another seed, and a validation run must use a seed of its own.

**Scores**, each a rate with its Wilson 95 % interval (scipy's ``binomtest(...).proportion_ci``):

- ``single_accuracy``: a nameable single effect (one effect of the vocabulary, not ``faint``) named right;
- ``confident_wrong``: a named effect (the verdict or one in ``also``) that the case does not hold, over all
  cases, and over the cases where an effect was named (``named_wrong``);
- ``none_false_positive``: a no-effect case given anything but ``none``;
- ``outside_unexplained``: an out-of-vocabulary case, not ``faint``, given ``unexplained`` (``partial`` included);
- ``combined_primary``: a combined case, its primary not ``faint``, whose primary effect is named (verdict or
  ``also``);
- ``abstention``: an effect case given ``none`` or ``unexplained``;
- ``place_accuracy``: the place of a right verdict (an added mass by the member it sits on);
- ``single_accuracy_by_level``: the same by the rung of the footprint the case reached
  (`workbench.proving.cases.reached_level`), and ``single_accuracy_by_requested_level`` by the rung it asked for
  (every single case; the scores of seeds up to 12 were given this way);
- ``single_accuracy_by_measurement``: the same by how the case was measured (`measurement_label`: the file's
  quantity, the sensed one, the line spacing; `validation_specs`);
- ``faint_none``: a case whose primary effect reached less than half the small rung's footprint (``faint``: no
  diagnosis can tell it from the as-built frame) given ``none``; these cases count in none of the single,
  out-of-vocabulary or combined-primary rates (they do in ``confident_wrong``, ``abstention`` and the confusion
  matrix).
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import numpy as np
from scipy.stats import binomtest

from workbench.diagnose.candidates import members_at
from workbench.diagnose.observations import Allowance
from workbench.diagnose.verdict import diagnose, diagnosis_record
from workbench.model.frame import Frame
from workbench.proving.cases import (
    FAINT,
    IDENTIFICATION,
    LEVELS,
    CaseSpec,
    case_campaign,
    case_mix,
    drawn_measurements,
    reached_level,
)
from workbench.proving.frames import proving_frame
from workbench.proving.mechanisms import NONE, OUTSIDE
from workbench.rig.effects import ADDED_MASS, UNEXPLAINED
from workbench.workflow.measured import measured_modes

__all__ = ["ProvingResult", "validation_specs", "run_proving_case", "quantity_label",
           "measurement_label", "wilson", "score"]


@dataclass(frozen=True)
class ProvingResult:
    """One blind proving-ground case: the truth, the verdict and their comparison (module docstring)."""

    case: int
    seed: int
    frame: str
    category: str  # none, single, combined or outside
    truth: str  # the primary effect (none, a vocabulary name or outside_vocabulary)
    secondary: str | None
    level: str
    truth_where: str | None
    mechanism: str | None
    footprint: float | None  # the footprint the primary effect reached (relative shift or damping ratio)
    verdict: str
    where: str | None
    also: tuple[str, ...]
    partial: str | None
    confidence: float
    shrinkage: float
    right: bool
    named_wrong: bool
    place_right: bool | None
    wall_time_s: float
    record: dict
    reached: str = ""  # the rung the primary's footprint reached (`reached_level`); "" without an effect
    quantity: str = CaseSpec.quantity  # the measurement (`CaseSpec`): the file's FRF quantity, the sensed one, lines
    sensed: str = CaseSpec.sensed
    df_hz: float = CaseSpec.df_hz


def validation_specs(cases: int, seed: int, measurement: str = "drawn") -> list[CaseSpec]:
    """The first ``cases`` diagnosis cases of the proving ground's mix for ``seed`` (identification cases left out).

    ``measurement``: ``drawn``, each case measured as a lab might (`workbench.proving.cases.drawn_measurements`:
    accelerometers or a vibrometer, accelerance, mobility or receptance in the file, 3200 to 6400 lines), the
    default since seed 19; ``fixed``, accelerance on 0.25 Hz lines for every case, as in the runs up to seed 18.
    """
    if measurement not in ("drawn", "fixed"):
        raise ValueError(f"validation_specs: measurement {measurement!r} is not drawn or fixed")
    specs: list[CaseSpec] = []
    n = cases
    while len(specs) < cases:
        specs = [s for s in case_mix(n, seed) if s.kind != IDENTIFICATION]
        n += cases - len(specs)
    return drawn_measurements(specs[:cases], seed) if measurement == "drawn" else specs[:cases]


def _category(spec: CaseSpec) -> str:
    if spec.kind == NONE:
        return "none"
    if spec.kind == OUTSIDE:
        return "outside"
    return "combined" if spec.secondary else "single"


def _same_place(frame: Frame, effect: str, truth: str | None, where: str | None) -> bool:
    if truth is None:
        return where is None
    if effect == ADDED_MASS.name:
        return bool({m for m, _ in members_at(frame, truth)} & {m for m, _ in members_at(frame, where)})
    return where == truth


def run_proving_case(allowance: Allowance, spec: CaseSpec) -> ProvingResult:
    """Simulate a case, diagnose its campaign blind under ``allowance`` (the frame's stated tolerances), score it
    against the truth (a `workbench.tasks.Mapper` task, ``allowance`` its shared argument).
    """
    campaign, truth = case_campaign(spec)
    assert isinstance(campaign.frame, Frame)  # the proving ground writes frame files
    start = time.perf_counter()
    result = diagnose(campaign.frame, measured_modes(campaign, None, "diagnose"),  # the truth is not passed
                      allowance=allowance)
    wall = time.perf_counter() - start
    category = _category(spec)
    allowed = {spec.kind} | ({spec.secondary} if spec.secondary else set())
    named = [e for e in (result.verdict, *(a["effect"] for a in result.also)) if e not in (NONE, UNEXPLAINED)]
    if category == "combined":
        right = spec.kind in named
    else:
        right = result.verdict == {"none": NONE, "outside": UNEXPLAINED}.get(category, spec.kind)
    frame = proving_frame(spec.frame)
    place = None
    if right and category in ("single", "combined") and result.verdict == spec.kind:
        place = _same_place(frame, spec.kind, truth["where"], result.where)
    primary = truth.get("primary") or {}
    return ProvingResult(
        spec.case, spec.seed, spec.frame, category, spec.kind if spec.kind != NONE else NONE, spec.secondary,
        spec.level, truth["where"], primary.get("mechanism"), primary.get("footprint"), result.verdict,
        result.where, tuple(a["effect"] for a in result.also), (result.partial or {}).get("effect"),
        result.confidence, result.shrinkage, bool(right), any(e not in allowed for e in named), place, wall,
        diagnosis_record(campaign.name, result),
        reached_level(primary["footprint"], primary["channel"]) if primary else "", spec.quantity, spec.sensed,
        spec.df_hz)


def quantity_label(result: ProvingResult) -> str:
    """``"receptance (from accelerance)"``: the file's quantity, and the sensed one where it differs."""
    return result.quantity + ("" if result.sensed == result.quantity else f" (from {result.sensed})")


def measurement_label(result: ProvingResult) -> str:
    """``"receptance (from accelerance), 0.195 Hz"``: how a case was measured, as the scores group it."""
    return f"{quantity_label(result)}, {result.df_hz:.3g} Hz"


def wilson(hits: int, n: int) -> dict[str, Any]:
    """``{"hits", "n", "rate", "ci95"}``: the rate and its Wilson 95 % interval (None without cases)."""
    if n == 0:
        return {"hits": 0, "n": 0, "rate": None, "ci95": None}
    ci = binomtest(hits, n).proportion_ci(0.95, method="wilson")
    return {"hits": hits, "n": n, "rate": hits / n, "ci95": [float(ci.low), float(ci.high)]}


def _rate(results: list[ProvingResult], keep: Callable[[ProvingResult], bool],
          hit: Callable[[ProvingResult], bool]) -> dict[str, Any]:
    chosen = [r for r in results if keep(r)]
    return wilson(sum(bool(hit(r)) for r in chosen), len(chosen))


def score(results: list[ProvingResult]) -> dict[str, Any]:
    """The module docstring's scores, a confusion matrix (truth -> verdict) and the cost per case."""
    effect_cases = [r for r in results if r.category in ("single", "combined")]
    confusion: dict[str, dict[str, int]] = {}
    for r in results:
        row = confusion.setdefault(r.truth if r.category != "combined" else f"{r.truth} (+ secondary)", {})
        row[r.verdict] = row.get(r.verdict, 0) + 1
    placed = [r for r in results if r.place_right is not None]

    def single(r: ProvingResult) -> bool:
        return r.category == "single" and r.reached != FAINT

    return {
        "cases": len(results),
        "single_accuracy": _rate(results, single, lambda r: r.right),
        "single_accuracy_by_level": {level: _rate([r for r in results if r.reached == level], single,
                                                  lambda r: r.right) for level in LEVELS},
        "single_accuracy_by_requested_level": {level: _rate([r for r in results if r.level == level],
                                                            lambda r: r.category == "single", lambda r: r.right)
                                               for level in LEVELS},
        "single_accuracy_by_measurement": {label: _rate([r for r in results if measurement_label(r) == label],
                                                        single, lambda r: r.right)
                                           for label in sorted({measurement_label(r) for r in results})},
        "faint_none": _rate(results, lambda r: r.reached == FAINT, lambda r: r.verdict == NONE),
        "single_partial_right": _rate(results, single, lambda r: r.right or r.partial == r.truth),
        "confident_wrong": _rate(results, lambda r: True, lambda r: r.named_wrong),
        "named_wrong": _rate(results, lambda r: r.verdict not in (NONE, UNEXPLAINED), lambda r: r.named_wrong),
        "none_false_positive": _rate(results, lambda r: r.category == "none", lambda r: r.verdict != NONE),
        "outside_unexplained": _rate(results, lambda r: r.category == "outside" and r.reached != FAINT,
                                     lambda r: r.verdict == UNEXPLAINED),
        "combined_primary": _rate(results, lambda r: r.category == "combined" and r.reached != FAINT,
                                  lambda r: r.right),
        "abstention": wilson(sum(r.verdict in (NONE, UNEXPLAINED) for r in effect_cases), len(effect_cases)),
        "place_accuracy": wilson(sum(bool(r.place_right) for r in placed), len(placed)),
        "confusion": confusion,
        "diagnosis_time_s": {"median": float(np.median([r.wall_time_s for r in results])) if results else None,
                             "max": float(max((r.wall_time_s for r in results), default=0.0))},
    }

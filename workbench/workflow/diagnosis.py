"""The gap diagnosis of a campaign, and its blind validation on the virtual rig: the numbers the commands write.

`diagnose_campaign` is the computing part of ``workbench diagnose`` (read the campaign, its measured
modes, diagnose, the ``diagnosis.json`` record); `validate` that of ``workbench validate-diagnosis``
(blind rig cases, `workbench.workflow.rig_cases`, and their summary), and `validation_files` the
texts it writes. The page is drawn by `workbench.report.diagnosis_page`; the command line writes.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from workbench.diagnose.verdict import Diagnosis, diagnose, diagnosis_record
from workbench.io.campaign import Campaign, load_campaign
from workbench.io.outputs import csv_text, json_text
from workbench.model.frame import Frame
from workbench.model.frame_file import read_frame
from workbench.progress import Progress
from workbench.tasks import Mapper, serial_mapper
from workbench.workflow.measured import measured_modes
from workbench.workflow.rig_cases import CASE_TYPES, CaseResult, run_case, summarise

__all__ = ["CampaignDiagnosis", "diagnose_campaign", "validate", "validation_files"]

CASE_COLUMNS = ["seed", "truth", "truth_where", "truth_parameters", "expected", "verdict", "where", "shrinkage",
                "effect_right", "place_right", "wall_time_s"]


@dataclass(frozen=True)
class CampaignDiagnosis:
    """A campaign, its diagnosis and the ``diagnosis.json`` record (with ``synthetic``)."""

    campaign: Campaign
    diagnosis: Diagnosis
    record: dict[str, Any]


def diagnose_campaign(path: str | Path, count: int | None = None,
                      notify: Callable[[str], None] | None = None) -> CampaignDiagnosis:
    """Read a campaign, diagnose its gap (`workbench.diagnose.verdict.diagnose`), make its record.

    Parameters
    ----------
    path : the campaign directory (modes.csv, FRFs, or moments.csv).
    count : use at most the first ``count`` modes.
    notify : called with a short message before each stage.
    """
    campaign = load_campaign(path)
    if notify:
        notify("modes of every test (modes.csv or circle fit)")
    measured = measured_modes(campaign, count, "diagnose")
    result = diagnose(campaign.frame, measured, notify)
    record = diagnosis_record(campaign.name, result)
    record["synthetic"] = bool(campaign.synthetic)
    return CampaignDiagnosis(campaign, result, record)


def _case(frame: Frame, task: tuple[str, int]) -> CaseResult:
    """One validation case: ``task = (effect kind, seed)``; the frame is shared by all."""
    return run_case(frame, *task)


def validate(cases: int, seed: int, frame_path: str | Path, progress: Progress | None = None,
             mapper: Mapper | None = None) -> dict[str, Any]:
    """``cases`` blind cases from ``seed`` on the frame file (`workbench.workflow.rig_cases`), summarised.

    The effect types come in turn (`CASE_TYPES`); case ``i`` is seeded ``seed * 100003 + i``.
    ``progress("validation cases", done, cases)`` is called after each case when no ``mapper``
    (`workbench.tasks.Mapper`, e.g. Dask's) runs them; a case's numbers depend only on its seed.

    Returns
    -------
    `workbench.workflow.rig_cases.summarise` of the cases, with ``seed``, ``frame``, ``wall_time_s``
    (s) and ``results`` (the `CaseResult` of every case).
    """
    frame = read_frame(frame_path)
    kinds = [CASE_TYPES[i % len(CASE_TYPES)] for i in range(cases)]
    start = time.perf_counter()
    run = mapper or serial_mapper(progress)
    results = run(_case, [(kinds[i], seed * 100_003 + i) for i in range(cases)], "validation cases", frame)
    summary = summarise(results)
    summary.update({"seed": seed, "frame": str(frame_path), "wall_time_s": time.perf_counter() - start})
    summary["results"] = results
    return summary


def validation_files(summary: dict[str, Any]) -> dict[str, str | bytes]:
    """``summary.json`` (the summary without its results) and ``cases.csv`` (one row per case) of `validate`."""
    rows = [(r.seed, r.truth, r.truth_where, json_text(r.truth_parameters).strip(), r.expected, r.verdict, r.where,
             r.shrinkage, r.effect_right, r.place_right, r.wall_time_s) for r in summary["results"]]
    return {"summary.json": json_text({k: v for k, v in summary.items() if k != "results"}),
            "cases.csv": csv_text(CASE_COLUMNS, rows)}

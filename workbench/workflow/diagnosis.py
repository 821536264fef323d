"""The gap diagnosis of a campaign, and its blind validation on the proving ground: what the commands write.

`diagnose_campaign` is the computing part of ``workbench diagnose`` (read the campaign, its measured
modes, diagnose, the ``diagnosis.json`` record); `validate` that of ``workbench validate-diagnosis``
(blind proving-ground cases, `workbench.workflow.proving_validation`, and their scores), and
`validation_files` the files it writes. The pages are drawn by `workbench.report.diagnosis_page`.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Any

from workbench.diagnose.decision import EXPLAINED_LEVEL, GAP_LEVEL, MIN_SHRINKAGE, NAME_CONFIDENCE, PAIR_EVIDENCE
from workbench.diagnose.frf_levels import LEVEL_ALPHA, LEVEL_FLOOR
from workbench.diagnose.observations import (
    COMMON_SD,
    DAMPING_MODEL_SD,
    DEFAULT_ALLOWANCE,
    FORM_SD,
    MODEL_FLOOR,
    Allowance,
)
from workbench.diagnose.verdict import Diagnosis, diagnose, diagnosis_record
from workbench.io.campaign import Campaign, load_campaign
from workbench.io.outputs import csv_text, json_text
from workbench.progress import Progress
from workbench.proving.campaigns import SOURCE
from workbench.proving.nuisances import NuisanceSettings
from workbench.tasks import Mapper, serial_mapper
from workbench.workflow.measured import measured_modes
from workbench.workflow.proving_validation import ProvingResult, run_proving_case, score, validation_specs

__all__ = ["CampaignDiagnosis", "diagnose_campaign", "validate", "validation_files"]

CASE_COLUMNS = ["case", "seed", "frame", "category", "truth", "secondary", "level", "truth_where", "mechanism",
                "footprint", "reached", "verdict", "where", "also", "partial", "confidence", "shrinkage", "right",
                "named_wrong", "place_right", "quantity", "sensed", "df_hz", "wall_time_s"]


@dataclass(frozen=True)
class CampaignDiagnosis:
    """A campaign, its diagnosis and the ``diagnosis.json`` record (with ``synthetic``)."""

    campaign: Campaign
    diagnosis: Diagnosis
    record: dict[str, Any]


def diagnose_campaign(path: str | Path, count: int | None = None, notify: Callable[[str], None] | None = None,
                      mapper: Mapper | None = None, allowance: Allowance = DEFAULT_ALLOWANCE) -> CampaignDiagnosis:
    """Read a campaign, diagnose its gap (`workbench.diagnose.verdict.diagnose`), make its record.

    Parameters
    ----------
    path : the campaign directory (modes.csv, FRFs, or moments.csv).
    count : use at most the first ``count`` modes.
    notify : called with a short message before each stage.
    mapper : runs the bands' votes, the tests' circle fits and the candidates' grids (`workbench.tasks.Mapper`);
        default, one after the other.
    allowance : how well the frame's member ends and sections are known (`workbench.diagnose.observations.Allowance`).
    """
    campaign = load_campaign(path)
    if notify:
        notify("modes of every test (modes.csv or circle fit)")
    measured = measured_modes(campaign, count, "diagnose", mapper)
    result = diagnose(campaign.frame, measured, notify, mapper=mapper, allowance=allowance)
    record = diagnosis_record(campaign.name, result)
    record["synthetic"] = bool(campaign.synthetic)
    return CampaignDiagnosis(campaign, result, record)


def validate(cases: int, seed: int, progress: Progress | None = None, mapper: Mapper | None = None,
             measurement: str = "drawn", allowance: Allowance = DEFAULT_ALLOWANCE) -> dict[str, Any]:
    """``cases`` blind proving-ground cases from ``seed`` (`workbench.workflow.proving_validation`), scored;
    ``measurement`` as `workbench.workflow.proving_validation.validation_specs`; each diagnosis under
    ``allowance`` (the frame's stated tolerances; the defaults, as `workbench diagnose`).

    ``progress("validation cases", done, cases)`` is called after each case when no ``mapper``
    (`workbench.tasks.Mapper`, e.g. Dask's) runs them; a case's numbers depend only on the seed.

    Returns
    -------
    `workbench.workflow.proving_validation.score` of the cases, with ``seed``, ``generator``, ``wall_time_s``
    (s), the decision's frozen levels (``levels``) and ``results`` (the `ProvingResult` of every case).
    """
    start = time.perf_counter()
    run = mapper or serial_mapper(progress)
    results = run(run_proving_case, validation_specs(cases, seed, measurement), "validation cases", allowance)
    summary = score(results)
    summary.update({"seed": seed, "generator": SOURCE, "nuisances": asdict(NuisanceSettings()),
                    "measurement": measurement,
                    "wall_time_s": time.perf_counter() - start,
                    "levels": {"gap_level": GAP_LEVEL, "explained_level": EXPLAINED_LEVEL,
                               "min_shrinkage": MIN_SHRINKAGE, "name_confidence": NAME_CONFIDENCE,
                               "pair_evidence": PAIR_EVIDENCE, "model_floor": MODEL_FLOOR, "common_sd": COMMON_SD,
                               "damping_model_sd": DAMPING_MODEL_SD, "form_sd": FORM_SD,
                               "geometry_sd_m": allowance.geometry_sd_m,
                               "section_second_moment_sd": allowance.section_sd[0],
                               "section_area_sd": allowance.section_sd[1],
                               "frf_level_floor": LEVEL_FLOOR, "frf_level_alpha": LEVEL_ALPHA}})
    summary["results"] = results
    return summary


def validation_files(summary: dict[str, Any]) -> dict[str, str | bytes]:
    """``validation.json`` (the summary and one compact entry per case) and ``cases.csv`` (one row per case, the
    diagnosis's wall time last) of `validate`; the page (`workbench.report.validation_page.validation_html`)
    reads the JSON record.
    """
    results: list[ProvingResult] = summary["results"]
    rows = [tuple(getattr(r, c) if c not in ("also",) else " ".join(r.also) for c in CASE_COLUMNS) for r in results]
    record = {k: v for k, v in summary.items() if k != "results"}
    record["case_results"] = [dict(zip(CASE_COLUMNS, row)) for row in rows]
    return {"validation.json": json_text(record), "cases.csv": csv_text(CASE_COLUMNS, rows)}

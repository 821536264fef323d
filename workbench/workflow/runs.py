"""Whole runs: the identification report's (`report_run`) and the demo's (`demo_run`), numbers only.

A `Run` is what a report page draws: campaign studies and section 5 predictions
(`workbench.workflow.study`), with the run's own steps and settings.

The demo spreads its work over the processes of one `workbench.workflow.execution.mapper`, in two
stages: the campaigns are loaded and circle-fitted (the one-bolt sweeps also moment-matched, for
the joint models that section 5 applies), then the studies and the predictions run side by side.
Each task is a whole campaign, so the numbers are those of a serial run for the same seed; the
step lines of a task are told when it returns (`workbench.workflow.steps.tell`).
"""

from __future__ import annotations

import time
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, replace
from pathlib import Path

from workbench.identify.moments import MomentFit, moment_matching
from workbench.model.structure import structure_of
from workbench.progress import Progress
from workbench.workflow.execution import mapper as task_mapper
from workbench.workflow.measured import Loaded, campaign_label, load_and_extract, load_campaigns, measured_modes
from workbench.workflow.report_inputs import load_for_report
from workbench.workflow.steps import Notify, Step, tell
from workbench.workflow.study import JointSource, Prediction, Study, joint_sources, predict_campaign, study_campaign

__all__ = ["Run", "identify_sources", "report_run", "demo_run", "DEMO_STUDIES", "DEMO_BAYES", "DEMO_PREDICTIONS"]

DEMO_STUDIES = ("one_bolt_vertical_sweep", "one_bolt_horizontal_sweep")  # one joint group each (Table 4)
DEMO_BAYES = ("one_bolt_vertical_sweep",)  # emcee where the time budget allows (about 15 s)
DEMO_PREDICTIONS = ("two_bolt_table5", "four_bolt_table6")  # section 5; table7's mode 9 scatters (campaigns/README)


@dataclass(frozen=True)
class Run:
    """A whole report's content: campaign studies, section 5 predictions, and the run's settings.

    ``steps`` are the run-level steps (loading and circle fits); each study and prediction keeps its own.
    """

    title: str
    studies: tuple[Study, ...]
    predictions: tuple[Prediction, ...]
    steps: tuple[Step, ...]
    seed: int
    samples: int
    bayes_steps: int
    diagnosis: dict | None = None  # a diagnosis.json record, in the report's summary where one is part of the run


def _fit_of(path: str, loaded: Loaded, seed: int) -> MomentFit:
    """Moment matching of one loaded campaign, as `study_campaign` does it."""
    campaign, extraction = loaded
    data = (extraction.measured_modes(f"{path} (modes by circle fit of its FRFs)") if extraction is not None
            else measured_modes(campaign, None, "identify from"))
    return moment_matching(structure_of(campaign.frame), data, seed=seed)


def _sources_of(path: str, loaded: Loaded, seed: int) -> dict[str, JointSource]:
    """Moment matching of one loaded campaign: group name -> `JointSource`."""
    return joint_sources(_fit_of(path, loaded, seed), campaign_label(loaded[0]))


def _merge_sources(found: Mapping[str, Mapping[str, JointSource]]) -> dict[str, JointSource]:
    """The sources of several campaigns (path -> sources) in one mapping.

    Raises
    ------
    ValueError
        Two campaigns identify the same joint group.
    """
    sources: dict[str, JointSource] = {}
    for path, some in found.items():
        for group, source in some.items():
            if group in sources:
                raise ValueError(f"{path}: joint group {group!r} is already identified on {sources[group].campaign!r}")
            sources[group] = source
    return sources


def identify_sources(loaded: Mapping[str, Loaded], seed: int = 0) -> dict[str, JointSource]:
    """Moment matching on each loaded one-bolt campaign; group name -> `JointSource`.

    Parameters
    ----------
    loaded : path -> ``(campaign, extraction or None)`` (`load_campaigns`).

    Raises
    ------
    ValueError
        Two campaigns identify the same joint group.
    """
    return _merge_sources({path: _sources_of(path, pair, seed) for path, pair in loaded.items()})


def report_run(campaign_path: str | Path, *, joints_from: Sequence[str | Path] = (), seed: int = 0,
               samples: int = 1000, bayes: bool = True, bayes_steps: int = 3000, workers: int = 1,
               bands: Sequence[tuple[float, float]] | None = None, progress: Progress | None = None,
               notify: Notify = None) -> Run:
    """`workbench report`: one campaign's study (modes.csv, else a circle fit with ``bands``, Hz:
    `load_for_report`) and, with ``joints_from``, its section 5 prediction from their joint models.
    """
    start = time.perf_counter()
    with task_mapper(workers, None, progress) as tasks:
        campaign, extraction, note = load_for_report(campaign_path, bands, tasks)
        loaded = load_campaigns([str(p) for p in joints_from], tasks, progress) if joints_from else {}
        run_steps = [Step("load and circle-fit", time.perf_counter() - start, f"{1 + len(loaded)} campaign(s)")]
        studied = replace(campaign, frf=None) if extraction is None and note else campaign  # modes.csv as it is
        study = study_campaign(studied, extraction, seed=seed, samples=samples, bayes=bayes,
                               bayes_steps=bayes_steps, mapper=tasks, progress=progress, notify=notify)
    study = replace(study, extraction_note=note) if note else study
    predictions: tuple[Prediction, ...] = ()
    if joints_from:
        if extraction is None:
            raise ValueError(f"{campaign_path}: no circle fit of FRFs to set a prediction against"
                             + (" (the campaign's modes.csv is used: pass --bands to circle-fit)" if note else ""))
        t0 = time.perf_counter()
        sources = identify_sources(loaded, seed)
        run_steps.append(Step("joint models of the sources", time.perf_counter() - t0,
                              ", ".join(f"{g} from {s.campaign}" for g, s in sources.items()), seed))
        predictions = (predict_campaign(campaign, extraction, sources, seed=seed, progress=progress,
                                        notify=notify),)
    return Run(f"Identification report: {study.name}", (study,), predictions, tuple(run_steps), seed, samples,
               bayes_steps)


def _demo_load(seed: int, task: tuple[str, bool]) -> tuple[Loaded, MomentFit | None]:
    """Stage one of the demo: a campaign loaded and circle-fitted, and moment-matched when asked."""
    path, identify = task
    loaded = load_and_extract(path)
    return loaded, (_fit_of(path, loaded, seed) if identify else None)


def _demo_work(shared: tuple[int, int, int, dict[str, JointSource]],
               task: tuple[str, Loaded, bool, MomentFit | None]) -> Study | Prediction:
    """Stage two of the demo: a campaign's study (``"study"``, reusing stage one's moment matching)
    or section 5 prediction (``"predict"``).
    """
    seed, samples, bayes_steps, sources = shared
    kind, (campaign, extraction), bayes, fit = task
    if kind == "study":
        return study_campaign(campaign, extraction, seed=seed, samples=samples, bayes=bayes, bayes_steps=bayes_steps,
                              fit=fit)
    if extraction is None:
        raise ValueError(f"{campaign.path}: the campaign has no FRFs to set a prediction against")
    return predict_campaign(campaign, extraction, sources, seed=seed)


def demo_run(campaigns_dir: str | Path, *, seed: int = 0, samples: int = 500, bayes_steps: int = 2000,
             workers: int = 2, progress: Progress | None = None, notify: Notify = None) -> Run:
    """`workbench demo`: the paper's chain on the bundled campaigns (`DEMO_STUDIES`, `DEMO_BAYES`,
    `DEMO_PREDICTIONS`): identify the vertical and horizontal joint models on the one-bolt sweeps,
    then predict the two- and four-bolt frames with them (section 5); two stages over ``workers``
    processes (module docstring).

    Raises
    ------
    ValueError
        A bundled campaign is missing from ``campaigns_dir``.
    """
    root = Path(campaigns_dir)
    names = DEMO_STUDIES + DEMO_PREDICTIONS
    missing = [n for n in names if not (root / n / "campaign.toml").is_file()]
    if missing:
        raise ValueError(f"{root}: the bundled campaigns are not there (missing {', '.join(missing)}); run from the "
                         "repository root or pass --campaigns DIR")
    if notify is not None:
        notify(f"demo: circle fits of {', '.join(names)} from {root}/ ({workers} processes)")
    start = time.perf_counter()
    # the largest first, so that the processes finish together; the longest study first too
    order = DEMO_PREDICTIONS + DEMO_STUDIES
    with task_mapper(workers, None, progress) as tasks:
        stage = tasks(_demo_load, [(str(root / n), n in DEMO_STUDIES) for n in order], "circle fits", seed)
        loaded = {n: pair for n, (pair, _) in zip(order, stage)}
        fits = {n: fit for n, (_, fit) in zip(order, stage)}
        sources = _merge_sources({str(root / n): joint_sources(fits[n], campaign_label(loaded[n][0]))
                                  for n in DEMO_STUDIES})
        run_steps = [Step("load and circle-fit", time.perf_counter() - start,
                          f"{len(names)} campaigns, {workers} processes")]
        if notify is not None:
            notify(f"loaded and circle-fitted {len(names)} campaigns ({run_steps[0].wall_time_s:.1f} s)")
        work = ([("study", loaded[n], n in DEMO_BAYES, fits[n]) for n in DEMO_STUDIES]
                + [("predict", loaded[n], False, None) for n in DEMO_PREDICTIONS])
        done = tasks(_demo_work, work, "studies and predictions", (seed, samples, bayes_steps, sources))
    for result in done:
        tell(notify, f"{result.name}: ", result.steps)
    studies = tuple(r for r in done if isinstance(r, Study))
    predictions = tuple(r for r in done if isinstance(r, Prediction))
    return Run("Bolted-joint variability: identification on one-bolt frames, prediction of multi-bolt frames",
               studies, predictions, tuple(run_steps), seed, samples, bayes_steps)

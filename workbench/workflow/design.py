"""`workbench design`: score the candidate designs, recommend one, check it by simulation (CONTRACTS.md 3).

The predictions come from `workbench.plan.predict` (one task per design, handed out by the caller's
mapper: local processes or a Dask scheduler). The optional check (`verify_design`) simulates whole
campaigns of the recommended design: each test's moduli drawn by level as the prediction assumes,
the frequencies solved exactly (no Rayleigh quotient), the extraction's scatter added, and the real
moment matching run on each with its own bootstrap intervals.
"""

from __future__ import annotations

import math
import os
import warnings
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np

from workbench.extraction.records import MeasuredModes
from workbench.identify.data import JointGroups, joint_groups
from workbench.identify.moments import Z95, moment_matching
from workbench.io.campaign import Campaign, Factor, campaign_toml
from workbench.io.outputs import DESIGN_STAMP, csv_text
from workbench.model.frame import Frame
from workbench.model.matrix_model import MatrixModel
from workbench.model.structure import Structure, structure_at_moduli, structure_modes
from workbench.plan.candidates import Design, candidate_designs
from workbench.plan.predict import DesignPrediction, Planner, PlanSettings, stratified_moduli
from workbench.tasks import Mapper, serial_mapper

DEFAULT_BUDGET = 60  # tests, when the user gives none (the full factorial of four bolts, 81, when larger)

__all__ = ["DesignPlan", "plan_design", "cov_guesses", "plan_prediction", "verify_design", "Verification",
           "planned_laws", "design_files"]


@dataclass(frozen=True)
class DesignPlan:
    """Every candidate's prediction and the choice (CONTRACTS.md section 3's rule).

    recommended : the cheapest design whose predicted CoV width is at most ``target`` for every group;
        when none is, the one with the smallest largest CoV width (``reached`` False).
    planner : the model, its groups, the laws planned for and the settings, shared by every prediction.
    """

    target: float
    budget: int
    predictions: tuple[DesignPrediction, ...]
    recommended: DesignPrediction
    reached: bool
    planner: Planner

    @property
    def model(self) -> Structure:
        return self.planner.model

    @property
    def groups(self) -> JointGroups:
        return self.planner.groups

    @property
    def mean_pa(self) -> np.ndarray:
        return self.planner.mean_pa

    @property
    def cov(self) -> np.ndarray:
        return self.planner.cov

    @property
    def settings(self) -> PlanSettings:
        return self.planner.settings


def cov_guesses(texts: list[str] | None) -> dict[str, float]:
    """``--cov NAME=VALUE`` options as a dict."""
    out = {}
    for text in texts or ():
        name, _, value = text.partition("=")
        try:
            out[name.strip()] = float(value)
        except ValueError:
            raise ValueError(f"--cov {text}: expected NAME=VALUE, e.g. horizontal=0.2") from None
    return out


def planned_laws(model: Structure, groups: JointGroups,
                 cov_guess: dict[str, float] | None) -> tuple[np.ndarray, np.ndarray]:
    """Each group's mean modulus (the file's) and CoV (the file's, or the user's guess by group or joint name)."""
    names = {j.name: g for g, members in enumerate(groups.members) for j in (model.joints[i] for i in members)}
    cov = np.array([np.mean([model.joints[i].cov for i in members]) for members in groups.members])
    for key, value in (cov_guess or {}).items():
        if key in groups.groups:
            g = groups.groups.index(key)
        elif key in names:
            g = names[key]
        else:
            raise ValueError(f"--cov {key}={value}: no joint or joint group {key!r} in the model "
                             f"(groups: {', '.join(groups.groups)}; joints: {', '.join(names)})")
        if not (0.0 < value < 1.0):
            raise ValueError(f"--cov {key}={value}: a CoV between 0 and 1 is expected")
        cov[g] = value
    for g, c in enumerate(cov):
        if not c > 0:
            raise ValueError(f"joint group {groups.groups[g]!r}: the model gives it no CoV (cov = 0); "
                             f"give a guess with --cov {groups.groups[g]}=0.1")
    return np.array(groups.nominal_pa, float), cov


def plan_design(model: Structure, budget: int | None = None, target: float = 0.5,
                cov_guess: dict[str, float] | None = None, settings: PlanSettings | None = None,
                mapper: Mapper | None = None) -> DesignPlan:
    """Predict every candidate design within ``budget`` tests and recommend one (module docstring).

    Raises
    ------
    ValueError
        A budget below the number of parameters (a mean and a CoV per group), a target not in (0, 10].
    """
    settings = settings or PlanSettings()
    groups = joint_groups(model)
    n_parameters = 2 * len(groups.groups)
    n_joints = len(model.joints)
    budget = max(DEFAULT_BUDGET, 3**n_joints if n_joints <= 4 else 0) if budget is None else budget
    if budget < max(n_parameters, 3):
        raise ValueError(f"--budget {budget}: fewer tests than the {n_parameters} parameters to identify (a mean "
                         f"modulus and a CoV for each of the groups {', '.join(groups.groups)}); give at least "
                         f"{max(n_parameters, 3)}")
    if not (0.0 < target <= 10.0):
        raise ValueError(f"--target {target}: a relative interval width in (0, 10] is expected")
    mean_pa, cov = planned_laws(model, groups, cov_guess)
    planner = Planner(model, groups, mean_pa, cov, settings)
    designs = candidate_designs(n_joints, budget, low=max(n_parameters, 3), seed=settings.seed)
    run = mapper or serial_mapper()
    predictions = tuple(run(Planner.predict, designs, "designs", planner))  # predict(planner, design)
    reaching = [p for p in predictions if np.all(p.width[:, 1] <= target)]
    if reaching:
        best = min(reaching, key=lambda p: (p.design.tests, float(p.width[:, 1].max())))
    else:
        best = min(predictions, key=lambda p: (float(p.width[:, 1].max()), p.design.tests))
        warnings.warn(f"no design within {budget} tests reaches a CoV width of {target:g} for every group; "
                      f"recommending the most precise, {best.design.name} (widths "
                      f"{', '.join(f'{w:.2f}' for w in best.width[:, 1])})", stacklevel=2)
    return DesignPlan(target, budget, predictions, best, bool(reaching), planner)


def plan_prediction(plan: DesignPlan, design: Design) -> DesignPrediction:
    """The prediction of a design of one's own (a candidate or not) under ``plan``'s laws and settings."""
    return plan.planner.predict(design)


@dataclass(frozen=True)
class Verification:
    """Moment matching on ``campaigns`` simulated campaigns of one design.

    estimate : (campaigns, n_groups, 2) identified (mean Pa, CoV).
    width : (campaigns, n_groups, 2) reported 95 % interval width over the true value (NaN: no interval).
    truth : (n_groups, 2) the laws simulated.
    """

    design: Design
    estimate: np.ndarray
    width: np.ndarray
    truth: np.ndarray

    @property
    def median_width(self) -> np.ndarray:
        return np.nanmedian(self.width, axis=0)

    @property
    def spread(self) -> np.ndarray:
        """2 x 1.96 x the sd of the log estimates (the relative 95 % spread)."""
        return 2.0 * Z95 * np.log(self.estimate).std(axis=0, ddof=1)

    @property
    def bias(self) -> np.ndarray:
        return np.mean(self.estimate, axis=0) / self.truth - 1.0


def _one_campaign(shared: tuple, task: tuple[int, int]) -> tuple[np.ndarray, np.ndarray]:
    model, groups, mean_pa, cov, design, count, scatter = shared
    index, seed = task
    rng = np.random.default_rng(seed)
    n_joints = len(model.joints)
    gamma = stratified_moduli(design.levels, design.level_count, groups.per_joint(cov, n_joints), rng, 1)[0]
    moduli = gamma * groups.per_joint(mean_pa, n_joints)
    f = np.array([structure_modes(structure_at_moduli(model, row), count).frequency_hz[:count] for row in moduli])
    f = f * (1.0 + scatter * rng.standard_normal(f.shape))
    measured = MeasuredModes(f, modes=np.arange(1, count + 1), tests=tuple(f"{t + 1:02d}" for t in range(len(f))),
                             source=f"simulated campaign {index} of {design.name}")
    fit = moment_matching(model, measured, groups, seed=index)
    estimate = np.stack([fit.mean_pa, fit.cov], axis=1)
    width = np.full_like(estimate, math.nan)
    truth = np.stack([mean_pa, cov], axis=1)
    for col, ci in enumerate((fit.mean_ci95, fit.cov_ci95)):
        if ci is not None:
            width[:, col] = (ci[:, 1] - ci[:, 0]) / truth[:, col]
    return estimate, width


def verify_design(plan: DesignPlan, design: Design, campaigns: int = 12, seed: int = 1,
                  mapper: Mapper | None = None) -> Verification:
    """Moment matching on ``campaigns`` simulated campaigns of ``design`` (module docstring); seeds from
    ``SeedSequence(seed).spawn``, so the numbers do not depend on the mapper.
    """
    seeds = [int(s.generate_state(1)[0]) for s in np.random.SeedSequence(seed).spawn(campaigns)]
    shared = (plan.model, plan.groups, plan.mean_pa, plan.cov, design, plan.settings.count,
              plan.settings.frequency_scatter)
    run = mapper or serial_mapper()
    results = run(_one_campaign, list(enumerate(seeds)), "verification campaigns", shared)
    return Verification(design, np.array([r[0] for r in results]), np.array([r[1] for r in results]),
                        np.stack([plan.mean_pa, plan.cov], axis=1))


def with_settings(plan_settings: PlanSettings, count: int | None = None, frequency_scatter: float | None = None,
                  seed: int | None = None) -> PlanSettings:
    """``plan_settings`` with the command line's options that were given."""
    s = plan_settings
    return replace(s, count=s.count if count is None else count, seed=s.seed if seed is None else seed,
                   frequency_scatter=s.frequency_scatter if frequency_scatter is None else frequency_scatter)


def design_files(plan: DesignPlan, model_path: Path, out: Path, frame: Frame | MatrixModel) -> dict[str, str]:
    """``designs.csv``, and the recommended design as ``design.csv`` and ``campaign.toml`` (CONTRACTS.md 2-3)."""
    rows = []
    for p in plan.predictions:
        for g, group in enumerate(plan.groups.groups):
            for c, parameter in enumerate(("youngs_modulus", "cov")):
                rows.append((p.design.name, p.design.tests, group, parameter, float(p.width[g, c]),
                             "true" if p is plan.recommended else "false"))
    designs = csv_text(["design", "tests", "group", "parameter", "predicted_rel_ci95_width", "recommended"], rows)
    best = plan.recommended.design
    joints = [j.name for j in plan.model.joints]
    factors = tuple(Factor(f"bolt_{name}", "tightening", {str(i): n for i, n in enumerate(best.level_names, 1)},
                           joint=name) for name in joints)
    width = len(str(best.tests))
    design = csv_text(["test_id", *(f.name for f in factors)],
                      ([f"{t + 1:0{max(2, width)}d}", *map(str, row)] for t, row in enumerate(best.levels)))
    frame_file = Path(os.path.relpath(model_path.resolve(), out.resolve())).as_posix()
    campaign = Campaign(name=f"planned campaign: {best.name}", frame=frame, synthetic=False,
                        description=f"{best.tests} tests planned by workbench design (target CoV width "
                                    f"{plan.target:g}); no measurement yet",
                        source=f"{DESIGN_STAMP} planned for {model_path.name}", factors=factors, frame_file=frame_file)
    return {"designs.csv": designs, "design.csv": design, "campaign.toml": campaign_toml(campaign)}

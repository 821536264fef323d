"""The identification report's and the demo's workflow, numbers only (no figure, no HTML).

One campaign (`study_campaign`): its FRFs -> circle-fit modes of every test
(`workbench.workflow.measured.extract_campaign`)
-> the nominal fit, eq. (1), and the paper's two-step moment matching, eq. (10)-(11)
(`workbench.identify.moments.moment_matching`) -> the Bayesian identification (`workbench.identify.bayes`) where it
applies -> SMR1, SMR2, adaptive and Pert2 against a seeded Monte Carlo on the identified model
(Figure 11) -> the stochastic FRF of the identified model (Figure 12, `workbench.uq.prediction.frf_band`)
with the measured mean modal damping of each mode (paper 2.2.2).

Section 5 (`predict_campaign`): the joint models identified on the one-bolt frames, one per joint
group (vertical, horizontal; Table 4), applied to a multi-bolt frame
(`workbench.model.joints.frame_with_joint_models`), whose frequency moments (adaptive SMR) and FRF
band are set against that frame's own measured FRFs and circle-fit frequencies (Figures 14, 16).

Whole runs (the report's, the demo's) are in `workbench.workflow.runs`. Each stage returns a
frozen record that the report draws (`workbench.report.page`, `workbench.report.plots`).
Random steps take the ``seed`` given and record it; ``notify`` receives one line per finished
step (the command line prints it); ``progress`` (`workbench.progress`) follows the long steps (Monte
Carlo, emcee, FRF band). This module imports neither pandas nor matplotlib: campaigns are loaded
through `workbench.io.campaign`, imported where they are loaded.
"""

from __future__ import annotations

import time
from collections.abc import Mapping
from dataclasses import dataclass, field

import numpy as np

from workbench.extraction.records import MeasuredModes
from workbench.identify.bayes import Posterior, bayes_identify
from workbench.identify.moments import MomentFit, moment_matching
from workbench.io.campaign import Campaign
from workbench.model.frame import Frame
from workbench.model.joints import frame_with_joint_models
from workbench.model.matrix_model import MatrixModel
from workbench.model.structure import Structure, structure_of
from workbench.progress import Progress
from workbench.tasks import Mapper
from workbench.uq.prediction import (
    BAND_CHECKS,
    BAND_QUIET_LINES,
    BAND_SAMPLES,
    FrequencyComparison,
    FRFBand,
    band_detail,
    compare_frequencies,
    frf_band,
)
from workbench.uq.smr import propagate
from workbench.uq.stochastic import (
    TENSOR_LIMIT,
    FrequencyMoments,
    MonteCarloResult,
    joint_model,
    monte_carlo,
    quadrature_reference,
)
from workbench.workflow.measured import (
    Extraction,
    campaign_label,
    extract_campaign,
    frequency_axis,
    measured_modes,
)
from workbench.workflow.steps import Notify, Step, Steps

__all__ = ["ACCURACY_METHODS", "Step", "Accuracy", "JointSource", "Study", "study_campaign", "joint_sources",
           "Prediction", "predict_campaign"]

ACCURACY_METHODS = ("smr1", "smr2", "adaptive", "pert2")  # Figure 11's methods, and our adaptive one

# ------------------------------------------------------------------------------------ one campaign

@dataclass(frozen=True)
class Accuracy:
    """Figure 11: the frequency moments of the SMR methods against references, on one model.

    As in ``benchmarks/smr_accuracy.py``: the errors are measured against the exact tensor-Gauss
    reference (`workbench.uq.stochastic.quadrature_reference`, no sampling noise) where it is
    affordable, with the seeded Monte Carlo as one more bar and its 3-standard-error band; without
    the exact reference, against the Monte Carlo. (A Monte Carlo of a few hundred samples has a
    std error of several % on the std: alone it could not resolve SMR errors of 0.1-1 %.)

    Attributes
    ----------
    methods : method name (`ACCURACY_METHODS`) -> its moments of the first modes.
    reference : the Monte Carlo (draws, seed, standard errors).
    exact : the quadrature moments, or None (more random joints than the tensor rule's
        `workbench.uq.stochastic.TENSOR_LIMIT`).
    """

    methods: dict
    reference: MonteCarloResult
    exact: FrequencyMoments | None = None

    @property
    def samples(self) -> int:
        return int(self.reference.frequency_hz.shape[0])

    def errors_percent(self) -> tuple[dict, dict]:
        """``(mean, std)`` relative errors against the exact reference (else the Monte Carlo), %,
        method -> (n_modes,); the Monte Carlo itself is the entry ``"mc"`` when the exact reference exists.
        """
        ref = self.exact if self.exact is not None else self.reference.moments
        compared = dict(self.methods)
        if self.exact is not None:
            compared["mc"] = self.reference.moments
        mean = {m: 100.0 * (r.mean_hz / ref.mean_hz - 1.0) for m, r in compared.items()}
        std = {m: 100.0 * (r.std_hz / ref.std_hz - 1.0) for m, r in compared.items()}
        return mean, std

    def reference_band_percent(self) -> tuple[np.ndarray, np.ndarray]:
        """Three Monte Carlo standard errors of the mean and of the std, in % of each."""
        se_mean, se_std = self.reference.standard_errors()
        ref = self.reference.moments
        return 300.0 * se_mean / ref.mean_hz, 300.0 * se_std / ref.std_hz


@dataclass(frozen=True)
class JointSource:
    """A joint group's identified model, and where it comes from (section 5's input).

    ``youngs_modulus_pa`` and ``cov`` define the Gamma law of eq. (8)-(9); the intervals are the
    moment matching's approximate 95 % intervals (None without tests).
    """

    group: str
    youngs_modulus_pa: float
    cov: float
    youngs_modulus_ci95: tuple[float, float] | None
    cov_ci95: tuple[float, float] | None
    campaign: str
    method: str = "moments"


def joint_sources(fit: MomentFit, campaign_name: str) -> dict[str, JointSource]:
    """Group name -> `JointSource` of a moment-matching fit."""
    out = {}
    for g, group in enumerate(fit.groups.groups):
        ci_e = None if fit.mean_ci95 is None else (float(fit.mean_ci95[g][0]), float(fit.mean_ci95[g][1]))
        ci_c = None if fit.cov_ci95 is None else (float(fit.cov_ci95[g][0]), float(fit.cov_ci95[g][1]))
        out[group] = JointSource(group, float(fit.mean_pa[g]), float(fit.cov[g]), ci_e, ci_c, campaign_name)
    return out


def _joint_models(sources: Mapping[str, JointSource]) -> dict[str, tuple[float, float]]:
    return {g: (s.youngs_modulus_pa, s.cov) for g, s in sources.items()}


@dataclass(frozen=True)
class Study:
    """Everything the report shows about one campaign (module notes); ``*_note`` say why a part is absent.

    Attributes
    ----------
    campaign : the loaded campaign; extraction : its circle-fit modes, None without FRFs.
    data : the identification's input (per-test frequencies, or published moments).
    moments : the moment matching (its ``nominal`` is the eq. (1) fit, Table 2).
    joints : group -> identified `JointSource` (moment matching).
    posterior : the Bayesian identification, or None (``bayes_note``).
    accuracy : Figure 11 on the identified model, or None (``accuracy_note``).
    band : the identified model's FRF band (Figure 12), or None (``band_note``).
    steps : the steps run, with their wall times and seeds.
    """

    campaign: Campaign
    extraction: Extraction | None
    data: MeasuredModes
    moments: MomentFit
    joints: dict[str, JointSource]
    posterior: Posterior | None
    accuracy: Accuracy | None
    band: FRFBand | None
    steps: tuple[Step, ...]
    extraction_note: str = ""
    bayes_note: str = ""
    accuracy_note: str = ""
    band_note: str = ""

    @property
    def name(self) -> str:
        return campaign_label(self.campaign)


def _bayes_refusal(data: MeasuredModes, bayes: bool) -> str:
    if not bayes:
        return "not run: skipped on request (--no-bayes, or the demo's time budget)"
    if not data.has_tests:
        return ("not run: the campaign holds only published moments, and the full likelihood needs every "
                "test's frequencies")
    return ""


def study_campaign(campaign, extraction: Extraction | None = None, *, seed: int = 0, samples: int = 1000,
                   bayes: bool = True, bayes_steps: int = 3000, bayes_burn: int | None = None,
                   mapper: Mapper | None = None, progress: Progress | None = None, notify: Notify = None,
                   fit: MomentFit | None = None) -> Study:
    """Identify and propagate one campaign (module notes).

    Parameters
    ----------
    campaign : a loaded campaign (`workbench.io.campaign.load_campaign`).
    extraction : its circle-fit modes if already extracted (`extract_campaign`); extracted here
        when None and the campaign has FRFs.
    seed : seeds the bootstrap of the moment matching's intervals, emcee, the Monte Carlo reference
        and the FRF band.
    samples : Monte Carlo samples of the Figure 11 reference (the paper: 10 000); the FRF band takes
        `BAND_SAMPLES` draws by SMR, as the paper's envelope.
    bayes : run the Bayesian identification where it applies; bayes_steps, bayes_burn : its
        kept and discarded steps per walker (burn-in default: a quarter of the kept steps, at most 500).
    mapper : runs the Monte Carlo reference's chunks (`workbench.workflow.execution.mapper`).
    fit : the campaign's moment matching if already done with this ``seed`` (the demo's first stage);
        done here when None.
    progress : called as the long steps advance (`workbench.progress`); notify : one line per finished step.
    """
    steps = Steps(notify, f"{campaign_label(campaign)}: ")
    source = str(campaign.path or campaign.name)
    extraction_note = ""
    if extraction is None and campaign.frf is not None:
        extraction = extract_campaign(campaign)
    if extraction is not None:
        steps.add("circle fit", None, f"{len(extraction.bands)} modes x {len(extraction.tests)} tests",
                  wall_time_s=extraction.wall_time_s)
        data = extraction.measured_modes(source + " (modes by circle fit of its FRFs)")
    else:
        extraction_note = ("The campaign holds no FRFs (only "
                           f"{'published moments' if campaign.moments is not None else 'extracted modes'}), "
                           "so there are no measured FRFs to overlay and no circle fit to show.")
        data = measured_modes(campaign, None, "identify from")

    model = structure_of(campaign.frame)
    fit = fit or moment_matching(model, data, seed=seed)
    sources = joint_sources(fit, campaign_label(campaign))
    steps.add("moment matching", None, ", ".join(f"{g}: E = {s.youngs_modulus_pa / 1e9:.3g} GPa, "
                                                 f"CoV = {100 * s.cov:.3g} %" for g, s in sources.items()), fit.seed,
              wall_time_s=fit.wall_time_s)

    posterior, bayes_note = None, _bayes_refusal(data, bayes)
    if not bayes_note:
        start = time.perf_counter()
        burn = min(500, bayes_steps // 4) if bayes_burn is None else bayes_burn
        posterior = bayes_identify(model, data, seed=seed, steps=bayes_steps, burn=burn, progress=progress)
        steps.add("Bayesian identification (emcee)", start,
                  f"{posterior.walkers} walkers x {posterior.steps} steps, max R-hat {posterior.rhat.max():.3f}", seed)

    identified = structure_of(frame_with_joint_models(campaign.frame, _joint_models(sources)))
    joints = joint_model(identified)
    count = int(np.asarray(data.modes).max())
    accuracy, accuracy_note = None, ""
    if joints.random.any():
        start = time.perf_counter()
        methods = {m: _propagate(identified, joints, m, count, seed) for m in ACCURACY_METHODS}
        reference = monte_carlo(identified, joints, count, samples, seed, mapper, progress)
        random = int(joints.random.sum())
        exact = (quadrature_reference(identified, joints, count, points=9 if random <= 2 else 5)
                 if random <= TENSOR_LIMIT else None)  # 5^4 = 625 solves at most, about 3 s
        accuracy = Accuracy(methods, reference, exact)
        steps.add("SMR against Monte Carlo", start, f"{count} modes, {samples} samples"
                  + (f", exact {exact.method} reference" if exact is not None else ""), seed)
    else:
        accuracy_note = "The identified joint model has no random joint (every CoV is 0): nothing to propagate."

    band, band_note = None, ""
    if extraction is None:
        band_note = ("The campaign holds no measured FRFs to compare a predicted band with, nor the measured "
                     "modal damping the FRF synthesis needs (paper 2.2.2).")
    elif accuracy is None:
        band_note = accuracy_note
    else:
        start = time.perf_counter()
        band = frf_band(identified, joints, frequency_axis(extraction), extraction.mean_damping(),
                        quantity=campaign.quantity, samples=BAND_SAMPLES, seed=seed, quiet_lines=BAND_QUIET_LINES,
                        check_samples=BAND_CHECKS, progress=progress)
        steps.add("stochastic FRF", start, band_detail(band), seed)
    return Study(campaign, extraction, data, fit, sources, posterior, accuracy, band, tuple(steps.items),
                 extraction_note, bayes_note, accuracy_note, band_note)


def _propagate(model: Structure, joints, method: str, count: int, seed: int) -> FrequencyMoments:
    return propagate(model, joints, method, count, seed=seed)


# -------------------------------------------------------------------------------- section 5

@dataclass(frozen=True)
class Prediction:
    """Section 5: a multi-bolt frame predicted from joint models identified elsewhere.

    Attributes
    ----------
    campaign, extraction : the multi-bolt campaign and its circle-fit modes (the measurement).
    sources : group -> the `JointSource` applied to that group's joints.
    frame : the campaign's frame with those joint models (`frame_with_joint_models`).
    moments : adaptive SMR moments of the predicted frequencies (modes in the model's order).
    band : the predicted FRF band (Figures 14, 16) with the campaign's measured mean damping.
    comparison : predicted against measured frequency means and spreads (`compare_frequencies`).
    steps : wall times and seeds.
    """

    campaign: Campaign
    extraction: Extraction
    sources: dict[str, JointSource]
    frame: Frame | MatrixModel
    moments: FrequencyMoments
    band: FRFBand
    comparison: FrequencyComparison
    steps: tuple[Step, ...] = field(default=())

    @property
    def name(self) -> str:
        return campaign_label(self.campaign)


def predict_campaign(campaign, extraction: Extraction, sources: Mapping[str, JointSource], *, seed: int = 0,
                     progress: Progress | None = None, notify: Notify = None) -> Prediction:
    """Predict a multi-bolt campaign from joint models identified on other campaigns (section 5).

    Parameters
    ----------
    campaign : the campaign predicted (its frame names the joint groups of ``sources``).
    extraction : its circle-fit modes (`extract_campaign`): the measured frequencies and damping.
    sources : group (or joint) name -> `JointSource`; joints that no source names keep the frame
        file's model (the report lists which).
    seed : of the FRF band's draws (`BAND_SAMPLES` of them, by SMR).

    Raises
    ------
    ValueError
        A source names no group or joint of the frame.
    """
    steps = Steps(notify, f"{campaign_label(campaign)}: ")
    start = time.perf_counter()
    frame = frame_with_joint_models(campaign.frame, _joint_models(sources))
    model = structure_of(frame)
    joints = joint_model(frame)
    measured = extraction.frequency_hz()
    count = min(measured.shape[1], model.size - 2)
    moments = _propagate(model, joints, "adaptive", count, seed)
    comparison = compare_frequencies(moments, measured)
    worst = float(np.nanmax(np.abs(comparison.mean_rel_error)))
    steps.add("predicted moments (adaptive SMR)", start, f"{count} modes, largest mean error {100 * worst:.2f} %")
    start = time.perf_counter()
    band = frf_band(model, joints, frequency_axis(extraction), extraction.mean_damping(), quantity=campaign.quantity,
                    samples=BAND_SAMPLES, seed=seed, quiet_lines=BAND_QUIET_LINES, check_samples=BAND_CHECKS,
                    progress=progress)
    steps.add("predicted FRF band", start, band_detail(band), seed)
    return Prediction(campaign, extraction, dict(sources), frame, moments, band, comparison, tuple(steps.items))

"""A case mix for validating the diagnosis and the identification on data the workbench did not make.

`case_mix` lists `CaseSpec` records over: no effect; each effect of the vocabulary with a magnitude ladder;
combined effects (a primary and a weaker secondary: ``kind`` the primary, ``secondary`` set);
out-of-vocabulary effects; and joint identification on the paper's designs, across the bundled frames and
the generated ones (`workbench.proving.frames`).
`case_campaign` turns a spec into a campaign and its truth.

**Magnitudes** are footprints (`workbench.proving.footprint`), so that a level means the same on every
geometry: the largest relative frequency shift of the modes the band measures (`footprint.measurable_top_hz`:
not one whose resonance the band's top cuts) of 0.3 % (small: about the
scatter the nuisances leave between tests), 1 % (medium), 3 % (large); for joint damping the largest
added damping ratio of 0.1 %, 0.3 %, 1 %. A secondary effect has a third of the primary's footprint.
Where a mechanism cannot reach a level within its physical bounds (a wire tie's strength, a stinger's
own mass), the truth records the footprint it reached, and a score reads the case at the rung that footprint
is nearest (`reached_level`): a wire tie asked for a 1 % shift that its strength caps at 0.06 % is not a medium
effect. Below half the small rung it is ``faint``: the per-mode residual of the no-effect cases' as-built frames
is of that size (development seeds 10 and 11: a largest residual of 0.12 % in the median case, 0.22 % in the
90th percentile), so no diagnosis can tell it from none.

**Designs** (factor and design layout of ``workbench/plan/designs.py``, rebuilt here):

- ``blind``: the rig's blind cases: 4 tests at low and 4 at high amplitude, alternating; every joint
  scattered between tests by a Gamma law of CoV ``joint_cov`` (0.02) about the file's mean; the nominal file
  carries its joints deterministic (CoV 0), as the rig's blind cases do;
- ``paper``: joint identification: two joints, the paper's Table 5 (amplitude x bolt_A x bolt_B, 18 tests);
  three or more, Table 6's two-level factorial with a centre point at low amplitude (17 tests for four);
  one, amplitude x three tightening levels, twice (12 tests). Each joint group's law (mean and CoV) is
  drawn around the file's (mean x 0.75-1.3, CoV 0.05-0.25) and each test's moduli drawn from it; the
  tightening levels are labels only: the moduli are independent draws of the law, which is what the
  identification assumes.

**Measurement**: `case_mix` measures every case as accelerance on 0.25 Hz lines over 0-1250 Hz;
`drawn_measurements` (the blind validation's default since seed 19) draws each case's as a lab's: the sensors
(accelerometers, or a laser vibrometer's mobility), the quantity the software exports (accelerance, mobility or
receptance, the noise staying the sensed quantity's), and 3200, 5000 or 6400 lines over the band.

The nominal file is the frame with ``beam_theory = "timoshenko"`` (the article's beams are Timoshenko: the
gap is the effect, not the beam theory), except in ``shear_deformation`` cases, where it is Euler-Bernoulli.
"""

from __future__ import annotations

import itertools
from dataclasses import asdict, dataclass, replace
from typing import Any

import numpy as np

from workbench.io.campaign import Campaign, Factor
from workbench.model.frame import Frame
from workbench.progress import Progress
from workbench.proving.article import Article
from workbench.proving.campaigns import CampaignSettings, simulate_campaign
from workbench.proving.footprint import article_frequencies, calibrate
from workbench.proving.frames import FRAME_NAMES, proving_frame
from workbench.proving.mechanisms import EFFECTS, NONE, OUTSIDE, Mechanism, vocabulary_mechanism
from workbench.proving.nuisances import streams
from workbench.proving.outside import outside_mechanism

__all__ = ["CaseSpec", "KINDS", "LEVELS", "MEASUREMENTS", "MEASUREMENT_SHARES", "LINE_SPACINGS_HZ", "FOOTPRINTS",
           "DAMPING_FOOTPRINTS", "FAINT", "FAINT_SHARE", "case_mix", "drawn_measurements", "case_campaign",
           "calibrated_primary",
           "expected_verdict", "reached_level", "design_of"]

COMBINED, IDENTIFICATION = "combined", "identification"
KINDS = (NONE,) + EFFECTS + (COMBINED, OUTSIDE, IDENTIFICATION)
LEVELS = ("small", "medium", "large")
FOOTPRINTS = {"small": 0.003, "medium": 0.01, "large": 0.03}
DAMPING_FOOTPRINTS = {"small": 0.001, "medium": 0.003, "large": 0.01}
FAINT = "faint"  # a footprint below FAINT_SHARE of the small rung (module docstring)
FAINT_SHARE = 0.5
SECONDARY_SHARE = 1.0 / 3.0
_AMPLITUDE = Factor("amplitude", "amplitude", {"low": "low amplitude", "high": "high amplitude (5 x low)"})
_TIGHTENING = {"1": "hand-tight, preload < 100 N", "2": "1800 N", "3": "6000 N"}
# (sensed, exported): an accelerometer's accelerance, or the receptance or mobility its software exports; a laser
# vibrometer's mobility, or its receptance; a lab's mix, accelerometers first
MEASUREMENTS = (("accelerance", "accelerance"), ("accelerance", "receptance"), ("accelerance", "mobility"),
                ("mobility", "mobility"), ("mobility", "receptance"))
MEASUREMENT_SHARES = (0.4, 0.15, 0.1, 0.25, 0.1)
LINE_SPACINGS_HZ = (1250.0 / 6400, 0.25, 1250.0 / 3200)  # 6400, 5000 and 3200 lines over the 1250 Hz band
_MEASUREMENT_STREAM = 0x6D656173  # "meas": the measurement's own stream of a mix's seed
_COMBINABLE = tuple(e for e in EFFECTS if e != "shear_deformation")  # shear changes the nominal file itself


@dataclass(frozen=True)
class CaseSpec:
    """One validation case.

    Attributes
    ----------
    case : its number in the mix. seed : the seed of everything drawn for it.
    frame : a name of `workbench.proving.frames.FRAME_NAMES`.
    kind : none, a vocabulary effect (the primary one when ``secondary`` is set: a combined case),
        outside_vocabulary or identification.
    level : small, medium or large (the primary's footprint); "" for none and identification.
    variant : the mechanism (a name of `workbench.proving.mechanisms.VARIANTS` or of
        `workbench.proving.outside.OUTSIDE_VARIANTS`), None to draw one.
    where : the effect's place, None to draw one.
    secondary, secondary_variant : a combined case's weaker effect and its mechanism.
    design : ``blind`` or ``paper`` (module docstring). joint_cov : the blind design's joint scatter.
    blind_tests : the blind design's number of tests (even: low and high amplitude alternating).
    quantity, sensed, df_hz : the measurement (`workbench.proving.campaigns.CampaignSettings`): the file's FRF
        quantity, the quantity the sensors measure (where the noise is added), the line spacing (Hz).
    """

    case: int
    seed: int
    frame: str
    kind: str
    level: str = ""
    variant: str | None = None
    where: str | None = None
    secondary: str | None = None
    secondary_variant: str | None = None
    design: str = "blind"
    joint_cov: float = 0.02
    blind_tests: int = 8
    quantity: str = CampaignSettings.quantity  # the proving ground's fixed measurement, by default
    sensed: str = CampaignSettings.quantity
    df_hz: float = CampaignSettings.df_hz

    def settings(self) -> CampaignSettings:
        """The campaign's measurement settings (the nuisances at their defaults)."""
        return CampaignSettings(df_hz=self.df_hz, quantity=self.quantity, sensed=self.sensed)


def case_mix(n_cases: int, seed: int) -> list[CaseSpec]:
    """``n_cases`` specs cycling over `KINDS` (each kind's levels in turn), frames and details drawn from ``seed``.

    The same ``(n_cases, seed)`` always gives the same list, and a longer list starts with a shorter one's cases.
    Every case is measured as accelerance on 0.25 Hz lines; `drawn_measurements` draws a lab's mix instead.
    """
    rng = np.random.default_rng(np.random.SeedSequence(seed))
    children = np.random.SeedSequence(seed).spawn(n_cases)
    specs = []
    for i in range(n_cases):
        kind = KINDS[i % len(KINDS)]
        level = LEVELS[(i // len(KINDS)) % len(LEVELS)] if kind not in (NONE, IDENTIFICATION) else ""
        frame = FRAME_NAMES[int(rng.integers(len(FRAME_NAMES)))]
        secondary = None
        if kind == COMBINED:
            kind, secondary = (str(x) for x in rng.choice(_COMBINABLE, 2, replace=False))
        case_seed = int(children[i].generate_state(1)[0])
        specs.append(CaseSpec(i, case_seed, frame, kind, level, secondary=secondary,
                              design="paper" if kind == IDENTIFICATION else "blind"))
    return specs


def drawn_measurements(specs: list[CaseSpec], seed: int) -> list[CaseSpec]:
    """``specs`` each measured as a lab might: (sensed, exported) quantities from `MEASUREMENTS` with
    `MEASUREMENT_SHARES`, the line spacing from `LINE_SPACINGS_HZ`, drawn in the specs' order from a stream of
    ``seed`` of its own (the specs' frames, kinds and case seeds stay what `case_mix` drew).
    """
    rng = np.random.default_rng(np.random.SeedSequence([seed, _MEASUREMENT_STREAM]))
    drawn = []
    for spec in specs:
        sensed, quantity = MEASUREMENTS[int(rng.choice(len(MEASUREMENTS), p=MEASUREMENT_SHARES))]
        df_hz = float(LINE_SPACINGS_HZ[int(rng.integers(len(LINE_SPACINGS_HZ)))])
        drawn.append(replace(spec, quantity=quantity, sensed=sensed, df_hz=df_hz))
    return drawn


def expected_verdict(kind: str) -> str:
    """The diagnosis's right verdict for a kind: the effect, ``none``, or ``unexplained`` outside the vocabulary."""
    if kind == OUTSIDE:
        return "unexplained"
    if kind in (NONE, IDENTIFICATION):
        return NONE
    return kind


def reached_level(footprint: float, channel: str) -> str:
    """The rung of the ladder nearest (in ratio) the footprint a case reached, or `FAINT` below `FAINT_SHARE` of
    the small rung (module docstring).

    Parameters
    ----------
    footprint : the reached footprint (relative frequency shift, or added damping ratio when ``channel`` is
        ``"damping"``).
    channel : the mechanism's channel: ``"damping"`` reads the damping ladder, any other the frequency one.
    """
    ladder = DAMPING_FOOTPRINTS if channel == "damping" else FOOTPRINTS
    if not footprint > FAINT_SHARE * ladder[LEVELS[0]]:
        return FAINT
    return min(LEVELS, key=lambda level: abs(np.log(footprint / ladder[level])))


def _bolt_factors(frame: Frame) -> tuple[Factor, ...]:
    return tuple(Factor(f"bolt_{chr(ord('A') + k)}", "tightening", dict(_TIGHTENING), j)
                 for k, j in enumerate(frame.joint_names))


def design_of(kind: str, frame: Frame, blind_tests: int = 8) -> tuple[tuple[Factor, ...], list[dict[str, str]]]:
    """The factors and tests of a design (module docstring): ``blind`` (``blind_tests`` of them) or ``paper``."""
    if kind == "blind":
        return (_AMPLITUDE,), [{"amplitude": level} for level in ("low", "high") * (blind_tests // 2)]
    if kind != "paper":
        raise ValueError(f"design_of: {kind!r} is not blind or paper")
    bolts = _bolt_factors(frame)
    names = [b.name for b in bolts]
    if len(bolts) == 1:
        tests = [{"amplitude": a, names[0]: lv} for a in ("low", "high") for lv in "123"] * 2
    elif len(bolts) == 2:  # Table 5: full factorial, the last factor fastest
        tests = [dict(zip(["amplitude"] + names, c)) for c in itertools.product(("low", "high"), "123", "123")]
    else:  # Table 6: 2^n on levels 1/3 by the count of bolts at 3, then a centre point
        tests = [{"amplitude": "low", **{b: "3" if k in chosen else "1" for k, b in enumerate(names)}}
                 for count in range(len(names) + 1) for chosen in itertools.combinations(range(len(names)), count)]
        tests.append({"amplitude": "low", **{b: "2" for b in names}})
    return (_AMPLITUDE,) + bolts, tests


def _mechanism(frame: Frame, effect: str, variant: str | None, where: str | None,
               rng: np.random.Generator) -> Mechanism:
    if effect == OUTSIDE:
        return outside_mechanism(frame, rng, variant)
    return vocabulary_mechanism(frame, effect, rng, where, variant)


def _target(mechanism: Mechanism, level: str, share: float = 1.0) -> float:
    ladder = DAMPING_FOOTPRINTS if mechanism.channel == "damping" else FOOTPRINTS
    return ladder[level] * share


def _effect_record(mechanism: Mechanism, x: float, fp: float, target: float) -> dict[str, Any]:
    return {"effect": mechanism.effect, "mechanism": mechanism.name, "where": mechanism.where, "intensity": x,
            "footprint": fp, "target_footprint": target, "channel": mechanism.channel,
            "parameters": mechanism.parameters(x)}


def _joint_laws(spec: CaseSpec, frame: Frame, rng: np.random.Generator) -> dict[str, tuple[float, float]]:
    """Each joint's Gamma law: the file's mean and ``joint_cov`` (blind), or a law per group drawn around the file's."""
    if spec.design == "blind":
        return {j.name: (j.youngs_modulus, spec.joint_cov) for j in frame.joints}
    groups: dict[str, tuple[float, float]] = {}
    for j in frame.joints:
        if j.group not in groups:
            groups[j.group] = (float(rng.uniform(0.75, 1.3)), float(rng.uniform(0.05, 0.25)))
    return {j.name: (j.youngs_modulus * groups[j.group][0], groups[j.group][1]) for j in frame.joints}


def calibrated_primary(spec: CaseSpec, rng: np.random.Generator | None = None,
                       f_max_hz: float | None = None) -> tuple[Mechanism, float, float]:
    """A case's primary mechanism, the intensity that gives its rung's footprint and that footprint.

    ``rng``: the case's effect stream (`workbench.proving.nuisances.streams`), drawn from ``spec.seed`` when None;
    ``f_max_hz``: the band's top, the spec's settings' when None.
    """
    frame = proving_frame(spec.frame)
    rng = streams(spec.seed).effect if rng is None else rng
    band = spec.settings().f_max_hz if f_max_hz is None else f_max_hz
    mech = _mechanism(frame, spec.kind, spec.variant, spec.where, rng)
    x, fp = calibrate(Article(frame), mech, _target(mech, spec.level), f_max_hz=band)
    return mech, x, fp


def case_campaign(spec: CaseSpec, settings: CampaignSettings | None = None,
                  progress: Progress | None = None) -> tuple[Campaign, dict[str, Any]]:
    """The campaign of one case and its truth (module docstring).

    Returns
    -------
    (Campaign, truth)
        The campaign carries the nominal frame file; the truth (JSON-ready) adds to
        `workbench.proving.campaigns.simulate_campaign`'s: ``case`` (the spec), ``effect`` (a vocabulary name,
        ``none`` or ``outside_vocabulary``), ``expected_verdict``, ``where``, ``level``, ``primary`` and
        ``secondary`` (mechanism, place, intensity, footprint reached and target, parameters with the
        vocabulary's magnitude key), ``article_hz`` (the nuisance-free article's first frequencies) and, for
        joint identification, the joint laws per group.
    """
    frame = proving_frame(spec.frame)
    settings = settings or spec.settings()
    rng = streams(spec.seed).effect
    base = Article(frame)
    nominal = replace(frame, beam_theory="timoshenko")
    effect = spec.kind
    article, primary, secondary = base, None, None
    band = settings.f_max_hz  # a shift above the band is never measured
    if effect not in (NONE, IDENTIFICATION):
        mech, x, fp = calibrated_primary(spec, rng, band)
        article, primary = mech.build(base, x), _effect_record(mech, x, fp, _target(mech, spec.level))
        if mech.nominal is not None:
            nominal = mech.nominal(frame, x)
        if spec.secondary is not None:
            second = _mechanism(frame, spec.secondary, spec.secondary_variant, None, rng)
            target = _target(second, spec.level, SECONDARY_SHARE)
            x2, fp2 = calibrate(base, second, target, f_max_hz=band)
            article, secondary = second.build(article, x2), _effect_record(second, x2, fp2, target)
    if spec.design == "blind":
        nominal = replace(nominal, joints=tuple(replace(j, cov=0.0) for j in nominal.joints))
    factors, tests = design_of(spec.design, frame, spec.blind_tests)
    laws = _joint_laws(spec, frame, rng)
    name = f"proving-ground case {spec.case}: {spec.kind} {spec.level}".strip()
    campaign, truth = simulate_campaign(nominal, article, factors, tests, laws, spec.seed, settings, name=name,
                                        description=f"Proving ground, {spec.frame}, seed {spec.seed}",
                                        progress=progress)
    truth.update({
        "case": asdict(spec), "frame": spec.frame, "effect": effect if effect != IDENTIFICATION else NONE,
        "expected_verdict": expected_verdict(spec.kind), "where": primary["where"] if primary else None,
        "level": spec.level, "combined": secondary is not None, "primary": primary, "secondary": secondary,
        "article_hz": article_frequencies(article).tolist(),
    })
    if spec.design == "paper":
        truth["groups"] = {j.group: {"mean_pa": laws[j.name][0], "cov": laws[j.name][1]} for j in frame.joints}
    return campaign, truth


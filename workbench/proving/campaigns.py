"""Campaigns of the proving ground: a test article measured over a design, as a `workbench.io.campaign.Campaign`.

The campaign's ``frame`` is the **nominal** frame file (what the user's model says); its data come from the
`Article` (the nominal frame, as built, with the hidden effect) and the nuisances of
`workbench.proving.nuisances`. One test of the design:

1. its temperature offset (drift over the sequence) scales every modulus;
2. each joint's modulus is its Gamma draw for the test, times the joint's amplitude softening at the test's
   amplitude level (``low`` = 1, ``high`` = 5, or numeric levels over the lowest);
3. the article is discretised (`workbench.proving.fem.discretise`), its modes found up to three times
   the band's top (the rest enter as residual flexibility), the damping drawn (`DampingModel`);
4. the FRF at every sensor for the force at the excitation (`workbench.proving.beams.frf`, a direct
   solve per line where the article has dashpots) in the quantity the sensor measures (``sensed``:
   accelerance for an accelerometer, mobility for a vibrometer), plus noise at each sensor's SNR, then
   converted to the quantity the file holds (``quantity``: what the test software exports) by
   ``(i w)^k``, so that an accelerometer's receptance carries its noise divided by ``w^2``, as an exported
   one does (the 0 Hz line, where that division has no value, is written as 0).

The FRF table has the virtual rig's layout (``test_id`` 1..n as integers, the frame's sensors in order,
``frequency_hz``, ``real``, ``imag``; 0 to 1250 Hz every 0.25 Hz by default), so that the workbench's circle fit
and identification read it as any campaign. The truth (`simulate_campaign`'s second value) is JSON-ready
and never part of the campaign.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field, replace
from typing import Any

import numpy as np
import pandas as pd

from workbench.io.campaign import Campaign, Factor
from workbench.model.frame import Frame
from workbench.progress import Progress, report
from workbench.proving.article import Article
from workbench.proving.beams import QUANTITIES, damped_modes, frf, solve_modes
from workbench.proving.fem import discretise
from workbench.proving.geometry import perturb_geometry
from workbench.proving.nuisances import (
    NuisanceSettings,
    Streams,
    add_noise,
    damping_model,
    gamma_draws,
    perturb_frame,
    sensor_snr_db,
    stratified_gamma_draws,
    streams,
    temperature_offsets,
)

__all__ = ["CampaignSettings", "AMPLITUDE_RATIOS", "amplitude_ratios", "simulate_campaign", "SOURCE"]

AMPLITUDE_RATIOS = {"low": 1.0, "high": 5.0}  # paper 2.2.2: the high amplitude is five times the low one
SOURCE = "synthetic: the proving ground (workbench.proving), independent elements, mechanisms and nuisances"


@dataclass(frozen=True)
class CampaignSettings:
    """The measurement: band, quantity, how many modes the truth reports, and the nuisances."""

    f_max_hz: float = 1250.0
    df_hz: float = 0.25
    quantity: str = "accelerance"  # the FRFs' quantity in the file
    sensed: str | None = None  # the quantity the sensors measure, where the noise is added; None: ``quantity``
    truth_modes: int = 10  # the truth reports at least these modes, and every one in the band
    synthesis_factor: float = 3.0  # modes up to this times f_max are summed
    nuisances: NuisanceSettings = field(default_factory=NuisanceSettings)

    @property
    def sensed_quantity(self) -> str:
        """The quantity the sensors measure (``sensed``, or the file's ``quantity`` when it is None)."""
        return self.sensed or self.quantity

    def frequency_axis(self) -> np.ndarray:
        """(n,) Hz: 0 to ``f_max_hz`` every ``df_hz``."""
        return self.df_hz * np.arange(int(round(self.f_max_hz / self.df_hz)) + 1)


def amplitude_ratios(factors: Sequence[Factor], design: Sequence[Mapping[str, str]]) -> np.ndarray:
    """(n_tests,) each test's excitation amplitude over the lowest level (1 without an amplitude factor)."""
    amplitude = [f for f in factors if f.kind == "amplitude"]
    if not amplitude:
        return np.ones(len(design))
    name = amplitude[0].name
    keys = [str(test[name]) for test in design]
    try:
        values = np.array([float(k) for k in keys])
    except ValueError:
        values = np.array([AMPLITUDE_RATIOS[k] for k in keys])
    return values / values.min()


def _tables(frame: Frame, factors: Sequence[Factor], design: Sequence[Mapping[str, str]], axis: np.ndarray,
            curves: list[np.ndarray]) -> tuple[pd.DataFrame, pd.DataFrame]:
    """The FRF table (the rig's layout) and the design table."""
    sensors = [s.name for s in frame.sensors]
    n_tests, n_freq = len(design), axis.size
    values = np.stack(curves)
    frf_table = pd.DataFrame({
        "test_id": np.repeat(np.arange(1, n_tests + 1), len(sensors) * n_freq),
        "sensor": np.tile(np.repeat(np.array(sensors, dtype=object), n_freq), n_tests),
        "frequency_hz": np.tile(axis, n_tests * len(sensors)),
        "real": values.real.ravel(),
        "imag": values.imag.ravel(),
    })
    design_table = pd.DataFrame([{"test_id": i + 1, **{f.name: str(t[f.name]) for f in factors}}
                                 for i, t in enumerate(design)], columns=["test_id"] + [f.name for f in factors])
    return frf_table, design_table


@dataclass(frozen=True)
class _Built:
    """What every test of a campaign shares: the as-built article, its damping law, the sensors' SNR."""

    article: Article
    damping: Any
    snr_db: np.ndarray
    record: dict[str, Any]


def _frequencies(article: Article, count: int) -> np.ndarray:
    d = discretise(article, {j.name: j.youngs_modulus for j in article.frame.joints})
    return solve_modes(d.system.stiffness, d.system.mass, count).frequency_hz


def _build(article: Article, settings: CampaignSettings, rng: Streams) -> _Built:
    frame, manufacturing = perturb_frame(article.frame, settings.nuisances, rng.article)
    damping = damping_model(settings.nuisances, rng.article)
    snr = sensor_snr_db(len(frame.sensors), settings.nuisances, rng.article)
    built = replace(article, frame=frame)
    if settings.nuisances.geometry_sd_range[1] > 0:  # drawn last: the draws above are the same with it off
        sd = float(rng.article.uniform(*settings.nuisances.geometry_sd_range))
        built, manufacturing["geometry"] = perturb_geometry(built, sd, rng.article)
        manufacturing["geometry"]["geometry_sd_m"] = sd
    # what manufacturing alone does to the frequencies (joints at their means, reference temperature): a gap
    # between model and article that no effect made, which a "none" verdict has to tolerate
    shift = _frequencies(built, settings.truth_modes) / _frequencies(article, settings.truth_modes) - 1.0
    record = {"manufacturing": manufacturing, "as_built_shift": shift.tolist(), "damping": damping.record(),
              "snr_db": {s.name: float(v) for s, v in zip(frame.sensors, snr)}}
    return _Built(built, damping, snr, record)


def _test(built: _Built, moduli: dict[str, float], temperature: float, settings: CampaignSettings,
          axis: np.ndarray, rng: Streams) -> tuple[np.ndarray, dict[str, Any]]:
    """One test's noisy FRFs (n_sensors, n_freq) and its truth (module docstring, steps 3-4)."""
    factor = 1.0 + settings.nuisances.temperature_coefficient * temperature
    d = discretise(built.article, moduli, factor)
    count = settings.truth_modes + 6
    modes = solve_modes(d.system.stiffness, d.system.mass, count, max_hz=settings.synthesis_factor * settings.f_max_hz)
    zeta = built.damping.ratios(modes.frequency_hz, rng.tests)
    sensed = settings.sensed_quantity
    noisy = _exported(add_noise(frf(d.system, modes, axis, zeta, sensed), built.snr_db, rng.noise), axis, sensed,
                      settings.quantity)
    n = max(settings.truth_modes, int(np.sum(modes.frequency_hz <= settings.f_max_hz)))
    if d.system.damping is None:
        freq, ratio = modes.frequency_hz[:n], zeta[:n]
    else:
        freq, ratio = (v[:n] for v in damped_modes(d.system, modes, zeta))
    return noisy, {"temperature_offset_k": float(temperature), "modulus_factor": float(factor),
                   "joint_moduli_pa": dict(moduli), "frequency_hz": freq.tolist(), "damping_ratio": ratio.tolist()}


def _exported(values: np.ndarray, frequency_hz: np.ndarray, sensed: str, quantity: str) -> np.ndarray:
    """``values`` (n_sensors, n_freq) measured as ``sensed``, in ``quantity``: times ``(i w)^(p - p_sensed)``
    (0 where that is infinite, at 0 Hz).
    """
    k = QUANTITIES.index(quantity) - QUANTITIES.index(sensed)  # in the order of the powers of i w
    if k == 0:
        return values
    iw = 2j * np.pi * np.asarray(frequency_hz, float)
    factor = np.zeros_like(iw)
    np.power(iw, k, out=factor, where=iw != 0)
    return values * factor[None, :]


def simulate_campaign(nominal: Frame, article: Article, factors: Sequence[Factor], design: Sequence[Mapping[str, str]],
                      joint_laws: Mapping[str, tuple[float, float]], seed: int,
                      settings: CampaignSettings | None = None, *, name: str = "proving-ground campaign",
                      description: str = "", progress: Progress | None = None,
                      strata: Mapping[str, str] | None = None) -> tuple[Campaign, dict[str, Any]]:
    """Measure ``article`` over ``design``: a campaign whose frame file is ``nominal``, and its truth.

    Parameters
    ----------
    nominal : the frame file the campaign carries (the user's model).
    article : the tested article (`workbench.proving.article.Article`), effect included, nuisances not.
    factors, design : the design's columns and one dict per test (factor name -> level key).
    joint_laws : joint name -> (mean modulus in Pa, coefficient of variation) of its Gamma law over the tests.
    seed : every random draw comes from ``SeedSequence(seed)`` (`workbench.proving.nuisances.streams`).
    strata : joint name -> the factor whose level picks the joint's draw: level ``l`` of ``L`` (in the
        factor's order) draws from the ``l``-th of ``L`` equal-probability slices of its law, instead of the
        whole law (`stratified_gamma_draws`); joints not named draw from the whole law.

    Returns
    -------
    (Campaign, truth)
        The truth: per test the levels, amplitude ratio, temperature, joint moduli, true frequencies (Hz)
        and damping ratios of the modes in the band (at least ``settings.truth_modes``); the joint laws with
        the drawn moduli, their sample mean and CoV; the nuisances drawn, with ``as_built_shift``, the
        relative frequency shift manufacturing alone gives the article's first modes.
    """
    settings = settings or CampaignSettings()
    rng = streams(seed)
    built = _build(article, settings, rng)
    n = len(design)
    temperature = temperature_offsets(n, settings.nuisances, rng.tests)
    laws = {j.name: tuple(joint_laws.get(j.name, (j.youngs_modulus, 0.0))) for j in article.frame.joints}
    draws = {j: gamma_draws(mean, cov, n, rng.tests) for j, (mean, cov) in laws.items()}
    for j, factor_name in (strata or {}).items():
        factor = next(f for f in factors if f.name == factor_name)
        keys = list(factor.levels)
        where = np.array([keys.index(str(test[factor_name])) for test in design])
        mean, cov = laws[j]
        draws[j] = stratified_gamma_draws(float(mean), float(cov), where, len(keys), rng.tests)
    amplitude = amplitude_ratios(factors, design)
    soft = {s.joint: s for s in article.softening}
    axis = settings.frequency_axis()
    curves, tests = [], []
    for i, levels in enumerate(design):
        moduli = {j: float(v[i]) * (soft[j].factor(amplitude[i]) if j in soft else 1.0) for j, v in draws.items()}
        curve, test = _test(built, moduli, float(temperature[i]), settings, axis, rng)
        curves.append(curve)
        tests.append({"test_id": i + 1, "levels": {f.name: str(levels[f.name]) for f in factors},
                      "amplitude_ratio": float(amplitude[i]), **test})
        report(progress, "proving-ground tests", i + 1, n)
    frf_table, design_table = _tables(nominal, factors, design, axis, curves)
    campaign = Campaign(name=name, frame=nominal, synthetic=True, quantity=settings.quantity,
                        description=description, source=SOURCE, factors=tuple(factors), design=design_table,
                        frf=frf_table)
    truth = {
        "generator": "workbench.proving", "campaign": name, "seed": seed, "quantity": settings.quantity,
        "sensed": settings.sensed_quantity, "f_max_hz": settings.f_max_hz, "df_hz": settings.df_hz,
        "joints": {j: {"mean_pa": float(laws[j][0]), "cov": float(laws[j][1]), "moduli_pa": v.tolist(),
                       "sample_mean_pa": float(v.mean()),
                       "sample_cov": float(v.std(ddof=1) / v.mean()) if v.size > 1 else 0.0}
                   for j, v in draws.items()},
        "nuisances": built.record, "tests": tests,
    }
    return campaign, truth

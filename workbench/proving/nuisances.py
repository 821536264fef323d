"""Nuisances of the proving ground: what a real campaign carries besides the effect under test.

Every case has them, the no-effect cases too:

- **manufacturing**: each material's Young's modulus and density, and each member's section width and
  thickness, off by a few tenths of a percent (one draw per article: the bars were cut once); and the
  geometry: each member end off where the file puts it by up to a millimetre in each direction, the
  article's spread drawn between 0 and 1 mm (a frame measured with more or less care: a length from two ends
  off by up to 0.35 % of a 0.4 m member; `workbench.proving.geometry`, since seed 24);
- **damping**: a level ``zeta0``, a trend with frequency ``(f / 100 Hz) ** alpha`` and a per-mode jitter
  (lognormal), drawn per article, and a small per-test jitter (the same mode re-measured never gives the
  same damping);
- **joint scatter**: each joint's modulus drawn per test from a Gamma law of given mean and CoV (maximum
  entropy for a positive quantity of given mean and dispersion, as the paper's eq. 8-9);
- **temperature**: an offset and a drift over the test sequence of a few K, plus a random walk; every
  modulus times ``1 + c_T dT`` with ``c_T = -3e-4 / K`` (aluminium, -0.03 %/K);
- **measurement noise**: complex circular Gaussian on each curve, its RMS relative to the curve's own RMS
  over the band with a signal-to-noise ratio that depends on the sensor (30 to 40 dB).

Each random draw comes from its own `numpy.random.Generator`, spawned from ``numpy.random.SeedSequence(seed)``
(`streams`): one stream per purpose, so that changing, say, the noise leaves the article and the tests the
same, and one seed always gives the same bytes.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace
from typing import Any

import numpy as np
import scipy.special

from workbench.model.frame import Frame, moved_frame

__all__ = ["NuisanceSettings", "Streams", "streams", "perturb_frame", "built_frame", "DampingModel", "damping_model",
           "temperature_offsets", "gamma_draws", "sensor_snr_db", "add_noise"]


@dataclass(frozen=True)
class NuisanceSettings:
    """Sizes of the nuisances (module docstring); SI units, ratios are relative."""

    material_sd: float = 0.003  # E and density
    section_sd: float = 0.003  # width and thickness of each member
    geometry_sd_range: tuple[float, float] = (0.0, 0.001)  # m, each member end's x and y (none before seed 24)
    damping_range: tuple[float, float] = (0.003, 0.006)  # zeta0
    damping_trend_range: tuple[float, float] = (-0.3, 0.3)  # alpha in (f / 100 Hz) ** alpha
    damping_mode_jitter: float = 0.15
    damping_test_jitter: float = 0.05
    temperature_coefficient: float = -3e-4  # 1/K
    temperature_offset_sd_k: float = 1.0
    temperature_drift_k: float = 3.0  # largest drift over the whole sequence, either sign
    temperature_walk_sd_k: float = 0.2  # per test
    snr_db_range: tuple[float, float] = (30.0, 40.0)


@dataclass(frozen=True)
class Streams:
    """One generator per purpose: the article's manufacturing and damping, the effect's details, the tests'
    joint and temperature draws, the measurement noise.
    """

    article: np.random.Generator
    effect: np.random.Generator
    tests: np.random.Generator
    noise: np.random.Generator


def streams(seed: int) -> Streams:
    """The four generators of a campaign, spawned from ``SeedSequence(seed)``."""
    a, e, t, n = (np.random.default_rng(s) for s in np.random.SeedSequence(seed).spawn(4))
    return Streams(a, e, t, n)


def perturb_frame(frame: Frame, settings: NuisanceSettings,
                  rng: np.random.Generator) -> tuple[Frame, dict[str, Any]]:
    """The as-built frame: material and section errors (module docstring), and their record
    (`built_frame` makes the frame from it).
    """
    record: dict[str, Any] = {"materials": {}, "sections": {}}
    for name in frame.materials:
        e, rho = 1.0 + settings.material_sd * rng.standard_normal(2)
        record["materials"][name] = {"youngs_modulus_factor": float(e), "density_factor": float(rho)}
    for member in frame.members:
        b, t = 1.0 + settings.section_sd * rng.standard_normal(2)
        record["sections"][member.name] = {"width_factor": float(b), "thickness_factor": float(t)}
    return built_frame(frame, record), record


def built_frame(frame: Frame, record: dict[str, Any]) -> Frame:
    """``frame`` with a manufacturing ``record``'s errors (`perturb_frame`'s; a campaign's truth holds it, with
    the geometry's member ends when drawn).

    Each member gets its own section (``<section>@<member>``): a flat bar of width ``b`` and thickness
    ``t`` with ``t = sqrt(12 I / A)``, ``b = A / t``; ``A`` scales as ``b t`` and ``I`` as ``b t^3``.
    """
    materials = {}
    for name, mat in frame.materials.items():
        factor = record["materials"][name]
        materials[name] = replace(mat, youngs_modulus=mat.youngs_modulus * factor["youngs_modulus_factor"],
                                  density=mat.density * factor["density_factor"])
    sections = dict(frame.sections)
    members = []
    for member in frame.members:
        sec = frame.sections[member.section]
        b, t = (record["sections"][member.name][k] for k in ("width_factor", "thickness_factor"))
        key = f"{member.section}@{member.name}"
        sections[key] = replace(sec, name=key, area=sec.area * b * t, second_moment=sec.second_moment * b * t**3)
        members.append(replace(member, section=key))
    built = replace(frame, materials=materials, sections=sections, members=tuple(members))
    if "geometry" in record:  # the member ends as built (`workbench.proving.geometry`; since seed 24)
        offsets = {n: (float(dx), float(dy)) for n, (dx, dy) in record["geometry"]["point_offsets_m"].items()}
        built = moved_frame(built, offsets)[0]
    return built


@dataclass(frozen=True)
class DampingModel:
    """Modal damping of an article: ``zeta_k = zeta0 (f_k / 100 Hz) ** alpha * jitter_k * test jitter``."""

    zeta0: float
    alpha: float
    mode_jitter: tuple[float, ...]  # per mode, by rank
    test_jitter_sd: float

    def ratios(self, frequency_hz: np.ndarray, rng: np.random.Generator) -> np.ndarray:
        """(m,) damping ratios of one test's modes at ``frequency_hz`` (m,) Hz."""
        f = np.maximum(np.asarray(frequency_hz, float), 1.0)
        jitter = np.array([self.mode_jitter[min(k, len(self.mode_jitter) - 1)] for k in range(f.size)])
        test = np.exp(self.test_jitter_sd * rng.standard_normal(f.size))
        return self.zeta0 * (f / 100.0) ** self.alpha * jitter * test

    def record(self) -> dict[str, Any]:
        return {"zeta0": self.zeta0, "alpha": self.alpha, "mode_jitter": list(self.mode_jitter),
                "test_jitter_sd": self.test_jitter_sd}


def damping_model(settings: NuisanceSettings, rng: np.random.Generator, modes: int = 64) -> DampingModel:
    """The article's damping law (module docstring), drawn once."""
    zeta0 = float(rng.uniform(*settings.damping_range))
    alpha = float(rng.uniform(*settings.damping_trend_range))
    sigma = settings.damping_mode_jitter
    jitter = np.exp(sigma * rng.standard_normal(modes) - 0.5 * sigma**2)
    return DampingModel(zeta0, alpha, tuple(float(x) for x in jitter), settings.damping_test_jitter)


def temperature_offsets(count: int, settings: NuisanceSettings, rng: np.random.Generator) -> np.ndarray:
    """(count,) temperature of each test over the reference, K: offset + linear drift + random walk."""
    offset = settings.temperature_offset_sd_k * rng.standard_normal()
    drift = rng.uniform(-settings.temperature_drift_k, settings.temperature_drift_k)
    walk = np.cumsum(settings.temperature_walk_sd_k * rng.standard_normal(count))
    ramp = np.linspace(0.0, 1.0, count) if count > 1 else np.zeros(count)
    return offset + drift * ramp + walk


def gamma_draws(mean: float, cov: float, count: int, rng: np.random.Generator) -> np.ndarray:
    """(count,) draws of a Gamma law of mean ``mean`` and coefficient of variation ``cov`` (``cov = 0``: constant).

    Shape ``1 / cov^2`` and scale ``mean cov^2``: mean ``mean``, standard deviation ``cov * mean``.
    """
    if cov < 0 or mean <= 0:
        raise ValueError(f"gamma_draws: need mean > 0 and cov >= 0, got {mean}, {cov}")
    if cov == 0:
        return np.full(count, float(mean))
    return rng.gamma(1.0 / cov**2, mean * cov**2, count)


def stratified_gamma_draws(mean: float, cov: float, stratum: np.ndarray, strata: int,
                           rng: np.random.Generator) -> np.ndarray:
    """Draws of the same Gamma law as `gamma_draws`, draw ``i`` from the ``stratum[i]``-th (0-based) of ``strata``
    equal-probability slices of it: a tightening level that spans its own part of the joint's range.
    """
    stratum = np.asarray(stratum, int)
    if cov == 0:
        return np.full(stratum.shape, float(mean))
    if np.any((stratum < 0) | (stratum >= strata)):
        raise ValueError(f"stratified_gamma_draws: strata must lie in 0..{strata - 1}")
    u = (stratum + rng.random(stratum.shape)) / strata
    return mean * cov**2 * scipy.special.gammaincinv(1.0 / cov**2, u)


def sensor_snr_db(count: int, settings: NuisanceSettings, rng: np.random.Generator) -> np.ndarray:
    """(count,) signal-to-noise ratio of each sensor, dB (uniform over ``settings.snr_db_range``)."""
    return rng.uniform(*settings.snr_db_range, count)


def add_noise(values: np.ndarray, snr_db: np.ndarray, rng: np.random.Generator) -> np.ndarray:
    """``values`` (n_sensors, n_freq) plus circular complex Gaussian noise of RMS ``RMS_f |H| 10^(-SNR / 20)``.

    ``snr_db`` (n_sensors,): each sensor's ratio; the RMS is each curve's over the band.
    """
    values = np.asarray(values, complex)
    rms = np.sqrt(np.mean(np.abs(values) ** 2, axis=-1, keepdims=True))
    sigma = rms * 10.0 ** (-np.asarray(snr_db, float)[:, None] / 20.0)
    noise = (rng.standard_normal(values.shape) + 1j * rng.standard_normal(values.shape)) / math.sqrt(2.0)
    return values + sigma * noise

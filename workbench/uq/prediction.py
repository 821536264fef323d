"""Stochastic FRF prediction and the section 5 transfer of joint models (Ghienne et al. 2020).

`frf_band` gives the mean, the envelope and the 5-95 % band of the FRF magnitude of a frame whose
joint moduli follow the Gamma laws of eq. (8)-(9), as in the paper's Figures 12, 14 and 16: Monte
Carlo over the joints, one exact eigen-solve per sample, the modes tracked against the nominal ones
by MAC (`workbench.uq.stochastic.track_modes`), and the FRF by modal superposition with the measured
modal damping of each tracked mode. For section 5, the joint models identified on the one-bolt
frames are set on the two- and four-bolt frames by `workbench.model.joints.frame_with_joint_models`;
`compare_frequencies` sets the predicted frequency moments beside the measured ones.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from workbench.model.assembly import Model
from workbench.model.modal import QUANTITIES, Modes, frame_frf, modal_superposition, model_modes, solve_modes
from workbench.progress import Progress, report
from workbench.uq.stochastic import FrequencyMoments, JointModel, track_modes

__all__ = ["FRFBand", "frf_band", "FrequencyComparison", "compare_frequencies"]

MODES_ABOVE = 4  # modes summed above the band: their quasi-static tail shapes the FRF below it
TRACKING_MODES = 4  # modes solved beyond those summed, so that a mode moving up is still tracked
MEMORY_BYTES = 200e6  # float32 magnitudes held at once; the frequency axis is cut into chunks above


@dataclass(frozen=True)
class FRFBand:
    """Statistics of the FRF magnitude over joint samples (Figures 12, 14, 16).

    Attributes
    ----------
    frequency_hz : (n_freq,) frequency lines, Hz.
    sensors : sensor names of the frame, in frame order.
    quantity : ``"accelerance"`` (m/s^2/N), ``"mobility"`` (m/s/N) or ``"receptance"`` (m/N).
    nominal : (n_sensors, n_freq) complex FRF with every joint at its mean modulus.
    mean, lower, upper, p05, p95 : (n_sensors, n_freq) mean, minimum, maximum, 5th and 95th
        percentiles over the samples of ``|H|``, in the unit of ``quantity``.
    natural_hz : (samples, n_modes) natural frequencies of each sample, Hz, column k the mode
        tracked to nominal mode k by MAC.
    samples : number of joint samples.
    seed : seed of the draws.
    """

    frequency_hz: np.ndarray
    sensors: tuple[str, ...]
    quantity: str
    nominal: np.ndarray
    mean: np.ndarray
    lower: np.ndarray
    upper: np.ndarray
    p05: np.ndarray
    p95: np.ndarray
    natural_hz: np.ndarray
    samples: int
    seed: int

    def __post_init__(self) -> None:
        shape = (len(self.sensors), self.frequency_hz.size)
        for name in ("nominal", "mean", "lower", "upper", "p05", "p95"):
            if getattr(self, name).shape != shape:
                raise ValueError(f"FRFBand: {name} has shape {getattr(self, name).shape}, expected {shape}")
        if self.natural_hz.ndim != 2 or self.natural_hz.shape[0] != self.samples:
            raise ValueError(f"FRFBand: natural_hz has shape {self.natural_hz.shape}, "
                             f"expected ({self.samples}, n_modes)")


def _axis(frequency_hz) -> np.ndarray:
    f = np.asarray(frequency_hz, float)
    if f.ndim != 1 or f.size == 0:
        raise ValueError(f"frequency_hz: expected a non-empty 1-D array, got shape {f.shape}")
    if not np.all(np.isfinite(f)) or np.any(f < 0):
        raise ValueError("frequency_hz: lines must be finite and not negative")
    return f


def _damping(damping_ratio, count: int) -> np.ndarray:
    zeta = np.atleast_1d(np.asarray(damping_ratio, float))
    if zeta.ndim != 1 or zeta.size == 0:
        raise ValueError(f"damping_ratio: expected a non-empty 1-D array, got shape {zeta.shape}")
    if not np.all(np.isfinite(zeta)) or np.any(zeta < 0):
        raise ValueError(f"damping_ratio: ratios must be finite and not negative, got {zeta}")
    return zeta[np.minimum(np.arange(count), zeta.size - 1)]


def _summed_modes(model: Model, top_hz: float, modes: int | None):
    """Nominal modes: ``modes`` of them, or those up to ``top_hz`` and `MODES_ABOVE` more."""
    limit = model.size - 2 - TRACKING_MODES
    if modes is not None:
        if not 1 <= modes <= limit:
            raise ValueError(f"modes: expected 1 to {limit} for a model of {model.size} dofs, got {modes}")
        return model_modes(model, modes)
    count = min(20, limit)
    while True:
        nominal = model_modes(model, count)
        keep = min(int(np.sum(nominal.frequency_hz <= top_hz)) + MODES_ABOVE, limit)
        if keep <= count:
            return Modes(nominal.eigenvalues[:keep], nominal.shapes[:, :keep])
        count = min(2 * count, limit)


def frf_band(model: Model, joints: JointModel, frequency_hz: np.ndarray, damping_ratio: np.ndarray, *,
             quantity: str = "accelerance", samples: int = 500, seed: int = 0, modes: int | None = None,
             progress: Progress | None = None) -> FRFBand:
    """Mean, envelope and 5-95 % band of the FRF magnitude under random joints (Figures 12, 14, 16).

    Monte Carlo over the normalised joint moduli ``gamma_j ~ Gamma(1 / cov_j^2, cov_j^2)`` (eq.
    8-9), drawn as ``joints.sample(samples, np.random.default_rng(seed))``; for each draw, the exact
    modes of ``K(gamma)`` (eq. 4), tracked against the nominal modes by the mass-weighted MAC, and
    the FRF at the frame's sensors for its excitation by modal superposition (no residual terms),
    mode k taking ``damping_ratio[k]``: the damping is a property of the tracked mode, as the
    measured modal damping is (paper 2.2.2), not of its rank in the sample.

    Parameters
    ----------
    model : assembled `workbench.model.assembly.Model` of a frame with sensors and an excitation.
    joints : Gamma laws of the model's joints (`workbench.uq.stochastic.joint_model`).
    frequency_hz : (n_freq,) frequency lines, Hz.
    damping_ratio : (n,) modal damping ratios of the nominal modes in order; the last repeats.
    quantity : ``"accelerance"`` (m/s^2/N), ``"mobility"`` (m/s/N) or ``"receptance"`` (m/N).
    samples : number of joint draws (at least 2; the paper uses 1 000 to 10 000).
    seed : seeds the draws; the same seed gives identical arrays.
    modes : number of modes summed; default those up to ``frequency_hz.max()`` and 4 more.
    progress : called after each sample (`workbench.progress`).

    Returns
    -------
    FRFBand

    Raises
    ------
    ValueError
        Bad axis, damping, quantity, sample count or mode count, a joint model of other joints,
        or one with no random joint.
    """
    f = _axis(frequency_hz)
    if quantity not in QUANTITIES:
        raise ValueError(f"quantity: {quantity!r} is not one of {', '.join(QUANTITIES)}")
    if samples < 2:
        raise ValueError(f"samples: need at least 2, got {samples}")
    if joints.names != model.joint_names:
        raise ValueError(f"joint model {joints.names} does not match the model's joints {model.joint_names}")
    if not np.any(joints.random):
        raise ValueError("joints: no joint has a random modulus (every cov is 0); use frame_frf")
    _damping(damping_ratio, 1)  # fail before any solve
    nominal = _summed_modes(model, float(f.max()), modes)
    count = nominal.count
    zeta = _damping(damping_ratio, count)
    reference = frame_frf(model, nominal, f, quantity, zeta)
    frame = model.frame
    if frame.excitation is None:  # frame_frf above refuses it first; said again for the reader and mypy
        raise ValueError(f"{frame.source}: the frame has no excitation: no FRF to band")
    responses = np.array([model.dof(s.point, s.dof) for s in frame.sensors])
    excitation = model.dof(frame.excitation.point, frame.excitation.dof)

    gammas = joints.sample(samples, np.random.default_rng(seed))
    natural = np.empty((samples, count))
    constants = np.empty((samples, responses.size, count))
    solved = min(count + TRACKING_MODES, model.size - 2)
    for s, gamma in enumerate(gammas):
        sample = solve_modes(model.stiffness(gamma), model.mass, solved)
        index, _ = track_modes(nominal, sample, model.mass)
        natural[s] = sample.frequency_hz[index]
        constants[s] = sample.shapes[responses][:, index] * sample.shapes[excitation, index]
        report(progress, "FRF band", s + 1, samples)

    # Percentiles need every sample of a line at once: float32 magnitudes (7 significant digits,
    # far below the Monte Carlo error) over as many lines as the memory budget allows.
    n_resp = responses.size
    step = max(1, int(MEMORY_BYTES // (4 * samples * n_resp)))
    stats = {name: np.empty((n_resp, f.size)) for name in ("mean", "lower", "upper", "p05", "p95")}
    magnitude = np.empty((samples, n_resp, min(step, f.size)), np.float32)
    for start in range(0, f.size, step):
        lines = f[start:start + step]
        block = magnitude[:, :, :lines.size]
        for s in range(samples):
            block[s] = np.abs(modal_superposition(lines, natural[s], zeta, constants[s], quantity))
        cut = slice(start, start + lines.size)
        stats["mean"][:, cut] = block.mean(axis=0, dtype=np.float64)
        stats["lower"][:, cut] = block.min(axis=0)
        stats["upper"][:, cut] = block.max(axis=0)
        stats["p05"][:, cut], stats["p95"][:, cut] = np.percentile(block, [5.0, 95.0], axis=0)
    return FRFBand(f, reference.responses, quantity, reference.values, natural_hz=natural,
                   samples=int(samples), seed=int(seed), **stats)


@dataclass(frozen=True)
class FrequencyComparison:
    """Predicted against measured eigenfrequency moments, mode by mode (section 5).

    Attributes
    ----------
    modes : (n,) 1-based mode numbers compared.
    predicted_mean_hz, predicted_std_hz : (n,) Hz.
    measured_mean_hz, measured_std_hz : (n,) Hz, over the tests where the mode was found (NaN
        if fewer than 1, respectively 2, tests found it).
    mean_rel_error : (n,) ``predicted_mean / measured_mean - 1``.
    std_ratio : (n,) ``predicted_std / measured_std``.
    """

    modes: np.ndarray
    predicted_mean_hz: np.ndarray
    predicted_std_hz: np.ndarray
    measured_mean_hz: np.ndarray
    measured_std_hz: np.ndarray
    mean_rel_error: np.ndarray
    std_ratio: np.ndarray


def compare_frequencies(predicted: FrequencyMoments, measured_hz: np.ndarray, modes=None) -> FrequencyComparison:
    """Compare predicted frequency moments with measured frequencies (the paper's section 5).

    Mode k of the prediction is paired with column k of ``measured_hz``: the ordering of the
    extracted modes is assumed to be the model's (no MAC pairing here).

    Parameters
    ----------
    predicted : moments from `workbench.uq.smr.propagate` or `workbench.uq.stochastic.monte_carlo`.
    measured_hz : (n_tests, n_modes) extracted frequencies, Hz, column k-1 for mode k; NaN where a
        test did not find the mode. Statistics skip NaNs; the std has ddof=1.
    modes : 1-based mode numbers to compare; default every mode both sides have.

    Returns
    -------
    FrequencyComparison
    """
    measured = np.asarray(measured_hz, float)
    if measured.ndim != 2 or measured.size == 0:
        raise ValueError(f"measured_hz: expected a non-empty (tests, modes) array, got shape {measured.shape}")
    available = min(predicted.count, measured.shape[1])
    chosen = np.arange(1, available + 1) if modes is None else np.atleast_1d(np.asarray(modes))
    if (chosen.size == 0 or chosen.ndim != 1 or not np.all(np.mod(chosen, 1) == 0)
            or chosen.min() < 1 or chosen.max() > available):
        raise ValueError(f"modes: expected 1-based mode numbers from 1 to {available}, got {modes}")
    column = chosen.astype(int) - 1
    x = measured[:, column]
    found = np.isfinite(x)
    n = found.sum(axis=0)
    with np.errstate(invalid="ignore", divide="ignore"):
        mean = np.where(found, x, 0.0).sum(axis=0) / n
        std = np.sqrt(np.where(found, (x - mean) ** 2, 0.0).sum(axis=0) / (n - 1))
        std = np.where(n > 1, std, np.nan)
        p_mean, p_std = predicted.mean_hz[column], predicted.std_hz[column]
        return FrequencyComparison(chosen.astype(int), p_mean, p_std, mean, std, p_mean / mean - 1.0, p_std / std)

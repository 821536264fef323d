"""Stochastic FRF prediction and the section 5 transfer of joint models (Ghienne et al. 2020).

`frf_band` gives the mean, the envelope and the 5-95 % band of the FRF magnitude of a frame whose
joint moduli follow the Gamma laws of eq. (8)-(9), as in the paper's Figures 12, 14 and 16: Monte
Carlo over the joints, each draw's modes by Rayleigh-Ritz on SMR2's basis (eq. 7; the paper's
SMR-based envelope of 10 000 samples) or by an exact eigen-solve tracked against the nominal modes
by MAC (`workbench.uq.stochastic.track_modes`), and the FRF by modal superposition with the
measured modal damping of each mode; a few exact solves of the same draws check the SMR band. For
section 5, the joint models identified on the one-bolt frames are set on the two- and four-bolt
frames by `workbench.model.joints.frame_with_joint_models`; `compare_frequencies` sets the
predicted frequency moments beside the measured ones.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from threadpoolctl import threadpool_limits

from workbench.model.modal import (
    QUANTITIES,
    Modes,
    modal_magnitude,
    shared_eigenvalues,
    solve_modes,
)
from workbench.model.structure import Structure, response_dofs, structure_frf, structure_modes
from workbench.progress import Progress, report
from workbench.uq.reduced import reduced_basis, reduced_modes
from workbench.uq.stochastic import FrequencyMoments, JointModel, track_modes

__all__ = ["BAND_METHODS", "BAND_SAMPLES", "BAND_CHECKS", "BAND_QUIET_LINES", "BandCheck", "FRFBand", "frf_band",
           "band_detail", "FrequencyComparison", "compare_frequencies"]

MODES_ABOVE = 4  # modes summed above the band: their quasi-static tail shapes the FRF below it
TRACKING_MODES = 4  # modes solved beyond those summed, so that a mode moving up is still tracked
MEMORY_BYTES = 200e6  # float32 magnitudes held at once; the frequency axis is cut into chunks above
BATCH_BYTES = 48e6  # float32 intermediates of the batched synthesis
BAND_METHODS = ("smr", "mc")
BAND_SAMPLES = 10_000  # draws of the paper's SMR-based FRF envelope
BAND_CHECKS = 200  # exact solves checking it
BAND_QUIET_LINES = 600  # lines of a band away from its modes (its plots are under a thousand pixels wide)
PEAK_HALF_WIDTHS = 3.0  # the report's zoom windows reach this many half-power half-widths past the draws
WINDOW_LINES = 150  # lines of a band around one mode (its zoom in the report is about 200 pixels wide)


@dataclass(frozen=True)
class BandCheck:
    """An SMR band checked against exact eigen-solves of the same joint draws.

    Attributes
    ----------
    samples : draws solved both ways (the band's first draws).
    lines_hz : (n_lines,) lines checked, Hz: the band's line nearest each summed nominal mode.
    frequency_rel_error : largest ``|f_smr / f_exact - 1|`` over those draws and the summed modes.
    quantile_rel_error : (n_sensors, n_lines) largest relative difference of the 5th, 50th and
        95th percentiles of ``|H|`` over those draws.
    """

    samples: int
    lines_hz: np.ndarray
    frequency_rel_error: float
    quantile_rel_error: np.ndarray


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
    method : ``"smr"`` (Rayleigh-Ritz on SMR2's basis per draw) or ``"mc"`` (one exact solve per draw).
    check : the SMR band against exact solves of its first draws, or None.
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
    method: str = "mc"
    check: BandCheck | None = None

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


def _summed_modes(model: Structure, top_hz: float, modes: int | None):
    """Nominal modes: ``modes`` of them, or those up to ``top_hz`` and `MODES_ABOVE` more."""
    limit = model.size - 2 - TRACKING_MODES
    if modes is not None:
        if not 1 <= modes <= limit:
            raise ValueError(f"modes: expected 1 to {limit} for a model of {model.size} dofs, got {modes}")
        return structure_modes(model, modes)
    count = min(20, limit)
    while True:
        nominal = structure_modes(model, count)
        keep = min(int(np.sum(nominal.frequency_hz <= top_hz)) + MODES_ABOVE, limit)
        if keep <= count:
            return Modes(nominal.eigenvalues[:keep], nominal.shapes[:, :keep])
        count = min(2 * count, limit)


def frf_band(model: Structure, joints: JointModel, frequency_hz: np.ndarray, damping_ratio: np.ndarray, *,
             quantity: str = "accelerance", samples: int = 10_000, seed: int = 0, modes: int | None = None,
             method: str = "smr", quiet_lines: int | None = None, check_samples: int = 0,
             progress: Progress | None = None) -> FRFBand:
    """Mean, envelope and 5-95 % band of the FRF magnitude under random joints (Figures 12, 14, 16).

    Monte Carlo over the normalised joint moduli ``gamma_j ~ Gamma(1 / cov_j^2, cov_j^2)`` (eq.
    8-9), drawn as ``joints.sample(samples, np.random.default_rng(seed))``; for each draw, the modes
    of ``K(gamma)`` (eq. 4) and the FRF at the frame's sensors for its excitation by modal
    superposition (no residual terms), mode k taking ``damping_ratio[k]``: the damping is a
    property of the mode, as the measured modal damping is (paper 2.2.2), not of its rank in the
    sample. The modes of a draw come from

    - ``method="smr"`` (default, the paper's SMR-based envelope of 10 000 samples): Rayleigh-Ritz
      of each draw on SMR2's reduced basis, the nominal modes and their first-order joint
      sensitivities (eq. 7; `workbench.uq.reduced`), no full eigen-solve per draw. Where two
      summed modes share an eigenvalue (no Nelson derivative), the exact solves below are used
      instead and ``FRFBand.method`` says so;
    - ``method="mc"``: one exact eigen-solve per draw, modes tracked against the nominal ones by the
      mass-weighted MAC.

    ``check_samples`` exact solves of the first draws check the SMR band (`BandCheck`: the same
    draws through both, so the difference is the reduction's error, not sampling noise).

    Parameters
    ----------
    model : an assembled frame or a matrix model (`workbench.model.structure`), with sensors and an excitation.
    joints : Gamma laws of the model's joints (`workbench.uq.stochastic.joint_model`).
    frequency_hz : (n_freq,) frequency lines, Hz.
    damping_ratio : (n,) modal damping ratios of the nominal modes in order; the last repeats.
    quantity : ``"accelerance"`` (m/s^2/N), ``"mobility"`` (m/s/N) or ``"receptance"`` (m/N).
    samples : number of joint draws (at least 2; the paper uses 1 000 to 10 000).
    seed : seeds the draws; the same seed gives identical arrays.
    modes : number of modes summed; default those up to ``frequency_hz.max()`` and 4 more.
    method : ``"smr"`` or ``"mc"``.
    quiet_lines : compute the band on the lines its plots need (`_band_lines`): `WINDOW_LINES`
        around each mode, and about this many elsewhere; None keeps every line.
        ``FRFBand.frequency_hz`` holds the lines kept.
    check_samples : exact solves checking an SMR band (0: none; at most ``samples``).
    progress : called as the work advances (`workbench.progress`).

    Returns
    -------
    FRFBand

    Raises
    ------
    ValueError
        Bad axis, damping, quantity, method, sample count or mode count, a joint model of other
        joints, or one with no random joint.
    """
    f = _axis(frequency_hz)
    if quantity not in QUANTITIES:
        raise ValueError(f"quantity: {quantity!r} is not one of {', '.join(QUANTITIES)}")
    if method not in BAND_METHODS:
        raise ValueError(f"method: {method!r} is not one of {', '.join(BAND_METHODS)}")
    if samples < 2:
        raise ValueError(f"samples: need at least 2, got {samples}")
    if not 0 <= check_samples <= samples:
        raise ValueError(f"check_samples: expected 0 to {samples}, got {check_samples}")
    if joints.names != model.joint_names:
        raise ValueError(f"joint model {joints.names} does not match the model's joints {model.joint_names}")
    if not np.any(joints.random):
        raise ValueError("joints: no joint has a random modulus (every cov is 0); use structure_frf")
    _damping(damping_ratio, 1)  # fail before any solve
    nominal = _summed_modes(model, float(f.max()), modes)
    zeta = _damping(damping_ratio, nominal.count)
    reference = structure_frf(model, nominal, f, quantity, zeta)
    dofs = _dofs(model)
    gammas = joints.sample(samples, np.random.default_rng(seed))
    if method == "smr" and shared_eigenvalues(nominal, nominal.count):
        method = "mc"  # Nelson's derivatives need distinct eigenvalues
    if method == "smr":
        natural, constants = _reduced_draws(model, joints, nominal, gammas, dofs)
    else:
        natural, constants = _exact_draws(model, nominal, gammas, dofs, progress)
    keep = np.arange(f.size) if quiet_lines is None else _band_lines(f, natural, zeta, nominal.frequency_hz,
                                                                     quiet_lines)
    stats = _statistics(f[keep], natural, zeta, constants, quantity, progress)
    check = None
    if check_samples and method == "smr":
        check = _check(model, nominal, gammas[:check_samples], dofs, natural[:check_samples],
                       constants[:check_samples], zeta, f[keep], quantity)
    return FRFBand(f[keep], reference.responses, quantity, reference.values[:, keep], natural_hz=natural,
                   samples=int(samples), seed=int(seed), method=method, check=check, **stats)


def _dofs(model: Structure) -> np.ndarray:
    """The sensors' dofs, then the excitation's."""
    sensors, excitation, _ = response_dofs(model)
    return np.append(sensors, excitation)


def _exact_draws(model: Structure, nominal: Modes, gammas: np.ndarray, dofs: np.ndarray,
                 progress: Progress | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Natural frequencies (S, K), Hz, and modal constants (S, n_sensors, K), 1/kg, by exact solves."""
    count = nominal.count
    natural = np.empty((len(gammas), count))
    constants = np.empty((len(gammas), dofs.size - 1, count))
    solved = min(count + TRACKING_MODES, model.size - 2)
    with threadpool_limits(1):  # many small solves: threaded BLAS only thrashes, the more so on a busy machine
        for s, gamma in enumerate(gammas):
            sample = solve_modes(model.stiffness(gamma), model.mass, solved)
            index, _ = track_modes(nominal, sample, model.mass)
            natural[s] = sample.frequency_hz[index]
            constants[s] = sample.shapes[dofs[:-1]][:, index] * sample.shapes[dofs[-1], index]
            report(progress, "FRF band", s + 1, len(gammas))
    return natural, constants


def _reduced_draws(model: Structure, joints: JointModel, nominal: Modes, gammas: np.ndarray,
                   dofs: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """As `_exact_draws`, by Rayleigh-Ritz on SMR2's basis (`workbench.uq.reduced`): no full solve per draw."""
    natural, shapes = reduced_modes(reduced_basis(model, nominal, joints), gammas, dofs)
    return natural, shapes[:, :-1, :] * shapes[:, -1:, :]


def _band_lines(f: np.ndarray, natural: np.ndarray, zeta: np.ndarray, nominal_hz: np.ndarray,
                quiet_lines: int) -> np.ndarray:
    """Indices of the lines a band is computed on, for its plots (`frf_band`'s ``quiet_lines``).

    Around each mode, the window the report zooms on (`workbench.workflow.measured.mode_windows`:
    the draws' 0.5-99.5 % frequencies and the nominal one, `PEAK_HALF_WIDTHS` half-power half-widths
    each side) keeps `WINDOW_LINES` lines, every line within `PEAK_HALF_WIDTHS` half-widths of the
    nominal resonance (the nominal FRF's peak); elsewhere, where the band is smooth, about
    ``quiet_lines`` lines evenly; the axis' ends always.
    """
    lo, hi = np.percentile(natural, [0.5, 99.5], axis=0)
    pad = PEAK_HALF_WIDTHS * zeta
    keep = np.zeros(f.size, bool)
    near = np.zeros(f.size, bool)
    for k in range(natural.shape[1]):
        window = np.flatnonzero((f >= min(lo[k], nominal_hz[k]) * (1.0 - pad[k]))
                                & (f <= max(hi[k], nominal_hz[k]) * (1.0 + pad[k])))
        near[window] = True
        keep[window[::max(1, int(np.ceil(window.size / WINDOW_LINES)))]] = True
        keep[np.abs(f - nominal_hz[k]) <= pad[k] * nominal_hz[k]] = True
    quiet = np.flatnonzero(~near)
    keep[quiet[::max(1, int(np.ceil(quiet.size / max(quiet_lines, 1))))]] = True
    keep[[0, -1]] = True
    return np.flatnonzero(keep)


def _statistics(f: np.ndarray, natural: np.ndarray, zeta: np.ndarray, constants: np.ndarray, quantity: str,
                progress: Progress | None = None) -> dict[str, np.ndarray]:
    """Mean, minimum, maximum, 5th and 95th percentiles of ``|H|`` over the draws, (n_sensors, n_freq) each.

    Percentiles need every draw of a line at once: float32 magnitudes (7 significant digits, far
    below the Monte Carlo error) over as many lines as `MEMORY_BYTES` allows, synthesised a batch of
    draws at a time (complex intermediates of `BATCH_BYTES`).
    """
    samples, n_resp, count = constants.shape
    step = max(1, int(MEMORY_BYTES // (4 * samples * n_resp)))
    batch = max(1, int(BATCH_BYTES // (12 * count * min(step, f.size))))
    stats = {name: np.empty((n_resp, f.size)) for name in ("mean", "lower", "upper", "p05", "p95")}
    magnitude = np.empty((samples, n_resp, min(step, f.size)), np.float32)
    for start in range(0, f.size, step):
        lines = f[start:start + step]
        block = magnitude[:, :, :lines.size]
        for s in range(0, samples, batch):
            block[s:s + batch] = modal_magnitude(lines, natural[s:s + batch], zeta, constants[s:s + batch], quantity)
        cut = slice(start, start + lines.size)
        stats["mean"][:, cut] = block.mean(axis=0, dtype=np.float64)
        stats["lower"][:, cut] = block.min(axis=0)
        stats["upper"][:, cut] = block.max(axis=0)
        stats["p05"][:, cut], stats["p95"][:, cut] = np.percentile(block, [5.0, 95.0], axis=0)
        report(progress, "FRF band lines", start + lines.size, f.size)
    return stats


def _check(model: Structure, nominal: Modes, gammas: np.ndarray, dofs: np.ndarray, natural: np.ndarray,
           constants: np.ndarray, zeta: np.ndarray, f: np.ndarray, quantity: str) -> BandCheck:
    """The reduced basis against exact solves of the same draws, at the line nearest each summed mode."""
    exact_natural, exact_constants = _exact_draws(model, nominal, gammas, dofs)
    inside = (nominal.frequency_hz >= f[0]) & (nominal.frequency_hz <= f[-1])
    lines = np.unique(f[np.abs(f[:, None] - nominal.frequency_hz[inside]).argmin(axis=0)])
    approx = modal_magnitude(lines, natural, zeta, constants, quantity)
    exact = modal_magnitude(lines, exact_natural, zeta, exact_constants, quantity)
    q_approx, q_exact = (np.percentile(x, [5.0, 50.0, 95.0], axis=0) for x in (approx, exact))
    return BandCheck(len(gammas), lines, float(np.max(np.abs(natural / exact_natural - 1.0))),
                     np.max(np.abs(q_approx / q_exact - 1.0), axis=0))


def band_detail(band: FRFBand) -> str:
    """One line: how ``band`` was computed and, for an SMR band, how far its check found it from exact solves."""
    how = {"smr": "Rayleigh-Ritz on SMR2's basis", "mc": "exact solves"}.get(band.method, band.method)
    text = (f"{band.samples} draws by {how}, {band.natural_hz.shape[1]} modes summed, "
            f"{band.frequency_hz.size} lines")
    if band.check is not None:
        check = band.check
        text += (f"; {check.samples} exact solves of the same draws: frequencies within "
                 f"{check.frequency_rel_error:.1e}, 5/50/95 % of |H| within {check.quantile_rel_error.max():.1e}")
    return text


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

"""The stochastic joint model (paper eq. 8-9) and the Monte Carlo reference for eigenfrequencies.

Each joint's normalised modulus ``gamma_j = Y_j / E[Y_j]`` follows the maximum-entropy law for a
positive quantity of given mean and dispersion, a Gamma law with mean 1:
``gamma_j ~ Gamma(shape = 1 / cov_j^2, scale = cov_j^2)``, independent from joint to joint
(joints of one group share the law, not the draw).

Monte Carlo solves the full eigenproblem for every sample and tracks the modes against the
nominal ones by the mass-weighted MAC (an assignment problem), never by sorting frequencies.
"""

from __future__ import annotations

import os
from concurrent.futures import ProcessPoolExecutor
from dataclasses import dataclass

import numpy as np

from scipy.optimize import linear_sum_assignment

from .modal import Modes, model_modes, solve_modes

__all__ = ["JointModel", "joint_model", "FrequencyMoments", "MonteCarloResult", "monte_carlo", "track_modes"]


@dataclass(frozen=True)
class JointModel:
    """Independent Gamma laws of the normalised joint moduli, one per joint of a frame.

    Attributes
    ----------
    names : joint names, in the frame's order.
    cov : (n_joints,) coefficients of variation; 0 means a deterministic joint.
    """

    names: tuple[str, ...]
    cov: np.ndarray

    def __post_init__(self) -> None:
        cov = np.asarray(self.cov, float)
        if cov.shape != (len(self.names),):
            raise ValueError(f"JointModel: {len(self.names)} joints but cov has shape {cov.shape}")
        if not np.all(np.isfinite(cov)) or np.any(cov < 0):
            raise ValueError(f"JointModel: cov must be finite and not negative, got {cov}")
        object.__setattr__(self, "cov", cov)

    @property
    def random(self) -> np.ndarray:
        """Mask of the joints whose modulus is random (cov > 0)."""
        return self.cov > 0

    @property
    def shape(self) -> np.ndarray:
        """Gamma shape ``1 / cov^2`` (inf for a deterministic joint)."""
        with np.errstate(divide="ignore"):
            return 1.0 / self.cov**2

    @property
    def scale(self) -> np.ndarray:
        """Gamma scale ``cov^2``."""
        return self.cov**2

    def sample(self, count: int, rng: np.random.Generator) -> np.ndarray:
        """``count`` draws of gamma, shape (count, n_joints); deterministic joints are 1."""
        out = np.ones((count, len(self.names)))
        r = self.random
        out[:, r] = rng.gamma(self.shape[r], self.scale[r], size=(count, int(r.sum())))
        return out


def joint_model(frame, cov: dict[str, float] | None = None) -> JointModel:
    """The joint model of a frame: each joint's ``cov`` from the frame file, or from ``cov``."""
    names = frame.joint_names
    values = {j.name: j.cov for j in frame.joints}
    for name, value in (cov or {}).items():
        if name not in values:
            raise KeyError(f"{frame.source}: joints: no joint named {name!r} (known: {', '.join(names)})")
        values[name] = value
    return JointModel(names, np.array([values[n] for n in names]))


@dataclass(frozen=True)
class FrequencyMoments:
    """First two moments of the first eigenfrequencies, modes in the nominal model's order.

    Attributes
    ----------
    mean_hz, std_hz : (n_modes,) Hz.
    method : how they were obtained (smr1, smr2, adaptive, pert2, mc).
    nominal_hz : (n_modes,) frequencies with every joint at its mean modulus.
    """

    mean_hz: np.ndarray
    std_hz: np.ndarray
    method: str
    nominal_hz: np.ndarray

    @property
    def count(self) -> int:
        return int(self.mean_hz.size)


@dataclass(frozen=True)
class MonteCarloResult:
    """Monte Carlo samples and moments.

    Attributes
    ----------
    moments : sample mean and (ddof=1) standard deviation.
    frequency_hz : (n_samples, n_modes) tracked eigenfrequencies of every sample.
    gamma : (n_samples, n_joints) the joint draws.
    min_mac : (n_samples,) worst MAC of the tracked modes of each sample against the nominal ones.
    seed : the seed that produced ``gamma``.
    """

    moments: FrequencyMoments
    frequency_hz: np.ndarray
    gamma: np.ndarray
    min_mac: np.ndarray
    seed: int

    def standard_errors(self) -> tuple[np.ndarray, np.ndarray]:
        """Sampling standard errors of the mean and of the std estimates, Hz (normal approximation
        corrected by the sample kurtosis)."""
        n = self.frequency_hz.shape[0]
        x = self.frequency_hz - self.frequency_hz.mean(axis=0)
        var = (x**2).mean(axis=0)
        kurt = (x**4).mean(axis=0) / np.maximum(var**2, 1e-300)
        return np.sqrt(var / n), np.sqrt(var * (kurt - 1.0) / (4.0 * n))


def track_modes(nominal: Modes, candidates: Modes, mass) -> tuple[np.ndarray, np.ndarray]:
    """Pair each nominal mode with a candidate mode by the mass-weighted MAC.

    Returns
    -------
    index : (nominal.count,) candidate mode assigned to each nominal mode.
    mac : (nominal.count,) the MAC of each pair.
    """
    cross = (nominal.shapes.T @ (mass @ candidates.shapes)) ** 2  # both mass-normalised
    rows, cols = linear_sum_assignment(-cross)
    index = np.empty(nominal.count, int)
    index[rows] = cols
    return index, cross[rows, cols][np.argsort(rows)]


def _solve_chunk(args) -> tuple[np.ndarray, np.ndarray]:
    model, nominal, gammas, extra = args
    count = nominal.count
    k_count = min(count + extra, model.size)
    mass_dense = model.mass.toarray()
    freqs = np.empty((len(gammas), count))
    worst = np.empty(len(gammas))
    for s, gamma in enumerate(gammas):
        modes = solve_modes(model.stiffness(gamma), model.mass, k_count)
        index, mac = track_modes(nominal, modes, mass_dense)
        freqs[s] = modes.frequency_hz[index]
        worst[s] = mac.min()
    return freqs, worst


def monte_carlo(model, joints: JointModel, count: int = 10, samples: int = 10_000, seed: int = 0,
                workers: int = 1, progress: bool = False, extra_modes: int = 4,
                chunk: int = 100) -> MonteCarloResult:
    """Monte Carlo moments of the first ``count`` eigenfrequencies: one exact eigen-solve per sample.

    Parameters
    ----------
    model : assembled `workbench.assembly.Model`.
    joints : the joint model (one law per joint of the model).
    count : modes to track (the nominal model's first ``count``).
    samples : number of joint draws.
    seed : seeds the draws; the same seed gives the same numbers, whatever ``workers``.
    workers : worker processes (1 runs in this process).
    progress : show a progress bar on standard error.
    extra_modes : modes solved beyond ``count`` so that a mode that moves up can still be tracked.
    chunk : samples per task.

    Returns
    -------
    MonteCarloResult
    """
    if joints.names != model.joint_names:
        raise ValueError(f"joint model {joints.names} does not match the model's joints {model.joint_names}")
    if samples < 2:
        raise ValueError(f"samples: need at least 2, got {samples}")
    nominal = model_modes(model, count)
    gamma = joints.sample(samples, np.random.default_rng(seed))
    tasks = [(model, nominal, gamma[i:i + chunk], extra_modes) for i in range(0, samples, chunk)]
    bar = None
    if progress:
        from tqdm import tqdm

        bar = tqdm(total=samples, desc="Monte Carlo", unit="sample", leave=False)
    results = []
    if workers > 1:
        with ProcessPoolExecutor(max_workers=min(workers, os.cpu_count() or 1)) as pool:
            for task, result in zip(tasks, pool.map(_solve_chunk, tasks)):
                results.append(result)
                if bar is not None:
                    bar.update(len(task[2]))
    else:
        for task in tasks:
            results.append(_solve_chunk(task))
            if bar is not None:
                bar.update(len(task[2]))
    if bar is not None:
        bar.close()
    freqs = np.concatenate([r[0] for r in results])
    worst = np.concatenate([r[1] for r in results])
    moments = FrequencyMoments(freqs.mean(axis=0), freqs.std(axis=0, ddof=1), "mc", nominal.frequency_hz)
    return MonteCarloResult(moments, freqs, gamma, worst, seed)




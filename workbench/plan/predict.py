"""How precisely a design will identify each joint group's mean modulus and CoV, before any test.

What the prediction assumes (and `workbench design`'s page says):

* **The estimator** is the paper's moment matching (`workbench.identify.moments`, eq. 10-11) with
  its own intervals: a bootstrap of the tests' frequency moments carried through the linearised
  two steps (`interval_map`, `moment_covariance`), the very code `workbench identify` runs.
* **The joints' moduli.** Each joint's modulus follows its group's Gamma law (eq. 8-9; mean and
  CoV from the model file, or the user's guess). The tightening levels are the lab's way to span
  that law (paper 4.2: levels "chosen ... to span the entire range of the possible joint stiffness
  values"): level ``l`` of ``L`` draws the modulus from the law's ``l``-th of ``L`` equal-probability
  strata. A design whose levels are unbalanced (mostly extreme levels) or correlated between joints
  (all bolts tightened alike) then shows its bias and its correlation, as a real campaign would.
* **The frequencies.** Each test's frequencies are the Rayleigh quotients of the nominal modes at
  that test's moduli (SMR1's eigenvalue, eq. 5), plus an extraction scatter (relative sd per mode
  and test, `PlanSettings.frequency_scatter`; the circle fit gives a few 1e-4 at 30-40 dB).

For each design, ``campaigns`` virtual campaigns are drawn (seeded); each gets the estimator's
interval width (delta method on its bootstrap covariance, `bootstrap_covariance`) and its linearised
estimate. The predicted width is the median of the widths (with few tests a few campaigns' widths are
very large), relative to the true value; the spread and bias of the estimates are returned beside it.
`benchmarks/design_check.py` checks the predictions against the real moment matching on proving-ground
campaigns, `--verify` on campaigns solved exactly.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy.stats import gamma as gamma_law

from workbench.identify.data import JointGroups
from workbench.identify.moments import Z95, SMRForward, interval_map
from workbench.model.structure import Structure, structure_at_moduli
from workbench.plan.candidates import Design
from workbench.uq import smr

__all__ = ["PlanSettings", "DesignPrediction", "Planner", "stratified_moduli", "bootstrap_covariance"]


@dataclass(frozen=True)
class PlanSettings:
    """How a prediction is made.

    count : modes the identification will use (the first ``count``).
    frequency_scatter : relative sd of one extracted frequency (extraction and test repeatability).
    campaigns : virtual campaigns per design.
    seed : of the virtual campaigns (the same for every design: common random numbers).
    method : the SMR forward model of the estimator (adaptive, smr1, smr2).
    """

    count: int = 8
    frequency_scatter: float = 3e-4
    campaigns: int = 400
    seed: int = 0
    method: str = "adaptive"


@dataclass(frozen=True)
class DesignPrediction:
    """A design's predicted precision, per group (rows) for (mean modulus, CoV) (columns).

    width : median 95 % interval width the estimator will report, over the true value.
    spread : 2 x 1.96 x the sd of the estimates over the virtual campaigns, over the true value.
    bias : mean relative error of the (linearised) estimates.
    """

    design: Design
    width: np.ndarray
    spread: np.ndarray
    bias: np.ndarray


def stratified_moduli(levels: np.ndarray, level_count: int, cov: np.ndarray, rng: np.random.Generator,
                      campaigns: int) -> np.ndarray:
    """Normalised moduli ``gamma`` (campaigns, n_tests, n_joints): level ``l`` draws from the ``l``-th of
    ``level_count`` equal-probability strata of Gamma(1/cov^2, cov^2) (eq. 9); cov 0 gives 1.
    """
    u = (levels[None] - 1 + rng.random((campaigns,) + levels.shape)) / level_count
    cov = np.asarray(cov, float)
    safe = np.where(cov > 0, cov, 1.0)
    draws = gamma_law.ppf(u, a=1.0 / safe**2, scale=safe**2)
    return np.where(cov > 0, draws, 1.0)


def bootstrap_covariance(f: np.ndarray) -> np.ndarray:
    """What a bootstrap of the tests gives for the covariance of the (means, CoVs) of ``f`` (..., n_tests, K):
    its first-order value, the infinitesimal jackknife ``sum_t IF_t IF_t^T / n^2`` (Efron 1982, ch. 6),
    with the influence of test t on a mode's mean ``d_t = f_t - mean`` and on its CoV
    ``(d_t^2 - v) / (2 s m) - delta d_t / m`` (``v`` the plug-in variance, ``s = sqrt(v)``). A resampling
    bootstrap per virtual campaign (`moment_covariance`) gives the same to its Monte Carlo error, at
    thousands of times the cost.
    """
    n = f.shape[-2]
    m = f.mean(axis=-2, keepdims=True)
    d = f - m
    v = (d**2).mean(axis=-2, keepdims=True)
    s = np.sqrt(v)
    influence = np.concatenate([d, (d**2 - v) / (2.0 * s * m) - (s / m) * d / m], axis=-1)
    return np.einsum("...ti,...tj->...ij", influence, influence) / n**2


class Planner:
    """The pieces shared by every design's prediction: the linearised estimator and the sensitivities."""

    def __init__(self, model: Structure, groups: JointGroups, mean_pa: np.ndarray, cov: np.ndarray,
                 settings: PlanSettings | None = None) -> None:
        """``mean_pa``, ``cov`` : (n_groups,) the joint laws the design is planned for (Pa, -)."""
        settings = settings or PlanSettings()
        if not 1 <= settings.count <= model.size - 2:
            raise ValueError(f"count: {settings.count} modes are not available from a model of {model.size} dofs")
        if not (settings.frequency_scatter >= 0 and math.isfinite(settings.frequency_scatter)):
            raise ValueError(f"frequency_scatter: expected a finite value >= 0, got {settings.frequency_scatter}")
        self.model, self.groups, self.settings = model, groups, settings
        self.mean_pa, self.cov = np.asarray(mean_pa, float), np.asarray(cov, float)
        n_joints = len(model.joints)
        self.joint_cov = groups.per_joint(self.cov, n_joints)
        modes = np.arange(1, settings.count + 1)
        forward = SMRForward(model, groups, modes, settings.method)
        lin = interval_map(forward, np.log(self.mean_pa), np.log(self.cov))
        if lin is None:
            raise ValueError("the modes do not tell the groups apart: the moment equations are singular")
        self.lin = lin
        # the virtual campaigns' own expectation: SMR1's moments are exact for their Rayleigh quotients, so
        # an estimate's departure from the truth is the design's doing, not the generator's
        mean_hz, std_hz = SMRForward(model, groups, modes, "smr1")(np.log(self.mean_pa), np.log(self.cov))
        self.population = np.concatenate([mean_hz, std_hz / mean_hz])
        at = structure_at_moduli(model, groups.per_joint(self.mean_pa, n_joints))
        sens = smr.sensitivities(at, settings.count)
        self.eigenvalues = sens.modes.eigenvalues[:settings.count]
        self.joint_energy = sens.joints[:settings.count]  # (K, n_joints) lambda_kj, (rad/s)^2

    def frequencies(self, gamma: np.ndarray, rng: np.random.Generator) -> np.ndarray:
        """Frequencies (Hz), (..., n_tests, K): Rayleigh quotients at ``gamma`` (eq. 5) with the scatter."""
        lam = self.eigenvalues + (gamma - 1.0) @ self.joint_energy.T
        f = np.sqrt(np.clip(lam, 0.0, None)) / (2.0 * np.pi)
        return f * (1.0 + self.settings.frequency_scatter * rng.standard_normal(f.shape))

    def predict(self, design: Design) -> DesignPrediction:
        """The design's predicted interval widths, spread and bias (module docstring)."""
        s = self.settings
        if design.levels.shape[1] != len(self.model.joints):
            raise ValueError(f"design {design.name}: {design.levels.shape[1]} columns for "
                             f"{len(self.model.joints)} joints")
        rng = np.random.default_rng(s.seed)
        gamma = stratified_moduli(design.levels, design.level_count, self.joint_cov, rng, s.campaigns)
        f = self.frequencies(gamma, rng)
        n_groups = self.mean_pa.size
        mean = f.mean(axis=1)
        measured = np.concatenate([mean, f.std(axis=1, ddof=1) / mean], axis=1)  # (campaigns, 2K)
        # estimate - truth, in logs: linear in the means, and in the logs of the frequencies' CoVs (to which
        # each group's log CoV answers with slope 1 to first order), so that a design seeing half the law's
        # spread gives half its CoV, not the tangent's extrapolation
        k = mean.shape[1]
        delta = self.population[k:]
        change = np.concatenate([mean - self.population[:k], delta * np.log(measured[:, k:] / delta)], axis=1)
        moves = change @ self.lin.T
        sd = np.sqrt(np.clip(np.einsum("gi,rij,gj->rg", self.lin, bootstrap_covariance(f), self.lin), 0.0, None))
        widths = np.exp(moves) * 2.0 * np.sinh(Z95 * sd)  # interval exp(estimate +- 1.96 sd) over the truth

        def as_groups(v: np.ndarray) -> np.ndarray:  # (2 G,) -> (G, 2): (mean, cov) columns
            return np.asarray(v).reshape(2, n_groups).T

        return DesignPrediction(design, as_groups(np.median(widths, axis=0)),
                                as_groups(2.0 * Z95 * moves.std(axis=0, ddof=1)),
                                as_groups(np.exp(moves).mean(axis=0) - 1.0))

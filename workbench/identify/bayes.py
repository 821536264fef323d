"""Bayesian identification of the joints' stochastic models: emcee on the full likelihood, arviz.

The likelihood, its priors and its forward model are `workbench.identify.likelihood`; this module
samples the posterior and summarises it.

**Cost** (2 shared cores, one BLAS thread): 40 tests x 10 modes, one joint, 48 walkers x 1800 steps:
about 20 s; 18 tests x 9 modes, two joints, 52 walkers: about 40 s (benchmarks/bayes_demo.py).

**Sampler**: `emcee.EnsembleSampler` (differential-evolution moves and an independence move fitted to the
burn-in, vectorised log-probability; `workbench.identify.sampler`), walkers 2 x dims + 2 (at least 24),
started from the Laplace approximation at the maximum a posteriori point (L-BFGS-B, finite-difference Hessian;
`workbench.identify.runs`, which also anchors a Laplace likelihood); ``burn`` steps discarded, ``burn // 2``
more adapt the independence move, then ``steps`` kept. Seeding: the walkers' start from
``numpy.random.default_rng(seed)`` and emcee's own generator through ``emcee.State(...,
random_state=RandomState(seed).get_state())`` (emcee silently ignores a bare integer there). Progress goes
through the `workbench.progress` callback, one ``"emcee"`` task over the burn-in and the kept steps (with a
Laplace likelihood, pilot runs of the burn-in's length go first, each its own task: `workbench.identify.runs`).
Diagnostics: arviz R-hat and bulk ESS (walkers as chains) and emcee's integrated autocorrelation time.
Intervals are equal-tailed 95 % (2.5, 97.5 %).

Only `workbench.identify.sampler` imports emcee; arviz (which pulls in pandas and xarray) is imported
only when a result is built (`load_arviz`). Writing the posterior to a file is the caller's
(`workbench.workflow.posterior`).
"""

from __future__ import annotations

import logging
import math
import time
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from workbench.extraction.records import MeasuredModes
from workbench.identify.data import JointGroups, Values, check_moments, joint_groups
from workbench.identify.laplace import ErrorTerms, LaplaceLikelihood, laplace_likelihood, shared_summary
from workbench.identify.likelihood import (
    COV_BOUNDS,
    MODULUS_BOUNDS_PA,
    SIGMA_BOUNDS,
    SIGMA_SCALE,
    SIGMA_SPREAD,
    LikelihoodModel,
    likelihood_model,
)
from workbench.identify.record import ESS_LIMIT, RHAT_LIMIT, settled
from workbench.identify.runs import chain_diagnostics, load_arviz, sample_anchored
from workbench.identify.sampler import run_ensemble
from workbench.model.structure import Structure
from workbench.model.tolerance import Tolerances
from workbench.progress import Progress

__all__ = ["Posterior", "run_ensemble", "bayes_identify", "chain_diagnostics", "load_arviz"]

log = logging.getLogger(__name__)


@dataclass(frozen=True)
class Posterior:
    """Result of `bayes_identify`.

    Attributes
    ----------
    source : the data's source.
    groups : joint group names; joints : the joint names of each group.
    modes : (K,) mode numbers used (1 = lowest).
    youngs_modulus, youngs_modulus_ci95 : (G,), (G, 2) posterior median and equal-tailed 95 %
        interval of each group's mean modulus, Pa.
    cov, cov_ci95 : (G,), (G, 2) the same for the CoV.
    sigma, sigma_ci95 : (K,), (K, 2) the same for each mode's relative measurement error.
    error_names, error_scales, error_scales_ci95 : the further error terms' scales (``common_error``
        ``s_u``, ``discrepancy_scale`` ``s_delta``, relative; `workbench.identify.laplace`), (E,), (E, 2).
    discrepancy, discrepancy_ci95 : (K,), (K, 2) each mode's discrepancy ``delta_k`` (relative), or
        None without that term: the posterior over the sampled parameters of its Laplace law.
    sensitivity, sensitivity_ci95 : the same for each mode's sensitivity error ``eps_k`` (log of the factor
        on the mode's joint energies), or None without it.
    factors, factors_ci95, factor_names, factor_prior_sd : the same for the frame's manufacturing factors (logs
        from the drawing; None and () without tolerances) and their prior sds.
    trust_reached : the groups whose posterior mean modulus reaches the edge of the region where the
        anchored forward model holds (`workbench.identify.laplace.LaplaceLikelihood.mean_bounds`), after
        anchoring a second time where the posterior was: a result the data and that model cannot place.
    reference_pa : (G,) the preliminary fit's moduli (the forward table's centre).
    forward : "exact" or "smr2"; forward_error : the table's largest relative error between nodes.
    parameter_names : the sampled parameters, in ``rhat``/``ess``/``autocorr_time`` order
        (moduli, CoVs, sigmas, reported in their natural units).
    rhat, ess, autocorr_time : (D,) arviz R-hat and bulk ESS (walkers as chains), emcee's
        integrated autocorrelation time (steps).
    acceptance_fraction : mean over the walkers.
    walkers, steps, burn, seed : the run; wall_time_s : the whole identification, s.
    idata : arviz InferenceData (posterior, sample_stats, observed_data, intervals).
    """

    source: str
    groups: tuple[str, ...]
    joints: tuple[tuple[str, ...], ...]
    modes: np.ndarray
    youngs_modulus: np.ndarray
    youngs_modulus_ci95: np.ndarray
    cov: np.ndarray
    cov_ci95: np.ndarray
    sigma: np.ndarray
    sigma_ci95: np.ndarray
    reference_pa: np.ndarray
    forward: str
    forward_error: float
    parameter_names: tuple[str, ...]
    rhat: np.ndarray
    ess: np.ndarray
    autocorr_time: np.ndarray
    acceptance_fraction: float
    walkers: int
    steps: int
    burn: int
    seed: int
    wall_time_s: float
    idata: Any = field(repr=False, compare=False, default=None)
    error_names: tuple[str, ...] = ()
    error_scales: np.ndarray = field(default_factory=lambda: np.zeros(0))
    error_scales_ci95: np.ndarray = field(default_factory=lambda: np.zeros((0, 2)))
    discrepancy: np.ndarray | None = None
    discrepancy_ci95: np.ndarray | None = None
    sensitivity: np.ndarray | None = None
    sensitivity_ci95: np.ndarray | None = None
    factors: np.ndarray | None = None
    factors_ci95: np.ndarray | None = None
    factor_names: tuple[str, ...] = ()
    factor_prior_sd: np.ndarray | None = None
    trust_reached: tuple[str, ...] = ()

    def __post_init__(self) -> None:
        g, k = len(self.groups), np.asarray(self.modes).size
        for name, shape in (("youngs_modulus", (g,)), ("youngs_modulus_ci95", (g, 2)), ("cov", (g,)),
                            ("cov_ci95", (g, 2)), ("sigma", (k,)), ("sigma_ci95", (k, 2))):
            if np.asarray(getattr(self, name)).shape != shape:
                raise ValueError(f"Posterior: {name} has shape {np.asarray(getattr(self, name)).shape}, "
                                 f"expected {shape}")

    @property
    def converged(self) -> bool:
        """Every parameter's R-hat at most `RHAT_LIMIT` and bulk ESS at least `ESS_LIMIT`."""
        return settled(self.rhat, self.ess)

    @property
    def mean_box_pa(self) -> tuple[float, float]:
        """The prior's support of the mean moduli, Pa: the search interval of the contract's bound rule."""
        return MODULUS_BOUNDS_PA

    @property
    def cov_box(self) -> tuple[float, float]:
        return COV_BOUNDS

    def joint_records(self) -> dict[str, dict[str, object]]:
        """identification.json's ``joints`` (CONTRACTS.md section 3): each joint gets its group's values."""
        out = {}
        for g, names in enumerate(self.joints):
            for name in names:
                out[name] = {"youngs_modulus": float(self.youngs_modulus[g]), "cov": float(self.cov[g]),
                             "youngs_modulus_ci95": [float(v) for v in self.youngs_modulus_ci95[g]],
                             "cov_ci95": [float(v) for v in self.cov_ci95[g]]}
                if self.groups[g] in self.trust_reached:  # the search interval's edge here (contract section 3)
                    out[name]["at_bound"] = True
        return out

    def error_records(self) -> dict[str, object]:
        """identification.json's ``errors`` (an extension key; relative values, medians and 95 % intervals):
        each mode's measurement error, the further error terms' scales, each mode's discrepancy and
        sensitivity error; ``manufacturing``: each factor's log from the drawing and its prior sd.
        """
        def entry(value: float, ci: np.ndarray) -> dict[str, object]:
            return {"value": float(value), "ci95": [float(ci[0]), float(ci[1])]}

        modes = [int(m) for m in self.modes]
        out: dict[str, object] = {"measurement": {f"mode{m}": entry(v, c)
                                                  for m, v, c in zip(modes, self.sigma, self.sigma_ci95)}}
        out.update({name: entry(v, c) for name, v, c in zip(self.error_names, self.error_scales,
                                                            self.error_scales_ci95)})
        if self.discrepancy is not None and self.discrepancy_ci95 is not None:
            out["discrepancy"] = {f"mode{m}": entry(v, c)
                                  for m, v, c in zip(modes, self.discrepancy, self.discrepancy_ci95)}
        if self.sensitivity is not None and self.sensitivity_ci95 is not None:
            out["sensitivity"] = {f"mode{m}": entry(v, c)
                                  for m, v, c in zip(modes, self.sensitivity, self.sensitivity_ci95)}
        if self.factors is not None and self.factors_ci95 is not None and self.factor_prior_sd is not None:
            out["manufacturing"] = {n: {**entry(v, c), "prior_sd": float(s)} for n, v, c, s in
                                    zip(self.factor_names, self.factors, self.factors_ci95, self.factor_prior_sd)}
        return out


def _inference_data(samples: dict[str, np.ndarray], lp: np.ndarray, measured: MeasuredModes, intervals: dict,
                    attrs: dict, thin: int) -> Any:
    """Arviz InferenceData of the kept steps (every ``thin``-th), the measured frequencies and the intervals."""
    az = load_arviz()
    import xarray as xr  # arrives with arviz (above): only when a result is built

    idata = az.from_dict(
        posterior={k: v[:, ::thin] for k, v in samples.items()},
        sample_stats={"lp": lp[:, ::thin]},
        observed_data={"frequency_hz": np.asarray(measured.frequency_hz, float)},
        coords={"test": np.arange(measured.frequency_hz.shape[0]), "mode": np.asarray(measured.modes, int)},
        dims={"frequency_hz": ["test", "mode"]},
        attrs=attrs,
    )
    bounds = {"quantile": [0.025, 0.5, 0.975]}
    idata.add_groups({"intervals": xr.Dataset({k: (("quantile",), v) for k, v in intervals.items()}, coords=bounds)})
    return idata


def bayes_identify(model: Structure, measured: MeasuredModes, groups: JointGroups | None = None, *,
                   start: Values | None = None, walkers: int | None = None, steps: int = 3000, burn: int = 500,
                   seed: int = 0, forward: str = "exact", integration: str = "auto",
                   errors: ErrorTerms | None = None, max_steps: int | None = None,
                   progress: Progress | None = None, tolerances: Tolerances | None = None) -> Posterior:
    """Bayesian identification of each joint group's mean modulus and CoV from every test (module notes).

    Parameters
    ----------
    model : assembled model of the campaign's frame (its joint moduli only start the search).
    measured : every test's frequencies; a campaign with only published moments is refused.
    groups : joint groups (default: the frame's).
    start : (n_groups,) starting moduli, Pa (default the frame file's).
    walkers : emcee walkers (default 2 x dims + 2, at least 24, even). Fewer walkers run longer for the
        same cost, and R-hat over walkers as chains falls with each walker's length in autocorrelation
        times (two-bolt frame, 14 parameters: the same tau, 50 steps, with 30 walkers as with 56).
    steps, burn : kept and discarded steps per walker.
    seed : seeds the walkers' start and emcee; written into the result.
    forward : "exact" or "smr2" values in the forward table (tensor-rule integration).
    integration : how each test's latent moduli are integrated out: ``"quadrature"`` (adaptive
        Gauss-Hermite on a tensor table, one or two joints, `workbench.identify.likelihood`),
        ``"laplace"`` (any number, `workbench.identify.laplace`; the result's ``forward`` is then
        ``"anchored"``) or ``"auto"``: quadrature up to two joints without further error terms,
        Laplace otherwise.
    errors : the error terms beside each mode's measurement error (Laplace only): a test-level
        common error and the model's discrepancy per mode. Default: none with quadrature, both with
        Laplace.
    max_steps : the chains are extended past ``steps`` until every parameter's R-hat is at most
        `RHAT_LIMIT` and its bulk ESS at least `ESS_LIMIT` (`workbench.identify.record`), up to this many
        kept steps (default ``steps``: no extension). The result's ``steps`` are those kept.
    progress : called after each emcee step (`run_ensemble`, `workbench.progress`).
    tolerances : the frame's manufacturing tolerances, integrated as latent factors (Laplace only,
        `workbench.identify.members`).

    Raises
    ------
    ValueError
        Moments that cannot be identified from (`workbench.identify.data.check_moments`), published
        moments only, a bad ``start``, more than two random joints (`likelihood_model`).
    """
    t0 = time.perf_counter()
    lm, forward, forward_error = _likelihood(model, measured, groups, start, forward, integration, errors, tolerances)
    groups = groups or joint_groups(model)
    ndim = lm.ndim
    walkers = walkers or max(24, 2 * ndim + 2)
    walkers += walkers % 2
    rng = np.random.default_rng(seed)
    lm, sampler, forward_error, reached = sample_anchored(lm, walkers, steps, burn, seed, max_steps, progress,
                                                          forward_error, rng)
    chain = sampler.get_chain()  # (steps, walkers, D)
    trust_reached = tuple(groups.groups[i] for i in np.flatnonzero(reached))
    steps = chain.shape[0]
    lp = sampler.get_log_prob().T  # (walkers, steps)
    tau = _autocorr_time(sampler)
    g, k = lm.n_groups, lm.fbar.size
    modulus = np.exp(chain[..., :g] + np.log(lm.reference_pa))
    cov = np.exp(chain[..., g:2 * g])
    scales = np.exp(chain[..., 2 * g:])  # the sigmas, then the further error scales
    terms = lm.terms if isinstance(lm, LaplaceLikelihood) else ErrorTerms(False, False)
    names = [f"youngs_modulus_{n}" for n in groups.groups] + [f"cov_{n}" for n in groups.groups] + \
        [f"sigma_mode{m}" for m in np.asarray(measured.modes, int)] + list(terms.names)
    natural = np.concatenate([modulus, cov, scales], axis=-1)  # (steps, walkers, D)
    samples = {n: natural[..., i].T for i, n in enumerate(names)}  # (walkers, steps)
    rhat, ess = chain_diagnostics(chain)
    q = np.percentile(natural.reshape(-1, ndim), [2.5, 50.0, 97.5], axis=0)  # (3, D)
    intervals = {n: q[:, i] for i, n in enumerate(names)}
    wall = time.perf_counter() - t0
    attrs = {"seed": seed, "walkers": walkers, "steps": steps, "burn": burn, "forward": forward,
             "forward_error": forward_error, "wall_time_s": wall, "source": measured.source,
             "interval": "equal-tailed 95 % (2.5, 97.5 percentiles)",
             "priors": f"E log-uniform [1e8, 1e12] Pa; cov uniform (0.005, 0.6); sigma_k on [{SIGMA_BOUNDS[0]:g}, "
             f"{SIGMA_BOUNDS[1]:g}], their geometric mean half-normal ({SIGMA_SCALE:g}), log sigma_k normal about its "
             f"log (sd {SIGMA_SPREAD:g})" + "".join(f"; {n} half-normal ({scale:g}) on [{lo:g}, {hi:g}]"
                                                    for n, (lo, hi), scale
                                                    in zip(terms.names, lm.extra_bounds, lm.extra_scales))
             + ("; manufacturing factors' logs normal about the drawing (sds: errors.manufacturing)"
                if isinstance(lm, LaplaceLikelihood) and lm.factor_names else ""),
             "reference_pa": lm.reference_pa.tolist(), "autocorr_time": tau.tolist(),
             "acceptance_fraction": float(np.mean(sampler.acceptance_fraction))}
    thin = max(1, math.ceil(steps / 500))
    idata = _inference_data(samples, lp, measured, intervals, attrs, thin)
    post = Posterior(
        source=measured.source, groups=groups.groups,
        joints=tuple(tuple(model.joint_names[i] for i in m) for m in groups.members),
        modes=np.asarray(measured.modes, int),
        youngs_modulus=q[1, :g], youngs_modulus_ci95=q[[0, 2], :g].T,
        cov=q[1, g:2 * g], cov_ci95=q[[0, 2], g:2 * g].T,
        sigma=q[1, 2 * g:2 * g + k], sigma_ci95=q[[0, 2], 2 * g:2 * g + k].T,
        reference_pa=lm.reference_pa, forward=forward, forward_error=forward_error,
        parameter_names=tuple(names), rhat=rhat, ess=ess, autocorr_time=tau,
        acceptance_fraction=float(np.mean(sampler.acceptance_fraction)),
        walkers=walkers, steps=steps, burn=burn, seed=seed, wall_time_s=wall, idata=idata,
        error_names=terms.names, error_scales=q[1, 2 * g + k:], error_scales_ci95=q[[0, 2], 2 * g + k:].T,
        trust_reached=trust_reached,
        **(shared_summary(lm, chain, rng) if isinstance(lm, LaplaceLikelihood) else {}))
    if not post.converged:
        log.warning("%s: the chains have not converged (max R-hat %.3f, limit %.2f; min ESS %.0f, limit %d; "
                    "%d steps)", measured.source, rhat.max(), RHAT_LIMIT, ess.min(), ESS_LIMIT, steps)
    return post


def _likelihood(model: Structure, measured: MeasuredModes, groups: JointGroups | None, start: Values | None,
                forward: str, integration: str, errors: ErrorTerms | None, tolerances: Tolerances | None = None
                ) -> tuple[LikelihoodModel | LaplaceLikelihood, str, float]:
    """The likelihood `bayes_identify` samples, the name of its forward model and that model's error."""
    check_moments(measured)
    if integration not in ("auto", "quadrature", "laplace"):
        raise ValueError(f"integration: {integration!r} is not one of auto, quadrature, laplace")
    further = (errors is not None and (errors.common or errors.discrepancy)) or tolerances is not None
    if integration == "quadrature" and further:
        raise ValueError("bayes: the common and discrepancy error terms and tolerances need the Laplace integration")
    if integration == "laplace" or (integration == "auto" and (len(model.joint_names) > 2 or further)):
        laplace, error = laplace_likelihood(model, measured, groups, start, errors, tolerances)  # refuses moments
        return laplace, "anchored", error
    table, error = likelihood_model(model, measured, groups, start, forward)
    return table, forward, error


def _autocorr_time(sampler: Any) -> np.ndarray:
    """Emcee's integrated autocorrelation time per parameter, without its "shorter than 50 tau" note."""
    quiet = logging.getLogger("emcee.autocorr")
    level = quiet.level
    quiet.setLevel(logging.ERROR)
    try:
        with np.errstate(invalid="ignore", divide="ignore"):  # a walker that moved in no step: tau is NaN
            return np.asarray(sampler.get_autocorr_time(quiet=True))
    finally:
        quiet.setLevel(level)

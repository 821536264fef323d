"""The ensemble runs of `workbench.identify.bayes.bayes_identify`: where the walkers start and where the
Laplace likelihood is anchored.

The walkers start from the Laplace approximation at a maximum a posteriori point of the population's means
and CoVs (`start`, `map_search`). A Laplace likelihood (`workbench.identify.laplace`) is anchored where
that point puts each test (`workbench.identify.anchored`), and anchored again at the posterior's median
when the posterior leans on the edge of the region those anchors hold or has gone far from them
(`sample_anchored`). Arviz's diagnostics (`chain_diagnostics`) decide when a chain has run long enough.
"""

from __future__ import annotations

import logging
import math
import warnings
from collections.abc import Callable
from types import ModuleType
from typing import Any

import numpy as np
from scipy.optimize import minimize

from workbench.identify.laplace import LaplaceLikelihood
from workbench.identify.likelihood import COV_BOUNDS, SIGMA_BOUNDS, LikelihoodModel
from workbench.identify.record import settled
from workbench.identify.sampler import run_ensemble
from workbench.progress import Progress

__all__ = ["start", "map_search", "sample_anchored", "chain_diagnostics", "load_arviz", "MAP_BOX", "TRUST_EDGE",
           "MOVED_SD", "REANCHORINGS", "PILOT_STEPS"]

log = logging.getLogger(__name__)

MAP_BOX = 0.2  # half-width (log units) of the box the MAP search moves in: where the posterior stays finite


def start(lm: LikelihoodModel | LaplaceLikelihood, walkers: int,
          rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray]:
    """Maximum a posteriori point and walkers drawn from the Laplace approximation there.

    The MAP by L-BFGS-B (gradient by central differences, one vectorised call); the covariance from the
    finite-difference Hessian (eigenvalues floored). Starting the ensemble from the Laplace approximation
    rather than a tiny ball lets a short burn-in reach the stationary law.

    Parameters
    ----------
    lm : the likelihood (its ``log_posterior`` over the sampled parameters, logs of the moduli relative to
        ``reference_pa``, CoVs and error scales).
    walkers : how many walkers to draw.
    rng : draws the walkers.

    Returns
    -------
    x_map : (D,) the point found; initial : (walkers, D) the walkers, each with a finite log-posterior.
    """
    g, d = lm.n_groups, lm.ndim
    f = lm.table(lm.z_start)
    resid = np.where(lm.mask, lm.f_obs / f - 1.0, np.nan)
    sig0 = np.clip(np.nanstd(resid, axis=0), 2 * SIGMA_BOUNDS[0], 0.5 * SIGMA_BOUNDS[1])
    eps0 = np.array([lm.z_start[:, lm.joint_group == i].mean() for i in range(g)])
    c0 = np.clip([lm.z_start[:, lm.joint_group == i].std() for i in range(g)], 0.02, 0.4)
    extra = lm.extra_bounds
    # the further error scales start at their priors' scales: from there the likelihood's slope leads
    # down to what the data need, whereas from a small value it is flat (the latent shifts then sit
    # on their prior's zero) and the optimiser would stay there
    x0 = np.concatenate([eps0, np.log(c0), np.log(sig0), np.log(np.asarray(lm.extra_scales, float))])
    inner = 1e-6
    bounds = ([(lo + inner, hi - inner) for lo, hi in lm.mean_bounds]
              + [(math.log(COV_BOUNDS[0]) + inner, math.log(COV_BOUNDS[1]) - inner)] * g
              + [(math.log(SIGMA_BOUNDS[0]) + inner, math.log(SIGMA_BOUNDS[1]) - inner)] * lm.fbar.size
              + [(math.log(lo) + inner, math.log(hi) - inner) for lo, hi in extra])
    x0 = np.clip(x0, [b[0] + 1e-3 for b in bounds], [b[1] - 1e-3 for b in bounds])
    eye = np.eye(d)
    h = 1e-5

    def fun(x):
        v = lm.log_posterior(np.vstack([x, x + h * eye, x - h * eye]))
        if not np.all(np.isfinite(v)):
            return 1e300, np.zeros(d)
        return -v[0], -(v[1:d + 1] - v[d + 1:]) / (2.0 * h)

    # the population's means and CoVs only: with the error scales free the search follows the
    # hierarchical funnel (a measurement scale walked 2.4 in log down to its bound on the four-bolt frame,
    # 800 calls, 20 s); the scales start where the start's residuals and the priors put them
    free = np.arange(2 * g)

    def fun_free(y):
        value, gradient = fun(np.concatenate([y, x0[2 * g:]]))
        return value, gradient[free]

    x = np.concatenate([map_search(fun_free, x0[free], np.array(bounds)[free]), x0[2 * g:]])
    # Hessian: [f(x+hi+hj) - f(x+hi-hj) - f(x-hi+hj) + f(x-hi-hj)] / 4h^2, one vectorised call
    hh = 1e-3
    i, j = np.triu_indices(d)
    si, sj = hh * eye[i], hh * eye[j]
    v = lm.log_posterior(np.vstack([x + si + sj, x + si - sj, x - si + sj, x - si - sj])).reshape(4, -1)
    hess = np.zeros((d, d))
    hess[i, j] = -(v[0] - v[1] - v[2] + v[3]) / (4.0 * hh * hh)
    hess[j, i] = hess[i, j]
    if np.all(np.isfinite(hess)):
        values, vectors = np.linalg.eigh(hess)
        values = np.maximum(values, 1.0 / 0.3**2)  # no direction wider than 0.3 in log units
        root = vectors / np.sqrt(values)
    else:
        root = 0.01 * eye
    ball = x + rng.standard_normal((walkers, d)) @ root.T
    ok = np.isfinite(lm.log_posterior(ball))
    ball[~ok] = x + 1e-4 * rng.standard_normal((int((~ok).sum()), d))
    return x, ball


def map_search(fun: Callable[[np.ndarray], tuple[float, np.ndarray]], x0: np.ndarray, bounds: np.ndarray,
               box: float = MAP_BOX, rounds: int = 12) -> np.ndarray:
    """L-BFGS-B within a box of half-width ``box`` (log units) that moves with the optimum.

    On the whole bounds L-BFGS-B's first Cauchy step, taken with a unit Hessian, runs the full gradient
    (hundreds of log units on the measurement scales) into a corner where the posterior is not finite,
    and its line search then stops at the start: the first anchors' MAP sat 0.2 from the optimum, 17 in
    log-posterior below it. A box around the current point keeps every trial step where the posterior
    is finite; the box moves until the optimum is inside it, not on an edge it alone imposed.

    Parameters
    ----------
    fun : the objective and its gradient at a point (minimised).
    x0 : (D,) the start; bounds : (D, 2) the parameters' bounds.
    box : the moving box's half-width, in the parameters' (log) units; rounds : moves of the box at most.

    Returns
    -------
    (D,) the minimum found.
    """
    x = x0
    for _ in range(rounds):
        lo = np.maximum(bounds[:, 0], x - box)
        hi = np.minimum(bounds[:, 1], x + box)
        x = minimize(fun, x, jac=True, method="L-BFGS-B", bounds=np.column_stack([lo, hi]),
                     options={"maxiter": 500, "ftol": 1e-12, "gtol": 1e-6}).x
        on_box_edge = ((x - lo < 1e-6) & (lo > bounds[:, 0])) | ((hi - x < 1e-6) & (hi < bounds[:, 1]))
        if not on_box_edge.any():
            break
    return x


# --------------------------------------------------------------------------------------- diagnostics

def load_arviz() -> ModuleType:
    """The arviz module, imported with its FutureWarning silenced (it announces its 1.0 refactor on import)."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", FutureWarning)
        import arviz  # pulls in pandas and xarray: imported only when a result is built or drawn

    return arviz


def chain_diagnostics(chain: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Arviz rank-normalised split R-hat and bulk ESS of each parameter, walkers as chains, (D,) each, of
    ``chain`` (steps, walkers, D): invariant under monotone maps, so the sampled logs give the reported's.
    """
    az = load_arviz()
    per = np.moveaxis(chain, -1, 0).transpose(0, 2, 1)  # (D, walkers, steps)
    return (np.array([float(az.rhat(p)) for p in per]), np.array([float(az.ess(p)) for p in per]))


def sample_anchored(lm: LikelihoodModel | LaplaceLikelihood, walkers: int, steps: int, burn: int, seed: int,
                    max_steps: int | None, progress: Progress | None, forward_error: float, rng: np.random.Generator
                    ) -> tuple[LikelihoodModel | LaplaceLikelihood, Any, float, np.ndarray]:
    """The ensemble run of `bayes_identify`, with a Laplace likelihood anchored where its posterior is.

    A Laplace likelihood is anchored again where the MAP population puts each test
    (`workbench.identify.anchored`; with tolerances, twice: the factors' terms are expanded about their
    first mode, then about the next). Pilot runs of ``max(burn, PILOT_STEPS)`` steps then go first: while
    the posterior leans on the edge of the region the anchors hold (`LaplaceLikelihood.mean_bounds`) or
    its median has gone far from them (`_leaves`), it is anchored at the pilot's median and the walkers go
    on from where they were (at most `REANCHORINGS` pilots). The kept run is checked once more, and run
    again anchored at its median if it has left.

    Parameters
    ----------
    lm : the likelihood; walkers : how many; steps, burn, max_steps : the kept run's (`run_ensemble`).
    seed : the kept run's emcee seed; pilot ``i`` is seeded ``seed + 1 + i`` so that the kept run, which
        starts where a pilot ended, does not replay the random numbers that brought it there.
    progress : called after each step of every run (each run is its own ``"emcee"`` task).
    forward_error : the forward model's error as built; rng : draws the walkers' start.

    Returns
    -------
    lm : the likelihood the kept run sampled; sampler : emcee's, holding it; forward_error : that
    likelihood's forward model's error; reached : (G,) which groups reach their trust region's edge
    (`_at_trust_edge`; none with quadrature).
    """
    x_map, initial = start(lm, walkers, rng)
    if isinstance(lm, LaplaceLikelihood):
        lm, forward_error = lm.reanchored(x_map)
        x_map, initial = start(lm, walkers, rng)
        if lm.factor_sd.size:  # the factors' terms expanded about their first mode: once more about the next
            lm, forward_error = lm.reanchored(x_map)
            _, initial = start(lm, walkers, rng)
        for i in range(REANCHORINGS):  # short pilot runs find where the posterior goes before the kept run
            chain = run_ensemble(lm.log_posterior, initial, max(burn, PILOT_STEPS), 0, seed + 1 + i,
                                 progress).get_chain()
            chain, initial = chain[chain.shape[0] // 2:], chain[-1].copy()
            if not _leaves(lm, chain):
                break
            lm, forward_error, initial = _anchored_at(lm, chain, rng)

    def kept(lm: LikelihoodModel | LaplaceLikelihood, initial: np.ndarray) -> Any:
        return run_ensemble(lm.log_posterior, initial, steps, burn, seed, progress, until=_settled,
                            max_steps=max_steps, independence=burn > 0)

    sampler = kept(lm, initial)
    if not isinstance(lm, LaplaceLikelihood):
        return lm, sampler, forward_error, np.zeros(lm.n_groups, bool)
    if _leaves(lm, sampler.get_chain()):
        lm, forward_error, initial = _anchored_at(lm, sampler.get_chain(), rng)
        sampler = kept(lm, initial)
        if _leaves(lm, sampler.get_chain()):
            log.warning("the posterior has left its anchors again after its kept run was re-anchored: its "
                        "intervals lean on where the forward model was anchored")
    return lm, sampler, forward_error, _at_trust_edge(lm, sampler.get_chain())


def _leaves(lm: LaplaceLikelihood, chain: np.ndarray) -> bool:
    """Whether the posterior in ``chain`` (steps, walkers, D) has left where ``lm`` was anchored (``lm`` has been
    `LaplaceLikelihood.reanchored`, which sets ``trust_centre``): a group's median log mean modulus more than
    `MOVED_SD` posterior sds (of that log) from ``trust_centre``, or a group leaning on its trust region's
    edge (`_at_trust_edge`). The anchors (and the factors' expansion point) come from a search with the error
    scales fixed at their priors', which on the four-bolt frame put the horizontal mean 17-45 % below where
    the posterior went (seed 18, campaign 1: a -24 % interval with the tolerances stated wide).
    """
    eps = chain.reshape(-1, chain.shape[-1])[:, :lm.n_groups]
    moved = np.abs(np.median(eps, axis=0) - lm.trust_centre) > MOVED_SD * np.std(eps, axis=0)
    return bool(np.any(moved) or np.any(_at_trust_edge(lm, chain)))


def _anchored_at(lm: LaplaceLikelihood, chain: np.ndarray, rng: np.random.Generator
                 ) -> tuple[LaplaceLikelihood, float, np.ndarray]:
    """``lm`` anchored at the posterior median of ``chain`` (steps, walkers, D), its forward model's error, and
    walkers to go on from: the chain's last (a new MAP search with fixed scales could stray again); any that
    the new anchors cannot evaluate moved onto one that they can.
    """
    median = np.median(chain.reshape(-1, chain.shape[-1]), axis=0)
    lm, error = lm.reanchored(median)
    initial = chain[-1].copy()
    bad = ~np.isfinite(lm.log_posterior(initial))
    if bad.any():
        source = initial[~bad] if not bad.all() else median[None, :]
        initial[bad] = (source[rng.integers(source.shape[0], size=int(bad.sum()))]
                        + 1e-4 * rng.standard_normal((int(bad.sum()), median.size)))
    return lm, error, initial


def _at_trust_edge(lm: LaplaceLikelihood, chain: np.ndarray) -> np.ndarray:
    """(G,) whether each group's log mean modulus in ``chain`` (steps, walkers, D) comes within `TRUST_EDGE`
    of a side of its trust region that is inside the prior's support (its 0.5 % or 99.5 % quantile).
    """
    g = lm.n_groups
    eps = chain.reshape(-1, chain.shape[-1])[:, :g]
    low, high = np.quantile(eps, [0.005, 0.995], axis=0)
    box, prior = lm.mean_bounds, lm.support_mean_bounds
    return (((low < box[:, 0] + TRUST_EDGE) & (box[:, 0] > prior[:, 0]))
            | ((high > box[:, 1] - TRUST_EDGE) & (box[:, 1] < prior[:, 1])))


def _settled(chain: np.ndarray) -> bool:
    rhat, ess = chain_diagnostics(chain)
    return settled(rhat, ess)


TRUST_EDGE = 0.03  # log units: a posterior this close to its trust region's edge leans on it
MOVED_SD = 1.0  # a posterior median this many sds from the anchors is anchored again (`_leaves`)
REANCHORINGS = 3  # pilot runs at most before the kept run
PILOT_STEPS = 200  # a pilot run's steps at least (a pilot runs the burn-in's length when that is longer)

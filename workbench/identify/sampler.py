"""Emcee's ensemble for the Bayesian identification: differential evolution, and an independence
proposal fitted to the burn-in.

**Why not differential evolution alone.** Its autocorrelation time grows with the dimension, about
three steps per parameter: on a 20-dimensional standard normal, 42 walkers, tau = 59 steps and
the largest R-hat 1.034 after 3000 steps. R-hat over walkers as chains falls as ``1 + tau / n``
with each walker's length ``n``, so 1.01 takes about 140 tau. On the four-bolt frame's posterior
(20 parameters, error terms on) DE's tau reached 200-270 steps: the per-mode measurement errors have
long tails towards zero (a test's latent moduli can absorb one mode's scatter), and after 12 000
steps (367 s) the largest R-hat was still 1.026.

**The independence move.** After the burn-in, a multivariate Student t (`T_DOF` degrees of freedom)
is fitted to the burn-in's second half, each parameter in the coordinate (its log, as sampled, or
its exponential, the scale itself) where its burn-in sample is least skewed: a scale whose
posterior reaches towards zero is far closer to normal in linear coordinates. A second adaptation
phase (half the burn-in) runs the mixed moves and the t is refitted on it; then it is frozen for the
kept chain, so the chain is a Metropolis-Hastings chain with a fixed proposal (``MHMove`` with the
proposal's density ratio), and adaptation ends before the kept steps, as it must. The kept steps
mix `INDEPENDENCE_SHARE` independence moves with differential evolution, which keeps exploring
where the t is thin. On the four-bolt frame (20 parameters, with the pooled prior of
`workbench.identify.likelihood`) the autocorrelation time is about 10 steps, and the chains met
R-hat <= 1.01 after 1500 kept steps, 57 s in all (benchmarks/bayes_many_joints.py).
"""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import Any

import numpy as np

from workbench.progress import Progress, report

__all__ = ["run_ensemble", "StudentProposal", "INDEPENDENCE_SHARE", "T_DOF"]

T_DOF = 10.0  # the proposal's tails: heavier than the posterior's, so that the ratio of densities stays bounded
INDEPENDENCE_SHARE = 0.8  # of the kept steps' moves; the rest differential evolution
STRAY_LOG_PROB = 10.0  # a walker this far (plus the posterior's own spread) below the median is stranded


class StudentProposal:
    """A multivariate Student t fitted to samples, in coordinates where chosen parameters are
    exponentiated (`fit`); as emcee's ``MHMove`` proposal it returns the proposed points and
    ``log q(x) - log q(x')``, the independence sampler's density ratio (with the coordinates' Jacobian).
    """

    def __init__(self, dof: float = T_DOF) -> None:
        self.dof = dof
        self.linear = np.zeros(0, bool)
        self.mean: np.ndarray = np.zeros(0)
        self.root: np.ndarray = np.zeros((0, 0))
        self.inverse_root: np.ndarray = np.zeros((0, 0))

    def fit(self, points: np.ndarray) -> StudentProposal:
        """Fit to ``points`` (M, D); each parameter exponentiated where that makes it less skewed."""
        with np.errstate(over="ignore", invalid="ignore"):  # a parameter too large to exponentiate stays as it is
            self.linear = _skewness(np.exp(points)) ** 2 < _skewness(points) ** 2
        y = self._forward(points)
        self.mean = y.mean(axis=0)
        self.root = np.linalg.cholesky(np.cov(y.T) + 1e-12 * np.eye(y.shape[1]))
        self.inverse_root = np.linalg.inv(self.root)
        return self

    def _forward(self, theta: np.ndarray) -> np.ndarray:
        out = np.array(theta, float)
        out[:, self.linear] = np.exp(out[:, self.linear])  # only those: the others may be too large for exp
        return out

    def log_density(self, theta: np.ndarray) -> np.ndarray:
        """``log q(theta)`` (N,) up to a constant: the t's density of the coordinates times their Jacobian."""
        y = (self._forward(theta) - self.mean) @ self.inverse_root.T
        d = theta.shape[1]
        return (-0.5 * (self.dof + d) * np.log1p(np.sum(y * y, axis=1) / self.dof)
                + np.sum(np.where(self.linear, theta, 0.0), axis=1))

    def __call__(self, coords: np.ndarray, random: np.random.RandomState) -> tuple[np.ndarray, np.ndarray]:
        n, d = coords.shape
        y = self.mean + (random.randn(n, d) @ self.root.T) / np.sqrt(random.chisquare(self.dof, n) / self.dof)[:, None]
        outside = np.any(self.linear & (y <= 0.0), axis=1)  # a scale below zero: no parameter there, rejected
        proposed = y.copy()
        proposed[:, self.linear] = np.log(np.where(y[:, self.linear] > 0.0, y[:, self.linear], 1.0))
        proposed[outside] = coords[outside]
        ratio = self.log_density(coords) - self.log_density(proposed)
        return proposed, np.where(outside, -np.inf, ratio)


def _skewness(x: np.ndarray) -> np.ndarray:
    centred = x - x.mean(axis=0)
    sd = centred.std(axis=0)
    return np.mean(centred**3, axis=0) / np.where(sd > 0, sd, 1.0) ** 3


def run_ensemble(log_prob: Callable[[np.ndarray], np.ndarray], initial: np.ndarray, steps: int, burn: int, seed: int,
                 progress: Progress | None = None, until: Callable[[np.ndarray], bool] | None = None,
                 max_steps: int | None = None, independence: bool = False) -> Any:
    """Emcee's ensemble on a vectorised ``log_prob`` ((N, D) -> (N,)), seeded.

    Moves: differential evolution, which mixes far better than the stretch move on this
    likelihood; with ``independence``, also the fitted independence move (module docstring).
    emcee 3.1.6's ``DESnookerMove`` is biased (it samples a 12-D standard Gaussian with a standard
    deviation of 0.78; fixed upstream in dfm/emcee PR #531, not yet released): with 20 % of snooker
    moves the 95 % intervals came out 18-28 % too narrow (benchmarks/compare_estimators.py).

    Parameters
    ----------
    log_prob : vectorised log-probability.
    initial : (walkers, D) starting points.
    steps, burn : kept and discarded steps per walker (with ``independence``, ``burn // 2`` more
        discarded steps adapt the proposal).
    seed : seeds emcee's generator.
    progress : called as ``progress("emcee", done, total)`` after each step (`workbench.progress`).
    until, max_steps : when given, the kept chain ((steps, walkers, D)) is extended by ``steps // 2`` at a
        time until ``until(chain)`` holds or ``max_steps`` are kept.
    independence : mix in the independence move fitted to the burn-in (needs ``burn`` > 0).

    Returns
    -------
    emcee.EnsembleSampler
        Holding the ``steps`` kept (``get_chain``). The same ``seed`` and ``initial`` give the same chain.
    """
    import emcee  # heavy, and needed only when sampling: importing this module stays light

    walkers, ndim = initial.shape
    # fewer walkers than 2 D: differential evolution then moves each walker within the other half's span;
    # the independence move reaches every direction (bayes_identify uses D + 4 walkers with it)
    few = walkers < 2 * ndim

    def de() -> Any:
        return emcee.moves.DEMove(live_dangerously=few)

    sampler = emcee.EnsembleSampler(walkers, ndim, log_prob, vectorize=True, moves=[(de(), 1.0)])
    done, total = 0, burn + steps + (burn // 2 if independence and burn else 0)

    def advance(on: Any, state: Any, iterations: int) -> Any:
        # sampler.sample is what run_mcmc iterates: the same chain, with a report after every step
        nonlocal done
        for state in on.sample(state, iterations=iterations):  # noqa: B007, B020 (returns the last state)
            done += 1
            report(progress, "emcee", done, total)
        return state

    state = emcee.State(initial, random_state=np.random.RandomState(seed).get_state())
    if burn:
        state = advance(sampler, state, burn)
        stray = _strays(state.log_prob, ndim)
        if stray.any():  # move them onto the others and burn in again: the kept chain starts from the new ensemble
            good = np.flatnonzero(~stray)
            rng = np.random.default_rng(seed)
            coords = state.coords.copy()
            spread = coords[good].std(axis=0)
            jitter = 1e-3 * spread * rng.standard_normal((stray.sum(), ndim))
            coords[stray] = coords[rng.choice(good, stray.sum())] + jitter
            total += burn // 2
            sampler.reset()
            state = advance(sampler, emcee.State(coords, random_state=state.random_state), burn // 2)
        if independence:
            proposal = StudentProposal().fit(sampler.get_chain()[-max(burn // 2, 1):].reshape(-1, ndim))
            sampler = emcee.EnsembleSampler(walkers, ndim, log_prob, vectorize=True,
                                            moves=[(de(), 1.0 - INDEPENDENCE_SHARE),
                                                   (emcee.moves.MHMove(proposal), INDEPENDENCE_SHARE)])
            state = advance(sampler, state, burn // 2)
            proposal.fit(sampler.get_chain().reshape(-1, ndim))  # frozen from here: the kept chain's proposal
        sampler.reset()
    state = advance(sampler, state, steps)
    kept, chunk = steps, max(steps // 2, 1)
    while until is not None and kept < (max_steps or steps) and not until(sampler.get_chain()):
        chunk = min(chunk, (max_steps or steps) - kept)
        total += chunk
        state = advance(sampler, state, chunk)
        kept += chunk
    return sampler


def _strays(log_prob: np.ndarray, ndim: int) -> np.ndarray:
    """Walkers stranded in a region of negligible posterior (a local optimum the burn-in did not leave).

    At stationarity a D-dimensional near-Gaussian posterior's log density sits ``chi2_D / 2`` below
    its peak: spread ``sqrt(D / 2)``. A walker more than ``5 sqrt(D / 2) + STRAY_LOG_PROB`` below the
    median has odds below e^-10 of belonging there; differential-evolution moves, built from other
    walkers' differences, rarely propose the jump back, and one such walker alone spoils R-hat.
    """
    return log_prob < np.median(log_prob) - 5.0 * math.sqrt(ndim / 2.0) - STRAY_LOG_PROB

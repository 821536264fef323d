"""The targeted gap test's family-wise p-value: the least p-value of correlated candidates, read against its law
under no effect (the min-p adjustment of Westfall & Young 1993), where Bonferroni multiplied it by their count.

The frequency channel's targeted test (`workbench.diagnose.decision`, 1) fits every candidate, reads each
in-sample drop of the chi-square as a p-value, and keeps the least. Bonferroni's bound on that search, the
p-value times the number of candidates, holds whatever their dependence, but the candidates of one frame are
far from independent: one effect at neighbouring places, the forms of one support, every joint's modulus and
each one's move the modes in nearly the same patterns. Thirty such
candidates are a handful of independent ones, and the bound overstates the search: a medium clamp (proving-ground
seed 12, case 13) whose two-dof form lowered the chi-square by 15.4, p = 4.6e-4 alone, came out 0.015 over 32
candidates, and ``none``; read against the family's own law below, 0.0098.

Here the least p-value is read against its own distribution under no effect. About the no-effect point each
candidate changes the means along its tangent ``g`` (one column, or two for a support giving way in two dofs, or
the drive's spring and moving mass), and, whitened by the covariance the chi-square uses
(`workbench.diagnose.observations.Observations.joint_covariance`), a residual ``z ~ N(0, I)`` lets it lower its
chi-square by ``(g.z)^2 / |g|^2`` (``max(0, -g.z)^2 / |g|^2`` where the effect can act one way only: a mass is
added, a support softens; the best non-negative pair for two columns).
Each simulated drop is read with the candidate's own law, as the measured drop is; the family-wise p-value of
a measured least p-value ``p`` is the share of `NULL_DRAWS` draws whose least p-value is ``p`` or below. It is
exact for candidates linear about no effect under the stated covariance, and never above Bonferroni's bound
(but for the draws' sampling error: about 1e-3 at ``p`` = 0.01). A candidate the draws do not stand for adds its
own p-value (the union bound, Bonferroni's term): one whose tangent cannot be formed; an added mass, whose places
a screen of the whole frame picked from the data and whose drop is read with three parameters to charge that
search, which a fixed tangent does not repeat; a joint's softening, whose drop is read against F because the
levels' covariance is estimated from a few tests, which the draws take as known (`workbench.diagnose.decision`).
The draws use a fixed seed (`NULL_SEED`): the same campaign gives the same p-values.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np
from scipy.special import erfc

from workbench.diagnose.fitting import BOUND_TOLERANCE, Frequencies, damping_columns
from workbench.diagnose.observations import Observations, damping_whiten

__all__ = ["NULL_DRAWS", "NULL_SEED", "TANGENT_STEP", "Tangent", "NullFamily", "tangent", "null_family", "damping_null",
           "one_dof_tail"]

NULL_DRAWS = 20000  # draws of the least p-value under no effect: its share at 0.01 to about +-0.0007
NULL_SEED = 20261128
TANGENT_STEP = 0.02  # of a parameter's range: the step of the tangent, inside the linear range of every curve


def one_dof_tail(drop: np.ndarray) -> np.ndarray:
    """Chi-square's tail with one degree of freedom, ``erfc(sqrt(x / 2))``: the numbers of
    ``scipy.stats.chi2.sf(x, 1)`` two hundred times faster on the null's `NULL_DRAWS` draws (40 ms a law otherwise).
    """
    return erfc(np.sqrt(np.maximum(drop, 0.0) / 2.0))


@dataclass(frozen=True)
class Tangent:
    """A candidate's change of the relative means about no effect (module docstring).

    ``columns`` (n_present, k): per column, the change of ``predicted / measured`` over the present means (the
    order of `Observations.joint_covariance`), oriented into the parameter's range; ``one_sided`` per column.
    """

    columns: np.ndarray
    one_sided: tuple[bool, ...]


def tangent(model: Frequencies, present: np.ndarray) -> Tangent | None:
    """The tangent of one curve's candidate at its no-effect coordinate (softening: the slope nil), two-sided where
    that coordinate lies inside the range (beyond `BOUND_TOLERANCE` of either end), else into the range; no
    column where the curve does not move the means (it lowers no chi-square), None where it has no value.
    """
    span = model.hi - model.lo
    if model.amplitude:
        start = 0.0
    elif model.curve.nominal is None:
        return None
    else:
        start = float(model.curve.coordinate(model.curve.nominal))
    below, above = start - model.lo, model.hi - start
    two_sided = min(below, above) > BOUND_TOLERANCE * span
    h = TANGENT_STEP * span
    if two_sided and min(below, above) >= h:
        change = model.predict(start + h) - model.predict(start - h)
    elif above >= below:  # the roomier side: the only one at an end, either one inside (the sign is then free)
        change = model.predict(start + min(h, above)) - model.predict(start)
    else:
        change = model.predict(start - min(h, below)) - model.predict(start)
    column = (change / model.obs.frequency_hz)[present]
    if not np.all(np.isfinite(column)):
        return None
    if not np.any(column != 0.0):
        return Tangent(np.zeros((column.size, 0)), ())
    return Tangent(column[:, None], (not two_sided,))


def _drops(columns: np.ndarray, one_sided: tuple[bool, ...], z: np.ndarray) -> np.ndarray:
    """(n_draws,) chi-square drops of whitened residuals ``z`` (n_draws, n) along whitened ``columns`` (n, k)."""
    z = -z  # the candidate's residual is r + a g: a change lowers the chi-square where it points against r
    singles = []
    for j in range(columns.shape[1]):
        g = columns[:, j]
        proj = z @ g / np.sqrt(g @ g)
        singles.append(np.maximum(proj, 0.0) ** 2 if one_sided[j] else proj ** 2)
    if columns.shape[1] == 1:
        return singles[0]
    q, r = np.linalg.qr(columns)
    coef = np.linalg.solve(r, (z @ q).T).T  # (n_draws, k) unconstrained least squares
    whole = np.sum((z @ q) ** 2, axis=1)
    feasible = np.all((coef >= 0.0) | ~np.array(one_sided)[None, :], axis=1)
    # where the unconstrained best breaks a sign, the best lies on a face: one column alone (k = 2)
    return np.where(feasible, whole, np.max(np.stack(singles), axis=0))


class NullFamily:
    """The least p-value of a channel's candidates under no effect (module docstring).

    Parameters
    ----------
    tangents : per candidate, its `Tangent` in the covariance's order, or None where it has none.
    laws : per candidate, its p-value as a function of its drops (the same law as the measured drop's).
    covariance : (n_present, n_present) the chi-square's covariance of the relative means.
    draws, seed : the simulation's size and seed.
    """

    def __init__(self, tangents: Sequence[Tangent | None], laws: Sequence[Callable[[np.ndarray], np.ndarray]],
                 covariance: np.ndarray, draws: int = NULL_DRAWS, seed: int = NULL_SEED):
        lower = np.linalg.cholesky(covariance)
        z = np.random.default_rng(seed).standard_normal((draws, covariance.shape[0]))
        # each draw's largest drop per law: a law falls with the drop, so the least p-value of the candidates read
        # with one law is that law at their largest drop (the same numbers, one evaluation per law: a chi-square
        # tail on 20 000 draws takes 10 ms, and thirty candidates share two or three laws)
        largest: dict[Callable[[np.ndarray], np.ndarray], np.ndarray] = {}
        self.missing = 0
        for t, law in zip(tangents, laws):
            if t is None:
                self.missing += 1
                continue
            if t.columns.shape[1] == 0:  # it cannot lower the chi-square
                continue
            whitened = np.linalg.solve(lower, t.columns)  # z . L^-1 g: the drop in the chi-square's metric
            drops = _drops(whitened, t.one_sided, z)
            largest[law] = np.maximum(largest[law], drops) if law in largest else drops
        least = np.ones(draws)
        for law, drops in largest.items():
            least = np.minimum(least, law(drops))
        self.least = np.sort(least)
        self.size = len(tangents)

    def adjusted(self, p_one: float) -> float:
        """The family-wise p-value of a candidate's own p-value ``p_one`` (never 0: the draws' share counts the
        measured one among them).
        """
        share = (np.searchsorted(self.least, p_one, side="right") + 1) / (self.least.size + 1)
        return float(min(1.0, share + self.missing * p_one))


def null_family(obs: Observations, models: Sequence[Sequence[Frequencies]],
                laws: Sequence[Callable[[np.ndarray], np.ndarray]], draws: int = NULL_DRAWS) -> NullFamily:
    """The `NullFamily` of a frequency channel whose candidates are ``models`` (one curve, or the two of a
    support's two-dof form; none for a candidate left to the union bound) with their p-value ``laws``, under the
    covariance of the in-sample chi-square.
    """
    present, covariance = obs.joint_covariance(np.ones(obs.frequency_hz.shape[1], bool))
    tangents: list[Tangent | None] = []
    for group in models:
        parts = [tangent(m, present) for m in group]
        if not parts or any(p is None for p in parts):
            tangents.append(None)
            continue
        tangents.append(Tangent(np.hstack([p.columns for p in parts if p is not None]),
                                tuple(s for p in parts if p is not None for s in p.one_sided)))
    return NullFamily(tangents, laws, covariance, draws)


def damping_null(obs: Observations, shares: Sequence[np.ndarray], law: Callable[[np.ndarray], np.ndarray],
                 draws: int = NULL_DRAWS) -> NullFamily:
    """The `NullFamily` of the damping channel, whose candidates add ``eta * share`` (eta >= 0) to the damping
    baseline: each ``share`` (n_modes,) or (n_cond, n_modes), read with ``law``.

    Exact rather than a tangent's: a damping candidate is linear in its parameter. In the whitened metric of
    `workbench.diagnose.observations.damping_whiten` (identity covariance) its column, less its projection on
    the baseline's columns (`workbench.diagnose.fitting.damping_columns`, refitted with it), lowers the
    chi-square by ``max(0, -g.z)^2 / |g|^2``. Until seed 22 the damping channel used Bonferroni's bound, which
    counts a dashpot's hysteretic and viscous forms at one joint (nearly the same pattern over a narrow band) as
    two independent searches and reads a one-sided drop as two-sided.
    """
    if obs.damping is None:
        raise ValueError("damping_null: no damping was measured")
    base = np.stack([damping_whiten(obs, c).ravel() for c in damping_columns(obs, np.ones(obs.damping.shape[1], bool))],
                    axis=1)
    q, _ = np.linalg.qr(base)
    tangents: list[Tangent | None] = []
    for share in shares:
        whole = damping_whiten(obs, np.broadcast_to(share, obs.damping.shape)).ravel()
        g = whole - q @ (q.T @ whole)
        lowers = g @ g > 1e-12 * max(float(whole @ whole), 1e-300)  # else the baseline's level already holds it
        tangents.append(Tangent(g[:, None] if lowers else np.zeros((g.size, 0)), (True,) if lowers else ()))
    return NullFamily(tangents, [law] * len(tangents), np.eye(base.shape[0]), draws)


"""Two effects at once: a primary and a secondary, when no single candidate explains a frequency gap.

A real structure rarely carries one effect alone (a soft support *and* a sensor's mass). Each pair of the
best-ranked frequency candidates is fitted with both parameters; their frequency changes are added,
``f = f_base + (f_1(u_1) - f_base) + (f_2(u_2) - f_base)``: first order in each effect's change (both are a few
percent at most, where the cross term is of the order of their product), which keeps every evaluation on the
curves already solved. The pair's held-out error is measured by the same leave-one-mode-out protocol as a
single candidate's (`workbench.diagnose.fitting`).
"""

from __future__ import annotations

import itertools
import math
from dataclasses import dataclass

import numpy as np

from workbench.diagnose.fitting import CandidateFit, Frequencies
from workbench.diagnose.observations import Observations, frequency_chi2_many, frequency_score, rms

__all__ = ["PAIR_POOL", "PairFit", "PairGrid", "form_pairs", "pair_fits"]

PAIR_POOL = 6  # pairs are formed among this many best-ranked frequency candidates


@dataclass(frozen=True)
class PairFit:
    """Two candidates fitted together: their parameters, errors and in-sample prediction (Hz)."""

    first: CandidateFit
    second: CandidateFit
    parameters: tuple[dict, dict]
    chi2_frequency: float
    heldout_chi2_frequency: float
    freq_rms_rel_error: float
    heldout_freq_rms_rel_error: float
    predicted_hz: np.ndarray
    heldout_logdet: float = 0.0  # as `CandidateFit.heldout_logdet`
    at_bound: bool = False  # either effect's parameter at a far end of its range (`Frequencies.at_bound`)

    @property
    def heldout_score(self) -> float:
        """As `CandidateFit.heldout_score`: the two fitted parameters are refitted by leave-one-mode-out, but what
        each effect chose on every mode (an added mass's place and position) is charged as for the single.
        """
        return self.heldout_chi2_frequency + self.heldout_logdet + self.first.extra_charge + self.second.extra_charge


GRID = 33  # coarse values of each parameter scanned together, before the zoom
ZOOM = 9  # values per parameter of each zoomed scan around the best point so far
ZOOMS = 3  # zoomed scans: the last steps by 1/2048 of each parameter's range


class PairGrid:
    """A pair's predictions on a grid of both parameters (scaled to [0, 1]), solved once for every mode mask.

    Leave-one-mode-out fits the pair once per mode; the predictions do not depend on the mask, only the
    chi-square does, so one vectorised scan serves every fit and the zoom solves only its few new points.
    """

    def __init__(self, models: tuple[Frequencies, Frequencies], obs: Observations, baseline_hz: np.ndarray):
        self.a, self.b = models
        self.obs, self.baseline_hz = obs, baseline_hz
        self.lo = np.array([self.a.lo, self.b.lo])
        self.span = np.array([self.a.hi - self.a.lo, self.b.hi - self.b.lo])
        self.x = np.linspace(0.0, 1.0, GRID)
        self.coarse = self.predict(self.x, self.x)

    def predict(self, x1: np.ndarray, x2: np.ndarray) -> np.ndarray:
        """(n1 * n2, n_cond, n_modes) predictions, Hz, on the grid ``x1`` x ``x2`` (scaled parameters)."""
        p1 = self.a.predict_many(self.lo[0] + np.clip(x1, 0.0, 1.0) * self.span[0])
        p2 = self.b.predict_many(self.lo[1] + np.clip(x2, 0.0, 1.0) * self.span[1])
        return (p1[:, None] + p2[None, :] - self.baseline_hz).reshape(-1, *self.baseline_hz.shape)

    def at_bound(self, u: np.ndarray) -> bool:
        """Whether either parameter of ``u`` (unscaled) sits at a far end of its range (`Frequencies.at_bound`)."""
        return self.a.at_bound(float(u[0])) or self.b.at_bound(float(u[1]))

    def fit(self, mask: np.ndarray) -> tuple[np.ndarray, np.ndarray, float]:
        """``(u, prediction, chi2 on mask)`` of the pair fitted on the modes in ``mask``: the coarse grid's
        best point, then `ZOOMS` grids, each over the previous grid's cells around its best point.
        """
        cache: dict = {}
        costs = frequency_chi2_many(self.obs, self.coarse, mask, cache)  # inf where a curve has no value
        i, j = divmod(int(np.argmin(costs)), GRID)
        x, p, c = np.array([self.x[i], self.x[j]]), self.coarse[i * GRID + j], float(costs[i * GRID + j])
        step = 1.0 / (GRID - 1)
        for _ in range(ZOOMS):
            x1, x2 = (x[0] + np.linspace(-step, step, ZOOM), x[1] + np.linspace(-step, step, ZOOM))
            fine = self.predict(x1, x2)
            fine_costs = frequency_chi2_many(self.obs, fine, mask, cache)
            k = int(np.argmin(fine_costs))
            if fine_costs[k] < c:
                x, p, c = np.clip([x1[k // ZOOM], x2[k % ZOOM]], 0.0, 1.0), fine[k], float(fine_costs[k])
            step *= 2.0 / (ZOOM - 1)
        return self.lo + x * self.span, p, c


def pair_fits(singles: list[CandidateFit], models: dict[tuple[str, str | None, str], Frequencies], obs: Observations,
              baseline_hz: np.ndarray) -> list[PairFit]:
    """Every pair among the `PAIR_POOL` best frequency candidates of ``singles`` (ranked best first), fitted in
    sample and leave one mode out on a grid of both parameters (`PairGrid`), best held-out score first
    (`CandidateFit.heldout_score`). ``models`` holds each candidate's `Frequencies` by `CandidateFit.key`. Two
    forms of one effect at one place are no pair of effects: they are one candidate (`form_pairs`), scored
    among the singles.
    """
    pool = [c for c in singles if c.channel == "frequency" and c.key in models][:PAIR_POOL]
    n_modes = obs.frequency_hz.shape[1]
    everything = np.ones(n_modes, bool)
    out = []
    for first, second in itertools.combinations(pool, 2):
        if (first.effect, first.where) == (second.effect, second.where):
            continue
        pair = (models[first.key], models[second.key])
        grid = PairGrid(pair, obs, baseline_hz)
        u, in_hz, in_chi2 = grid.fit(everything)
        held = np.full_like(obs.frequency_hz, np.nan)
        for k in range(n_modes):
            mask = everything.copy()
            mask[k] = False
            held[:, k] = grid.fit(mask)[1][:, k]
        params = (_parameters(first, pair[0], u[0]), _parameters(second, pair[1], u[1]))
        held_chi2, held_logdet = frequency_score(obs, held, baseline_hz)
        out.append(PairFit(first, second, params, in_chi2, held_chi2, rms(in_hz / obs.frequency_hz - 1.0),
                           rms(held / obs.frequency_hz - 1.0), in_hz, held_logdet,
                           grid.at_bound(u)))
    out.sort(key=lambda p: p.heldout_score if math.isfinite(p.heldout_chi2_frequency) else np.inf)
    return out


def form_pairs(models: list[Frequencies], effect: str) -> list[tuple[Frequencies, Frequencies]]:
    """Every two forms of ``effect`` at one place among ``models``: one effect with two parameters (a support's
    two dofs; the drive's spring and the mass moving with it, `workbench.diagnose.candidates.drive_sweeps`).

    A clamp gives way in rotation and in translation at once (a foot plate that rocks and slides, a base whose
    compliance sits below the node and couples the two); one spring at a time fits such a support only as well
    as one of its dofs carries the change, and another effect's single form may then fit better. Two forms at one
    place are added at first order, as a pair of effects is (module docstring): on a large coupled clamp of the
    proving ground (a 3 % footprint), the exact two-spring model fitted to the same modes gave a chi-square
    within 2 % of the first-order one. The second parameter is refitted in every leave-one-out fold, yet
    charged ``ln N`` as well (`CandidateFit.extra_charge`): a prior against the richer form of the same support,
    as a pair of effects must each lower the chi-square by `workbench.diagnose.decision.PAIR_EVIDENCE`.
    """
    chosen = [m for m in models if m.curve.effect == effect and not m.amplitude]
    return [(a, b) for a, b in itertools.combinations(chosen, 2) if a.curve.where == b.curve.where]


def _parameters(fit: CandidateFit, model: Frequencies, u: float) -> dict:
    """A candidate's parameters at the pair's coordinate ``u``, named as its single fit names them."""
    if model.amplitude:
        return {name: float(u) for name in fit.parameters}
    return model.curve.parameters(float(u))

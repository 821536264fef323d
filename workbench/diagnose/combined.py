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
from scipy.optimize import minimize

from workbench.diagnose.fitting import CandidateFit, Frequencies
from workbench.diagnose.observations import Observations, frequency_chi2, frequency_score, rms

__all__ = ["PAIR_POOL", "PairFit", "pair_fits"]

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

    @property
    def heldout_score(self) -> float:
        """As `CandidateFit.heldout_score` (two parameters, neither chosen beyond the leave-one-out refit)."""
        return self.heldout_chi2_frequency + self.heldout_logdet


def _fit(models: tuple[Frequencies, Frequencies], start: tuple[float, float], obs: Observations,
         baseline_hz: np.ndarray, mask: np.ndarray) -> tuple[np.ndarray, np.ndarray, float]:
    """``(u, prediction, chi2 on mask)`` of the pair fitted on the modes in ``mask``."""
    a, b = models
    span = np.array([a.hi - a.lo, b.hi - b.lo])
    lo = np.array([a.lo, b.lo])
    cache: dict = {}

    def predict(x: np.ndarray) -> np.ndarray:
        u = lo + np.clip(x, 0.0, 1.0) * span
        return a.predict(u[0]) + b.predict(u[1]) - baseline_hz

    def cost(x: np.ndarray) -> float:
        p = predict(x)
        return frequency_chi2(obs, p, mask, cache) if np.all(np.isfinite(p[:, mask])) else 1e300

    x0 = (np.asarray(start) - lo) / np.where(span > 0, span, 1.0)
    res = minimize(cost, x0, method="Powell", bounds=[(0.0, 1.0), (0.0, 1.0)], options={"xtol": 1e-5, "ftol": 1e-9})
    x = res.x if res.fun <= cost(x0) else x0
    return lo + np.clip(x, 0.0, 1.0) * span, predict(x), float(cost(x))


def pair_fits(singles: list[CandidateFit], models: dict[tuple[str, str | None], Frequencies], obs: Observations,
              baseline_hz: np.ndarray) -> list[PairFit]:
    """Every pair among the `PAIR_POOL` best frequency candidates of ``singles`` (ranked best first), fitted in
    sample and leave one mode out, best held-out score first (`CandidateFit.heldout_score`).

    ``models`` holds each candidate's `Frequencies` by ``(effect, where)``; each pair starts from its two
    single fits on every mode.
    """
    pool = [c for c in singles if c.channel == "frequency" and (c.effect, c.where) in models][:PAIR_POOL]
    n_modes = obs.frequency_hz.shape[1]
    everything = np.ones(n_modes, bool)
    starts = {(c.effect, c.where): models[(c.effect, c.where)].fit(everything)[0] for c in pool}
    out = []
    for first, second in itertools.combinations(pool, 2):
        keys = ((first.effect, first.where), (second.effect, second.where))
        pair = (models[keys[0]], models[keys[1]])
        start = (starts[keys[0]], starts[keys[1]])
        u, in_hz, in_chi2 = _fit(pair, start, obs, baseline_hz, everything)
        held = np.full_like(obs.frequency_hz, np.nan)
        for k in range(n_modes):
            mask = everything.copy()
            mask[k] = False
            held[:, k] = _fit(pair, start, obs, baseline_hz, mask)[1][:, k]
        params = (_parameters(first, pair[0], u[0]), _parameters(second, pair[1], u[1]))
        held_chi2, held_logdet = frequency_score(obs, held, baseline_hz)
        out.append(PairFit(first, second, params, in_chi2, held_chi2, rms(in_hz / obs.frequency_hz - 1.0),
                           rms(held / obs.frequency_hz - 1.0), in_hz, held_logdet))
    out.sort(key=lambda p: p.heldout_score if math.isfinite(p.heldout_chi2_frequency) else np.inf)
    return out


def _parameters(fit: CandidateFit, model: Frequencies, u: float) -> dict:
    """A candidate's parameters at the pair's coordinate ``u``, named as its single fit names them."""
    if model.amplitude:
        return {name: float(u) for name in fit.parameters}
    return model.curve.parameters(float(u))

"""The diagnosis's baseline: the nominal model's predicted campaign means and its pairing with the measured modes.

The frame file's model with its joints at their mean, its frequencies multiplied by the ratio of
the stochastic mean (adaptive SMR, eq. 5-7 and Figure 10, with the file's joint CoVs) to the nominal frequency,
since a campaign's mean is E[f], not f(E[Y]). Measured modes are paired with model modes by
frequency (an assignment on |log f_measured / f_model|), once, on the baseline.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.optimize import linear_sum_assignment

from workbench.diagnose.observations import Observations
from workbench.model.assembly import Model
from workbench.model.frame import Frame
from workbench.model.matrix_model import MatrixModel
from workbench.model.modal import Modes
from workbench.model.structure import Structure, structure_modes, structure_of
from workbench.uq.smr import adaptive
from workbench.uq.stochastic import joint_model

__all__ = ["EXTRA_MODES", "BAND_MARGIN", "PAIR_WINDOW", "Baseline", "baseline"]

EXTRA_MODES = 3  # model modes beyond the measured count, for the pairing
BAND_MARGIN = 1.3  # model modes up to this times the highest measured frequency
PAIR_WINDOW = 0.2  # a measured mode more than 20 % from its model mode is not paired


@dataclass(frozen=True)
class Baseline:
    """The nominal model, its modes and their pairing with the measured modes.

    Attributes
    ----------
    frame, model : the nominal frame (or matrix model) and its assembled model (the matrix model itself).
    modes : its first ``count`` modes.
    pairing : (n_measured,) index of the model mode paired with each measured mode (any, where unpaired).
    mean_ratio : (count,) E[f] / f(E[Y]) per model mode (1 with deterministic joints).
    count : model modes solved (up to `BAND_MARGIN` times the highest measured frequency, at most the model's
        size - 2).
    """

    frame: Frame | MatrixModel
    model: Structure
    modes: Modes
    pairing: np.ndarray
    mean_ratio: np.ndarray
    count: int
    unpaired: np.ndarray | None = None  # (n_measured,) True where no model mode lies within PAIR_WINDOW

    @property
    def planar(self) -> tuple[Frame, Model]:
        """The frame and its assembled model, for the frame-only candidates; TypeError on a matrix model."""
        if not isinstance(self.frame, Frame) or not isinstance(self.model, Model):
            raise TypeError(f"{self.model.source}: a matrix model has no frame geometry")
        return self.frame, self.model

    def frequency(self, model_hz: np.ndarray) -> np.ndarray:
        """Predicted campaign means of the measured modes (..., n_measured), Hz, from model frequencies (..., count)."""
        return (model_hz * self.mean_ratio)[..., self.pairing]


def baseline(frame: Frame | MatrixModel, obs: Observations) -> Baseline:
    """The baseline of ``frame`` against the observations (module docstring).

    The model's modes reach `BAND_MARGIN` times the highest measured frequency: a campaign often misses modes
    its sensors do not see (two modes 3 % apart, one of them at a node), and a pairing offered only as many
    model modes as were measured then pairs the last measured modes with model modes far below them. A
    measured mode with no model mode within `PAIR_WINDOW` is left unpaired (`Baseline.unpaired`).
    """
    model = structure_of(frame)
    n_meas = obs.frequency_hz.shape[1]
    measured = np.nanmean(obs.frequency_hz, axis=0)
    limit = model.size - 2
    count = min(n_meas + EXTRA_MODES, limit)
    modes = structure_modes(model, count)
    ceiling = min(limit, 3 * n_meas + EXTRA_MODES)  # a band is not worth more model modes than this
    while modes.frequency_hz[-1] < BAND_MARGIN * np.nanmax(measured) and count < ceiling:
        count = min(count + max(n_meas // 2, 4), ceiling)
        modes = structure_modes(model, count)
    ratio = np.ones(count)
    if any(j.cov > 0 for j in frame.joints):
        moments = adaptive(model, joint_model(model), count)
        ratio = moments.mean_hz / moments.nominal_hz
    cost = np.nan_to_num(np.abs(np.log(measured[:, None] / (modes.frequency_hz * ratio)[None, :])), nan=1e3)
    # each measured mode may also stay unpaired, at the window's cost: one odd mode then does not push the
    # others one model mode along
    window = np.log(1.0 + PAIR_WINDOW)
    rows, cols = linear_sum_assignment(np.hstack([cost, np.where(np.eye(n_meas, dtype=bool), window, 1e6)]))
    pairing = np.zeros(n_meas, int)
    unpaired = np.ones(n_meas, bool)
    paired = cols < count
    pairing[rows[paired]] = cols[paired]
    unpaired[rows[paired]] = False
    return Baseline(frame, model, modes, pairing, ratio, count, unpaired)

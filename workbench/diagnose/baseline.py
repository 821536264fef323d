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

__all__ = ["EXTRA_MODES", "Baseline", "baseline"]

EXTRA_MODES = 3  # model modes beyond the measured count, for the pairing


@dataclass(frozen=True)
class Baseline:
    """The nominal model, its modes and their pairing with the measured modes.

    Attributes
    ----------
    frame, model : the nominal frame (or matrix model) and its assembled model (the matrix model itself).
    modes : its first ``count`` modes.
    pairing : (n_measured,) index of the model mode paired with each measured mode.
    mean_ratio : (count,) E[f] / f(E[Y]) per model mode (1 with deterministic joints).
    count : model modes solved (measured modes + `EXTRA_MODES`, at most the model's size - 2).
    """

    frame: Frame | MatrixModel
    model: Structure
    modes: Modes
    pairing: np.ndarray
    mean_ratio: np.ndarray
    count: int

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
    """The baseline of ``frame`` against the observations (module docstring)."""
    model = structure_of(frame)
    n_meas = obs.frequency_hz.shape[1]
    count = min(n_meas + EXTRA_MODES, model.size - 2)
    modes = structure_modes(model, count)
    ratio = np.ones(count)
    if any(j.cov > 0 for j in frame.joints):
        moments = adaptive(model, joint_model(model), count)
        ratio = moments.mean_hz / moments.nominal_hz
    measured = np.nanmean(obs.frequency_hz, axis=0)
    cost = np.abs(np.log(measured[:, None] / (modes.frequency_hz * ratio)[None, :]))
    rows, cols = linear_sum_assignment(np.nan_to_num(cost, nan=1e3))
    pairing = np.empty(n_meas, int)
    pairing[rows] = cols
    return Baseline(frame, model, modes, pairing, ratio, count)

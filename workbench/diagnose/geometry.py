"""The frame's geometry as a model-form error: how the measured modes move when a member end is off.

A frame file's coordinates were measured, not known. Each member end's x and y is taken as uncertain by
`workbench.diagnose.observations.GEOMETRY_SD`, independently; moving one by a small step in the nominal model
(`workbench.model.frame.moved_frame`: the points along a member and the joints' spans keep their fractions of
its length) and solving its modes again gives each measured mode's relative change, a column of the
`workbench.diagnose.observations.Discrepancy`'s ``geometry``. A bending mode moves as the inverse square of its
member's length, so half a millimetre on a 0.4 m frame is a few tenths of a percent, mode by mode: the
per-mode floor alone would read it as a gap.
"""

from __future__ import annotations

import numpy as np

from workbench.diagnose.baseline import Baseline
from workbench.diagnose.observations import GEOMETRY_SD
from workbench.model.frame import Frame, member_ends, moved_frame
from workbench.model.structure import structure_modes, structure_of

__all__ = ["STEP_M", "geometry_columns"]

STEP_M = 1e-4  # m, the forward difference's step: the change is linear over it to 1e-3 of itself


def geometry_columns(base: Baseline, sd_m: float = GEOMETRY_SD) -> np.ndarray | None:
    """(n_measured, 2 n_ends): each measured mode's relative frequency change per ``sd_m`` (m) of each member
    end's x and y, by forward differences on the nominal model; None for a matrix model (no geometry).

    Each moved model's modes are paired with the baseline's paired modes by the nearest frequency in ratio (a
    step of 0.1 mm moves no mode past its neighbour but in a pair closer than 1e-3, where the two are one
    mode to the pairing anyway).
    """
    if not isinstance(base.frame, Frame):
        return None
    frame = base.frame
    f0 = base.modes.frequency_hz[base.pairing]
    columns = []
    for name in member_ends(frame):
        for axis in range(2):
            step = (STEP_M, 0.0) if axis == 0 else (0.0, STEP_M)
            moved, _ = moved_frame(frame, {name: step})
            f = structure_modes(structure_of(moved), base.count).frequency_hz
            nearest = f[np.argmin(np.abs(np.log(f[None, :] / f0[:, None])), axis=1)]
            columns.append((nearest / f0 - 1.0) * (sd_m / STEP_M))
    return np.array(columns).T

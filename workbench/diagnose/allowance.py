"""The as-built beyond its stated allowance: the frequency channel's test along the discrepancy's own columns.

The frame's geometry and sections enter the gap tests as model-form error (`workbench.diagnose.observations`,
``geometry`` and ``sections``): each member end's x and y, each member's second moment of area and area, known
to the allowance the user states, carried to the modes by the nominal model's sensitivities. The omnibus test
spreads its power over every direction a residual could take, and the targeted test looks along the
vocabulary's candidates; neither looks along these columns themselves. A column built a few millimetres off
the drawing, or one member's section several of its tolerances thicker, moves the modes along one such column
by more than its allowance, and neither test sees a 1 % shift of that shape: the diagnosis read it as ``none``
(proving ground, seeds 19 to 27: 17 of 20 medium moved columns, every medium thicker member).

So each column ``c`` (the change of the relative means per one stated sd) is tested as a candidate is: the
chi-square's drop when the residual may move along it freely, ``(c' W r)^2 / (c' W c)`` with ``W`` the inverse
of the covariance that already holds the column's own allowance, read as chi-square with one degree of freedom,
the least p-value of the columns made family-wise by its law under no effect (`workbench.diagnose.family`, min-p).
Under the stated allowance a column's share of the residual is one standard deviation of chance, so the test
rejects only where one member end or one section sits several allowances off: a gap the model, as drawn and
toleranced, does not cover. No candidate of the vocabulary has that form; the verdict is then ``unexplained``
unless one explains the gap (`workbench.diagnose.decision`). On development seeds 9003 to 9006 it found 2 of
the 12 medium out-of-vocabulary cases read ``none``, no single effect the other tests missed, and no no-effect
campaign (least family-wise p-value 0.036 over 37); its level is the other tests' (`GAP_LEVEL`), not tuned.
"""

from __future__ import annotations

import numpy as np

from workbench.diagnose.family import NullFamily, Tangent, one_dof_tail
from workbench.diagnose.observations import Observations

__all__ = ["allowance_evidence"]


def allowance_evidence(obs: Observations, baseline_hz: np.ndarray) -> dict | None:
    """The allowance test (module docstring) of the relative residuals of ``baseline_hz`` (n_cond, n_modes), Hz:
    the column whose drop is least likely (``direction``: ``<point>.x``, ``<member>.second_moment``, ...), its
    drop (``chi2_drop``), the family-wise ``p_value`` over the ``columns`` tried; None without a frame's columns.
    """
    d = obs.discrepancy
    parts = [(c, names) for c, names in ((d.geometry, d.geometry_names), (d.sections, d.section_names))
             if c is not None]
    if not parts:
        return None
    for c, group in parts:
        if c.shape[1] != len(group):
            raise ValueError(f"allowance_evidence: {c.shape[1]} columns for {len(group)} names")
    present, cov = obs.joint_covariance(np.ones(obs.frequency_hz.shape[1], bool))
    mode = np.nonzero(present)[1]
    columns = np.hstack([c for c, _ in parts])[mode]  # one error per column, shared by the conditions
    moves = np.any(columns != 0.0, axis=0)  # a member end whose move changes no measured mode
    names = [n for n, m in zip((n for _, group in parts for n in group), moves) if m]
    columns = columns[:, moves]
    if not names:
        return None
    w = np.linalg.inv(cov)
    r = (baseline_hz / obs.frequency_hz - 1.0)[present]  # the chi-square's residual (`frequency_chi2_many`)
    along = columns.T @ w @ r
    information = np.einsum("ij,ik,kj->j", columns, w, columns)
    drops = along ** 2 / information
    best = int(np.argmax(drops))
    family = NullFamily([Tangent(columns[:, [j]], (False,)) for j in range(len(names))], [one_dof_tail] * len(names),
                        cov)
    return {"direction": names[best], "chi2_drop": float(drops[best]),
            "p_value": family.adjusted(float(one_dof_tail(drops[best]))), "columns": len(names)}

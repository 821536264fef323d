"""The ``identification.json`` record of an identification (CONTRACTS.md section 3)."""

from __future__ import annotations

from collections.abc import Iterable
from typing import Any

import numpy as np

from workbench.model.frame import Frame
from workbench.model.matrix_model import MatrixModel

__all__ = ["BOUND_TOLERANCE", "RHAT_LIMIT", "ESS_LIMIT", "settled", "identification_record", "bound_failures",
           "sampler_diagnostics"]

# a Bayesian fit whose group mean leans on the region where its forward model holds (Posterior.trust_reached)
TRUST_EDGE_FAILURE = ("its group's posterior mean modulus reaches the edge of the region where the Laplace "
                      "likelihood's anchored forward model holds, after anchoring again where the posterior was "
                      "(a per-mode discrepancy can stand in for the joints' means when there are few modes for "
                      "the joints: --errors common leaves it out)")
# CONTRACTS.md section 3: an estimate within 1 % of a bound of its search interval is a failed identification
BOUND_TOLERANCE = 0.01
# a sampled estimate is stood behind when every parameter's R-hat is at most this and its bulk
# effective sample size at least that (Vehtari et al. 2021's thresholds)
RHAT_LIMIT = 1.01
ESS_LIMIT = 400


def settled(rhat: Any, ess: Any) -> bool:
    """Every parameter's R-hat at most `RHAT_LIMIT` and its bulk ESS at least `ESS_LIMIT`: the one rule
    by which the chains run on, a posterior says it converged and the command refuses it.
    """
    return bool(np.all(np.asarray(rhat) <= RHAT_LIMIT) and np.all(np.asarray(ess) >= ESS_LIMIT))


def identification_record(campaign_name: str, method: str, frame: Frame | MatrixModel, fit: Any,
                          modes_used: Iterable[int], wall_time_s: float) -> dict:
    """The ``identification.json`` structure of CONTRACTS.md section 3.

    ``fit`` either has ``joint_records()`` (the ``joints`` block itself, e.g. a Bayesian
    `workbench.identify.bayes.Posterior`) or ``groups`` (`workbench.identify.data.JointGroups` of
    ``frame``), ``mean_pa`` and ``cov`` ((n_groups,) each) and optionally ``mean_ci95`` /
    ``cov_ci95`` ((n_groups, 2) or None), as a `workbench.identify.moments.MomentFit`. Every joint
    of a group gets its group's values; joints are keyed by name, in the frame's order.

    Parameters
    ----------
    campaign_name, method : written as given.
    frame : the campaign's frame.
    fit : the identification's result (above).
    modes_used : mode numbers (1 = lowest) the fit used.
    wall_time_s : the identification's wall time, s.
    """
    if hasattr(fit, "joint_records"):
        joints = fit.joint_records()
    else:
        groups = fit.groups
        n = len(frame.joints)
        if sorted(j for members in groups.members for j in members) != list(range(n)):
            raise ValueError(f"{frame.source}: fit groups {groups.members} do not cover the frame's {n} joints")
        mean_ci, cov_ci = getattr(fit, "mean_ci95", None), getattr(fit, "cov_ci95", None)

        def pair(ci, g):
            return None if ci is None else [float(ci[g][0]), float(ci[g][1])]

        group_of = {j: g for g, members in enumerate(groups.members) for j in members}
        joints = {name: {"youngs_modulus": float(fit.mean_pa[group_of[j]]), "cov": float(fit.cov[group_of[j]]),
                               "youngs_modulus_ci95": pair(mean_ci, group_of[j]), "cov_ci95": pair(cov_ci, group_of[j])}
                  for j, name in enumerate(frame.joint_names) if j in group_of}
    if set(joints) == set(frame.joint_names):  # a fit lists its joints group by group: written in the frame's order
        joints = {name: joints[name] for name in frame.joint_names}
    if list(joints) != list(frame.joint_names):
        raise ValueError(f"{frame.source}: the fit's joints {list(joints)} are not the frame's "
                         f"{list(frame.joint_names)}")
    for entry in joints.values():
        if _at_bounds(entry, fit):
            entry["at_bound"] = True
    return {"campaign": str(campaign_name), "method": str(method), "joints": joints,
            "modes_used": [int(m) for m in modes_used], "wall_time_s": float(wall_time_s)}


def _at_bounds(entry: dict, fit: Any) -> list[str]:
    """``youngs_modulus at the lower bound 1e+08 Pa``-like phrases for an entry's estimates on their bounds."""
    hits = []
    for key, box, unit in (("youngs_modulus", getattr(fit, "mean_box_pa", None), " Pa"),
                           ("cov", getattr(fit, "cov_box", None), "")):
        if box is None:
            continue
        lo, hi = box
        value = float(entry[key])
        if value <= lo * (1 + BOUND_TOLERANCE):
            hits.append(f"{key} {value:.4g}{unit} is within 1 % of the search interval's lower bound {lo:g}{unit}")
        elif value >= hi * (1 - BOUND_TOLERANCE):
            hits.append(f"{key} {value:.4g}{unit} is within 1 % of the search interval's upper bound {hi:g}{unit}")
    return hits


def bound_failures(record: dict, fit: Any) -> list[str]:
    """One message per joint whose estimate sits on a bound of its search interval (CONTRACTS.md section 3)."""
    return [f"joint {name!r}: {'; '.join(_at_bounds(entry, fit) or [TRUST_EDGE_FAILURE])}"
            for name, entry in record["joints"].items() if entry.get("at_bound")]


def sampler_diagnostics(fit: Any) -> dict | None:
    """``identification.json``'s ``diagnostics`` of a sampled fit, or None for a fit with no chains.

    ``{"rhat_max", "ess_min", "converged", "limits"}``: ``converged`` is False unless every
    parameter's R-hat is at most `RHAT_LIMIT` and its bulk ESS at least `ESS_LIMIT`, so that a
    reader sees an unconverged posterior for what it is.
    """
    rhat, ess = getattr(fit, "rhat", None), getattr(fit, "ess", None)
    if rhat is None or ess is None:
        return None
    rhat_max, ess_min = float(max(rhat)), float(min(ess))
    return {"rhat_max": rhat_max, "ess_min": ess_min,
            "converged": settled(rhat, ess),
            "limits": {"rhat_max": RHAT_LIMIT, "ess_min": ESS_LIMIT}}

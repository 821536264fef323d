"""What every estimator reads, and the checks it makes before any work.

The measured modes of a campaign are one `workbench.extraction.records.MeasuredModes`: every test's
frequencies, or one row of published means with their deviations. `check_moments` refuses a
record whose moments cannot be identified from. `JointGroups` says which joints share one
stochastic model (the frame file's ``group``: the paper's vertical-beam and horizontal-beam joints).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from workbench.extraction.records import MeasuredModes
from workbench.model.frame import Frame, Joint
from workbench.model.matrix_model import MatrixJoint
from workbench.model.structure import Structure

__all__ = ["Values", "JointGroups", "joint_groups", "usable_modes", "check_moments", "resolve_groups", "per_group",
           "check_box", "check_modes"]

Values = float | Sequence[float] | np.ndarray
"""One value per joint group (or one for all): a number, a sequence or an array."""


@dataclass(frozen=True)
class JointGroups:
    """Joints sharing one stochastic model: ``members[g]`` holds the joints of group ``groups[g]``.

    Attributes
    ----------
    groups : group names, in the order of first appearance in the frame.
    members : for each group, the indices of its joints in ``frame.joints``.
    nominal_pa : for each group, the frame file's mean modulus of its joints (they must agree), Pa.
    """

    groups: tuple[str, ...]
    members: tuple[tuple[int, ...], ...]
    nominal_pa: tuple[float, ...]

    def per_joint(self, values: np.ndarray, n_joints: int) -> np.ndarray:
        """Spread one value per group (a mean modulus, a CoV) to one per joint, (n_joints,)."""
        out = np.zeros(n_joints)
        for g, joints in enumerate(self.members):
            out[list(joints)] = values[g]
        return out


def joint_groups(frame: Frame | Structure) -> JointGroups:
    """The frame's joint groups; joints of one group must have the same file modulus.

    Raises
    ------
    ValueError
        A frame without joints, or a group whose joints disagree on their mean modulus.
    """
    joints: Sequence[Joint | MatrixJoint] = frame.joints
    if not joints:
        raise ValueError(f"{frame.source}: joints: the frame has no joint to identify")
    order: list[str] = []
    members: dict[str, list[int]] = {}
    for i, joint in enumerate(joints):
        if joint.group not in members:
            order.append(joint.group)
            members[joint.group] = []
        members[joint.group].append(i)
    nominal = []
    for g in order:
        moduli = {joints[i].youngs_modulus for i in members[g]}
        if len(moduli) > 1:
            raise ValueError(f"{frame.source}: joints: group {g!r} mixes mean moduli {sorted(moduli)}")
        nominal.append(moduli.pop())
    return JointGroups(tuple(order), tuple(tuple(members[g]) for g in order), tuple(nominal))


def usable_modes(measured: MeasuredModes) -> tuple[MeasuredModes, list[int]]:
    """``measured`` without the modes extracted in fewer than 2 tests, and their numbers.

    Such a mode has no sample deviation, and `check_moments` refuses it; the command line leaves it
    out with a warning instead, so that one mode the circle fit lost does not cost the campaign
    (identification.json's ``modes_used`` lists what was used). Published moments are returned whole.
    """
    if not measured.has_tests:
        return measured, []
    keep = np.sum(np.isfinite(measured.frequency_hz), axis=0) >= 2
    if keep.all() or not keep.any():  # nothing to leave out, or nothing left: check_moments says which
        return measured, []
    return measured.select(keep), [int(m) for m in np.asarray(measured.modes)[~keep]]


def check_moments(measured: MeasuredModes) -> None:
    """Refuse measured modes whose moments cannot be identified from.

    Per-test records need at least 2 tests and every mode extracted in at least 2 of them (a
    sample deviation); then, as for published moments, one finite positive mean and one finite
    non-negative deviation per mode.

    Raises
    ------
    ValueError
        One line naming ``measured.source``.
    """
    source = measured.source
    if measured.has_tests:
        f = measured.frequency_hz
        if f.shape[0] < 2:
            raise ValueError(f"{source}: at least 2 tests are needed for moments, got {f.shape[0]}")
        counts = np.sum(np.isfinite(f), axis=0)
        if np.any(counts < 2):
            missing = [int(m) for m, c in zip(measured.modes, counts) if c < 2]
            raise ValueError(f"{source}: modes {missing} were extracted in fewer than 2 tests")
    n = np.asarray(measured.modes).size
    mean_hz, std_hz = np.asarray(measured.mean_hz, float), np.asarray(measured.std_hz, float)
    for name, value in (("mean_hz", mean_hz), ("std_hz", std_hz)):
        if value.shape != (n,) or not np.all(np.isfinite(value)):
            raise ValueError(f"{source}: {name}: expected {n} finite values, got {value}")
    if np.any(mean_hz <= 0) or np.any(std_hz < 0):
        raise ValueError(f"{source}: moments must be positive means and non-negative deviations")


def resolve_groups(model: Structure, groups: JointGroups | None) -> JointGroups:
    """``groups``, or the frame's own; each of the frame's joints must be in exactly one group."""
    if not model.joints:
        raise ValueError(f"{model.source}: joints: the frame has no joint to identify")
    groups = groups if groups is not None else joint_groups(model)
    n = len(model.joints)
    if sorted(j for members in groups.members for j in members) != list(range(n)):
        raise ValueError(f"groups: {groups.members} must hold each of the frame's {n} joints once")
    return groups


def per_group(name: str, value: Values, n_groups: int) -> np.ndarray:
    """``value`` as (n_groups,) finite positive floats; a scalar applies to every group."""
    out = np.array(value, float).reshape(-1) if np.ndim(value) else np.full(n_groups, float(np.asarray(value, float)))
    if out.shape != (n_groups,) or not np.all(np.isfinite(out)) or np.any(out <= 0):
        raise ValueError(f"{name}: expected {n_groups} finite positive values (one per group), got {value}")
    return out


def check_box(name: str, bounds: tuple[float, float]) -> tuple[float, float]:
    """``(low, high)`` as floats with ``0 < low < high``, both finite."""
    lo, hi = (float(b) for b in bounds)
    if not (math.isfinite(lo) and math.isfinite(hi) and 0 < lo < hi):
        raise ValueError(f"{name}: expected 0 < low < high, finite, got {bounds}")
    return lo, hi


def check_modes(model: Structure, measured: MeasuredModes) -> np.ndarray:
    """``measured.modes`` as distinct integer model mode numbers (1 = lowest) that ``model`` can solve."""
    modes = np.asarray(measured.modes)
    if modes.size == 0 or not np.all(np.equal(np.mod(modes, 1), 0)) or np.any(modes < 1):
        raise ValueError(f"{measured.source}: modes: expected mode numbers >= 1, got {modes}")
    modes = modes.astype(int)
    if len(set(modes.tolist())) != modes.size:
        raise ValueError(f"{measured.source}: modes: {modes} repeats a mode")
    if modes.max() > model.size - 2:
        raise ValueError(f"{measured.source}: modes: mode {modes.max()} asked of a model with {model.size} dofs")
    return modes

"""Identification of joint models from measured eigenfrequencies: the shared inputs.

`FrequencyData` is what a campaign offers to every estimator (nominal fit, moment matching,
Bayesian): the measured frequencies of each test and mode, or only their published moments.
`JointGroups` says which joints share one stochastic model (the frame file's ``group``: the
paper's vertical-beam and horizontal-beam joints).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

__all__ = ["FrequencyData", "JointGroups", "joint_groups"]


@dataclass(frozen=True)
class FrequencyData:
    """Measured eigenfrequencies for identification.

    Attributes
    ----------
    modes : (n_modes,) mode numbers (1 = lowest) of the model modes the columns pair with.
    mean_hz, std_hz : (n_modes,) sample mean and standard deviation (ddof=1) over the tests, or
        the published moments when no individual test is available.
    frequency_hz : (n_tests, n_modes) each test's frequencies (NaN where a mode was not
        extracted), or None for a campaign with only moments.
    tests : test ids, one per row of ``frequency_hz`` (empty without tests).
    source : where the numbers come from (for messages).
    """

    modes: np.ndarray
    mean_hz: np.ndarray
    std_hz: np.ndarray
    frequency_hz: np.ndarray | None = None
    tests: tuple = ()
    source: str = ""

    def __post_init__(self) -> None:
        n = np.asarray(self.modes).size
        for name in ("mean_hz", "std_hz"):
            value = np.asarray(getattr(self, name), float)
            if value.shape != (n,) or not np.all(np.isfinite(value)):
                raise ValueError(f"{self.source}: {name}: expected {n} finite values, got {value}")
        if np.any(np.asarray(self.mean_hz) <= 0) or np.any(np.asarray(self.std_hz) < 0):
            raise ValueError(f"{self.source}: moments must be positive means and non-negative deviations")
        if self.frequency_hz is not None:
            f = np.asarray(self.frequency_hz, float)
            if f.ndim != 2 or f.shape[1] != n or f.shape[0] != len(self.tests):
                raise ValueError(f"{self.source}: frequency_hz: expected ({len(self.tests)}, {n}), got {f.shape}")

    @property
    def has_tests(self) -> bool:
        return self.frequency_hz is not None

    @property
    def cov(self) -> np.ndarray:
        """Measured coefficient of variation of each mode's frequency."""
        return np.asarray(self.std_hz) / np.asarray(self.mean_hz)

    @classmethod
    def from_tests(cls, tests, modes, frequency_hz, source: str = "") -> FrequencyData:
        """From per-test frequencies (n_tests, n_modes), NaN for missing; moments over the tests."""
        f = np.asarray(frequency_hz, float)
        if f.shape[0] < 2:
            raise ValueError(f"{source}: at least 2 tests are needed for moments, got {f.shape[0]}")
        counts = np.sum(np.isfinite(f), axis=0)
        if np.any(counts < 2):
            missing = [int(m) for m, c in zip(modes, counts) if c < 2]
            raise ValueError(f"{source}: modes {missing} were extracted in fewer than 2 tests")
        return cls(np.asarray(modes), np.nanmean(f, axis=0), np.nanstd(f, axis=0, ddof=1), f, tuple(tests), source)


@dataclass(frozen=True)
class JointGroups:
    """Joints sharing one stochastic model: ``names[g]`` holds the joints of group ``groups[g]``.

    Attributes
    ----------
    groups : group names, in the order of first appearance in the frame.
    members : for each group, the indices of its joints in ``frame.joints``.
    nominal_pa : for each group, the frame file's mean modulus of its joints (they must agree).
    """

    groups: tuple[str, ...]
    members: tuple[tuple[int, ...], ...]
    nominal_pa: tuple[float, ...]

    def gamma_scale(self, mean_pa: np.ndarray, n_joints: int) -> np.ndarray:
        """Per-joint ``gamma`` that puts each group's mean modulus at ``mean_pa`` (n_groups,)."""
        scale = np.ones(n_joints)
        for g, joints in enumerate(self.members):
            scale[list(joints)] = mean_pa[g] / self.nominal_pa[g]
        return scale

    def per_joint(self, values: np.ndarray, n_joints: int) -> np.ndarray:
        """Spread one value per group (e.g. a CoV) to one per joint."""
        out = np.zeros(n_joints)
        for g, joints in enumerate(self.members):
            out[list(joints)] = values[g]
        return out


def joint_groups(frame) -> JointGroups:
    """The frame's joint groups; joints of one group must have the same file modulus.

    Raises
    ------
    ValueError
        A frame without joints, or a group whose joints disagree on their mean modulus.
    """
    if not frame.joints:
        raise ValueError(f"{frame.source}: joints: the frame has no joint to identify")
    order: list[str] = []
    members: dict[str, list[int]] = {}
    for i, joint in enumerate(frame.joints):
        if joint.group not in members:
            order.append(joint.group)
            members[joint.group] = []
        members[joint.group].append(i)
    nominal = []
    for g in order:
        moduli = {frame.joints[i].youngs_modulus for i in members[g]}
        if len(moduli) > 1:
            raise ValueError(f"{frame.source}: joints: group {g!r} mixes mean moduli {sorted(moduli)}")
        nominal.append(moduli.pop())
    return JointGroups(tuple(order), tuple(tuple(members[g]) for g in order), tuple(nominal))

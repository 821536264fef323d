"""`MeasuredModes`: the one record of a campaign's measured modes.

Extraction writes it (circle fit of every test, or a campaign's ``modes.csv``, or its published
moments), identification reads its frequencies, the diagnosis its frequencies, damping and
excitation amplitudes, and the report all of it. Nothing else holds "the modes of a test".
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace

import numpy as np

__all__ = ["MeasuredModes"]


def _table(value: np.ndarray | None, shape: tuple[int, ...], name: str) -> np.ndarray | None:
    if value is None:
        return None
    array = np.ascontiguousarray(np.atleast_2d(np.asarray(value)))
    if array.shape[:2] != shape:
        raise ValueError(f"{name}: shape {array.shape} differs from frequency_hz {shape}")
    return array


@dataclass(frozen=True)
class MeasuredModes:
    """Measured modes of a campaign: one row per test, or one row of published means.

    Attributes
    ----------
    frequency_hz : (n_rows, n_modes) natural frequencies, Hz; NaN where a mode was not found (or its
        fit is unusable). For published moments, one row of the published means.
    modes : (n_modes,) 1-based numbers of the model modes the columns pair with (default 1..n).
    damping_ratio : (n_rows, n_modes) viscous modal damping ratios, or None (None too when all NaN).
    tests : test ids, one per row; empty for published moments.
    amplitude : (n_tests,) excitation amplitude relative to the campaign's lowest level (scaled so
        that its minimum is 1), or None when the campaign has no amplitude factor.
    published_std_hz : (n_modes,) published standard deviations, Hz, when the row is published
        means (paper Table 3); None for per-test data.
    tests_count : number of tests behind published means.
    frequency_scatter_hz, damping_scatter : (n_rows, n_modes) spread of the estimate over the
        sensors combined (circle fit), or None when not known.
    flags : per row, per mode, the circle fit's quality flags (empty when not known).
    modal_constants : (n_rows, n_modes, n_sensors) complex receptance modal constants, 1/kg, or None.
    sensors : the names of ``modal_constants``' sensors, in its order; empty when they are the model's
        sensors in the file's order.
    source : where the numbers come from, for messages.
    design : (n_tests, n_columns) the tests' designed factors other than the amplitude, coded 0/1 per level
        but each factor's first, or None: the scatter the design puts between tests is not chance.
    """

    frequency_hz: np.ndarray
    modes: np.ndarray = None  # type: ignore[assignment]  # filled in __post_init__
    damping_ratio: np.ndarray | None = None
    tests: tuple[str, ...] = ()
    amplitude: np.ndarray | None = None
    published_std_hz: np.ndarray | None = None
    tests_count: int | None = None
    frequency_scatter_hz: np.ndarray | None = field(default=None, repr=False)
    damping_scatter: np.ndarray | None = field(default=None, repr=False)
    flags: tuple[tuple[tuple[str, ...], ...], ...] = field(default=(), repr=False)
    modal_constants: np.ndarray | None = field(default=None, repr=False)
    sensors: tuple[str, ...] = ()
    source: str = ""
    design: np.ndarray | None = field(default=None, repr=False)

    def __post_init__(self) -> None:
        where = f"{self.source}: " if self.source else ""
        # row-major arrays whatever their source (pivot tables, column selections): reductions over
        # the tests then round alike to the last bit, so the same data give the same moments
        f = np.ascontiguousarray(np.atleast_2d(np.asarray(self.frequency_hz, float)))
        object.__setattr__(self, "frequency_hz", f)
        if f.size == 0 or np.all(np.isnan(f)):
            raise ValueError(f"{where}frequency_hz: no measured frequency")
        if np.any(f[~np.isnan(f)] <= 0) or np.any(np.isinf(f)):
            raise ValueError(f"{where}frequency_hz: frequencies must be finite and positive")
        n_rows, n_modes = f.shape
        modes = np.arange(1, n_modes + 1) if self.modes is None else np.asarray(self.modes)
        if modes.shape != (n_modes,):
            raise ValueError(f"{where}modes: expected {n_modes} mode numbers, got {modes}")
        object.__setattr__(self, "modes", modes)
        if self.tests and len(self.tests) != n_rows:
            raise ValueError(f"{where}tests: {len(self.tests)} ids for {n_rows} rows of frequencies")
        d = _table(None if self.damping_ratio is None else np.asarray(self.damping_ratio, float), f.shape,
                   where + "damping_ratio")
        object.__setattr__(self, "damping_ratio", None if d is None or np.all(np.isnan(d)) else d)
        for name in ("frequency_scatter_hz", "damping_scatter", "modal_constants"):
            object.__setattr__(self, name, _table(getattr(self, name), f.shape, where + name))
        if self.design is not None:
            design = np.asarray(self.design, float)
            if design.ndim != 2 or design.shape[0] != n_rows or not np.all(np.isfinite(design)):
                raise ValueError(f"{where}design: expected {n_rows} rows of finite numbers, got shape {design.shape}")
            object.__setattr__(self, "design", design)
        if self.sensors and self.modal_constants is not None and len(self.sensors) != self.modal_constants.shape[-1]:
            raise ValueError(f"{where}sensors: {len(self.sensors)} names for {self.modal_constants.shape[-1]} "
                             "sensors of modal constants")
        if self.amplitude is not None:
            a = np.asarray(self.amplitude, float)
            if a.shape != (n_rows,) or not np.all(np.isfinite(a)) or np.any(a <= 0):
                raise ValueError(f"{where}amplitude: expected {n_rows} finite positive values, got {a}")
            object.__setattr__(self, "amplitude", a / a.min())
        if self.published_std_hz is not None:
            s = np.asarray(self.published_std_hz, float)
            if n_rows != 1 or s.shape != (n_modes,) or not np.all(np.isfinite(s)) or np.any(s < 0):
                raise ValueError(f"{where}std_hz: expected {n_modes} finite non-negative values beside one row "
                                 f"of means, got {s}")
            object.__setattr__(self, "published_std_hz", s)

    def select(self, keep: np.ndarray) -> MeasuredModes:
        """The record restricted to the modes (columns) where ``keep`` (n_modes,) is true."""
        keep = np.asarray(keep, bool)
        if keep.shape != (self.count,):
            raise ValueError(f"keep: expected {self.count} booleans, got shape {keep.shape}")

        def columns(a: np.ndarray | None) -> np.ndarray | None:
            return None if a is None else a[:, keep]

        return replace(self, frequency_hz=self.frequency_hz[:, keep], modes=self.modes[keep],
                       damping_ratio=columns(self.damping_ratio),
                       published_std_hz=None if self.published_std_hz is None else self.published_std_hz[keep],
                       frequency_scatter_hz=columns(self.frequency_scatter_hz),
                       damping_scatter=columns(self.damping_scatter),
                       flags=tuple(tuple(f for f, k in zip(row, keep) if k) for row in self.flags),
                       modal_constants=columns(self.modal_constants))

    @property
    def published(self) -> bool:
        """True when the record holds published moments, not individual tests."""
        return self.published_std_hz is not None

    @property
    def has_tests(self) -> bool:
        """True when every test's frequencies are known (not only published moments)."""
        return not self.published

    @property
    def count(self) -> int:
        """Number of modes (columns)."""
        return int(self.frequency_hz.shape[1])

    @property
    def mean_hz(self) -> np.ndarray:
        """(n_modes,) mean frequency over the tests (NaN-aware), or the published means, Hz."""
        if self.published:
            return self.frequency_hz[0]
        return np.nanmean(self.frequency_hz, axis=0)

    @property
    def std_hz(self) -> np.ndarray:
        """(n_modes,) sample standard deviation (ddof 1, NaN-aware) over the tests, or the published one, Hz."""
        if self.published_std_hz is not None:
            return self.published_std_hz
        return np.nanstd(self.frequency_hz, axis=0, ddof=1)

    @property
    def cov(self) -> np.ndarray:
        """(n_modes,) coefficient of variation of each mode's frequency."""
        return self.std_hz / self.mean_hz

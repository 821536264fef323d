"""Exact frequencies of the frame changed by one effect, on a grid of the effect's parameter.

Each candidate is the nominal frame changed by `workbench.rig.effects.apply_effect` (a matrix
model by `apply_matrix_effect`) with one parameter. The frequencies are computed exactly at each
grid value, tracked by MAC from the no-effect end outward, and interpolated by a cubic spline in
the parameter (or its logarithm), so that fits are then cheap.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np
import scipy.sparse as sp
from scipy.interpolate import CubicSpline

from workbench.diagnose.baseline import Baseline
from workbench.model.assembly import assemble
from workbench.model.matrix_model import MatrixModel
from workbench.model.modal import Modes, solve_modes
from workbench.model.structure import Structure
from workbench.rig.effects import Effect, EffectKind, apply_effect, apply_matrix_effect
from workbench.uq.stochastic import track_modes

__all__ = ["Curve", "sweep"]


@dataclass(frozen=True)
class Curve:
    """Exact frequencies of the frame changed by one effect, on a grid of its parameter.

    Attributes
    ----------
    effect, where, parameter : the effect's name, its place and the parameter of the grid.
    values : (n_grid,) parameter values, increasing, in the parameter's unit.
    frequency_hz : (n_grid, count) model frequencies, Hz, tracked to the baseline's modes.
    log : the spline runs in log(value).
    fixed : further parameters of the effect, the same on the whole grid.
    """

    effect: str
    where: str | None
    parameter: str
    values: np.ndarray
    frequency_hz: np.ndarray
    log: bool
    fixed: dict = field(default_factory=dict)

    def coordinate(self, value: float | np.ndarray) -> np.ndarray:
        """The spline's coordinate of parameter values: log(value) or value."""
        return np.log(value) if self.log else np.asarray(value, float)

    def parameters(self, u: float) -> dict:
        """The effect's parameters at the spline coordinate ``u``."""
        value = float(math.exp(u)) if self.log else float(u)
        return {self.parameter: value, **self.fixed}

    def interpolant(self) -> CubicSpline:
        """Model frequencies as a function of `coordinate`, NaN outside the grid."""
        # a cubic spline: 5 to 20 times closer to exact solves between grid points than PCHIP here
        return CubicSpline(self.coordinate(self.values), self.frequency_hz, axis=0, extrapolate=False)


def _model(base: Baseline, kind: EffectKind, where: str | None, value: float, fixed: dict) -> Structure:
    effect = Effect(kind.name, where, {kind.parameter or "": float(value), **fixed})
    return (apply_matrix_effect(base.frame, effect) if isinstance(base.frame, MatrixModel)
            else assemble(apply_effect(base.frame, effect)))


def _affine(base: Baseline, kind: EffectKind, where: str | None, values: np.ndarray, start: int,
            fixed: dict) -> Callable[[float], tuple[sp.spmatrix, sp.spmatrix]]:
    """``K(v), M(v)`` of the changed frame on the grid.

    Most effects change K or M linearly in their parameter (a spring, a mass, a joint's modulus, an axial
    force's geometric stiffness): then two assemblies give every grid value, ``A(v) = A_0 + (v - v_0) dA``,
    instead of one per value (assembly was as long as the eigen-solve). Linearity is checked, not assumed:
    a third assembly at the grid's middle must match the line to 1e-9 of the matrices' size, else every value
    is assembled.
    """
    v0, v1 = float(values[start]), float(values[-1] if start != values.size - 1 else values[0])
    a, b = _model(base, kind, where, v0, fixed), _model(base, kind, where, v1, fixed)
    k0, m0, k1, m1 = a.stiffness(), a.mass, b.stiffness(), b.mass
    exact = lambda v: (lambda s: (s.stiffness(), s.mass))(_model(base, kind, where, v, fixed))  # noqa: E731
    if k0.shape != k1.shape:
        return exact
    dk, dm = (k1 - k0) / (v1 - v0), (m1 - m0) / (v1 - v0)
    vm = float(values[(start + (values.size - 1 if start == 0 else 0)) // 2])
    km, mm = exact(vm)
    if km.shape != k0.shape:
        return exact
    for got, line in ((km, k0 + (vm - v0) * dk), (mm, m0 + (vm - v0) * dm)):
        scale = max(abs(got).max(), 1e-300)
        if abs(got - line).max() > 1e-9 * scale:
            return exact
    return lambda v: (k0 + (v - v0) * dk, m0 + (v - v0) * dm)


def sweep(base: Baseline, kind: EffectKind, where: str | None, values: np.ndarray, start: int, log: bool,
          fixed: dict | None = None) -> Curve | None:
    """Solve the changed frame at each grid value, from ``values[start]`` (no effect) outward.

    Parameters
    ----------
    base : the baseline (nominal frame and mode count).
    kind : the effect; its ``parameter`` runs over ``values`` (in its unit).
    where : the effect's place.
    values : (n_grid,) increasing parameter values.
    start : index of the value without effect, where the modes are the baseline's in order.
    log : interpolate in log(value).
    fixed : further parameters of the effect.

    Returns
    -------
    The curve on the grid values where the frame could be solved (a buckled or singular frame
    ends the grid), or None with fewer than 4 of them.
    """
    parameter = kind.parameter
    if parameter is None:
        raise ValueError(f"sweep: {kind.name} has no parameter to sweep")
    fixed = dict(fixed or {})
    out = np.full((values.size, base.count), np.nan)
    try:
        matrices = _affine(base, kind, where, values, start, fixed)
    except ValueError:
        return None

    def solve(v: float) -> tuple[sp.spmatrix, Modes]:
        k, m = matrices(v)
        modes = solve_modes(k, m, base.count + 2)
        if modes.eigenvalues[0] <= 0.0:
            raise ValueError("buckled")
        return m, modes

    try:
        mass, modes = solve(values[start])
    except ValueError:
        return None
    order = np.arange(base.count)  # next to the no-effect end, the order is the baseline's
    first = Modes(modes.eigenvalues[order], modes.shapes[:, order])
    out[start] = first.frequency_hz
    for direction in (1, -1):
        previous = first
        i = start + direction
        while 0 <= i < values.size:
            try:
                mass, modes = solve(values[i])
            except ValueError:  # buckled or singular: the grid ends here
                break
            index, _ = track_modes(previous, modes, mass)
            previous = Modes(modes.eigenvalues[index], modes.shapes[:, index])
            out[i] = previous.frequency_hz
            i += direction
    ok = ~np.isnan(out[:, 0])
    if ok.sum() < 4:
        return None
    return Curve(kind.name, where, parameter, values[ok], out[ok], log, fixed)

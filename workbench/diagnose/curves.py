"""Exact frequencies of the frame changed by one effect, on a grid of the effect's parameter.

Each candidate is the nominal frame changed by `workbench.rig.effects.apply_effect` (a matrix
model by `apply_matrix_effect`) with one parameter. The frequencies are computed exactly at each
grid value, tracked by MAC from the no-effect end outward, and interpolated by a cubic spline in
the parameter (or its logarithm), so that fits are then cheap. Each grid is a `Sweep`, a task that
`solve_sweeps` hands to a `workbench.tasks.Mapper`: the grids are independent, and on a 12-test campaign
they are most of the diagnosis's time.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np
import scipy.linalg as sla
import scipy.sparse as sp
from scipy.interpolate import CubicSpline
from scipy.sparse.linalg import splu

from workbench.diagnose.baseline import Baseline
from workbench.model.assembly import assemble
from workbench.model.matrix_model import MatrixModel
from workbench.model.modal import SHIFT, Modes, solve_modes
from workbench.model.structure import Structure
from workbench.rig.effects import EFFECTS, Effect, EffectKind, apply_effect, apply_matrix_effect
from workbench.tasks import Mapper, serial
from workbench.uq.stochastic import track_modes

__all__ = ["Curve", "Sweep", "solve_sweeps", "sweep"]

RITZ_COLUMNS = 40  # a linear change touching more dofs enters the basis by the loads it puts on the modes
RITZ_KRYLOV = 4  # block Krylov levels of the changed dofs in the Ritz basis
RITZ_GUARD = 8  # start modes beyond twice the count kept in the Ritz basis
RITZ_TOLERANCE = 1e-7  # relative frequency error allowed at the grid's ends against exact solves


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
    nominal : the parameter's value without the effect (the grid's start), or None when not known.
    """

    effect: str
    where: str | None
    parameter: str
    values: np.ndarray
    frequency_hz: np.ndarray
    log: bool
    fixed: dict = field(default_factory=dict)
    nominal: float | None = None

    def coordinate(self, value: float | np.ndarray) -> np.ndarray:
        """The spline's coordinate of parameter values: log(value) or value."""
        return np.log(value) if self.log else np.asarray(value, float)

    def parameters(self, u: float) -> dict:
        """The effect's parameters at the spline coordinate ``u``."""
        value = float(math.exp(u)) if self.log else float(u)
        return {self.parameter: value, **self.fixed}

    @property
    def form(self) -> str:
        """Which form of the effect at its place: the swept parameter and the fixed ones (`CandidateFit.form`)."""
        return ",".join([self.parameter, *(f"{k}={v:.6g}" if isinstance(v, float) else f"{k}={v}"
                                           for k, v in sorted(self.fixed.items()))])

    def interpolant(self) -> CubicSpline:
        """Model frequencies as a function of `coordinate`, NaN outside the grid."""
        # a cubic spline: 5 to 20 times closer to exact solves between grid points than PCHIP here
        return CubicSpline(self.coordinate(self.values), self.frequency_hz, axis=0, extrapolate=False)


def _model(base: Baseline, kind: EffectKind, where: str | None, value: float, fixed: dict, parameter: str) -> Structure:
    effect = Effect(kind.name, where, {parameter: float(value), **fixed})
    return (apply_matrix_effect(base.frame, effect) if isinstance(base.frame, MatrixModel)
            else assemble(apply_effect(base.frame, effect)))


def _affine(base: Baseline, kind: EffectKind, where: str | None, values: np.ndarray, start: int,
            fixed: dict, parameter: str) -> Callable[[float], tuple[sp.spmatrix, sp.spmatrix]]:
    """``K(v), M(v)`` of the changed frame on the grid.

    Most effects change K or M linearly in their parameter (a spring, a mass, a joint's modulus, an axial
    force's geometric stiffness): then two assemblies give every grid value, ``A(v) = A_0 + (v - v_0) dA``,
    instead of one per value (assembly was as long as the eigen-solve). Linearity is checked, not assumed:
    a third assembly at the grid's middle must match the line to 1e-9 of the matrices' size, else every value
    is assembled.
    """
    v0, v1 = float(values[start]), float(values[-1] if start != values.size - 1 else values[0])
    a, b = _model(base, kind, where, v0, fixed, parameter), _model(base, kind, where, v1, fixed, parameter)
    k0, m0, k1, m1 = a.stiffness(), a.mass, b.stiffness(), b.mass
    exact = lambda v: (lambda s: (s.stiffness(), s.mass))(_model(base, kind, where, v, fixed, parameter))  # noqa: E731
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
    return _Line(v0, k0, m0, dk, dm)


@dataclass(frozen=True)
class _Line:
    """``K(v) = K_0 + (v - v_0) dK``, ``M(v)`` likewise: an effect linear in its parameter."""

    v0: float
    k0: sp.spmatrix
    m0: sp.spmatrix
    dk: sp.spmatrix
    dm: sp.spmatrix

    def __call__(self, v: float) -> tuple[sp.spmatrix, sp.spmatrix]:
        return self.k0 + (v - self.v0) * self.dk, self.m0 + (v - self.v0) * self.dm


def _ritz_sweep(line: _Line, values: np.ndarray, start: int, count: int) -> np.ndarray | None:
    """(n_grid, count) tracked frequencies, Hz, from one Ritz basis, or None when it is not exact enough.

    A change linear in its parameter acts through the few columns of dK and dM: the start's modes (with a
    guard) plus the responses of the start to those columns, static and `RITZ_KRYLOV` - 1 further block
    Krylov levels, span the changed low modes closely (component mode synthesis with the residual
    flexibility's next terms), so every grid value is a small dense eigenproblem instead of a sparse
    solve. Checked, not assumed: at both ends of the grid the Ritz frequencies must match exact solves to
    `RITZ_TOLERANCE`, else None (the caller solves every value).
    """
    change = (abs(line.dk) + abs(line.dm)).tocsc()
    columns = np.flatnonzero(np.diff(change.indptr))
    n = line.k0.shape[0]
    if columns.size == 0 or 2 * count + RITZ_GUARD >= n - 1:
        return None
    start_modes = solve_modes(line.k0, line.m0, 2 * count + RITZ_GUARD)
    if columns.size <= RITZ_COLUMNS:  # the changed dofs themselves
        block = sp.csc_matrix((np.ones(columns.size), (columns, np.arange(columns.size))),
                              shape=(n, columns.size)).toarray()
    else:  # a change spread over many dofs (a member's geometric stiffness): the loads it puts on the low modes
        low = start_modes.shapes[:, :count + 2]
        block = np.hstack([line.dk @ low, line.dm @ low])
        block = block[:, np.linalg.norm(block, axis=0) > 0.0]
    factor = splu((line.k0 - SHIFT * line.m0).tocsc())
    blocks = [start_modes.shapes, factor.solve(block)]
    for _ in range(RITZ_KRYLOV - 1):  # (K^-1 M)^j K^-1 of the columns: the change's dynamic, not only static, reach
        blocks.append(factor.solve(line.m0 @ np.linalg.qr(blocks[-1])[0]))
    basis, _ = np.linalg.qr(np.hstack(blocks))
    reduced = [basis.T @ (a @ basis) for a in (line.k0, line.m0, line.dk, line.dm)]

    def reduced_at(v: float) -> tuple[np.ndarray, np.ndarray]:
        k, m = reduced[0] + (v - line.v0) * reduced[2], reduced[1] + (v - line.v0) * reduced[3]
        return 0.5 * (k + k.T), 0.5 * (m + m.T)

    def solve(v: float) -> Modes:
        """Modes in the basis' coordinates: their MAC in the reduced mass is the full one (V' M V = M_r)."""
        w, y = sla.eigh(*reduced_at(v), subset_by_index=[0, count + 1])
        return Modes(w, y)

    out = np.full((values.size, count), np.nan)
    first = solve(values[start])
    if first.eigenvalues[0] <= 0.0:
        return None
    out[start] = first.frequency_hz[:count]
    for direction in (1, -1):
        previous = Modes(first.eigenvalues[:count], first.shapes[:, :count])
        i = start + direction
        while 0 <= i < values.size:
            modes = solve(values[i])
            if modes.eigenvalues[0] <= 0.0:  # buckled: the grid ends here, as for exact solves
                break
            index, _ = track_modes(previous, modes, reduced_at(values[i])[1])
            previous = Modes(modes.eigenvalues[index], modes.shapes[:, index])
            out[i] = previous.frequency_hz
            i += direction
    solved = np.flatnonzero(np.isfinite(out[:, 0]))
    for i in {int(solved[0]), int(solved[-1])} - {start}:  # the last values solved each way
        exact = solve_modes(*line(values[i]), count + 2)
        error = solve(values[i]).frequency_hz[:count] / exact.frequency_hz[:count] - 1.0  # the same lowest modes
        if exact.eigenvalues[0] <= 0.0 or np.max(np.abs(error)) > RITZ_TOLERANCE:
            return None
    return out


def sweep(base: Baseline, kind: EffectKind, where: str | None, values: np.ndarray, start: int, log: bool,
          fixed: dict | None = None, swept: str | None = None) -> Curve | None:
    """Solve the changed frame at each grid value, from ``values[start]`` (no effect) outward.

    Parameters
    ----------
    base : the baseline (nominal frame and mode count).
    kind : the effect; its ``parameter`` (or ``swept``) runs over ``values`` (in its unit).
    where : the effect's place.
    values : (n_grid,) increasing parameter values.
    start : index of the value without effect, where the modes are the baseline's in order.
    log : interpolate in log(value).
    fixed : further parameters of the effect.
    swept : the parameter that runs over ``values`` when not the effect's own (a support's ``ux`` or ``uy``).

    Returns
    -------
    The curve on the grid values where the frame could be solved (a buckled or singular frame
    ends the grid), or None with fewer than 4 of them.
    """
    parameter = swept or kind.parameter
    if parameter is None:
        raise ValueError(f"sweep: {kind.name} has no parameter to sweep")
    fixed = dict(fixed or {})
    try:
        matrices = _affine(base, kind, where, values, start, fixed, parameter)
    except ValueError:
        return None

    def solve(v: float) -> tuple[sp.spmatrix, Modes]:
        k, m = matrices(v)
        modes = solve_modes(k, m, base.count + 2)
        if modes.eigenvalues[0] <= 0.0:
            raise ValueError("buckled")
        return m, modes

    out = _ritz_sweep(matrices, values, start, base.count) if isinstance(matrices, _Line) else None
    if out is None:
        try:
            _, modes = solve(values[start])
        except ValueError:
            return None
        out = _exact_sweep(solve, values, start, base.count, modes)
    ok = ~np.isnan(out[:, 0])
    if ok.sum() < 4:
        return None
    return Curve(kind.name, where, parameter, values[ok], out[ok], log, fixed, float(values[start]))


def _exact_sweep(solve: Callable[[float], tuple[sp.spmatrix, Modes]], values: np.ndarray, start: int, count: int,
                 modes: Modes) -> np.ndarray:
    """(n_grid, count) tracked frequencies, Hz, one sparse solve per grid value from ``modes`` at the start."""
    out = np.full((values.size, count), np.nan)
    order = np.arange(count)  # next to the no-effect end, the order is the baseline's
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
    return out


@dataclass(frozen=True)
class Sweep:
    """One candidate's grid: `sweep`'s arguments but the baseline (a task `solve_sweeps` hands out).

    ``effect`` is the effect's name in `workbench.rig.effects.EFFECTS`; the rest as in `sweep`.
    """

    effect: str
    where: str | None
    values: np.ndarray
    start: int
    log: bool
    fixed: dict = field(default_factory=dict)
    swept: str | None = None


def _solve_sweep(base: Baseline, task: Sweep) -> Curve | None:
    return sweep(base, EFFECTS[task.effect], task.where, task.values, task.start, task.log, task.fixed, task.swept)


def solve_sweeps(base: Baseline, tasks: list[Sweep], mapper: Mapper | None = None) -> list[Curve]:
    """The curves of ``tasks`` that could be solved, in their order, each grid a task of ``mapper`` (default:
    one after the other in this process) with ``base`` shared.
    """
    curves = (mapper or serial)(_solve_sweep, tasks, "candidate grids", base)
    return [c for c in curves if c is not None]

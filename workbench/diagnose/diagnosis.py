"""Sim-to-real gap diagnosis: where the nominal model misses, which effect explains it, how far it shrinks.

The paper (section 5.2) ends with a gap it cannot close: the four-bolt frame's mean frequencies are
over-estimated, and the authors suspect the beam model, the boundary conditions, the joint model
or stress locked in by the tightening sequence. This module answers with the vocabulary of
CONTRACTS.md section 3 (`workbench.rig.effects`).

**Observations.** The tests are grouped by excitation amplitude (one condition when the campaign
has no amplitude factor). For each condition ``c`` and measured mode ``i``: the mean frequency
and, when measured, the mean damping ratio. Their standard errors come from the scatter of the
tests about a straight line in amplitude (a mean when there is one condition), divided by the
square root of the condition's test count, with a relative floor (`ModalData.relative_floor`,
1e-4 for circle-fit frequencies: the extraction's bias at 40 dB is 3e-5). Published means with a
published std use ``std / sqrt(tests)``.

**Baseline.** The frame file's model with its joints at their mean, its frequencies multiplied by
the ratio of the stochastic mean (adaptive SMR, eq. 12-13, with the file's joint CoVs) to the
nominal frequency, since a campaign's mean is E[f], not f(E[Y]). Measured modes are paired with
model modes by frequency (an assignment on |log f_measured / f_model|), once, on the baseline.
Damping baseline: one modal damping ratio for every mode, fitted (the frame file's ratio is a
placeholder, not a model).

**Where** (`localise`): the relative frequency residuals are projected on the sensitivity of each
mode to a relative change of each region's stiffness (its share of the mode's strain energy,
``0.5 * phi^T K_R phi / lambda``) or mass (``-0.5 * phi^T M_R phi``): members, joints, support
springs, named points (a mass there, or a spring at the excitation point). A region's score is
the share of the weighted residual a one-parameter change of that region explains (a squared
cosine, 0 to 1). Joints are also scored on the damping residuals against their energy share.

**Which** (`diagnose`): each effect of the vocabulary, at each place it can sit, is the nominal
frame changed by `workbench.rig.effects.apply_effect` with one parameter (a support's rotational
stiffness, a mass, a shear coefficient, a stinger stiffness, an axial force, a joint's modulus
factor, a softening slope, a joint loss factor); added masses also choose their position along
a member. The exact frequencies are computed on a grid of the parameter, tracked by MAC from
the no-effect end, and interpolated (PCHIP); fits are then cheap.

**Held-out protocol: leave one mode out.** For each measured mode, every candidate is refitted on
the other modes and predicts that mode (all its conditions, frequency and damping). The held-out
error is the error of those predictions. A candidate that fits by bending one parameter to noise
predicts the held-out modes badly; the effect that is present predicts them. The baseline has no
frequency parameter, so its held-out frequency error is its in-sample error. Candidates are
ranked by their total held-out chi-square (frequency and damping, each residual over its standard
error); the ranking also lists the BIC, ``chi2 + p ln N``.

**Verdict.** ``none`` when the baseline's chi-square per observation is within `GAP_RATIO` of 1 on
both frequency and damping. Otherwise the best-ranked candidate, if its held-out chi-square per
observation on the data it acts on is within `EXPLAINED_RATIO` (the gap is then explained down to
measurement scatter) and it shrinks the held-out error by at least `MIN_SHRINKAGE`; else
``unexplained``: a real gap remains that no candidate of the vocabulary brings to the scatter.
``shrinkage = 1 - heldout error after / baseline error`` on the held-out data, the RMS of the
relative frequency errors (the RMS of the damping errors for ``joint_damping``).
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np
from scipy.interpolate import CubicSpline
from scipy.optimize import linear_sum_assignment, minimize_scalar
from scipy.sparse.linalg import splu

from workbench.model.assembly import assemble, element_energies, joint_energies
from workbench.rig.effects import Effect, apply_effect
from workbench.model.frame import Frame, member_length
from workbench.model.modal import Modes, model_modes
from workbench.uq.stochastic import track_modes

__all__ = ["GAP_RATIO", "EXPLAINED_RATIO", "MIN_SHRINKAGE", "ModalData", "Observations", "Region",
           "CandidateFit", "Diagnosis", "observations", "localise", "diagnose", "diagnosis_record", "members_at"]

GAP_RATIO = 4.0  # baseline chi2 per observation above this: a gap beyond scatter
EXPLAINED_RATIO = 10.0  # held-out chi2 per observation at most this: explained down to scatter
MIN_SHRINKAGE = 0.3  # and the held-out error must shrink by at least this much
GRID_POINTS = 33
EXTRA_MODES = 3  # model modes beyond the measured count, for the pairing


@dataclass(frozen=True)
class ModalData:
    """Measured modes of a campaign.

    Attributes
    ----------
    frequency_hz : (n_tests, n_modes) natural frequencies, Hz; NaN where a mode was not found.
    damping_ratio : (n_tests, n_modes) or None.
    amplitude : (n_tests,) excitation amplitude relative to the campaign's lowest level (>= 1), or
        None when the campaign has no amplitude factor.
    std_hz : (n_modes,) published std of the frequencies, for published means (one row).
    tests_count : number of tests behind published means.
    relative_floor : floor of the relative standard error of a mean frequency.
    damping_floor : floor of the relative standard error of a mean damping ratio.
    modes : (n_modes,) 1-based labels of the measured modes.
    """

    frequency_hz: np.ndarray
    damping_ratio: np.ndarray | None = None
    amplitude: np.ndarray | None = None
    std_hz: np.ndarray | None = None
    tests_count: int | None = None
    relative_floor: float = 1e-4
    damping_floor: float = 0.02
    modes: np.ndarray | None = None

    def __post_init__(self) -> None:
        f = np.atleast_2d(np.asarray(self.frequency_hz, float))
        object.__setattr__(self, "frequency_hz", f)
        if f.size == 0 or np.all(np.isnan(f)):
            raise ValueError("frequency_hz: no measured frequency")
        if np.any(f[~np.isnan(f)] <= 0) or np.any(np.isinf(f)):
            raise ValueError("frequency_hz: frequencies must be finite and positive")
        if self.damping_ratio is not None:
            d = np.atleast_2d(np.asarray(self.damping_ratio, float))
            if d.shape != f.shape:
                raise ValueError(f"damping_ratio: shape {d.shape} differs from frequency_hz {f.shape}")
            object.__setattr__(self, "damping_ratio", None if np.all(np.isnan(d)) else d)
        if self.amplitude is not None:
            a = np.asarray(self.amplitude, float)
            if a.shape != (f.shape[0],) or not np.all(np.isfinite(a)) or np.any(a <= 0):
                raise ValueError(f"amplitude: expected {f.shape[0]} finite positive values, got {a}")
            object.__setattr__(self, "amplitude", a / a.min())
        if self.modes is None:
            object.__setattr__(self, "modes", np.arange(1, f.shape[1] + 1))


@dataclass(frozen=True)
class Observations:
    """Condition means and their standard errors (module docstring).

    ``amplitude`` (n_cond,); ``frequency_hz``, ``frequency_se`` (n_cond, n_modes);
    ``frequency_cov`` (n_cond, n_modes, n_modes) of the relative errors of the means; ``damping``,
    ``damping_se`` likewise or None; NaN marks a missing mean.
    """

    amplitude: np.ndarray
    frequency_hz: np.ndarray
    frequency_se: np.ndarray
    frequency_cov: np.ndarray  # (n_cond, n_modes, n_modes) of the relative errors of the means
    damping: np.ndarray | None
    damping_se: np.ndarray | None


def _condition_means(values: np.ndarray, amplitude: np.ndarray, floor_rel: float,
                     published_std: np.ndarray | None, tests_count: int | None):
    """Condition means, their standard errors and the relative covariance of each condition's means.

    The tests' deviations from a straight line in amplitude (a mean with one condition) give the
    covariance across modes of one test: a joint whose modulus scatters from test to test moves
    every mode at once, so the errors of the means are correlated, and a chi-square that ignored
    it would read a chance joint scatter as a gap.
    """
    levels = np.unique(amplitude)
    means = np.array([np.nanmean(np.where((amplitude == a)[:, None], values, np.nan), axis=0) for a in levels])
    counts = np.array([np.sum(~np.isnan(values[amplitude == a]), axis=0) for a in levels])
    design = np.stack([np.ones_like(amplitude), amplitude], axis=1) if levels.size > 1 else np.ones((amplitude.size, 1))
    deviation = np.zeros_like(values)
    dof = np.zeros(values.shape[1])
    for k in range(values.shape[1]):
        ok = ~np.isnan(values[:, k])
        if not ok.any():
            continue
        dof[k] = ok.sum() - np.linalg.matrix_rank(design[ok])
        if dof[k] >= 1:
            coef = np.linalg.lstsq(design[ok], values[ok, k], rcond=None)[0]
            deviation[ok, k] = (values[ok, k] - design[ok] @ coef) / np.nanmean(values[ok, k])
    usable = dof >= 1
    covariance = np.zeros((values.shape[1],) * 2)
    if usable.any():
        d = np.where(usable, deviation, 0.0)
        covariance = d.T @ d / np.sqrt(np.outer(np.maximum(dof, 1), np.maximum(dof, 1)))
    if published_std is not None:  # published means: their std, no correlation known
        rel = np.asarray(published_std, float) / np.nanmean(values, axis=0)
        covariance = np.where(np.diag(usable), covariance, np.diag(rel ** 2))
        counts = np.maximum(counts, tests_count or 1)
    n = np.maximum(counts, 1)
    cov_means = np.array([covariance / np.sqrt(np.outer(n[c], n[c])) + np.diag(np.full(values.shape[1], floor_rel ** 2))
                          for c in range(levels.size)])
    se = np.sqrt(np.array([np.diag(c) for c in cov_means])) * np.abs(means)
    return levels, means, se, cov_means


def observations(data: ModalData) -> Observations:
    """Condition means, standard errors and covariances of a campaign's modes (module docstring)."""
    n_tests = data.frequency_hz.shape[0]
    amplitude = data.amplitude if data.amplitude is not None else np.ones(n_tests)
    levels, f, f_se, f_cov = _condition_means(data.frequency_hz, amplitude, data.relative_floor, data.std_hz,
                                              data.tests_count)
    d = d_se = None
    if data.damping_ratio is not None:
        _, d, d_se, _ = _condition_means(data.damping_ratio, amplitude, data.damping_floor, None, None)
    return Observations(levels, f, f_se, f_cov, d, d_se)


def _frequency_chi2(obs: Observations, predicted_hz: np.ndarray, mask: np.ndarray | None = None,
                    cache: dict | None = None) -> float:
    """``sum_c r_c^T C_c^-1 r_c`` of the relative residuals over the modes in ``mask``."""
    r = predicted_hz / obs.frequency_hz - 1.0
    mask = np.ones(r.shape[1], bool) if mask is None else mask
    total = 0.0
    for c in range(r.shape[0]):
        idx = mask & ~np.isnan(r[c])
        key = (c, idx.tobytes())
        if cache is None or key not in cache:
            w = np.linalg.inv(obs.frequency_cov[c][np.ix_(idx, idx)])
            if cache is not None:
                cache[key] = w
        else:
            w = cache[key]
        total += float(r[c, idx] @ w @ r[c, idx])
    return total


# ------------------------------------------------------------------------------------------- model

@dataclass(frozen=True)
class _Baseline:
    frame: Frame
    model: object
    modes: Modes
    pairing: np.ndarray  # (n_measured,) model mode of each measured mode
    mean_ratio: np.ndarray  # (n_model,) E[f] / f(E[Y]) per model mode
    count: int

    def frequency(self, model_hz: np.ndarray) -> np.ndarray:
        """Predicted campaign means of the measured modes from model frequencies (..., n_model)."""
        return (model_hz * self.mean_ratio)[..., self.pairing]


def _baseline(frame: Frame, obs: Observations) -> _Baseline:
    model = assemble(frame)
    n_meas = obs.frequency_hz.shape[1]
    count = min(n_meas + EXTRA_MODES, model.size - 2)
    modes = model_modes(model, count)
    ratio = np.ones(count)
    if any(j.cov > 0 for j in frame.joints):
        from workbench.uq.smr import adaptive
        from workbench.uq.stochastic import joint_model

        moments = adaptive(model, joint_model(frame), count)
        ratio = moments.mean_hz / moments.nominal_hz
    measured = np.nanmean(obs.frequency_hz, axis=0)
    cost = np.abs(np.log(measured[:, None] / (modes.frequency_hz * ratio)[None, :]))
    rows, cols = linear_sum_assignment(np.nan_to_num(cost, nan=1e3))
    pairing = np.empty(n_meas, int)
    pairing[rows] = cols
    return _Baseline(frame, model, modes, pairing, ratio, count)


@dataclass(frozen=True)
class _Curve:
    """Exact frequencies of the frame changed by one effect, on a grid of its parameter."""

    effect: str
    where: str | None
    parameter: str
    values: np.ndarray  # (n_grid,) parameter values, increasing
    frequency_hz: np.ndarray  # (n_grid, n_model) tracked to the baseline's modes
    log: bool
    fixed: dict = field(default_factory=dict)

    def coordinate(self, value):
        return np.log(value) if self.log else np.asarray(value, float)

    def interpolant(self) -> CubicSpline:
        # a cubic spline: 5 to 20 times closer to exact solves between grid points than PCHIP here
        return CubicSpline(self.coordinate(self.values), self.frequency_hz, axis=0, extrapolate=False)


def _sweep(base: _Baseline, effect: str, where: str | None, parameter: str, values: np.ndarray, start: int,
           log: bool, fixed: dict | None = None) -> _Curve | None:
    """Solve the changed frame at each grid value, from ``values[start]`` (no effect) outward."""
    fixed = dict(fixed or {})
    out = np.full((values.size, base.count), np.nan)

    def solve(v: float):
        frame = apply_effect(base.frame, Effect(effect, where, {parameter: float(v), **fixed}))
        model = assemble(frame)
        return model, model_modes(model, base.count + 2)

    try:
        model, modes = solve(values[start])
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
                model, modes = solve(values[i])
            except ValueError:  # buckled or singular: the grid ends here
                break
            index, _ = track_modes(previous, modes, model.mass)
            previous = Modes(modes.eigenvalues[index], modes.shapes[:, index])
            out[i] = previous.frequency_hz
            i += direction
    ok = ~np.isnan(out[:, 0])
    if ok.sum() < 4:
        return None
    return _Curve(effect, where, parameter, values[ok], out[ok], log, fixed)


def _reference_bending(frame: Frame, point: str) -> tuple[float, float]:
    """EI (N.m2) and length (m) of the first member that starts or ends at ``point``."""
    for m in frame.members:
        if point in (m.start, m.end):
            return (frame.materials[m.material].youngs_modulus * frame.sections[m.section].second_moment,
                    member_length(frame, m))
    m = frame.members[0]
    return frame.materials[m.material].youngs_modulus * frame.sections[m.section].second_moment, member_length(frame, m)


def _frame_curves(base: _Baseline, obs: Observations, residual: np.ndarray, weight: np.ndarray) -> list[_Curve]:
    """One curve per effect and place the frame allows (module docstring)."""
    frame, curves = base.frame, []
    for s in frame.supports:
        if s.rz is None:
            continue
        if math.isinf(s.rz):
            ei, length = _reference_bending(frame, s.point)
            values = ei / length * np.logspace(-2, 3, GRID_POINTS)
        else:
            values = s.rz * np.logspace(-3, 0, GRID_POINTS)
        curves.append(_sweep(base, "support_compliance", s.point, "rz", values, values.size - 1, True))
    if frame.excitation is not None:
        d = base.model.dof(frame.excitation.point, frame.excitation.dof)
        unit = np.zeros(base.model.size)
        unit[d] = 1.0
        k_static = 1.0 / float(splu(base.model.stiffness().tocsc()).solve(unit)[d])
        values = k_static * np.logspace(-4, 1, GRID_POINTS)
        curves.append(_sweep(base, "stinger_stiffness", frame.excitation.point, "stiffness", values, 0, True,
                             {"dof": frame.excitation.dof}))
    for m in frame.members:
        ei = frame.materials[m.material].youngs_modulus * frame.sections[m.section].second_moment
        euler = math.pi ** 2 * ei / member_length(frame, m) ** 2
        values = np.unique(np.concatenate([np.linspace(-0.6, 0.0, 10), np.linspace(0.0, 2.0, 16)])) * euler
        curves.append(_sweep(base, "axial_prestress", m.name, "axial_force", values,
                             int(np.flatnonzero(values == 0.0)[0]), False))
    values = np.logspace(-1, 1, 2 * (GRID_POINTS // 2) + 1)
    for j in frame.joints:
        curves.append(_sweep(base, "joint_stiffness_shift", j.name, "factor", values, values.size // 2, True))
    if len(frame.joints) > 1:  # every joint at once (where null): the file's joint model itself is off
        curves.append(_sweep(base, "joint_stiffness_shift", None, "factor", values, values.size // 2, True))
    if frame.beam_theory != "timoshenko":
        kappa = next((s.shear_coefficient for s in frame.sections.values() if s.shear_coefficient), 5.0 / 6.0)
        values = kappa * np.logspace(-1.5, 2, GRID_POINTS)
        curves.append(_sweep(base, "shear_deformation", None, "shear_coefficient", values, values.size - 1, True))
    curves.extend(_mass_curves(base, obs, residual, weight))
    return [c for c in curves if c is not None]


def _mass_curves(base: _Baseline, obs: Observations, residual: np.ndarray, weight: np.ndarray,
                 keep: int = 3, reach_m: float = 0.03) -> list[_Curve]:
    """Added-mass curves at the few positions whose mass sensitivity best fits the residual.

    The first-order screen ranks every mesh node; around each of the ``keep`` best (5 cm apart),
    the nodes within ``reach_m`` are fitted on a coarse exact grid and the best one gets the
    full grid: the screen is linear, a mass of 10 % of the frame is not.
    """
    frame, model, mesh = base.frame, base.model, base.model.mesh
    shapes = model.expand(base.modes.shapes)[:, base.pairing]
    translation = shapes[0::3] ** 2 + shapes[1::3] ** 2  # (n_nodes, n_measured): -0.5 m T per kg
    scores = np.array([_explained(-0.5 * translation[node], residual, weight) for node in range(len(mesh.node_xy))])
    total_mass = float(model.mass.diagonal()[0::3].sum())
    coarse = total_mass * np.logspace(-3.5, 0, 13)
    chosen, curves = [], []
    for node in np.argsort(scores)[::-1]:
        if len(chosen) == keep:
            break
        if _place(frame, mesh, int(node)) is None or any(
                np.hypot(*(mesh.node_xy[node] - mesh.node_xy[c])) < 0.05 for c in chosen):
            continue
        chosen.append(int(node))
        near = [n for n in range(len(mesh.node_xy)) if np.hypot(*(mesh.node_xy[n] - mesh.node_xy[node])) <= reach_m
                and _place(frame, mesh, n) is not None]
        best, best_cost = None, np.inf
        for n in near:
            where, fixed = _place(frame, mesh, n)
            cost = _mass_cost(base, obs, where, fixed, coarse)
            if cost < best_cost:
                best, best_cost = (where, fixed), cost
        if best is not None and "position" in best[1]:
            best = _refine_position(base, obs, best[0], best[1]["position"], coarse, frame)[0]
        elif best is not None:  # a named point: the mass may sit a few mm off it, along a member through it
            for member, position in _positions_of_point(frame, best[0]):
                refined, cost = _refine_position(base, obs, member, position, coarse, frame)
                if cost < best_cost:
                    best, best_cost = refined, cost
        if best is not None:
            values = total_mass * np.logspace(-3.5, 0, GRID_POINTS)
            curves.append(_sweep(base, "added_mass", best[0], "mass", values, 0, True, best[1]))
    return curves


def _mass_cost(base: _Baseline, obs: Observations, where: str, fixed: dict, masses: np.ndarray) -> float:
    curve = _sweep(base, "added_mass", where, "mass", masses, 0, True, fixed)
    return np.inf if curve is None else _fit_curve(base, obs, curve, np.ones(obs.frequency_hz.shape[1], bool))[2]


def _refine_position(base: _Baseline, obs: Observations, member: str, position: float, masses: np.ndarray,
                     frame: Frame) -> tuple[tuple[str, dict], float]:
    """Position of a mass between mesh nodes: a bounded scalar search within one element each side."""
    step = frame.element_length / member_length(frame, frame.member(member))
    lo, hi = max(position - step, 0.005), min(position + step, 0.995)
    res = minimize_scalar(lambda x: _mass_cost(base, obs, member, {"position": float(x)}, masses),
                          bounds=(lo, hi), method="bounded", options={"xatol": 1e-4, "maxiter": 12})
    return (member, {"position": round(float(res.x), 4)}), float(res.fun)


def members_at(frame: Frame, name: str | None) -> list[tuple[str, float]]:
    """Members a frame name stands on, with its position along each (fraction of the length from the start).

    A member is itself (position None); a point, every member whose segment holds it; a joint, its member.
    """
    if name is None:
        return []
    if any(m.name == name for m in frame.members):
        return [(name, None)]
    if name in frame.points:
        x, y = frame.points[name]
        out = []
        for m in frame.members:
            (x0, y0), (x1, y1) = frame.points[m.start], frame.points[m.end]
            length = math.hypot(x1 - x0, y1 - y0)
            off = abs((x1 - x0) * (y - y0) - (y1 - y0) * (x - x0)) / length
            along = ((x - x0) * (x1 - x0) + (y - y0) * (y1 - y0)) / length
            if off < 1e-9 * length and -1e-9 * length <= along <= length * (1 + 1e-9):
                out.append((m.name, along / length))
        return out
    return [(j.member, None) for j in frame.joints if j.name == name]


def _positions_of_point(frame: Frame, point: str) -> list[tuple[str, float]]:
    return [(m, p) for m, p in members_at(frame, point) if p is not None]


def _place(frame: Frame, mesh, node: int) -> tuple[str, dict] | None:
    """A mesh node as a named point, or as a member and a position along it (None on a support)."""
    supported = {s.point for s in frame.supports}
    for name, n in mesh.point_node.items():
        if n == node:
            return (None if name in supported else (name, {}))
    member = int(mesh.element_member[np.flatnonzero((mesh.connectivity == node).any(axis=1))[0]])
    m = frame.members[member]
    x0 = np.asarray(frame.points[m.start])
    position = float(np.hypot(*(mesh.node_xy[node] - x0)) / member_length(frame, m))
    return m.name, {"position": round(position, 4)}


def _explained(direction: np.ndarray, residual: np.ndarray, weight: np.ndarray) -> float:
    """Share of the weighted residual a multiple of ``direction`` explains (squared cosine)."""
    ok = ~np.isnan(residual) & ~np.isnan(direction)
    a, r, w = direction[ok], residual[ok], weight[ok]
    denominator = float(np.sum(w * a * a) * np.sum(w * r * r))
    return float(np.sum(w * a * r) ** 2 / denominator) if denominator > 0 else 0.0


# --------------------------------------------------------------------------------------- localise

@dataclass(frozen=True)
class Region:
    """A region of the frame and how much of the residual a change of it explains."""

    region: str
    kind: str  # member, joint, support, point
    mechanism: str  # stiffness, mass, damping
    score: float


def _energy_shares(base: _Baseline) -> tuple[np.ndarray, np.ndarray]:
    """Each joint's share of the measured modes' strain energy, and of each member's outside joints."""
    model, shapes = base.model, base.modes.shapes[:, base.pairing]
    rest, per_joint = joint_energies(model, shapes)
    total = rest + per_joint.sum(axis=0)
    per_element = element_energies(model, shapes)
    outside = model.mesh.element_joint < 0
    members = np.array([per_element[outside & (model.mesh.element_member == i)].sum(axis=0)
                        for i in range(len(model.frame.members))])
    return per_joint / total, members / total


def localise(base: _Baseline, obs: Observations, predicted_hz: np.ndarray,
             damping_residual: np.ndarray | None = None,
             shares: tuple[np.ndarray, np.ndarray] | None = None) -> list[Region]:
    """Regions scored by the share of the residual their stiffness, mass or damping explains.

    ``shares``: `_energy_shares` of the baseline when the caller has them already.
    """
    frame, model, mesh = base.frame, base.model, base.model.mesh
    residual = (obs.frequency_hz / predicted_hz - 1.0).mean(axis=0)
    weight = 1.0 / np.nanmean((obs.frequency_se / obs.frequency_hz) ** 2, axis=0)
    shapes = model.expand(base.modes.shapes)[:, base.pairing]
    lam = base.modes.eigenvalues[base.pairing]
    joint_share, member_share = shares if shares is not None else _energy_shares(base)
    regions = []
    lengths = mesh.element_lengths()
    for i, m in enumerate(frame.members):
        regions.append(Region(m.name, "member", "stiffness", _explained(0.5 * member_share[i], residual, weight)))
        rho_a = frame.materials[m.material].density * frame.sections[m.section].area
        elements = np.flatnonzero(mesh.element_member == i)
        nodal = np.zeros(len(mesh.node_xy))
        np.add.at(nodal, mesh.connectivity[elements].ravel(), np.repeat(0.5 * rho_a * lengths[elements], 2))
        kinetic = nodal @ (shapes[0::3] ** 2 + shapes[1::3] ** 2)
        regions.append(Region(m.name, "member", "mass", _explained(-0.5 * kinetic, residual, weight)))
    for j, joint in enumerate(frame.joints):
        regions.append(Region(joint.name, "joint", "stiffness", _explained(0.5 * joint_share[j], residual, weight)))
        if damping_residual is not None and obs.damping is not None:
            d_weight = 1.0 / np.nanmean(obs.damping_se ** 2, axis=0)
            centred = joint_share[j] - np.average(joint_share[j], weights=d_weight)
            regions.append(Region(joint.name, "joint", "damping", _explained(centred, damping_residual, d_weight)))
    for s in frame.supports:
        if s.rz is not None and not math.isinf(s.rz):
            phi = shapes[3 * mesh.point_node[s.point] + 2]
            regions.append(Region(s.point, "support", "stiffness", _explained(0.5 * s.rz * phi ** 2 / lam, residual, weight)))
    supported = {s.point for s in frame.supports}
    for name, node in mesh.point_node.items():
        if name in supported:
            continue
        regions.append(Region(name, "point", "mass", _explained(-0.5 * (shapes[3 * node] ** 2 + shapes[3 * node + 1] ** 2),
                                                                 residual, weight)))
        if frame.excitation is not None and frame.excitation.point == name:
            phi = shapes[3 * node + ("ux", "uy", "rz").index(frame.excitation.dof)]
            regions.append(Region(name, "point", "stiffness", _explained(0.5 * phi ** 2 / lam, residual, weight)))
    best: dict[tuple[str, str], Region] = {}
    for r in regions:  # one entry per region: its best mechanism
        if (r.region, r.kind) not in best or r.score > best[(r.region, r.kind)].score:
            best[(r.region, r.kind)] = r
    return sorted(best.values(), key=lambda r: -r.score)


# ---------------------------------------------------------------------------------------- diagnose

@dataclass(frozen=True)
class CandidateFit:
    """One effect at one place, fitted: in-sample and held-out errors (module docstring)."""

    effect: str
    where: str | None
    parameters: dict
    channel: str  # "frequency" or "damping": the data it changes
    chi2: float  # in-sample, frequency + damping
    heldout_chi2: float
    heldout_chi2_frequency: float
    heldout_chi2_damping: float
    freq_rms_rel_error: float
    heldout_freq_rms_rel_error: float
    damping_rms_error: float | None
    heldout_damping_rms_error: float | None
    parameter_count: int
    bic: float


@dataclass(frozen=True)
class Diagnosis:
    """Everything `diagnosis_record` writes, plus the arrays the report plots."""

    modes: np.ndarray  # measured mode labels
    amplitude: np.ndarray
    measured_hz: np.ndarray  # (n_cond, n_modes)
    frequency_se_hz: np.ndarray
    baseline_hz: np.ndarray  # (n_cond, n_modes)
    best_hz: np.ndarray | None  # the verdict's in-sample prediction, or None
    baseline: CandidateFit
    ranking: list[CandidateFit]
    localisation: list[Region]
    verdict: str
    where: str | None
    shrinkage: float
    observations_count: dict
    wall_time_s: float = 0.0


def _chi2(residual: np.ndarray, se: np.ndarray) -> float:
    z = residual / se
    return float(np.nansum(z * z))


def _rms(x: np.ndarray) -> float:
    return float(np.sqrt(np.nanmean(x * x))) if np.any(~np.isnan(x)) else float("nan")


class _Frequencies:
    """Predicted condition means as a function of one parameter, fitted by a scan and Brent."""

    def __init__(self, base: _Baseline, obs: Observations, curve: _Curve, amplitude_joint: bool = False):
        self.base, self.obs, self.curve, self.amplitude = base, obs, curve, amplitude_joint
        self.spline = curve.interpolant()
        if amplitude_joint:  # gamma(a) = 1 - c a, c up to 0.9 of what would zero the modulus
            lowest = float(curve.values.min())
            c_max = (1.0 - max(lowest, 0.1)) / float(obs.amplitude.max())
            self.lo, self.hi = 0.0, c_max
        else:
            u = curve.coordinate(curve.values)
            self.lo, self.hi = float(u.min()), float(u.max())

    def predict(self, u: float) -> np.ndarray:
        if self.amplitude:
            model_hz = self.spline(np.log(1.0 - u * self.obs.amplitude))  # (n_cond, n_model)
        else:
            model_hz = np.broadcast_to(self.spline(u), (self.obs.amplitude.size, self.base.count))
        return self.base.frequency(np.asarray(model_hz))

    def fit(self, modes_mask: np.ndarray) -> tuple[float, np.ndarray]:
        u, predicted, _ = self.fit_cost(modes_mask)
        return u, predicted

    def fit_cost(self, modes_mask: np.ndarray) -> tuple[float, np.ndarray, float]:
        f = self.obs.frequency_hz[:, modes_mask]
        cache: dict = {}

        def cost(u: float) -> float:
            p = self.predict(u)
            if not np.all(np.isfinite(p[:, modes_mask][~np.isnan(f)])):
                return np.inf
            return _frequency_chi2(self.obs, p, modes_mask, cache)

        grid = np.linspace(self.lo, self.hi, 161)
        costs = np.array([cost(u) for u in grid])
        i = int(np.argmin(costs))
        a, b = grid[max(i - 1, 0)], grid[min(i + 1, grid.size - 1)]
        if b > a:
            res = minimize_scalar(cost, bounds=(a, b), method="bounded", options={"xatol": 1e-6 * (self.hi - self.lo)})
            u = float(res.x) if res.fun <= costs[i] else float(grid[i])
        else:
            u = float(grid[i])
        return u, self.predict(u), cost(u)


def _fit_curve(base: _Baseline, obs: Observations, curve: _Curve, modes_mask: np.ndarray):
    return _Frequencies(base, obs, curve).fit_cost(modes_mask)


def _damping_fit(obs: Observations, share: np.ndarray | None, modes_mask: np.ndarray) -> tuple[np.ndarray, dict]:
    """Least squares of ``zeta = c0 (+ eta * share)``, eta >= 0; predictions on every mode."""
    d, se = obs.damping[:, modes_mask], obs.damping_se[:, modes_mask]
    ok = ~np.isnan(d)
    w = 1.0 / se[ok]
    columns = [np.ones_like(d)]
    if share is not None:
        columns.append(np.broadcast_to(share[modes_mask], d.shape))
    a = np.stack([c[ok] for c in columns], axis=1) * w[:, None]
    coef = np.linalg.lstsq(a, d[ok] * w, rcond=None)[0]
    if share is not None and coef[1] < 0:  # a joint does not remove damping
        coef = np.array([np.sum(d[ok] * w * w) / np.sum(w * w), 0.0])
    full = np.ones_like(obs.damping) * coef[0]
    if share is not None:
        full = full + coef[1] * share[None, :]
    return full, ({"eta": float(coef[1])} if share is not None else {})


def _evaluate(effect: str, where: str | None, parameters_of: Callable[[float], dict], channel: str,
              fit_frequency: Callable[[np.ndarray], tuple[float, np.ndarray]] | None,
              fit_damping: Callable[[np.ndarray], tuple[np.ndarray, dict]] | None,
              obs: Observations, baseline_hz: np.ndarray, p_count: int) -> tuple[CandidateFit, np.ndarray]:
    """In-sample fit and leave-one-mode-out predictions of one candidate."""
    n_modes = obs.frequency_hz.shape[1]
    everything = np.ones(n_modes, bool)
    held_f = np.full_like(obs.frequency_hz, np.nan)
    params: dict = {}
    if fit_frequency is not None:
        u, in_f = fit_frequency(everything)
        params = parameters_of(u)
        for k in range(n_modes):
            mask = everything.copy()
            mask[k] = False
            held_f[:, k] = fit_frequency(mask)[1][:, k]
    else:
        in_f = held_f = baseline_hz
    chi2 = _frequency_chi2(obs, in_f)
    held_chi2_f = _frequency_chi2(obs, held_f)
    held_chi2_d = 0.0
    d_rms = held_d_rms = None
    n_obs = int(np.sum(~np.isnan(obs.frequency_hz)))
    if obs.damping is not None:
        in_d, d_params = fit_damping(everything)
        held_d = np.full_like(obs.damping, np.nan)
        for k in range(n_modes):
            mask = everything.copy()
            mask[k] = False
            held_d[:, k] = fit_damping(mask)[0][:, k]
        if channel == "damping":
            params = d_params
        chi2 += _chi2(in_d - obs.damping, obs.damping_se)
        held_chi2_d = _chi2(held_d - obs.damping, obs.damping_se)
        d_rms, held_d_rms = _rms(in_d - obs.damping), _rms(held_d - obs.damping)
        n_obs += int(np.sum(~np.isnan(obs.damping)))
    fit = CandidateFit(effect, where, params, channel, chi2, held_chi2_f + held_chi2_d, held_chi2_f, held_chi2_d,
                       _rms(in_f / obs.frequency_hz - 1.0), _rms(held_f / obs.frequency_hz - 1.0),
                       d_rms, held_d_rms, p_count, chi2 + p_count * math.log(max(n_obs, 2)))
    return fit, in_f


def diagnose(frame: Frame, data: ModalData, progress: Callable[[str], None] | None = None) -> Diagnosis:
    """Locate, name and measure the gap between ``frame`` and a campaign's modes (module docstring).

    Parameters
    ----------
    frame : the nominal model (the campaign's frame file), joints at their mean modulus.
    data : the measured modes.
    progress : called with a short message before each stage.

    Returns
    -------
    Diagnosis
    """
    import time

    start = time.perf_counter()
    say = progress or (lambda message: None)
    obs = observations(data)
    say("baseline model and pairing")
    base = _baseline(frame, obs)
    baseline_hz = np.broadcast_to(base.frequency(base.modes.frequency_hz), obs.frequency_hz.shape).copy()
    residual = (obs.frequency_hz / baseline_hz - 1.0).mean(axis=0)
    weight = 1.0 / np.nanmean((obs.frequency_se / obs.frequency_hz) ** 2, axis=0)
    shares = _energy_shares(base)
    joint_share = shares[0]
    fit_base_damping = (lambda mask: _damping_fit(obs, None, mask)) if obs.damping is not None else None

    baseline, _ = _evaluate("baseline", None, lambda u: {}, "frequency", None, fit_base_damping, obs, baseline_hz, 0)
    damping_residual = None
    if obs.damping is not None:
        damping_residual = np.nanmean(obs.damping - _damping_fit(obs, None, np.ones(obs.damping.shape[1], bool))[0], axis=0)
    regions = localise(base, obs, baseline_hz, damping_residual, shares)

    say("candidate effects: exact frequencies on parameter grids")
    curves = _frame_curves(base, obs, residual, weight)
    ranking, predictions = [], {}
    for curve in curves:
        model = _Frequencies(base, obs, curve)

        def parameters_of(u, curve=curve):
            value = float(math.exp(u)) if curve.log else float(u)
            return {curve.parameter: value, **curve.fixed}

        fit, in_f = _evaluate(curve.effect, curve.where, parameters_of, "frequency", model.fit, fit_base_damping,
                              obs, baseline_hz, 1 + ("position" in curve.fixed))
        ranking.append(fit)
        predictions[(fit.effect, fit.where)] = in_f
    if obs.amplitude.size > 1:
        for curve in curves:
            if curve.effect != "joint_stiffness_shift":
                continue
            model = _Frequencies(base, obs, curve, amplitude_joint=True)
            fit, in_f = _evaluate("amplitude_softening", curve.where, lambda u: {"slope": float(u)}, "frequency",
                                  model.fit, fit_base_damping, obs, baseline_hz, 1)
            ranking.append(fit)
            predictions[(fit.effect, fit.where)] = in_f
    if obs.damping is not None:
        for j, joint in enumerate(frame.joints):
            fit, _ = _evaluate("joint_damping", joint.name, lambda u: {}, "damping", None,
                               lambda mask, j=j: _damping_fit(obs, joint_share[j], mask), obs, baseline_hz, 1)
            ranking.append(fit)
            predictions[(fit.effect, fit.where)] = baseline_hz
    ranking.sort(key=lambda c: (c.heldout_chi2, c.bic))

    n_f = int(np.sum(~np.isnan(obs.frequency_hz)))
    n_d = int(np.sum(~np.isnan(obs.damping))) if obs.damping is not None else 0
    chi2_f = _frequency_chi2(obs, baseline_hz)
    chi2_d = baseline.chi2 - chi2_f  # the damping baseline's in-sample part
    gap = chi2_f > GAP_RATIO * n_f or (n_d > 1 and chi2_d > GAP_RATIO * (n_d - 1))
    verdict, where, shrinkage, best_hz = "none", None, 0.0, None
    if gap:
        verdict = "unexplained"
        if ranking:
            best = ranking[0]
            shrink = _shrinkage(best, baseline)
            held_channel = _channel_chi2(best, n_f, n_d)
            if held_channel <= EXPLAINED_RATIO and shrink >= MIN_SHRINKAGE:
                verdict, where, shrinkage = best.effect, best.where, shrink
                best_hz = predictions[(best.effect, best.where)]
    return Diagnosis(data.modes, obs.amplitude, obs.frequency_hz, obs.frequency_se, baseline_hz, best_hz, baseline,
                     ranking, regions, verdict, where, shrinkage, {"frequency": n_f, "damping": n_d},
                     time.perf_counter() - start)


def _shrinkage(fit: CandidateFit, baseline: CandidateFit) -> float:
    if fit.channel == "damping":
        return 1.0 - fit.heldout_damping_rms_error / baseline.heldout_damping_rms_error
    return 1.0 - fit.heldout_freq_rms_rel_error / baseline.heldout_freq_rms_rel_error


def _channel_chi2(fit: CandidateFit, n_f: int, n_d: int) -> float:
    """Held-out chi2 per observation on the data the candidate changes."""
    if fit.channel == "damping":
        return fit.heldout_chi2_damping / max(n_d, 1)
    return fit.heldout_chi2_frequency / max(n_f, 1)


def diagnosis_record(campaign_name: str, diagnosis: Diagnosis) -> dict:
    """``diagnosis.json`` (CONTRACTS.md section 3), plus fields a reader may ignore."""
    d = diagnosis
    mean_measured = np.nanmean(d.measured_hz, axis=0)
    mean_model = np.nanmean(d.baseline_hz, axis=0)
    rows = [{"mode": int(m), "measured_hz": float(fm), "model_hz": float(fp), "rel_error": float(fp / fm - 1.0)}
            for m, fm, fp in zip(d.modes, mean_measured, mean_model) if np.isfinite(fm)]

    def entry(c: CandidateFit) -> dict:
        return {"effect": c.effect, "where": c.where, "parameters": c.parameters,
                "freq_rms_rel_error": c.freq_rms_rel_error, "heldout_freq_rms_rel_error": c.heldout_freq_rms_rel_error,
                "damping_rms_error": c.damping_rms_error, "heldout_damping_rms_error": c.heldout_damping_rms_error,
                "chi2": c.chi2, "heldout_chi2": c.heldout_chi2, "bic": c.bic, "parameter_count": c.parameter_count}

    return {
        "campaign": campaign_name,
        "baseline": {"freq_rms_rel_error": d.baseline.freq_rms_rel_error, "modes": rows,
                     "damping_rms_error": d.baseline.damping_rms_error, "chi2": d.baseline.chi2,
                     "observations": d.observations_count},
        "localization": [{"region": r.region, "score": r.score, "kind": r.kind, "mechanism": r.mechanism}
                         for r in d.localisation],
        "ranking": [entry(c) for c in d.ranking],
        "verdict": {"effect": d.verdict, "where": d.where, "shrinkage": d.shrinkage},
        "protocol": "leave one mode out: each candidate refitted on the other modes predicts the held-out mode",
        "wall_time_s": d.wall_time_s,
    }

"""The paper's eq. (1): joint moduli whose model frequencies best match the measured means.

    eps_LS = sum_k (f_k^exp - f_k^EF)^2                                     (eq. 1)

`eq1_residual` is the equation's terms. Two solvers minimise it, for two different jobs, and
both stay because their results are part of what is reported and reproduced:

`nominal_fit` is the identification's nominal fit (Table 2, and the start of the moment matching,
`workbench.identify.moments`): the group moduli minimising eq. (1) in Hz by Nelder-Mead on the
measured means. Unknowns are the log-moduli; the bounds are Nelder-Mead's own (scipy clips the
simplex into the box). A coarse log scan over the whole box, one group at a time, runs first, so
the frame file's modulus is only a starting point: a start 10x off still converges. Modes are
paired by order or by MAC. Other named model parameters (supports, masses) are not fitted here:
that is the diagnosis's job.

`reference_fit` only centres the Bayesian forward table (`workbench.identify.likelihood`):
Gauss-Newton on eq. (1)'s terms in log frequency, with SMR1's exact derivatives and one eigen-solve
per iteration, about ten times cheaper than the scan and simplex. The posterior does not depend on
the centre, but the table's nodes, hence the chains' last bits, do: replacing either solver by
the other would change the published numbers of the estimator that uses it.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
from scipy.optimize import linear_sum_assignment, minimize

from workbench.extraction.records import MeasuredModes
from workbench.identify.data import (
    JointGroups,
    Values,
    check_box,
    check_modes,
    check_moments,
    per_group,
    resolve_groups,
)
from workbench.model.joints import joint_scale
from workbench.model.modal import mac
from workbench.model.structure import Structure, sensor_dofs, structure_modes
from workbench.uq.smr import sensitivities

__all__ = ["SCAN_POINTS", "NominalFit", "eq1_residual", "nominal_fit", "reference_fit"]

SCAN_POINTS = 17  # log-modulus grid of the coarse scan: 4 per decade on the default 1e8-1e12 Pa box
EXTRA_MODES = 4  # model modes beyond the highest measured one offered to MAC pairing
TWO_PI = 2.0 * np.pi


def eq1_residual(measured: np.ndarray, model: np.ndarray) -> np.ndarray:
    """Eq. (1)'s terms before squaring, ``f_k^exp - f_k^EF``, in the units (or logs) given."""
    return measured - model


@dataclass(frozen=True)
class NominalFit:
    """Result of `nominal_fit` (paper eq. 1).

    Attributes
    ----------
    groups : the joint groups fitted.
    moduli_pa : (n_groups,) fitted joint modulus of each group, Pa.
    modes : (n_modes,) measured mode numbers (``measured.modes``).
    model_modes : (n_modes,) model mode number (1 = lowest) paired with each measured mode.
    measured_hz, model_hz : (n_modes,) measured mean and model frequency, Hz.
    residual_hz : (n_modes,) ``measured_hz - model_hz``; ``relative_error`` the same over ``measured_hz``.
    rms_relative_error : root mean square of ``relative_error``.
    eps_ls : eq. (1), ``sum residual_hz^2``, Hz^2.
    mac : (n_modes,) MAC of each pair (``pairing="mac"``), else None.
    pairing : "order" or "mac".
    iterations, evaluations : Nelder-Mead iterations; eigen-solves including the scan.
    wall_time_s : s.
    """

    groups: JointGroups
    moduli_pa: np.ndarray
    modes: np.ndarray
    model_modes: np.ndarray
    measured_hz: np.ndarray
    model_hz: np.ndarray
    residual_hz: np.ndarray
    relative_error: np.ndarray
    rms_relative_error: float
    eps_ls: float
    mac: np.ndarray | None
    pairing: str
    iterations: int
    evaluations: int
    wall_time_s: float


def _scan_then_simplex(objective: Callable[[np.ndarray], float], x0: np.ndarray, lo: float, hi: float,
                       points: int, step: float, xatol: float, fatol: float) -> tuple[np.ndarray, int]:
    """Coarse grid over [lo, hi] one coordinate at a time (two passes), then bounded Nelder-Mead."""
    x = np.clip(np.array(x0, float), lo, hi)
    if points > 1:
        grid = np.linspace(lo, hi, points)
        best = objective(x)
        for _ in range(2 if x.size > 1 else 1):
            for g in range(x.size):
                for value in grid:
                    trial = x.copy()
                    trial[g] = value
                    f = objective(trial)
                    if f < best:
                        best, x = f, trial
    simplex = np.repeat(x[None], x.size + 1, axis=0)
    for g in range(x.size):  # step towards the inside of the box
        simplex[g + 1, g] += step if x[g] + step <= hi else -step
    result = minimize(objective, x, method="Nelder-Mead", bounds=[(lo, hi)] * x.size,
                      options={"initial_simplex": simplex, "xatol": xatol, "fatol": fatol,
                               "maxiter": 2000 * x.size, "maxfev": 4000 * x.size})
    return np.clip(result.x, lo, hi), int(result.nit)


def _pairing(model: Structure, modes: np.ndarray, pairing: str,
             measured_shapes: np.ndarray | None) -> tuple[int, np.ndarray | None, np.ndarray | None]:
    """Model modes to solve, sensor dofs and measured shapes of the pairing (None, None by order)."""
    if pairing == "order":
        return int(modes.max()), None, None
    if pairing != "mac":
        raise ValueError(f"pairing: {pairing!r} is not one of order, mac")
    dofs = sensor_dofs(model)
    if measured_shapes is None:
        raise ValueError("measured_shapes: MAC pairing needs the measured shapes (n_sensors, n_modes)")
    shapes = np.asarray(measured_shapes)
    if shapes.shape != (dofs.size, modes.size) or not np.all(np.isfinite(shapes)):
        raise ValueError(f"measured_shapes: expected finite ({dofs.size} sensors, {modes.size} modes), "
                         f"got shape {shapes.shape}")
    return min(int(modes.max()) + EXTRA_MODES, model.size - 2), dofs, shapes


def nominal_fit(model: Structure, measured: MeasuredModes, groups: JointGroups | None = None,
                start_pa: Values | None = None, bounds_pa: tuple[float, float] = (1e8, 1e12),
                pairing: str = "order", measured_shapes: np.ndarray | None = None,
                scan_points: int = SCAN_POINTS) -> NominalFit:
    """Joint moduli minimising eq. (1) on the measured mean frequencies, by Nelder-Mead.

    Parameters
    ----------
    model : assembled model; its joints' file moduli are only a start.
    measured : measured modes; ``measured.mean_hz`` are fitted, paired with model modes ``measured.modes``.
    groups : joints sharing one modulus (default: the frame's groups).
    start_pa : (n_groups,) start moduli, Pa (default: the frame file's).
    bounds_pa : (low, high) box of every group's modulus, Pa.
    pairing : ``"order"``: measured mode ``measured.modes[i]`` is model mode ``measured.modes[i]``;
        ``"mac"``: each measured mode goes to the model mode (among the first ``max(measured.modes)
        + 4``) of highest MAC at the sensors, one to one, re-paired at every evaluation.
    measured_shapes : (n_sensors, n_modes) real or complex measured shapes at ``model.frame.sensors``
        (rows in the sensors' order, columns in ``measured.modes``' order); needed for ``"mac"``.
    scan_points : points of the coarse log scan over ``bounds_pa`` before Nelder-Mead (0: none).

    Returns
    -------
    NominalFit

    Notes
    -----
    The unknowns are ``log(Y_g)``; the box is enforced by scipy's bounded Nelder-Mead (vertices
    clipped into it). The objective is eq. (1) divided by ``sum f_exp^2`` (same minimiser).
    """
    start_time = time.perf_counter()
    check_moments(measured)
    groups = resolve_groups(model, groups)
    n_groups, n_joints = len(groups.groups), len(model.joints)
    lo, hi = check_box("bounds_pa", bounds_pa)
    start = np.array(groups.nominal_pa) if start_pa is None else per_group("start_pa", start_pa, n_groups)
    modes = check_modes(model, measured)
    target = np.asarray(measured.mean_hz, float)
    count, dofs, shapes = _pairing(model, modes, pairing, measured_shapes)
    calls = [0]

    def evaluate(x: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray | None]:
        calls[0] += 1
        solved = structure_modes(model, count, joint_scale(model, groups.per_joint(np.exp(x), n_joints)))
        if shapes is None:
            return solved.frequency_hz[modes - 1], modes, None
        table = mac(shapes, solved.shapes[dofs])
        rows, cols = linear_sum_assignment(-table)
        index = cols[np.argsort(rows)]
        return solved.frequency_hz[index], index + 1, table[np.arange(modes.size), index]

    scale = float(target @ target)

    def objective(x: np.ndarray) -> float:
        return float(np.sum(eq1_residual(target, evaluate(x)[0]) ** 2) / scale)

    step = (math.log(hi) - math.log(lo)) / max(scan_points - 1, 1) / 2 if scan_points > 1 else 0.1
    x, iterations = _scan_then_simplex(objective, np.log(start), math.log(lo), math.log(hi), scan_points,
                                       step, xatol=1e-9, fatol=1e-16)
    model_hz, paired, pair_mac = evaluate(x)
    residual = eq1_residual(target, model_hz)
    relative = residual / target
    return NominalFit(groups, np.exp(x), modes, np.asarray(paired, int), target, model_hz, residual, relative,
                      float(np.sqrt(np.mean(relative**2))), float(residual @ residual), pair_mac, pairing,
                      iterations, calls[0], time.perf_counter() - start_time)


def reference_fit(model: Structure, measured: MeasuredModes, groups: JointGroups, start_pa: Values,
                  iterations: int = 30) -> np.ndarray:
    """Group moduli whose model frequencies best match the test means (eq. 1 in log frequency).

    Gauss-Newton in ``log E_g`` on ``log f_k^exp - log f_k^EF`` with SMR1's exact first derivatives
    ``d log f_k / d log Y_j = lambda_kj / (2 lambda_k)`` and one eigen-solve per iteration; steps
    limited to a factor e. Only a reference point for the Bayesian forward model (module notes).

    Returns
    -------
    (n_groups,) moduli, Pa.
    """
    modes = np.asarray(measured.modes, int) - 1
    count = int(modes.max()) + 1
    target = np.log(np.asarray(measured.mean_hz, float))
    n_joints = len(model.joint_names)
    log_e = np.log(np.asarray(start_pa, float))
    for _ in range(iterations):
        gamma = joint_scale(model, groups.per_joint(np.exp(log_e), n_joints))
        sens = sensitivities(model, count, gamma)
        lam = sens.modes.eigenvalues[modes]
        jac = sens.joints[modes] / (2.0 * lam[:, None])
        jac_g = np.stack([jac[:, list(m)].sum(axis=1) for m in groups.members], axis=1)
        # log f^EF = 0.5 log(lambda) - log(2 pi); log(2 pi) is added last, which keeps the recorded rounding
        step, *_ = np.linalg.lstsq(jac_g, eq1_residual(target, 0.5 * np.log(lam)) + np.log(TWO_PI), rcond=None)
        step = np.clip(step, -1.0, 1.0)
        log_e = log_e + step
        if np.max(np.abs(step)) < 1e-7:
            break
    return np.exp(log_e)

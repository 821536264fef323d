"""The paper's two-step moment matching (section 4.1, eq. 10-11).

Step 1 fits the group means to the measured mean frequencies by eq. (10) (`mean_residuals`) with
the CoVs held (``DEFAULT_START_COV``); step 2 fits the CoVs by eq. (11) (`cov_residuals`), the
means held. The forward model is the SMR (adaptive by default) at the candidate means. Both
objectives are sums of squares, so each step is a bounded Gauss-Newton (scipy's trust-region
reflective ``least_squares``) in log mean / log CoV rather than a simplex: the same optimum with
about six times fewer SMR evaluations (two-bolt round trip from a 10x start: 95 against 520).
Because step 1's mean frequencies depend on the CoV held (``E[sqrt(lambda)] < sqrt(E[lambda])``),
the two steps are repeated (``sweeps``) until neither moves: the result is the point where each
step's objective is stationary in its own unknowns, the paper's two-step estimate made
self-consistent. Step 1 starts from the eq. (1) fit (`workbench.identify.nominal.nominal_fit`).

The SMR is evaluated on `workbench.model.joints.model_at_moduli`, a copy of the model whose joint
zones sit at the candidate means, so that its ``gamma`` is relative to the candidate mean as
eq. (9) requires. Scaling only the nominal solve (``smr.sensitivities(model, count, gamma)``) is
right for SMR1, but SMR2 (adaptive's refinement) builds its eigenvector derivatives and reduced
matrices from the unscaled model and then mixes two operating points (7 % mean error, 74 % std
error on the one-bolt frame at 11.5 GPa against a 24 GPa file): the copy avoids it.
`tests/test_identify.py` checks the copy against a re-assembled frame and the SMR on it against
`workbench.uq.stochastic.quadrature_reference`.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable
from dataclasses import dataclass
from functools import partial

import numpy as np
from scipy.optimize import least_squares, nnls

from workbench.extraction.records import MeasuredModes
from workbench.identify.data import JointGroups, Values, check_box, check_moments, per_group, resolve_groups
from workbench.identify.nominal import NominalFit, nominal_fit
from workbench.model.structure import Structure, structure_at_moduli
from workbench.uq import smr
from workbench.uq.limits import COV_LIMIT
from workbench.uq.stochastic import FrequencyMoments, JointModel

__all__ = ["DEFAULT_START_COV", "MomentFit", "mean_residuals", "cov_residuals", "moment_matching", "interval_map",
           "moment_covariance", "SMRForward"]

DEFAULT_START_COV = 0.05  # CoV held during the first step 1 (the paper's step 1 needs one; Table 4: 0.09, 0.22)
Z95 = 1.959963984540054
MEAN_XTOL = 1e-6  # least-squares tolerance on log mean (step 1); the SMR itself is good to about 1e-4
COV_XTOL = 1e-5  # on log cov (step 2)
METHODS: dict[str, Callable[..., FrequencyMoments]] = {"adaptive": smr.adaptive, "smr1": smr.smr1, "smr2": smr.smr2}

Forward = Callable[[np.ndarray, np.ndarray], tuple[np.ndarray, np.ndarray]]


@dataclass(frozen=True)
class MomentFit:
    """Result of `moment_matching` (paper section 4.1).

    Attributes
    ----------
    groups : the joint groups fitted.
    mean_pa, cov : (n_groups,) identified mean modulus (Pa) and CoV of each group; the normalised
        modulus ``gamma = Y / mean_pa`` follows Gamma(alpha = 1/cov^2, beta = cov^2) (eq. 9).
    modes, model_modes : (n_modes,) measured mode numbers and the model modes paired with them.
    measured_mean_hz, measured_delta : (n_modes,) measured mean and CoV of each mode's frequency.
    mean_hz, std_hz, delta : (n_modes,) the forward model's moments at the optimum (``delta = std/mean``).
    residual_mean_hz : (n_modes,) eq. (10) terms before squaring, ``measured_mean_hz - mean_hz``.
    residual_delta : (n_modes,) eq. (11) terms before squaring, ``measured_delta - delta``.
    eps_E : eq. (10), Hz^2.  eps_delta : eq. (11), dimensionless.
    mean_ci95, cov_ci95 : (n_groups, 2) approximate 95 % intervals, or None (see `moment_matching`).
    nominal : the eq. (1) fit that started step 1.
    method : forward model (adaptive, smr1, smr2).
    sweeps : step 1 + step 2 passes run.
    converged : the last pass moved the means by less than 1e-5 and the CoVs by less than 1e-4
        (relative); False when ``sweeps`` ran out first (the estimates are then from the last pass).
    evaluations : forward-model (SMR) evaluations, all steps and the intervals' Jacobian included
        (the nominal fit's eigen-solves are in ``nominal.evaluations``).
    seed : seed of the bootstrap behind the intervals (None without intervals).
    wall_time_s : s, nominal fit included.
    mean_box_pa, cov_box : the search intervals of the means (Pa) and the CoVs.
    """

    groups: JointGroups
    mean_pa: np.ndarray
    cov: np.ndarray
    modes: np.ndarray
    model_modes: np.ndarray
    measured_mean_hz: np.ndarray
    measured_delta: np.ndarray
    mean_hz: np.ndarray
    std_hz: np.ndarray
    delta: np.ndarray
    residual_mean_hz: np.ndarray
    residual_delta: np.ndarray
    eps_E: float
    eps_delta: float
    mean_ci95: np.ndarray | None
    cov_ci95: np.ndarray | None
    nominal: NominalFit
    method: str
    sweeps: int
    converged: bool
    evaluations: int
    seed: int | None
    wall_time_s: float
    mean_box_pa: tuple[float, float] = (1e8, 1e12)
    cov_box: tuple[float, float] = (1e-3, COV_LIMIT)


class SMRForward:
    """``(log mean, log cov) -> (mean_hz, std_hz)`` of the paired model modes by the SMR; counts its calls."""

    def __init__(self, model: Structure, groups: JointGroups, model_modes: np.ndarray, method: str) -> None:
        self.model, self.groups, self.model_modes = model, groups, model_modes
        self.propagate = METHODS[method]
        self.calls = 0

    def __call__(self, log_mean: np.ndarray, log_cov: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        self.calls += 1
        n_joints = len(self.model.joints)
        at = structure_at_moduli(self.model, self.groups.per_joint(np.exp(log_mean), n_joints))
        joints = JointModel(self.model.joint_names, self.groups.per_joint(np.exp(log_cov), n_joints))
        moments = self.propagate(at, joints, int(self.model_modes.max()))
        return moments.mean_hz[self.model_modes - 1], moments.std_hz[self.model_modes - 1]


def mean_residuals(forward: Forward, target_mean_hz: np.ndarray, log_mean: np.ndarray,
                   log_cov: np.ndarray) -> np.ndarray:
    """Eq. (10)'s terms ``E[f_k^exp] - E[f_k^EF]``, divided by ``sqrt(sum_k E[f_k^exp]^2)`` (same minimiser).

    Parameters
    ----------
    forward : the forward model, ``(log mean, log cov) -> (mean_hz, std_hz)`` of the paired modes.
    target_mean_hz : (n_modes,) measured mean frequencies, Hz.
    log_mean, log_cov : (n_groups,) logs of the candidate mean moduli (Pa) and CoVs.
    """
    mean, _ = forward(log_mean, log_cov)
    return (target_mean_hz - mean) / math.sqrt(float(target_mean_hz @ target_mean_hz))


def cov_residuals(forward: Forward, target_delta: np.ndarray, log_mean: np.ndarray,
                   log_cov: np.ndarray) -> np.ndarray:
    """Eq. (11)'s terms ``delta_k^exp - delta_k^EF`` (the frequencies' CoVs), over ``sqrt(sum_k delta_k^exp^2)``.

    Parameters as `mean_residuals`; ``target_delta`` (n_modes,) the measured CoVs.
    """
    mean, std = forward(log_mean, log_cov)
    return (target_delta - std / mean) / math.sqrt(float(target_delta @ target_delta))


def _linear_cov_start(model: Structure, groups: JointGroups, mean_pa: np.ndarray, model_modes: np.ndarray,
                      delta: np.ndarray, lo: float, hi: float) -> np.ndarray:
    """First-order CoVs: ``delta_k^2 = sum_g cov_g^2 sum_(j in g) (lambda_kj / 2 lambda_k)^2``, by NNLS."""
    at = structure_at_moduli(model, groups.per_joint(mean_pa, len(model.joints)))
    sens = smr.sensitivities(at, int(model_modes.max()))
    k = model_modes - 1
    share = (sens.joints[k] / (2.0 * sens.modes.eigenvalues[k, None])) ** 2  # (n_modes, n_joints)
    a = np.stack([share[:, list(members)].sum(axis=1) for members in groups.members], axis=1)
    solution, _ = nnls(a, delta**2)
    return np.clip(np.sqrt(solution), lo, hi)


def _moment_covariance(measured: MeasuredModes, bootstrap: int, seed: int) -> np.ndarray | None:
    """Covariance of the measured (means, CoVs) of the modes over the tests, by a bootstrap of tests."""
    return moment_covariance(np.asarray(measured.frequency_hz, float), bootstrap, seed)


def moment_covariance(f: np.ndarray, bootstrap: int, seed: int) -> np.ndarray | None:
    """Covariance of the (means, CoVs) of the columns of ``f`` (n_tests, n_modes; NaN: not found), by a
    bootstrap of its rows (tests); None when fewer than 10 resamples hold each mode twice.
    """
    n_tests = f.shape[0]
    rng = np.random.default_rng(seed)
    draws = f[rng.integers(0, n_tests, size=(bootstrap, n_tests))]  # (B, n_tests, n_modes)
    seen = np.isfinite(draws)
    count = seen.sum(axis=1)
    keep = np.all(count >= 2, axis=1)
    if keep.sum() < 10:
        return None
    draws, seen, count = draws[keep], seen[keep], count[keep]
    values = np.where(seen, draws, 0.0)
    mean = values.sum(axis=1) / count
    var = (np.where(seen, draws - mean[:, None], 0.0) ** 2).sum(axis=1) / (count - 1)
    return np.cov(np.concatenate([mean, np.sqrt(var) / mean], axis=1), rowvar=False)


def interval_map(forward: Forward, log_mean: np.ndarray, log_cov: np.ndarray) -> np.ndarray | None:
    """The linearised two-step estimator: d(log mean, log cov) / d(measured means, CoVs), (2 G, 2 K).

    From the stationarity conditions of both steps at (``log_mean``, ``log_cov``) (finite-difference
    Jacobians of the forward model, step 1e-3 in the logs). The intervals of `moment_matching` and
    the design predictions of `workbench.plan` both carry a covariance of the measured moments
    through it. None when the steps' Hessian is singular.
    """
    def moments(lm, lc):
        m, s = forward(lm, lc)
        return m, s / m

    h = 1e-3
    n_groups = log_mean.size
    jac = {}
    for name, base in (("mean", log_mean), ("cov", log_cov)):
        cols_m, cols_d = [], []
        for g in range(n_groups):
            up, down = base.copy(), base.copy()
            up[g] += h
            down[g] -= h
            args_up = (up, log_cov) if name == "mean" else (log_mean, up)
            args_down = (down, log_cov) if name == "mean" else (log_mean, down)
            (mu, du), (md, dd) = moments(*args_up), moments(*args_down)
            cols_m.append((mu - md) / (2 * h))
            cols_d.append((du - dd) / (2 * h))
        jac[name] = (np.stack(cols_m, axis=1), np.stack(cols_d, axis=1))
    (j_mm, j_dm), (j_mc, j_dc) = jac["mean"], jac["cov"]
    hessian = np.block([[j_mm.T @ j_mm, j_mm.T @ j_mc], [j_dc.T @ j_dm, j_dc.T @ j_dc]])
    n_modes = j_mm.shape[0]
    gradient = np.zeros((2 * n_groups, 2 * n_modes))
    gradient[:n_groups, :n_modes] = j_mm.T
    gradient[n_groups:, n_modes:] = j_dc.T
    try:
        return np.linalg.solve(hessian, gradient)
    except np.linalg.LinAlgError:
        return None


def _intervals(forward: Forward, log_mean: np.ndarray, log_cov: np.ndarray,
               sigma: np.ndarray) -> tuple[np.ndarray | None, np.ndarray | None]:
    """Delta-method 95 % intervals of the two-step estimator (see `moment_matching`)."""
    lin = interval_map(forward, log_mean, log_cov)
    if lin is None:
        return None, None
    n_groups = log_mean.size
    sd = np.sqrt(np.clip(np.diag(lin @ sigma @ lin.T), 0.0, None))
    band = Z95 * np.stack([-sd, sd], axis=1)
    return np.exp(log_mean[:, None] + band[:n_groups]), np.exp(log_cov[:, None] + band[n_groups:])


def _least_squares(residuals: Callable[[np.ndarray], np.ndarray], x0: np.ndarray, box: tuple[float, float],
                   xtol: float) -> np.ndarray:
    """Bounded Gauss-Newton (trust-region reflective) on a residual vector, forward-difference Jacobian."""
    lo, hi = box
    x0 = np.clip(x0, lo + 1e-9, hi - 1e-9)
    result = least_squares(residuals, x0, bounds=(lo, hi), method="trf", x_scale=1.0, diff_step=1e-6 / np.abs(x0),
                           xtol=xtol, ftol=1e-12, gtol=1e-12, max_nfev=200 * x0.size)
    return np.clip(result.x, lo, hi)


def _two_steps(model: Structure, groups: JointGroups, forward: SMRForward, measured_mean: np.ndarray,
               measured_delta: np.ndarray, log_mean: np.ndarray, log_cov: np.ndarray,
               bounds: tuple[tuple[float, float], tuple[float, float]],
               sweeps: int) -> tuple[np.ndarray, np.ndarray, int, bool]:
    """Step 1 (eq. 10, means) then step 2 (eq. 11, CoVs), repeated until a pass moves neither.

    ``bounds`` are the boxes of the means (Pa) and of the CoVs. Returns ``(log_mean, log_cov,
    passes run, converged)``; the first step 2 starts from the first-order CoVs (`_linear_cov_start`).
    """
    n_groups = log_mean.size
    (m_lo, m_hi), (c_lo, c_hi) = bounds
    box_m, box_c = (math.log(m_lo), math.log(m_hi)), (math.log(c_lo), math.log(c_hi))
    done, converged = 0, False
    for sweep in range(sweeps):
        previous = np.concatenate([log_mean, log_cov])
        log_mean = _least_squares(partial(mean_residuals, forward, measured_mean, log_cov=log_cov), log_mean, box_m,
                                  MEAN_XTOL)
        if sweep == 0:
            log_cov = np.log(_linear_cov_start(model, groups, np.exp(log_mean), forward.model_modes, measured_delta,
                                               c_lo, c_hi))
        log_cov = _least_squares(partial(cov_residuals, forward, measured_delta, log_mean), log_cov, box_c,
                                 COV_XTOL)
        done = sweep + 1
        moved = np.abs(np.concatenate([log_mean, log_cov]) - previous)
        converged = bool(np.all(moved[:n_groups] < 10 * MEAN_XTOL) and np.all(moved[n_groups:] < 10 * COV_XTOL))
        if sweep > 0 and converged:
            break
    return log_mean, log_cov, done, converged and done > 1


def moment_matching(model: Structure, measured: MeasuredModes, groups: JointGroups | None = None,
                    start: tuple[Values | None, Values | None] | None = None,
                    bounds_pa: tuple[float, float] = (1e8, 1e12), cov_bounds: tuple[float, float] = (1e-3, COV_LIMIT),
                    method: str = "adaptive", sweeps: int = 10,
                    pairing: str = "order", measured_shapes: np.ndarray | None = None, bootstrap: int = 2000,
                    seed: int = 0) -> MomentFit:
    """Mean and CoV of each joint group's modulus by the paper's two-step moment matching.

    Parameters
    ----------
    model : assembled model; its joints' file moduli are only a start.
    measured : measured moments (``mean_hz``, ``std_hz``) of modes ``measured.modes`` (paired by
        order, or by MAC through `nominal_fit`), and per-test frequencies when the campaign has them.
    groups : joints sharing one stochastic model (default: the frame's groups).
    start : ``(mean_pa, cov)`` per group, either may be None: the nominal fit's start modulus
        (default: the frame file's) and the CoV held in the first step 1 (default ``DEFAULT_START_COV``).
    bounds_pa, cov_bounds : boxes of the group means (Pa) and CoVs; the CoVs stop at
        `workbench.uq.limits.COV_LIMIT`, beyond which the SMR forward model is not accurate.
    method : the SMR forward model: ``"adaptive"`` (default), ``"smr1"`` or ``"smr2"``.
    sweeps : at most this many step 1 + step 2 passes; stops earlier once a pass moves the means
        by less than 1e-5 and the CoVs by less than 1e-4 (relative).
    pairing, measured_shapes : as in `nominal_fit`; the pairing found there is kept.
    bootstrap, seed : bootstrap resamples of the tests and their seed, for the intervals.

    Notes
    -----
    Step 1 minimises eq. (10) (`mean_residuals`) over ``log mean`` from the eq. (1) fit, CoVs held;
    step 2 minimises eq. (11) (`cov_residuals`) over ``log cov``, means held, from the first-order
    estimate ``delta_k^2 = sum_g cov_g^2 sum_(j in g) (lambda_kj / 2 lambda_k)^2`` (non-negative
    least squares on the measured ``delta^2``), which makes step 2 independent of the start CoV.
    Both by bounded trust-region least squares (forward-difference Jacobian, step 1e-6 in the logs).

    Intervals: with per-test frequencies, the covariance ``Sigma`` of the measured (means, CoVs)
    over the tests comes from a bootstrap of the tests (no model run), and is carried to the
    estimates through the linearised stationarity conditions of both steps (delta method with
    finite-difference Jacobians at the optimum, in log mean and log CoV): exp(estimate +- 1.96 sd).
    They cover the test-to-test sampling only, not model-form error; they are None for campaigns
    with only published moments (Table 3), or when an estimate sits on a bound (the linearisation
    does not hold there).
    """
    start_time = time.perf_counter()
    check_moments(measured)
    groups = resolve_groups(model, groups)
    n_groups = len(groups.groups)
    if method not in METHODS:
        raise ValueError(f"method: {method!r} is not one of adaptive, smr1, smr2")
    if not (isinstance(sweeps, int) and sweeps >= 1):
        raise ValueError(f"sweeps: expected a positive integer, got {sweeps!r}")
    start_mean, start_cov = (None, None) if start is None else start
    c_lo, c_hi = check_box("cov_bounds", cov_bounds)
    cov = np.full(n_groups, DEFAULT_START_COV) if start_cov is None else per_group("start cov", start_cov, n_groups)
    cov = np.clip(cov, c_lo, c_hi)
    m_lo, m_hi = check_box("bounds_pa", bounds_pa)
    nominal = nominal_fit(model, measured, groups, start_mean, bounds_pa, pairing, measured_shapes)
    target_mean = np.asarray(measured.mean_hz, float)
    target_delta = np.asarray(measured.cov, float)
    forward = SMRForward(model, groups, nominal.model_modes, method)
    if float(target_delta @ target_delta) == 0.0:
        raise ValueError(f"{measured.source}: std_hz: every measured deviation is 0; no CoV to identify")
    box_m, box_c = (math.log(m_lo), math.log(m_hi)), (math.log(c_lo), math.log(c_hi))
    log_mean, log_cov, done, converged = _two_steps(model, groups, forward, target_mean, target_delta,
                                                    np.log(nominal.moduli_pa), np.log(cov),
                                                    ((m_lo, m_hi), (c_lo, c_hi)), sweeps)
    mean_hz, std_hz = forward(log_mean, log_cov)
    delta = std_hz / mean_hz
    res_mean, res_delta = target_mean - mean_hz, target_delta - delta
    mean_ci = cov_ci = None
    used_seed = None
    on_bound = (np.any(np.isclose(log_mean[:, None], np.array(box_m)[None], rtol=0, atol=1e-6)) or
                np.any(np.isclose(log_cov[:, None], np.array(box_c)[None], rtol=0, atol=1e-6)))
    if measured.has_tests and not on_bound and bootstrap > 0:
        sigma = _moment_covariance(measured, bootstrap, seed)
        if sigma is not None:
            mean_ci, cov_ci = _intervals(forward, log_mean, log_cov, sigma)
            used_seed = seed
    evaluations = forward.calls + 1  # and the first-order CoV start's sensitivities
    return MomentFit(groups, np.exp(log_mean), np.exp(log_cov), nominal.modes, nominal.model_modes, target_mean,
                     target_delta, mean_hz, std_hz, delta, res_mean, res_delta, float(res_mean @ res_mean),
                     float(res_delta @ res_delta), mean_ci, cov_ci, nominal, method, done, converged, evaluations,
                     used_seed, time.perf_counter() - start_time, (m_lo, m_hi), (c_lo, c_hi))

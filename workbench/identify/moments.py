"""Identification of joint models from measured eigenfrequencies.

`FrequencyData` is what a campaign offers to every estimator (nominal fit, moment matching,
Bayesian): the measured frequencies of each test and mode, or only their published moments.
`JointGroups` says which joints share one stochastic model (the frame file's ``group``: the
paper's vertical-beam and horizontal-beam joints).

Two estimators of the paper live here (the Bayesian one is `workbench.identify.bayes`):

`nominal_fit`, eq. (1): the group moduli minimising ``sum_k (f_k^exp - f_k^EF)^2`` by Nelder-Mead
on the measured means. Unknowns are the log-moduli; the bounds are Nelder-Mead's own (scipy
clips the simplex into the box). A coarse log scan over the whole box, one group at a time, runs
first, so the frame file's modulus is only a starting point: a start 10x off still converges.
Other named model parameters (supports, masses) are not fitted here: that is the diagnosis's job.

`moment_matching`, section 4.1: step 1 fits the group means to the measured mean frequencies by
eq. (10) with the CoVs held (``DEFAULT_START_COV``); step 2 fits the CoVs by eq. (11), the means
held. The forward model is the SMR (adaptive by default) at the candidate means. Both objectives
are sums of squares, so each step is a bounded Gauss-Newton (scipy's trust-region reflective
``least_squares``) in log mean / log CoV rather than a simplex: the same optimum with about six
times fewer SMR evaluations (two-bolt round trip from a 10x start: 95 against 520). Because step 1's
mean frequencies depend on the CoV held (``E[sqrt(lambda)] < sqrt(E[lambda])``), the two steps are
repeated (``sweeps``) until neither moves: the result is the point where each step's objective is
stationary in its own unknowns, the paper's two-step estimate made self-consistent.

The SMR is evaluated on `model_at_moduli`, a copy of the model whose joint zones sit at the
candidate means, so that its ``gamma`` is relative to the candidate mean as eq. (9) requires.
Scaling only the nominal solve (``smr.sensitivities(model, count, gamma)``) is right for SMR1, but
SMR2 (adaptive's refinement) builds its eigenvector derivatives and reduced matrices from the
unscaled model and then mixes two operating points (7 % mean error, 74 % std error on the one-bolt
frame at 11.5 GPa against a 24 GPa file): the copy avoids it. `tests/test_identify.py` checks the
copy against a re-assembled frame and the SMR on it against `workbench.uq.stochastic.quadrature_reference`.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass

import numpy as np
from scipy.optimize import least_squares, linear_sum_assignment, minimize, nnls

from workbench.model.assembly import with_joint_scale

__all__ = ["FrequencyData", "JointGroups", "joint_groups", "model_at_moduli", "NominalFit", "nominal_fit",
           "MomentFit", "moment_matching", "identification_record", "DEFAULT_START_COV", "SCAN_POINTS"]

DEFAULT_START_COV = 0.05  # CoV held during the first step 1 (the paper's step 1 needs one; Table 4: 0.09, 0.22)
SCAN_POINTS = 17  # log-modulus grid of the coarse scan: 4 per decade on the default 1e8-1e12 Pa box
EXTRA_MODES = 4  # model modes beyond the highest measured one offered to MAC pairing
Z95 = 1.959963984540054
MEAN_XTOL = 1e-6  # least-squares tolerance on log mean (step 1); the SMR itself is good to about 1e-4
COV_XTOL = 1e-5  # on log cov (step 2)


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


# ---------------------------------------------------------------------------------------------
# shared checks and the model at candidate moduli


def _groups(model, groups: JointGroups | None) -> JointGroups:
    if not model.frame.joints:
        raise ValueError(f"{model.frame.source}: joints: the frame has no joint to identify")
    groups = groups if groups is not None else joint_groups(model.frame)
    n = len(model.frame.joints)
    if sorted(j for members in groups.members for j in members) != list(range(n)):
        raise ValueError(f"groups: {groups.members} must hold each of the frame's {n} joints once")
    return groups


def _per_group(name: str, value, n_groups: int) -> np.ndarray:
    out = np.array(value, float).reshape(-1) if np.ndim(value) else np.full(n_groups, float(value))
    if out.shape != (n_groups,) or not np.all(np.isfinite(out)) or np.any(out <= 0):
        raise ValueError(f"{name}: expected {n_groups} finite positive values (one per group), got {value}")
    return out


def _box(name: str, bounds) -> tuple[float, float]:
    lo, hi = (float(b) for b in bounds)
    if not (math.isfinite(lo) and math.isfinite(hi) and 0 < lo < hi):
        raise ValueError(f"{name}: expected 0 < low < high, finite, got {bounds}")
    return lo, hi


def _measured_modes(model, data: FrequencyData) -> np.ndarray:
    modes = np.asarray(data.modes)
    if modes.size == 0 or not np.all(np.equal(np.mod(modes, 1), 0)) or np.any(modes < 1):
        raise ValueError(f"{data.source}: modes: expected mode numbers >= 1, got {modes}")
    modes = modes.astype(int)
    if len(set(modes.tolist())) != modes.size:
        raise ValueError(f"{data.source}: modes: {modes} repeats a mode")
    if modes.max() > model.size - 2:
        raise ValueError(f"{data.source}: modes: mode {modes.max()} asked of a model with {model.size} dofs")
    return modes


def _joint_scale(model, groups: JointGroups, mean_pa: np.ndarray) -> np.ndarray:
    """Per joint ``mean_g / Y_file_j``: the ``gamma`` of ``Model.stiffness`` putting each group at ``mean_pa``."""
    scale = np.empty(len(model.frame.joints))
    for g, members in enumerate(groups.members):
        for j in members:
            scale[j] = mean_pa[g] / model.frame.joints[j].youngs_modulus
    return scale


def model_at_moduli(model, groups: JointGroups, mean_pa) -> object:
    """A copy of ``model`` whose joint zones are at the group moduli ``mean_pa`` (n_groups,), Pa.

    `workbench.model.assembly.with_joint_scale` at the groups' scale: exactly the model assembled with
    those joint moduli. The copy's ``gamma`` is then relative to the candidate means, as the
    SMR's Gamma laws of eq. (9) are.
    """
    mean_pa = _per_group("mean_pa", mean_pa, len(groups.groups))
    return with_joint_scale(model, _joint_scale(model, groups, mean_pa))


# ---------------------------------------------------------------------------------------------
# nominal fit, eq. (1)


@dataclass(frozen=True)
class NominalFit:
    """Result of `nominal_fit` (paper eq. 1).

    Attributes
    ----------
    groups : the joint groups fitted.
    moduli_pa : (n_groups,) fitted joint modulus of each group, Pa.
    modes : (n_modes,) measured mode numbers (``data.modes``).
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


def _sensor_dofs(model) -> np.ndarray:
    if not model.frame.sensors:
        raise ValueError(f"{model.frame.source}: sensors: MAC pairing needs sensors in the frame")
    return np.array([model.dof(s.point, s.dof) for s in model.frame.sensors])


def _scan_then_simplex(objective, x0: np.ndarray, lo: float, hi: float, points: int, step: float,
                       xatol: float, fatol: float) -> tuple[np.ndarray, int]:
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


def nominal_fit(model, data: FrequencyData, groups: JointGroups | None = None, start_pa=None,
                bounds_pa=(1e8, 1e12), pairing: str = "order", measured_shapes=None,
                scan_points: int = SCAN_POINTS) -> NominalFit:
    """Joint moduli minimising eq. (1) on the measured mean frequencies, by Nelder-Mead.

    Parameters
    ----------
    model : assembled `workbench.model.assembly.Model`; its joints' file moduli are only a start.
    data : measured frequencies; ``data.mean_hz`` are fitted, paired with model modes ``data.modes``.
    groups : joints sharing one modulus (default: the frame's groups).
    start_pa : (n_groups,) start moduli, Pa (default: the frame file's).
    bounds_pa : (low, high) box of every group's modulus, Pa.
    pairing : ``"order"``: measured mode ``data.modes[i]`` is model mode ``data.modes[i]``;
        ``"mac"``: each measured mode goes to the model mode (among the first ``max(data.modes)
        + 4``) of highest MAC at the sensors, one to one, re-paired at every evaluation.
    measured_shapes : (n_sensors, n_modes) real or complex measured shapes at ``model.frame.sensors``
        (rows in the sensors' order, columns in ``data.modes``' order); needed for ``"mac"``.
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
    groups = _groups(model, groups)
    n_groups = len(groups.groups)
    lo, hi = _box("bounds_pa", bounds_pa)
    start = np.array(groups.nominal_pa) if start_pa is None else _per_group("start_pa", start_pa, n_groups)
    modes = _measured_modes(model, data)
    target = np.asarray(data.mean_hz, float)
    if pairing == "order":
        count, dofs, shapes = int(modes.max()), None, None
    elif pairing == "mac":
        dofs = _sensor_dofs(model)
        if measured_shapes is None:
            raise ValueError("measured_shapes: MAC pairing needs the measured shapes (n_sensors, n_modes)")
        shapes = np.asarray(measured_shapes)
        if shapes.shape != (dofs.size, modes.size) or not np.all(np.isfinite(shapes)):
            raise ValueError(f"measured_shapes: expected finite ({dofs.size} sensors, {modes.size} modes), "
                             f"got shape {shapes.shape}")
        count = min(int(modes.max()) + EXTRA_MODES, model.size - 2)
    else:
        raise ValueError(f"pairing: {pairing!r} is not one of order, mac")
    from workbench.model.modal import mac, model_modes

    calls = [0]

    def evaluate(x: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray | None]:
        calls[0] += 1
        solved = model_modes(model, count, _joint_scale(model, groups, np.exp(x)))
        if shapes is None:
            return solved.frequency_hz[modes - 1], modes, None
        table = mac(shapes, solved.shapes[dofs])
        rows, cols = linear_sum_assignment(-table)
        index = cols[np.argsort(rows)]
        return solved.frequency_hz[index], index + 1, table[np.arange(modes.size), index]

    scale = float(target @ target)

    def objective(x: np.ndarray) -> float:
        return float(np.sum((target - evaluate(x)[0]) ** 2) / scale)

    step = (math.log(hi) - math.log(lo)) / max(scan_points - 1, 1) / 2 if scan_points > 1 else 0.1
    x, iterations = _scan_then_simplex(objective, np.log(start), math.log(lo), math.log(hi), scan_points,
                                       step, xatol=1e-9, fatol=1e-16)
    model_hz, paired, pair_mac = evaluate(x)
    residual = target - model_hz
    relative = residual / target
    return NominalFit(groups, np.exp(x), modes, np.asarray(paired, int), target, model_hz, residual, relative,
                      float(np.sqrt(np.mean(relative**2))), float(residual @ residual), pair_mac, pairing,
                      iterations, calls[0], time.perf_counter() - start_time)


# ---------------------------------------------------------------------------------------------
# moment matching, eq. (10)-(11)


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


def _forward(model, groups: JointGroups, model_modes: np.ndarray, method: str):
    """``(log mean, log cov) -> (mean_hz, std_hz)`` of the paired model modes by the SMR."""
    from workbench.uq import smr
    from workbench.uq.stochastic import JointModel

    propagate = {"adaptive": smr.adaptive, "smr1": smr.smr1, "smr2": smr.smr2}[method]
    count = int(model_modes.max())
    n_joints = len(model.frame.joints)

    def forward(log_mean: np.ndarray, log_cov: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        at = model_at_moduli(model, groups, np.exp(log_mean))
        joints = JointModel(model.joint_names, groups.per_joint(np.exp(log_cov), n_joints))
        moments = propagate(at, joints, count)
        return moments.mean_hz[model_modes - 1], moments.std_hz[model_modes - 1]

    return forward


def _linear_cov_start(model, groups: JointGroups, mean_pa: np.ndarray, model_modes: np.ndarray,
                      delta: np.ndarray, lo: float, hi: float) -> np.ndarray:
    """First-order CoVs: ``delta_k^2 = sum_g cov_g^2 sum_(j in g) (lambda_kj / 2 lambda_k)^2``, by NNLS."""
    from workbench.uq.smr import sensitivities

    sens = sensitivities(model_at_moduli(model, groups, mean_pa), int(model_modes.max()))
    k = model_modes - 1
    share = (sens.joints[k] / (2.0 * sens.modes.eigenvalues[k, None])) ** 2  # (n_modes, n_joints)
    a = np.stack([share[:, list(members)].sum(axis=1) for members in groups.members], axis=1)
    solution, _ = nnls(a, delta**2)
    return np.clip(np.sqrt(solution), lo, hi)


def _moment_covariance(data: FrequencyData, bootstrap: int, seed: int) -> np.ndarray | None:
    """Covariance of the measured (means, CoVs) of the modes over the tests, by a bootstrap of tests."""
    f = np.asarray(data.frequency_hz, float)
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


def _intervals(forward, log_mean, log_cov, sigma: np.ndarray, evaluations: list[int]):
    """Delta-method 95 % intervals of the two-step estimator (see `moment_matching`)."""
    def moments(lm, lc):
        evaluations[0] += 1
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
        lin = np.linalg.solve(hessian, gradient)
    except np.linalg.LinAlgError:
        return None, None
    sd = np.sqrt(np.clip(np.diag(lin @ sigma @ lin.T), 0.0, None))
    band = Z95 * np.stack([-sd, sd], axis=1)
    return np.exp(log_mean[:, None] + band[:n_groups]), np.exp(log_cov[:, None] + band[n_groups:])


def _least_squares(residuals, x0: np.ndarray, box: tuple[float, float], xtol: float) -> np.ndarray:
    """Bounded Gauss-Newton (trust-region reflective) on a residual vector, forward-difference Jacobian."""
    lo, hi = box
    x0 = np.clip(x0, lo + 1e-9, hi - 1e-9)
    result = least_squares(residuals, x0, bounds=(lo, hi), method="trf", x_scale=1.0, diff_step=1e-6 / np.abs(x0),
                           xtol=xtol, ftol=1e-12, gtol=1e-12, max_nfev=200 * x0.size)
    return np.clip(result.x, lo, hi)


def moment_matching(model, data: FrequencyData, groups: JointGroups | None = None, start=None,
                    bounds_pa=(1e8, 1e12), cov_bounds=(1e-3, 0.6), method: str = "adaptive", sweeps: int = 10,
                    pairing: str = "order", measured_shapes=None, bootstrap: int = 2000,
                    seed: int = 0) -> MomentFit:
    """Mean and CoV of each joint group's modulus by the paper's two-step moment matching.

    Parameters
    ----------
    model : assembled `workbench.model.assembly.Model`; its joints' file moduli are only a start.
    data : measured moments (``mean_hz``, ``std_hz``) of modes ``data.modes`` (paired by order, or
        by MAC through `nominal_fit`), and per-test frequencies when the campaign has them.
    groups : joints sharing one stochastic model (default: the frame's groups).
    start : ``(mean_pa, cov)`` per group, either may be None: the nominal fit's start modulus
        (default: the frame file's) and the CoV held in the first step 1 (default ``DEFAULT_START_COV``).
    bounds_pa, cov_bounds : boxes of the group means (Pa) and CoVs.
    method : the SMR forward model: ``"adaptive"`` (default), ``"smr1"`` or ``"smr2"``.
    sweeps : at most this many step 1 + step 2 passes; stops earlier once a pass moves the means
        by less than 1e-5 and the CoVs by less than 1e-4 (relative).
    pairing, measured_shapes : as in `nominal_fit`; the pairing found there is kept.
    bootstrap, seed : bootstrap resamples of the tests and their seed, for the intervals.

    Returns
    -------
    MomentFit

    Notes
    -----
    Step 1 minimises eq. (10) over ``log mean`` from the eq. (1) fit, CoVs held; step 2 minimises
    eq. (11) over ``log cov``, means held, from the first-order estimate ``delta_k^2 = sum_g cov_g^2
    sum_(j in g) (lambda_kj / 2 lambda_k)^2`` (non-negative least squares on the measured
    ``delta^2``), which makes step 2 independent of the start CoV. Both by bounded trust-region
    least squares (forward-difference Jacobian, step 1e-6 in the logs); the residuals are divided
    by ``sqrt(sum E[f_exp]^2)`` and ``sqrt(sum delta_exp^2)`` (same minimisers).

    Intervals: with per-test frequencies, the covariance ``Sigma`` of the measured (means, CoVs)
    over the tests comes from a bootstrap of the tests (no model run), and is carried to the
    estimates through the linearised stationarity conditions of both steps (delta method with
    finite-difference Jacobians at the optimum, in log mean and log CoV): exp(estimate +- 1.96 sd).
    They cover the test-to-test sampling only, not model-form error; they are None for campaigns
    with only published moments (Table 3), or when an estimate sits on a bound (the linearisation
    does not hold there).
    """
    start_time = time.perf_counter()
    groups = _groups(model, groups)
    n_groups = len(groups.groups)
    if method not in ("adaptive", "smr1", "smr2"):
        raise ValueError(f"method: {method!r} is not one of adaptive, smr1, smr2")
    if not (isinstance(sweeps, int) and sweeps >= 1):
        raise ValueError(f"sweeps: expected a positive integer, got {sweeps!r}")
    start_mean, start_cov = (None, None) if start is None else start
    c_lo, c_hi = _box("cov_bounds", cov_bounds)
    cov = np.full(n_groups, DEFAULT_START_COV) if start_cov is None else _per_group("start cov", start_cov, n_groups)
    cov = np.clip(cov, c_lo, c_hi)
    m_lo, m_hi = _box("bounds_pa", bounds_pa)
    nominal = nominal_fit(model, data, groups, start_mean, bounds_pa, pairing, measured_shapes)
    model_modes = nominal.model_modes
    target_mean = np.asarray(data.mean_hz, float)
    target_delta = np.asarray(data.cov, float)
    forward = _forward(model, groups, model_modes, method)
    evaluations = [0]
    scale_mean, scale_delta = float(target_mean @ target_mean), float(target_delta @ target_delta)
    if scale_delta == 0.0:
        raise ValueError(f"{data.source}: std_hz: every measured deviation is 0; no CoV to identify")

    def res_mean_fn(log_mean, log_cov) -> np.ndarray:  # eq. (10) terms, scaled
        evaluations[0] += 1
        mean, _ = forward(log_mean, log_cov)
        return (target_mean - mean) / math.sqrt(scale_mean)

    def res_delta_fn(log_mean, log_cov) -> np.ndarray:  # eq. (11) terms, scaled
        evaluations[0] += 1
        mean, std = forward(log_mean, log_cov)
        return (target_delta - std / mean) / math.sqrt(scale_delta)

    log_mean, log_cov = np.log(nominal.moduli_pa), np.log(cov)
    box_m, box_c = (math.log(m_lo), math.log(m_hi)), (math.log(c_lo), math.log(c_hi))
    done, converged = 0, False
    for sweep in range(sweeps):
        previous = np.concatenate([log_mean, log_cov])
        log_mean = _least_squares(lambda x: res_mean_fn(x, log_cov), log_mean, box_m, MEAN_XTOL)
        if sweep == 0:
            delta0 = _linear_cov_start(model, groups, np.exp(log_mean), model_modes, target_delta, c_lo, c_hi)
            evaluations[0] += 1
            log_cov = np.log(delta0)
        log_cov = _least_squares(lambda x: res_delta_fn(log_mean, x), log_cov, box_c, COV_XTOL)
        done = sweep + 1
        moved = np.abs(np.concatenate([log_mean, log_cov]) - previous)
        converged = bool(np.all(moved[:n_groups] < 10 * MEAN_XTOL) and np.all(moved[n_groups:] < 10 * COV_XTOL))
        if sweep > 0 and converged:
            break
    mean_hz, std_hz = forward(log_mean, log_cov)
    evaluations[0] += 1
    delta = std_hz / mean_hz
    res_mean, res_delta = target_mean - mean_hz, target_delta - delta
    mean_ci = cov_ci = None
    used_seed = None
    on_bound = (np.any(np.isclose(log_mean[:, None], np.array(box_m)[None], rtol=0, atol=1e-6)) or
                np.any(np.isclose(log_cov[:, None], np.array(box_c)[None], rtol=0, atol=1e-6)))
    if data.has_tests and not on_bound and bootstrap > 0:
        sigma = _moment_covariance(data, bootstrap, seed)
        if sigma is not None:
            mean_ci, cov_ci = _intervals(forward, log_mean, log_cov, sigma, evaluations)
            used_seed = seed
    return MomentFit(groups, np.exp(log_mean), np.exp(log_cov), nominal.modes, model_modes, target_mean,
                     target_delta, mean_hz, std_hz, delta, res_mean, res_delta, float(res_mean @ res_mean),
                     float(res_delta @ res_delta), mean_ci, cov_ci, nominal, method, done,
                     converged and done > 1, evaluations[0], used_seed, time.perf_counter() - start_time)


def identification_record(campaign_name: str, method: str, frame, fit, modes_used, wall_time_s: float) -> dict:
    """The ``identification.json`` structure of CONTRACTS.md section 3.

    ``fit`` either has ``joint_records()`` (the ``joints`` block itself, e.g. a Bayesian
    `workbench.identify.bayes.Posterior`) or ``groups`` (`JointGroups` of ``frame``), ``mean_pa`` and ``cov``
    ((n_groups,) each) and optionally ``mean_ci95`` / ``cov_ci95`` ((n_groups, 2) or None), as a
    `MomentFit`. Every joint of a group gets its group's values; joints are keyed by name, in the
    frame's order.
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
        joints = {joint.name: {"youngs_modulus": float(fit.mean_pa[group_of[j]]), "cov": float(fit.cov[group_of[j]]),
                               "youngs_modulus_ci95": pair(mean_ci, group_of[j]), "cov_ci95": pair(cov_ci, group_of[j])}
                  for j, joint in enumerate(frame.joints) if j in group_of}
    if list(joints) != list(frame.joint_names):
        raise ValueError(f"{frame.source}: the fit's joints {list(joints)} are not the frame's {list(frame.joint_names)}")
    return {"campaign": str(campaign_name), "method": str(method), "joints": joints,
            "modes_used": [int(m) for m in modes_used], "wall_time_s": float(wall_time_s)}

"""What the diagnosis fits: condition means of the measured modes, their standard errors and chi-squares.

The tests are grouped by excitation amplitude (one condition when the campaign has no amplitude
factor). For each condition ``c`` and measured mode ``i``: the mean frequency and, when measured,
the mean damping ratio. Their standard errors come from the scatter of the tests about a straight
line in amplitude (a mean when there is one condition), divided by the square root of the
condition's test count, with a relative floor (`RELATIVE_FLOOR`, 1e-4 for circle-fit frequencies:
the extraction's bias at 40 dB is 3e-5; `DAMPING_FLOOR` for damping). Their correlations across modes
(a joint that scatters moves every mode at once) are kept, and the matrix regularised with its Ledoit-Wolf
blend (`_shrunk`: the larger variance along each direction the tests sampled, the blend where they never did):
a campaign has fewer tests than modes, and its sample covariance is singular. The frequencies' standard
errors use it; the per-mode discrepancy uses the scatter as measured. Published means
with a published std use ``std / sqrt(tests)``.

**Model discrepancy.** A nominal model never reproduces a real structure's means to the precision with
which a campaign measures them: the as-built sections and materials are off by tenths of a percent, the
temperature moves every modulus. A gap is judged against the measurement error *plus* that model-form
error (`Discrepancy`), so that the diagnosis does not read an as-built tolerance as an effect:

- a **common shift** of every frequency (``common_sd``, `COMMON_SD` = 0.4 %: a material's E/rho known to
  +-1 %, a few kelvin), the same in every mode and condition; the chi-square marginalises it, so its
  value is estimated from the residual's mean structure rather than taken as an effect;
- a **per-mode error** (``mode_sd``), the same at every excitation level, so that a difference between
  levels (amplitude softening) is still measured against the scatter alone. It is the larger of
  `MODEL_FLOOR` (0.1 % since seed 25, 0.2 % before, when it stood for the sections too: what remains of
  another code's elements, mesh and joint representation once the sections and geometry below are carried
  by their own structure) and the
  campaign's own relative test-to-test scatter: a structure that moves by ``s`` between two mountings is not
  known, as built, to better than ``s``. The scatter is taken about the campaign's design (the amplitude line
  and the levels of its other factors, `MeasuredModes.design`): bolts tightened differently on purpose move
  the modes by design, not by chance;
- a candidate's **form**: an effect of the vocabulary is one parametrisation of a physical change (a
  rotational spring for a clamp, a zone's modulus for a joint), and the real mechanism distributes its change
  over the modes somewhat differently. A candidate's prediction of a mean is trusted to `FORM_SD` (10 %) of
  the change it predicts there (`frequency_score`), on top of the errors above; like the per-mode error, it is
  one error per mode, shared by the excitation levels;
- the frame's **geometry** (``geometry``, since seed 24): a frame file's coordinates were measured with a
  rule, and a bending mode moves as the inverse square of its member's length, so that a member end half a
  millimetre off moves modes by a few tenths of a percent, each by its own amount. Each member end's x and y
  are known to `GEOMETRY_SD` (0.5 mm), independently; the nominal model's sensitivities to them
  (`workbench.diagnose.geometry`) carry that error to the modes, shared by the levels like the per-mode
  error. Without it the stated errors read a frame whose ends sit 1 mm off as a gap in a fifth to a third of
  no-effect campaigns (`benchmarks/detection_ceiling.py`);
- the members' **sections** (``sections``, since seed 25): each member's second moment of area known to
  `SECOND_MOMENT_SD` (1 %) and its area to `AREA_SD` (0.5 %), independently (a machined bar's width and
  thickness known to about 0.3 %, without tying the two to a flat bar), carried to the modes by the nominal
  model's sensitivities (`workbench.diagnose.geometry.section_columns`). The modes one member bends move
  together, which a per-mode floor cannot say: with this term the floor shrinks from 0.2 to 0.1 %, and a
  known-shape test's reach on the validation's singles grows from 74 to 85 % while the as-built false alarms
  stay under 1 % (`benchmarks/detection_ceiling.py`, seed 24; the choice made there before any run);
- damping: each mode's damping ratio is modelled to `DAMPING_MODEL_SD` (20 %) of the campaign's typical
  (median) damping ratio; modal damping of a real structure scatters from mode to mode by that much whatever
  its model. Like the per-mode frequency error it is one error per mode, shared by the excitation levels
  (`damping_whiten`): the levels' differences are measured against the scatter alone.

These values were set on a development mix of the proving ground (`workbench.proving`, seed 9001) and frozen
before its validation run (another seed); ``diagnosis.json`` states them.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from workbench.extraction.records import MeasuredModes

__all__ = ["RELATIVE_FLOOR", "DAMPING_FLOOR", "MODEL_FLOOR", "COMMON_SD", "DAMPING_MODEL_SD", "GEOMETRY_SD",
           "SECOND_MOMENT_SD", "AREA_SD", "FORM_SD", "Allowance", "DEFAULT_ALLOWANCE",
           "Discrepancy",
           "Observations", "observations", "level_contrast_chi2", "frequency_chi2", "frequency_chi2_many",
           "frequency_score", "damping_chi2",
           "damping_whiten", "damping_levels_chi2", "mode_frequency_hz", "chi2", "rms"]

RELATIVE_FLOOR = 1e-4  # floor of the relative standard error of a mean frequency
DAMPING_FLOOR = 0.02  # floor of the relative standard error of a mean damping ratio
MODEL_FLOOR = 0.001  # per-mode relative model-form error, at least (module docstring)
COMMON_SD = 0.004  # common relative shift of every frequency (module docstring)
DAMPING_MODEL_SD = 0.2  # per-mode relative error of a damping model
GEOMETRY_SD = 5e-4  # m, each member end's x and y (module docstring)
SECOND_MOMENT_SD = 0.01  # relative, each member's second moment of area (module docstring)
AREA_SD = 0.005  # relative, each member's area (module docstring)
FORM_SD = 0.1  # relative error of a candidate's predicted change: its form is not the mechanism's


@dataclass(frozen=True)
class Allowance:
    """The frame's tolerances a user states (module docstring): each member end's x and y, m (0: the file's
    geometry exact), each member's second moment of area and area, relative ((0, 0): its sections exact).
    """

    geometry_sd_m: float = GEOMETRY_SD
    section_sd: tuple[float, float] = (SECOND_MOMENT_SD, AREA_SD)


DEFAULT_ALLOWANCE = Allowance()  # a frame measured with a rule, its bars machined


@dataclass(frozen=True)
class Discrepancy:
    """The model-form error a gap is judged against (module docstring); every value relative.

    ``geometry`` (n_modes, k): each measured mode's relative frequency change per ``allowance.geometry_sd_m``
    of each of the frame's ``k`` member-end coordinates (`workbench.diagnose.geometry`); None without a frame
    geometry or with that sd 0. ``sections`` (n_modes, 2 n_members) likewise per ``allowance.section_sd``
    (second moment's, area's relative sds; `workbench.diagnose.geometry.section_columns`).
    """

    mode_sd: float = MODEL_FLOOR
    common_sd: float = COMMON_SD
    damping_sd: float = DAMPING_MODEL_SD
    geometry: np.ndarray | None = field(default=None, compare=False)
    sections: np.ndarray | None = field(default=None, compare=False)
    allowance: Allowance | None = None  # the sds ``geometry`` and ``sections`` are per (None: no frame geometry)
    geometry_names: tuple[str, ...] = ()  # ``geometry``'s columns (`workbench.diagnose.geometry.column_names`)
    section_names: tuple[str, ...] = ()  # ``sections``' columns likewise


@dataclass(frozen=True)
class Observations:
    """Condition means and their standard errors (module docstring).

    ``amplitude`` (n_cond,); ``frequency_hz``, ``frequency_se`` (n_cond, n_modes), Hz;
    ``frequency_cov`` (n_cond, n_modes, n_modes) of the relative errors of the means; ``damping``,
    ``damping_se`` likewise (damping ratios) or None; NaN marks a missing mean.
    """

    amplitude: np.ndarray
    frequency_hz: np.ndarray
    frequency_se: np.ndarray
    frequency_cov: np.ndarray  # (n_cond, n_modes, n_modes) of the relative errors of the means
    damping: np.ndarray | None
    damping_se: np.ndarray | None
    discrepancy: Discrepancy = Discrepancy(0.0, 0.0, 0.0)
    scatter_dof: float = math.inf  # tests less the rank of the line and design the scatter is measured about
    scattered: np.ndarray | None = None  # (n_modes,) the modes whose scatter was measured (None: every one)

    def joint_covariance(self, mask: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Which (condition, mode) means of the modes in ``mask`` are present, and the covariance of their
        relative errors: each condition's measurement covariance plus the discrepancy, which is shared
        between conditions (module docstring).
        """
        present = ~np.isnan(self.frequency_hz) & mask[None, :]
        cond, mode = np.nonzero(present)
        cov = np.zeros((cond.size, cond.size))
        same_cond = cond[:, None] == cond[None, :]
        cov[same_cond] = self.frequency_cov[cond[:, None], mode[:, None], mode[None, :]][same_cond]
        d = self.discrepancy
        cov += d.mode_sd ** 2 * (mode[:, None] == mode[None, :]) + d.common_sd ** 2
        for columns in (d.geometry, d.sections):  # one error per coordinate or property, shared by the conditions
            if columns is not None:
                g = columns[mode]
                cov += g @ g.T
        return present, cov


def _design(amplitude: np.ndarray, levels: np.ndarray, designed: np.ndarray | None) -> np.ndarray:
    """(n_tests, n_columns): the amplitude line (a mean with one level) and the designed factors' levels."""
    design = np.stack([np.ones_like(amplitude), amplitude], axis=1) if levels.size > 1 else np.ones((amplitude.size, 1))
    if designed is not None:  # a test that differs by design from another does not scatter from it by chance
        design = np.hstack([design, designed])
    return design


def _test_covariance(values: np.ndarray, amplitude: np.ndarray, levels: np.ndarray,
                     designed: np.ndarray | None = None, regularise: bool = False) -> tuple[np.ndarray, np.ndarray]:
    """Covariance across modes of one test's relative deviation from the amplitude line (plus the designed
    factors' levels, ``designed``: `MeasuredModes.design`), and which modes have a degree of freedom left to
    estimate it; ``regularise``: regularised (`_shrunk`), for the chi-squares of the frequencies.
    """
    design = _design(amplitude, levels, designed)
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
        if regularise:
            covariance = _shrunk(covariance, d, float(np.mean(dof[usable])))
    return covariance, usable


def _shrunk(covariance: np.ndarray, deviation: np.ndarray, dof: float) -> np.ndarray:
    """The test covariance regularised with its blend ``B = (1 - w) C + w diag(C)``, ``w`` the Ledoit-Wolf
    intensity of its correlation matrix (Schaefer & Strimmer 2005, target "D"): along each direction the tests
    sampled, the larger of the two variances; in the directions they never sampled, ``B`` projected there.

    A campaign has fewer degrees of freedom (tests less design columns) than modes: the sample covariance is
    then singular, and a difference between two levels that falls outside the few directions the tests
    happened to scatter along is judged against the floor alone, a chi-square of 76 for a chance difference
    whose diagonal chi-square is 18 (proving-ground seed 5, case 212). Written here because the formula is a few
    lines on arrays the diagnosis already has (scikit-learn's `ledoit_wolf` shrinks towards a multiple of the
    identity, and the package does not depend on it).
    """
    sd = np.sqrt(np.diag(covariance))
    live = sd > 0
    n = deviation.shape[0]
    if np.sum(live) < 2 or dof < 1 or n < 2:
        return covariance
    x = deviation[:, live] / sd[live]  # standardised: sum_k x_ki x_kj / dof is the correlation r_ij
    products = x[:, :, None] * x[:, None, :]
    corr = covariance[np.ix_(live, live)] / np.outer(sd[live], sd[live])
    # Var(r_ij) from the spread of the products, r_ij = (n / dof) mean_k w_kij (Schaefer & Strimmer's
    # n / (n - 1)^3 where dof = n - 1)
    spread = n / ((n - 1) * dof ** 2) * np.sum((products - products.mean(axis=0)) ** 2, axis=0)
    off = ~np.eye(corr.shape[0], dtype=bool)
    size = float(np.sum(corr[off] ** 2))
    weight = 1.0 if size == 0.0 else min(1.0, float(np.sum(spread[off])) / size)
    block = covariance[np.ix_(live, live)]
    blend = (1.0 - weight) * block + weight * np.diag(np.diag(block))
    # along each of the sample's own directions, the larger of its variance and the blend's: the blend fills the
    # directions the few tests never scattered along, but it also lowers the variance along the direction a
    # scattering joint moves every mode, and a chance difference along it then reads as that joint softening
    # (proving-ground seed 7, case 51)
    values, vectors = np.linalg.eigh(block)
    sampled = values > 1e-10 * values[-1]
    v, empty = vectors[:, sampled], vectors[:, ~sampled]
    floor = np.einsum("ik,ij,jk->k", v, blend, v)
    projector = empty @ empty.T  # the directions never sampled, whatever basis eigh gave them
    shrunk = covariance.copy()
    shrunk[np.ix_(live, live)] = (v * np.maximum(values[sampled], floor)) @ v.T + projector @ blend @ projector
    return shrunk


def _condition_means(values: np.ndarray, amplitude: np.ndarray, floor_rel: float, published_std: np.ndarray | None,
                     tests_count: int | None, designed: np.ndarray | None = None,
                     regularise: bool = False) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Condition means, their standard errors and the relative covariance of each condition's means.

    The tests' deviations from a straight line in amplitude (a mean with one condition) give the
    covariance across modes of one test: a joint whose modulus scatters from test to test moves
    every mode at once, so the errors of the means are correlated, and a chi-square that ignored
    it would read a chance joint scatter as a gap.

    Returns
    -------
    levels (n_cond,), means and standard errors (n_cond, n_modes) in the unit of ``values``, and
    the covariances (n_cond, n_modes, n_modes) of the relative errors of the means.
    """
    levels = np.unique(amplitude)
    means = np.array([np.nanmean(np.where((amplitude == a)[:, None], values, np.nan), axis=0) for a in levels])
    counts = np.array([np.sum(~np.isnan(values[amplitude == a]), axis=0) for a in levels])
    covariance, usable = _test_covariance(values, amplitude, levels, designed, regularise)
    if published_std is not None:  # published means: their std, no correlation known
        rel = np.asarray(published_std, float) / np.nanmean(values, axis=0)
        covariance = np.where(np.diag(usable), covariance, np.diag(rel ** 2))
        counts = np.maximum(counts, tests_count or 1)
    n = np.maximum(counts, 1)
    cov_means = np.array([covariance / np.sqrt(np.outer(n[c], n[c])) + np.diag(np.full(values.shape[1], floor_rel ** 2))
                          for c in range(levels.size)])
    se = np.sqrt(np.array([np.diag(c) for c in cov_means])) * np.abs(means)
    return levels, means, se, cov_means


def observations(measured: MeasuredModes, relative_floor: float = RELATIVE_FLOOR,
                 damping_floor: float = DAMPING_FLOOR, discrepancy: Discrepancy | None = None) -> Observations:
    """Condition means, standard errors and covariances of a campaign's modes (module docstring).

    Parameters
    ----------
    measured : the measured modes (per test, or one row of published means with their std).
    relative_floor, damping_floor : floors of the relative standard errors of the mean frequencies
        and mean damping ratios.
    discrepancy : the model-form error; None for the module docstring's (its per-mode error from the
        campaign's scatter).
    """
    n_tests = measured.frequency_hz.shape[0]
    amplitude = measured.amplitude if measured.amplitude is not None else np.ones(n_tests)
    levels = np.unique(amplitude)
    designed = measured.design
    covariance, usable = _test_covariance(measured.frequency_hz, amplitude, levels, designed)
    if designed is not None and not usable.any():
        designed = None  # one test per design cell: the scatter across cells is all the campaign can tell
        covariance, usable = _test_covariance(measured.frequency_hz, amplitude, levels)
    if measured.published_std_hz is None and not usable.any():
        # with the floor alone as the error, any model error reads as a gap far beyond scatter
        raise ValueError(f"{measured.source}: tests: {n_tests} test(s) over {levels.size} excitation level(s) leave "
                         "no degree of freedom to measure the test-to-test scatter, so a gap cannot be told from "
                         "chance; diagnose needs a repeated test (or std_hz in moments.csv)")
    levels, f, f_se, f_cov = _condition_means(measured.frequency_hz, amplitude, relative_floor,
                                              measured.published_std_hz, measured.tests_count, designed, True)
    d = d_se = None
    if measured.damping_ratio is not None:
        _, d, d_se, _ = _condition_means(measured.damping_ratio, amplitude, damping_floor, None, None, designed)
    if discrepancy is None:
        scatter = float(np.sqrt(np.mean(np.diag(covariance)[usable]))) if usable.any() else 0.0
        if measured.published_std_hz is not None:
            scatter = float(np.sqrt(np.nanmean((np.asarray(measured.published_std_hz) / np.nanmean(
                measured.frequency_hz, axis=0)) ** 2)))
        discrepancy = Discrepancy(max(MODEL_FLOOR, scatter))
    rank = int(np.linalg.matrix_rank(_design(amplitude, levels, designed)))
    dof = math.inf if measured.published_std_hz is not None else float(max(n_tests - rank, 1))
    return Observations(levels, f, f_se, f_cov, d, d_se, discrepancy, dof, usable)


def level_contrast_chi2(obs: Observations, predicted_hz: np.ndarray) -> tuple[float, int]:
    """The chi-square of the line in amplitude through the relative residuals of the levels' means, and its
    degrees of freedom.

    The line's slope, mode by mode (two levels: their difference), under the measurement covariance alone (the
    discrepancy is shared by the levels and cancels). The scatter is measured about that same line
    (`_test_covariance`), so the slope is independent of it; deviations from the line at three levels or more
    are not, and stay with the means' chi-square. Its covariance is estimated with `Observations.scatter_dof`
    degrees of freedom, a handful: read against chi-square, a chance slope along the direction a scattering
    joint moves the modes reads as softening (proving-ground seed 7, case 90: a joint's draws 2.8 sd apart
    between the levels gave a drop of 25 where chance gives 8); `workbench.diagnose.decision` reads it against F.

    Parameters
    ----------
    obs : the observations (conditions by excitation amplitude).
    predicted_hz : (n_cond, n_modes) predicted means, Hz.

    Returns
    -------
    ``(chi2, q)``, ``q`` the modes every level holds and whose scatter was measured; ``(0, 0)`` with one level.
    """
    if obs.amplitude.size < 2:
        return 0.0, 0
    r = predicted_hz / obs.frequency_hz - 1.0
    keep = np.all(np.isfinite(r), axis=0) & (obs.scattered if obs.scattered is not None else True)
    q = int(np.sum(keep))
    if q == 0:
        return 0.0, 0
    lever = _lever(obs.amplitude)
    slope = lever @ r[:, keep]
    cov = np.einsum("c,cij->ij", lever ** 2, obs.frequency_cov[:, keep][:, :, keep])
    return float(slope @ np.linalg.solve(cov, slope)), q


def frequency_chi2(obs: Observations, predicted_hz: np.ndarray, mask: np.ndarray | None = None,
                   cache: dict | None = None) -> float:
    """``r^T C^-1 r`` of the relative residuals of every condition's means over the modes in ``mask``, ``C``
    the measurement covariance plus the discrepancy (`Observations.joint_covariance`).

    ``predicted_hz`` (n_cond, n_modes), Hz; a NaN prediction of a present mean gives inf. ``cache`` keeps the
    inverted covariance between calls with the same mask.
    """
    return float(frequency_chi2_many(obs, predicted_hz[None], mask, cache)[0])


def frequency_chi2_many(obs: Observations, predicted_hz: np.ndarray, mask: np.ndarray | None = None,
                        cache: dict | None = None) -> np.ndarray:
    """`frequency_chi2` of each of ``predicted_hz`` (n_u, n_cond, n_modes): (n_u,)."""
    mask = np.ones(obs.frequency_hz.shape[1], bool) if mask is None else mask
    key = mask.tobytes()
    if cache is None or key not in cache:
        present, cov = obs.joint_covariance(mask)
        entry = (present, np.linalg.inv(cov))
        if cache is not None:
            cache[key] = entry
    else:
        entry = cache[key]
    present, w = entry
    r = (predicted_hz / obs.frequency_hz - 1.0)[:, present]
    out = np.einsum("gi,ij,gj->g", r, w, r)
    return np.where(np.all(np.isfinite(r), axis=1), out, np.inf)


def frequency_score(obs: Observations, predicted_hz: np.ndarray, reference_hz: np.ndarray) -> tuple[float, float]:
    """``(chi2, log_det)`` of a candidate's predicted means under the covariance of `frequency_chi2` plus its
    form's error, ``FORM_SD * (predicted / reference - 1)`` on each mean, shared by a mode's excitation levels
    (module docstring).

    ``log_det`` is ``log det C_form - log det C``: ``chi2 + log_det`` is minus twice the Gaussian log density up
    to a constant shared by every candidate, so that a candidate does not gain by predicting large changes.
    """
    mask = np.ones(obs.frequency_hz.shape[1], bool)
    present, cov = obs.joint_covariance(mask)
    extra = (FORM_SD * (predicted_hz / reference_hz - 1.0))[present]
    r = (predicted_hz / obs.frequency_hz - 1.0)[present]
    if not (np.all(np.isfinite(r)) and np.all(np.isfinite(extra))):
        return float("inf"), 0.0
    # the form's error is the model's, as the per-mode discrepancy is: one error per mode, the same at every
    # excitation level (scaled by that level's change). Drawn anew per level, it would widen the differences
    # between levels, which only the measurement scatter limits, and its log det would swamp the score.
    mode = np.nonzero(present)[1]
    widened = cov + np.outer(extra, extra) * (mode[:, None] == mode[None, :])
    chi2 = float(r @ np.linalg.solve(widened, r))
    return chi2, float(np.linalg.slogdet(widened)[1] - np.linalg.slogdet(cov)[1])


def damping_chi2(obs: Observations, predicted: np.ndarray) -> float:
    """Chi-square of predicted damping ratios (n_cond, n_modes) against the measured means under one damping
    model error per mode shared by the levels (`damping_whiten`); 0 without measured damping.
    """
    if obs.damping is None or obs.damping_se is None:
        return 0.0
    return float(np.sum(damping_whiten(obs, predicted - obs.damping) ** 2))


def damping_whiten(obs: Observations, x: np.ndarray) -> np.ndarray:
    """(n_cond + 1, n_modes) ``x`` (n_cond, n_modes) on the damping means written as independent unit-variance
    terms; 0 where a mean is missing. Its squares sum to ``x^T V^-1 x``, mode by mode.

    A mode's means at the levels share one model error, ``damping_sd * median zeta`` (module docstring), on top
    of each level's standard error ``se_c``: ``V = diag(se_c^2) + (damping_sd * median zeta)^2 1 1^T``. With
    ``w_c = 1 / se_c^2``, ``W = sum w_c`` and the weighted mean ``x_bar = sum w_c x_c / W``, the first ``n_cond``
    rows are ``sqrt(w_c) (x_c - x_bar)`` (the levels' differences, against the measurement alone) and the last
    ``x_bar / sqrt(1 / W + model^2)`` (the levels' mean, against the measurement and the model's error), by
    Sherman-Morrison. Until seed 21 the model error was added to every level's mean on its own, which counted it
    once per level (with two levels the chi-square rejected at 5.9 % for a stated 1 %,
    `benchmarks/damping_null_calibration.py`).
    """
    if obs.damping is None or obs.damping_se is None:
        raise ValueError("damping_whiten: no damping was measured")
    x = np.broadcast_to(x, obs.damping.shape)
    present = ~np.isnan(obs.damping) & ~np.isnan(x)
    w = np.where(present, 1.0 / np.where(present, obs.damping_se, 1.0) ** 2, 0.0)
    total = w.sum(axis=0)
    some = total > 0
    x0 = np.where(present, x, 0.0)
    mean = np.where(some, (w * x0).sum(axis=0) / np.where(some, total, 1.0), 0.0)
    model = obs.discrepancy.damping_sd * float(np.nanmedian(obs.damping))
    mean_sd = np.sqrt(np.where(some, 1.0 / np.where(some, total, 1.0), 1.0) + model**2)
    return np.vstack([np.sqrt(w) * np.where(present, x0 - mean, 0.0), np.where(some, mean / mean_sd, 0.0)[None, :]])


def mode_frequency_hz(obs: Observations) -> np.ndarray:
    """(n_modes,) each mode's mean frequency over the levels, Hz (NaN for a mode no level measured)."""
    present = ~np.isnan(obs.frequency_hz)
    count = present.sum(axis=0)
    return np.where(count > 0, np.where(present, obs.frequency_hz, 0.0).sum(axis=0) / np.maximum(count, 1), np.nan)


def damping_levels_chi2(obs: Observations, predicted: np.ndarray | None = None) -> tuple[float, int]:
    """The chi-square of the line in amplitude through the damping residuals of the levels' means, and its
    degrees of freedom: `level_contrast_chi2` for damping ratios. The line's slope, mode by mode, under the
    measurement errors alone (the model's error, one per mode, cancels in it); ``(0, 0)`` with one level.
    ``predicted`` None: a model that damps each mode alike at every level, as every damping model of the
    vocabulary does (`workbench.diagnose.fitting.damping_columns`), so that the line is the measured means' own.
    """
    if obs.damping is None or obs.damping_se is None or obs.amplitude.size < 2:
        return 0.0, 0
    r = -obs.damping if predicted is None else np.broadcast_to(predicted, obs.damping.shape) - obs.damping
    keep = np.all(np.isfinite(r), axis=0) & (obs.scattered if obs.scattered is not None else True)
    if not np.any(keep):
        return 0.0, 0
    lever = _lever(obs.amplitude)
    slope = lever @ r[:, keep]
    return float(np.sum(slope**2 / (lever**2 @ obs.damping_se[:, keep] ** 2))), int(np.sum(keep))


def _lever(amplitude: np.ndarray) -> np.ndarray:
    """(n_cond,) the weights whose dot product with the levels' values is their least-squares slope in amplitude."""
    lever = amplitude - amplitude.mean()
    return lever / np.sum(lever**2)


def chi2(residual: np.ndarray, se: np.ndarray) -> float:
    """Sum of the squared residuals over their standard errors, NaN skipped."""
    z = residual / se
    return float(np.nansum(z * z))


def rms(x: np.ndarray) -> float:
    """Root mean square, NaN skipped (NaN when nothing is left)."""
    return float(np.sqrt(np.nanmean(x * x))) if np.any(~np.isnan(x)) else float("nan")

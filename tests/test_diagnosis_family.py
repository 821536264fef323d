"""The targeted gap test's family-wise p-value (`workbench.diagnose.family`): its closed forms, its bounds, and its
tangents against the fits they stand for."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest
from conftest import REPO
from scipy.stats import chi2 as chi2_law

from workbench.diagnose.baseline import baseline
from workbench.diagnose.candidates import frame_curves
from workbench.diagnose.family import NullFamily, Tangent, _drops, tangent
from workbench.diagnose.fitting import Frequencies
from workbench.diagnose.observations import frequency_chi2, observations
from workbench.extraction.records import MeasuredModes
from workbench.model.assembly import assemble
from workbench.model.frame_file import read_frame
from workbench.model.modal import model_modes

DRAWS = 40000
MC = 4.0 * np.sqrt(0.25 / DRAWS)  # four standard errors of a share, at worst


def _law(k: int):
    return lambda drop: chi2_law.sf(drop, k)


def _family(columns: list[np.ndarray], one_sided: list[bool], k: list[int], cov: np.ndarray | None = None):
    n = columns[0].shape[0]
    tangents = [Tangent(c[:, None] if c.ndim == 1 else c, (s,) if c.ndim == 1 else (s, s))
                for c, s in zip(columns, one_sided)]
    return NullFamily(tangents, [_law(x) for x in k], np.eye(n) if cov is None else cov, DRAWS, seed=4)


@pytest.mark.parametrize("p", [0.001, 0.01, 0.05])
def test_identical_candidates_are_one_and_orthogonal_ones_are_independent(p):
    g = np.array([1.0, 2.0, -1.0, 0.5, 0.0, 3.0])
    same = _family([g] * 20, [False] * 20, [1] * 20)
    assert same.adjusted(p) == pytest.approx(p, abs=MC * np.sqrt(p) * 2)  # one test, not 20
    eye = np.eye(6)
    apart = _family(list(eye), [False] * 6, [1] * 6)
    assert apart.adjusted(p) == pytest.approx(1 - (1 - p) ** 6, abs=MC)  # six independent tests (Sidak)
    assert apart.adjusted(p) <= 6 * p + MC  # and never above Bonferroni
    one_way = _family([g], [True], [1])  # an effect that acts one way only: half the draws lower nothing
    assert one_way.adjusted(p) == pytest.approx(p / 2, abs=MC * np.sqrt(p) * 2)


def test_a_two_dof_candidate_follows_the_chi_bar_square_law():
    # two orthogonal one-sided columns: the best non-negative fit's drop is 0, chi2(1) or chi2(2) with weights
    # 1/4, 1/2, 1/4 (the chi-bar-square law of a quadrant); read with chi2(2), as the two-dof form's drop is
    two = _family([np.eye(5)[:, :2]], [True], [2])
    for p in (0.005, 0.02, 0.1):
        q = chi2_law.isf(p, 2)
        assert two.adjusted(p) == pytest.approx(0.5 * chi2_law.sf(q, 1) + 0.25 * p, abs=MC)
    z = np.random.default_rng(1).standard_normal((2000, 5))
    exact = [max(0.0, -a) ** 2 + max(0.0, -b) ** 2 for a, b in z[:, :2]]  # a change against the residual
    assert np.allclose(_drops(np.eye(5)[:, :2] * [2.0, 0.5], (True, True), z), exact)  # scale-free, NNLS


def test_correlated_candidates_fall_between_one_test_and_bonferroni_and_a_missing_one_adds_its_p():
    rng = np.random.default_rng(2)
    base = rng.standard_normal(8)
    columns = [base + 0.3 * rng.standard_normal(8) for _ in range(30)]
    a = rng.standard_normal((8, 8))
    family = _family(columns, [bool(i % 2) for i in range(30)], [1] * 30, a @ a.T + np.eye(8))
    for p in (0.0005, 0.002):
        assert p / 2 - MC <= family.adjusted(p) <= 30 * p + MC
        assert family.adjusted(p) < 0.5 * 30 * p  # far below Bonferroni: thirty near copies of one pattern
    missing = NullFamily([Tangent(base[:, None], (False,)), None], [_law(1)] * 2, np.eye(8), DRAWS, seed=4)
    alone = NullFamily([Tangent(base[:, None], (False,))], [_law(1)], np.eye(8), DRAWS, seed=4)
    assert missing.adjusted(0.01) == pytest.approx(alone.adjusted(0.01) + 0.01)


@pytest.fixture(scope="module")
def two_bolt_null():
    frame = read_frame(REPO / "frames" / "two_bolt.toml")
    frame = replace(frame, joints=tuple(replace(j, cov=0.0) for j in frame.joints))
    rng = np.random.default_rng(0)
    f = model_modes(assemble(frame), 8).frequency_hz
    obs = observations(MeasuredModes(f * (1 + 1e-3 * rng.standard_normal((6, 1)) + 1e-4 * rng.standard_normal((6, 8)))))
    base = baseline(frame, obs)
    baseline_hz = np.broadcast_to(base.frequency(base.modes.frequency_hz), obs.frequency_hz.shape).copy()
    curves = frame_curves(base, obs, np.zeros(8), np.ones(8))
    return base, obs, baseline_hz, curves


def test_a_tangent_predicts_the_drop_its_curve_fit_finds_on_chance_residuals(two_bolt_null):
    # the family's drops are the fits' drops about no effect: residuals drawn from the chi-square's own
    # covariance, each fitted on its curve (scan and Brent) and projected on the curve's tangent
    base, obs, baseline_hz, curves = two_bolt_null
    present, cov = obs.joint_covariance(np.ones(8, bool))
    lower = np.linalg.cholesky(cov)
    rng = np.random.default_rng(3)
    chosen = {(c.effect, c.parameter): c for c in curves if c is not None}
    checked = 0
    for key in (("joint_stiffness_shift", "factor"), ("support_compliance", "rz"), ("axial_prestress", "axial_force")):
        if key not in chosen:
            continue
        fitted, linear = [], []
        for _ in range(12):
            z = rng.standard_normal(int(present.sum()))
            r = np.zeros(obs.frequency_hz.shape)
            r[present] = lower @ z
            moved = replace(obs, frequency_hz=baseline_hz / (1.0 + r))
            model = Frequencies(base, moved, chosen[key])
            _, _, chi2_fit = model.fit_cost(np.ones(8, bool))
            fitted.append(frequency_chi2(moved, baseline_hz) - chi2_fit)
            t = tangent(model, present)
            assert t is not None
            linear.append(float(_drops(np.linalg.solve(lower, t.columns), t.one_sided, z[None, :])[0]))
        fitted, linear = np.array(fitted), np.array(linear)
        assert np.all(fitted >= linear - 0.05 * np.maximum(linear, 1.0) - 1e-3)  # a curve fits at least its tangent
        assert np.allclose(fitted, linear, rtol=0.15, atol=0.15), (key, fitted, linear)
        checked += 1
    assert checked >= 2


class _Line:
    """A stand-in curve model, linear in its coordinate: what `tangent` reads of a `Frequencies`."""

    def __init__(self, nominal: float, lo: float = 0.0, hi: float = 1.0, amplitude: bool = False):
        from types import SimpleNamespace

        self.lo, self.hi, self.amplitude = lo, hi, amplitude
        self.direction = np.array([[1.0, -2.0, 0.5]])
        self.obs = SimpleNamespace(frequency_hz=np.full((1, 3), 100.0))
        self.curve = SimpleNamespace(nominal=nominal, coordinate=lambda v: v)

    def predict(self, u: float) -> np.ndarray:
        return 100.0 * (1.0 + 0.01 * u * self.direction)


def test_a_tangent_is_two_sided_only_where_no_effect_lies_inside_the_range():
    present = np.ones((1, 3), bool)
    for nominal, sided in ((0.0, True), (1.0, True), (0.5, False), (0.01, False), (0.99, False)):
        t = tangent(_Line(nominal), present)  # type: ignore[arg-type]
        assert t is not None and t.one_sided == (sided,)
        g = t.columns[:, 0] / np.linalg.norm(t.columns[:, 0])
        d = _Line(0).direction[0] / np.linalg.norm(_Line(0).direction[0])
        assert abs(abs(g @ d) - 1.0) < 1e-12  # the curve's own direction
        if nominal == 1.0:
            assert g @ d < 0  # into the range: from the top end, downwards
    flat = _Line(0.0)
    flat.direction = np.zeros((1, 3))
    t = tangent(flat, present)  # type: ignore[arg-type]
    assert t is not None and t.columns.shape == (3, 0)  # moves nothing: lowers nothing, counts for nothing
    g = np.array([1.0, 0.0, 2.0])
    with_flat = NullFamily([Tangent(g[:, None], (True,)), t], [_law(1)] * 2, np.eye(3), DRAWS, seed=4)
    alone = NullFamily([Tangent(g[:, None], (True,))], [_law(1)], np.eye(3), DRAWS, seed=4)
    assert with_flat.adjusted(0.01) == alone.adjusted(0.01) and with_flat.missing == 0
    assert alone.adjusted(1e-12) > 0.0  # never 0: the measured draw counts among the draws


def test_masses_softenings_and_candidates_without_curves_take_bonferronis_term():
    from workbench.diagnose.decision import frequency_null
    from workbench.diagnose.fitting import CandidateFit

    def fit(effect, where, channel="frequency"):
        return CandidateFit(effect, where, {}, channel, 1.0, 1.0, 1.0, 1.0, 0.0, 0.0, 0.0, None, None, 1, 0.0)

    obs = observations(MeasuredModes(100.0 * (1 + 1e-3 * np.random.default_rng(0).standard_normal((6, 3)))))
    line = _Line(0.5)
    line.obs = obs  # type: ignore[assignment]
    ranking = [fit("joint_stiffness_shift", "A"), fit("added_mass", "beam"), fit("amplitude_softening", "A"),
               fit("axial_prestress", "beam"), fit("joint_damping", "A", "damping")]
    models = {c.key: (line,) for c in ranking if c.effect != "axial_prestress"}
    null = frequency_null(obs, ranking, models)  # type: ignore[arg-type]
    assert null.size == 4 and null.missing == 3  # the mass, the softening and the force without a curve
    p = 0.01  # the joint drawn, two-sided (its nominal inside the range): p; plus Bonferroni's three terms
    assert null.adjusted(p) == pytest.approx(p + 3 * p, abs=4 * np.sqrt(p / 20000))

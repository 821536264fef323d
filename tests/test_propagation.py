"""Propagation of joint variability: SMR1, SMR2, adaptive, Pert2 and Monte Carlo against closed
forms, finite differences, the exact quadrature reference and each other."""

from __future__ import annotations

import math

import numpy as np
import pytest
from conftest import REPO
from scipy.special import gammaln

from workbench.model.assembly import assemble
from workbench.model.frame_file import parse_frame, read_frame
from workbench.model.generate import multibay_frame
from workbench.model.modal import model_modes
from workbench.uq.smr import (
    adaptive,
    eigenvector_derivatives,
    pert2,
    propagate,
    sensitivities,
    smr1,
    smr2,
)
from workbench.uq.sqrt_moments import sqrt_moments
from workbench.uq.stochastic import (
    JointModel,
    expectation_rule,
    gamma_gauss_rule,
    joint_model,
    monte_carlo,
    quadrature_reference,
)


@pytest.fixture(scope="module")
def vertical():
    return assemble(read_frame(REPO / "frames" / "one_bolt_vertical.toml"))


@pytest.fixture(scope="module")
def portal():
    """A symmetric portal with a bolted joint at each beam end: close column modes (veering)."""
    return assemble(multibay_frame(1, 1, element_length=0.02))


def test_gamma_law_has_mean_one_and_the_cov(rng):
    joints = JointModel(("a", "b", "c"), np.array([0.09, 0.22, 0.0]))
    draws = joints.sample(200_000, rng)
    np.testing.assert_allclose(draws.mean(axis=0), 1.0, atol=3e-3)
    np.testing.assert_allclose(draws.std(axis=0), [0.09, 0.22, 0.0], rtol=1e-2, atol=1e-12)
    assert np.all(draws[:, 2] == 1.0)
    # the same seed gives the same numbers
    assert np.array_equal(joints.sample(5, np.random.default_rng(7)), joints.sample(5, np.random.default_rng(7)))


def test_gamma_gauss_rule_is_exact_for_polynomials():
    shape, scale = 1 / 0.22**2, 0.22**2
    nodes, weights = gamma_gauss_rule(shape, scale, 6)
    # raw moments of Gamma(k, theta): theta^n Gamma(k + n) / Gamma(k), exact up to degree 11
    for n in range(12):
        assert weights @ nodes**n == pytest.approx(math.exp(n * math.log(scale) + gammaln(shape + n) - gammaln(shape)),
                                                   rel=1e-10)


def test_sqrt_moments_against_closed_form():
    # X = b gamma: E[sqrt X] = sqrt(b theta) Gamma(k + 1/2) / Gamma(k)
    for cov in (0.01, 0.09, 0.3, 0.8):
        k, theta, b = 1 / cov**2, cov**2, 3.7e5
        mean, std = sqrt_moments(0.0, [b], [k], [theta])
        exact = math.sqrt(b * theta) * math.exp(gammaln(k + 0.5) - gammaln(k))
        assert mean == pytest.approx(exact, rel=1e-10)
        assert std == pytest.approx(math.sqrt(b - exact**2), rel=1e-6)


def test_sqrt_moments_agrees_with_the_gauss_rule_for_several_joints():
    joints = JointModel(("a", "b", "c"), np.array([0.05, 0.22, 0.1]))
    a, b = 2.0e6, np.array([3.0e5, 1.0e5, 5.0e5])
    mean, std = sqrt_moments(a, b, joints.shape, joints.scale)
    gamma, w = expectation_rule(joints)
    f = np.sqrt(a + gamma @ b)
    assert mean == pytest.approx(w @ f, rel=1e-12)
    assert std == pytest.approx(np.sqrt(w @ (f - w @ f) ** 2), rel=1e-7)


def _quad_sqrt_moments(constant: float, weights: np.ndarray, shape: np.ndarray) -> tuple[float, float]:
    """The same integral by scipy's adaptive quadrature, a second method for the fixed rule."""
    from scipy.integrate import quad

    mu = constant + weights.sum()
    rate = weights / shape / mu

    def integrand(s: float) -> float:
        x = s * rate
        r = float(np.sum(shape * (x - np.log1p(x)))) if s > 1e-3 else float(np.sum(shape * x * x / 2 * (1 - 2 * x / 3)))
        return (np.exp(-s) * np.expm1(r) if r < 1 else np.exp(r - s) - np.exp(-s)) * s**-1.5

    total = sum(quad(integrand, a, b, epsabs=0.0, epsrel=1e-12, limit=400)[0]
                for a, b in ((0, 1), (1, 10), (10, 60), (60, np.inf)))
    delta = -np.sqrt(mu) / (2 * np.sqrt(np.pi)) * total
    return float(np.sqrt(mu) + delta), float(np.sqrt(-2 * np.sqrt(mu) * delta - delta**2))


def test_the_fixed_rule_matches_adaptive_quadrature_for_many_joints():
    rng = np.random.default_rng(7)
    for _ in range(12):
        n = int(rng.integers(1, 250))
        cov = rng.uniform(0.01, 0.45, n)
        weights = rng.exponential(1.0, (4, n)) * (rng.uniform(size=(4, n)) < rng.uniform(0.05, 1.0))
        weights[:, 0] += 0.1  # every sum random
        constant = rng.choice([0.0, 1e-3, 1.0, 100.0]) * weights.sum(axis=1)
        mean, std = sqrt_moments(constant, weights, 1 / cov**2, cov**2)
        for k in range(4):
            m, s = _quad_sqrt_moments(constant[k], weights[k], 1 / cov**2)
            assert mean[k] == pytest.approx(m, rel=1e-11) and std[k] == pytest.approx(s, rel=1e-8)


def test_zero_variance_gives_the_deterministic_answer_exactly(vertical):
    joints = JointModel(vertical.joint_names, np.zeros(1))
    nominal = model_modes(vertical, 6).frequency_hz
    for method in ("smr1", "smr2", "adaptive", "pert2"):
        m = propagate(vertical, joints, method, 6)
        np.testing.assert_allclose(m.mean_hz, nominal, rtol=1e-13)
        assert np.all(m.std_hz == 0)


def test_smr1_is_exact_when_one_joint_holds_all_the_stiffness():
    # K = gamma K_1: the eigenvectors do not depend on gamma, so SMR1 is the exact solution
    frame = parse_frame({
        "name": "beam all joint", "element_length": 0.02,
        "materials": {"al": {"youngs_modulus": 70e9, "density": 2700.0}},
        "sections": {"s": {"area": 2.4e-4, "second_moment": 1.28e-9}},
        "points": {"a": [0.0, 0.0], "b": [0.5, 0.0]},
        "members": [{"name": "m", "start": "a", "end": "b", "material": "al", "section": "s"}],
        "joints": [{"name": "J", "member": "m", "span": [0.0, 0.5], "youngs_modulus": 70e9, "cov": 0.3}],
        "supports": [{"point": "a", "ux": "fixed", "uy": "fixed", "rz": "fixed"}],
    })
    model = assemble(frame)
    joints = joint_model(frame)
    exact = quadrature_reference(model, joints, 5)
    for method in (smr1, smr2, adaptive):
        m = method(model, joints, 5)
        np.testing.assert_allclose(m.mean_hz, exact.mean_hz, rtol=1e-10)
        np.testing.assert_allclose(m.std_hz, exact.std_hz, rtol=1e-8)


def test_nelson_derivatives_match_finite_differences(portal):
    sens = sensitivities(portal, 6)
    joints = np.arange(len(portal.joint_names))
    derivative = eigenvector_derivatives(portal, sens, np.array([0, 2, 5]), joints[:3])
    h = 1e-6
    for c, j in enumerate(joints[:3]):
        gamma = np.ones(len(joints))
        gamma[j] += h
        up = model_modes(portal, 8, gamma)
        gamma[j] -= 2 * h
        down = model_modes(portal, 8, gamma)
        for row, k in enumerate((0, 2, 5)):
            fd = (up.shapes[:, k] - down.shapes[:, k]) / (2 * h)
            scale = np.abs(derivative[row][:, c]).max()
            np.testing.assert_allclose(derivative[row][:, c], fd, atol=1e-5 * scale)


def test_pert2_tends_to_the_exact_moments_as_variance_shrinks(vertical):
    errors = []
    for cov in (0.02, 0.01):
        joints = JointModel(vertical.joint_names, np.array([cov]))
        exact = quadrature_reference(vertical, joints, 6)
        p = pert2(vertical, joints, 6)
        np.testing.assert_allclose(p.mean_hz, exact.mean_hz, rtol=1e-7)
        errors.append(np.abs(p.std_hz / exact.std_hz - 1).max())
    # the first-order variance misses terms of relative order cov^2
    assert errors[1] < errors[0] / 3.5 and errors[1] < 3e-4


def test_smr2_error_shrinks_much_faster_than_smr1(vertical):
    e1, e2 = [], []
    for cov in (0.1, 0.05):
        joints = JointModel(vertical.joint_names, np.array([cov]))
        exact = quadrature_reference(vertical, joints, 8)
        e1.append(np.abs(smr1(vertical, joints, 8).std_hz / exact.std_hz - 1).max())
        e2.append(np.abs(smr2(vertical, joints, 8).std_hz / exact.std_hz - 1).max())
    assert e1[0] / e1[1] > 3.5  # SMR1: relative std error ~ cov^2
    assert e2[0] < e1[0] / 20 and e2[1] < e1[1] / 20


def test_rayleigh_quotient_beats_eq6_as_printed():
    model = assemble(read_frame(REPO / "frames" / "one_bolt_horizontal.toml"))
    joints = joint_model(model.frame)
    exact = quadrature_reference(model, joints, 10)
    rq = np.abs(smr2(model, joints, 10).std_hz / exact.std_hz - 1).max()
    printed = np.abs(smr2(model, joints, 10, rayleigh=False).std_hz / exact.std_hz - 1).max()
    assert rq < 0.01 and printed > 3 * rq


def test_proximity_factor_flags_the_veering_pair_that_smr1_gets_wrong(portal):
    joints = JointModel(portal.joint_names, np.full(2, 0.1))
    exact = quadrature_reference(portal, joints, 6)
    first = smr1(portal, joints, 6)
    error = np.abs(first.std_hz / exact.std_hz - 1)
    worst = int(error.argmax())
    assert error[worst] > 0.05 and first.proximity[worst] < 10
    result = adaptive(portal, joints, 6)
    assert result.refined[worst]
    np.testing.assert_allclose(result.std_hz, exact.std_hz, rtol=0.01)
    np.testing.assert_allclose(result.mean_hz, exact.mean_hz, rtol=1e-3)


def test_adaptive_keeps_smr1_where_it_is_good_enough(vertical):
    joints = JointModel(vertical.joint_names, np.array([0.03]))
    result = adaptive(vertical, joints, 8)
    exact = quadrature_reference(vertical, joints, 8)
    assert not result.refined.all()
    np.testing.assert_allclose(result.std_hz, exact.std_hz, rtol=0.005)


def test_monte_carlo_is_seeded_and_independent_of_workers(vertical):
    joints = joint_model(vertical.frame)
    a = monte_carlo(vertical, joints, 5, 60, seed=3, chunk=20)
    from workbench.workflow.execution import mapper

    with mapper(workers=2) as dask_two_workers:
        b = monte_carlo(vertical, joints, 5, 60, seed=3, mapper=dask_two_workers, chunk=20)
    c = monte_carlo(vertical, joints, 5, 60, seed=4, chunk=20)
    assert np.array_equal(a.frequency_hz, b.frequency_hz) and np.array_equal(a.gamma, b.gamma)
    assert not np.array_equal(a.frequency_hz, c.frequency_hz)


def test_monte_carlo_agrees_with_the_exact_moments_within_its_sampling_error(vertical):
    joints = joint_model(vertical.frame)
    exact = quadrature_reference(vertical, joints, 6)
    mc = monte_carlo(vertical, joints, 6, 400, seed=11)
    se_mean, se_std = mc.standard_errors()
    assert np.all(np.abs(mc.moments.mean_hz - exact.mean_hz) < 4 * se_mean)
    assert np.all(np.abs(mc.moments.std_hz - exact.std_hz) < 4 * se_std)
    # and a wrong target fails: the moments of a stiffer joint law are many errors away
    wrong = quadrature_reference(vertical, JointModel(vertical.joint_names, np.array([0.15])), 6)
    assert np.any(np.abs(mc.moments.std_hz - wrong.std_hz) > 6 * se_std)


def test_modes_are_tracked_by_shape_not_by_sorting():
    # Two unconnected cantilevers; the shorter one is all joint, so when its modulus drops its
    # first mode falls below the other's. Tracking must follow the shape: f = sqrt(gamma) f0.
    frame = parse_frame({
        "name": "two cantilevers", "element_length": 0.02,
        "materials": {"al": {"youngs_modulus": 70e9, "density": 2700.0}},
        "sections": {"s": {"area": 2.4e-4, "second_moment": 1.28e-9}},
        "points": {"a0": [0.0, 0.0], "a1": [0.0, 0.50], "b0": [1.0, 0.0], "b1": [1.0, 0.52]},
        "members": [{"name": "A", "start": "a0", "end": "a1", "material": "al", "section": "s"},
                    {"name": "B", "start": "b0", "end": "b1", "material": "al", "section": "s"}],
        "joints": [{"name": "J", "member": "A", "span": [0.0, 0.5], "youngs_modulus": 70e9, "cov": 0.2}],
        "supports": [{"point": "a0", "ux": "fixed", "uy": "fixed", "rz": "fixed"},
                     {"point": "b0", "ux": "fixed", "uy": "fixed", "rz": "fixed"}],
    })
    model = assemble(frame)
    nominal = model_modes(model, 2)
    assert nominal.frequency_hz[1] / nominal.frequency_hz[0] < 1.1  # B first, then A
    mc = monte_carlo(model, joint_model(frame), 2, 40, seed=5)
    a_mode = int(np.argmax(np.abs(model.expand(nominal.shapes)[0::3][model.mesh.point_node["a1"]])))
    crossed = np.sqrt(mc.gamma[:, 0]) * nominal.frequency_hz[a_mode] < nominal.frequency_hz[1 - a_mode]
    assert crossed.any() and (~crossed).any()
    np.testing.assert_allclose(mc.frequency_hz[:, a_mode], np.sqrt(mc.gamma[:, 0]) * nominal.frequency_hz[a_mode],
                               rtol=1e-9)
    np.testing.assert_allclose(mc.frequency_hz[:, 1 - a_mode], nominal.frequency_hz[1 - a_mode], rtol=1e-9)


def test_bad_joint_model_is_named(vertical):
    with pytest.raises(ValueError, match="does not match the model's joints"):
        smr1(vertical, JointModel(("Z",), np.array([0.1])), 3)
    with pytest.raises(KeyError, match="no joint named 'Q'"):
        joint_model(vertical.frame, {"Q": 0.1})
    with pytest.raises(ValueError, match="method"):
        propagate(vertical, joint_model(vertical.frame), "smr3", 3)



REFERENCE = REPO / "tests" / "reference" / "propagation_one_bolt.json"


@pytest.mark.parametrize("name", ["one_bolt_vertical", "one_bolt_horizontal"])
def test_figure11_adaptive_within_1_percent_of_monte_carlo(name):
    """Paper section 4.3 on our one-bolt frames: the adaptive strategy within 1 % on both moments of
    every mode, against the stored 10 000-sample Monte Carlo (tests/reference/
    make_propagation_reference.py, seed in the file), widened by 3 standard errors of that Monte
    Carlo; and within 1 % of the noise-free quadrature reference stored beside it."""
    import json

    ref = json.loads(REFERENCE.read_text())["frames"][name]
    model = assemble(read_frame(REPO / "frames" / f"{name}.toml"))
    joints = joint_model(model.frame)
    assert {k: v["cov"] for k, v in ref["joint"].items()} == dict(zip(joints.names, joints.cov))
    result = adaptive(model, joints, 10)
    mc = ref["mc"]
    for key, se in (("mean_hz", "se_mean_hz"), ("std_hz", "se_std_hz")):
        got, expected, sampling = (np.array(v) for v in (getattr(result, key), mc[key], mc[se]))
        assert np.all(np.abs(got - expected) <= 0.01 * expected + 3 * sampling), key
        np.testing.assert_allclose(got, ref["quadrature"][key], rtol=0.01)
    # SMR1 alone is not enough for the horizontal joint (the paper: std error up to 10 %)
    if name == "one_bolt_horizontal":
        first = smr1(model, joints, 10)
        assert np.abs(first.std_hz / np.array(ref["quadrature"]["std_hz"]) - 1).max() > 0.04


def test_smr_at_another_operating_point(vertical):
    """SMR on a model moved to other joint moduli equals SMR on the frame assembled there, and
    sensitivities rescaled by gamma are refused where they would be wrong (SMR2, adaptive)."""
    from dataclasses import replace as replace_dc

    from workbench.model.joints import model_at_moduli

    frame = vertical.frame
    moved = model_at_moduli(vertical, np.array([12e9]))  # half the file's 24 GPa
    rebuilt = assemble(replace_dc(frame, joints=tuple(replace_dc(j, youngs_modulus=12e9) for j in frame.joints)))
    joints = JointModel(vertical.joint_names, np.array([0.1]))
    a, b = adaptive(moved, joints, 6), adaptive(rebuilt, joints, 6)
    np.testing.assert_allclose(a.mean_hz, b.mean_hz, rtol=1e-10)
    np.testing.assert_allclose(a.std_hz, b.std_hz, rtol=1e-8)
    scaled = sensitivities(vertical, 6, np.array([0.5]))
    np.testing.assert_allclose(smr1(vertical, joints, 6, scaled).std_hz, smr1(rebuilt, joints, 6).std_hz, rtol=1e-8)
    with pytest.raises(ValueError, match="serve SMR1 only"):
        adaptive(vertical, joints, 6, sens=scaled)
    with pytest.raises(ValueError, match="serve SMR1 only"):
        smr2(vertical, joints, 6, sens=scaled)


def test_the_cov_limit_separates_usable_from_meaningless_smr2():
    # the reason for COV_LIMIT, on a frame it was not read off (benchmarks/cov_limit.py calibrated it on
    # the one-bolt frames): at the limit SMR2 is within 10 % of exact full solves in std; well above it,
    # off by more than half, which is why the command refuses there (and does not for mc)
    from workbench.uq.limits import COV_LIMIT, check_cov
    from workbench.uq.stochastic import quadrature_reference

    frame = read_frame(REPO / "frames" / "two_bolt.toml")
    model = assemble(frame)
    worst = {}
    for cov in (COV_LIMIT, 0.7):
        joints = joint_model(frame, {j: cov for j in frame.joint_names})
        exact = quadrature_reference(model, joints, 6, points=6)
        worst[cov] = np.max(np.abs(smr2(model, joints, 6).std_hz / exact.std_hz - 1))
    assert worst[COV_LIMIT] < 0.10 and worst[0.7] > 0.5
    joints = joint_model(frame, {j: 0.7 for j in frame.joint_names})
    with pytest.raises(ValueError, match=r"joints\[\d\]\.cov.*--method mc"):
        check_cov(model, joints, "adaptive")
    check_cov(model, joints, "mc")

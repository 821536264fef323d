"""Validate the dynamic-stiffness reference solver against closed forms."""

import numpy as np
import pytest
from scipy.optimize import brentq

try:  # works with ``python -m pytest`` or if tests/ becomes a package
    from tests.reference.dynamic_stiffness import (
        _clamped_member_count,
        member_dynamic_stiffness,
        natural_frequencies_hz,
        portal_frame_reference,
    )
except ImportError:  # plain ``pytest``: rootdir/tests is on sys.path
    from reference.dynamic_stiffness import (
        _clamped_member_count,
        member_dynamic_stiffness,
        natural_frequencies_hz,
        portal_frame_reference,
    )

RTOL = 1e-7
E, RHO, B, H, L = 210e9, 7850.0, 0.05, 0.1, 1.0
A, I = B * H, B * H ** 3 / 12.0
C_BAR = np.sqrt(E / RHO)
CANTILEVER_BL = [1.8751040687, 4.6940911330, 7.8547574382, 10.9955407349,
                 14.1371683910]
CLAMPED_BL = [4.7300407449, 7.8532046241, 10.9956078380, 14.1371654913,
              17.2787596574]


def bending_hz(bl, length=L, area=A, inertia=I):
    """Euler-Bernoulli frequency (Hz) for a root beta*L of a uniform beam."""
    return np.asarray(bl) ** 2 / (2 * np.pi * length ** 2) * np.sqrt(
        E * inertia / (RHO * area))


def line_model(n_members, angle_deg=30.0, area=A, inertia=I):
    """Straight member of length L split into collinear pieces, inclined."""
    d = np.array([np.cos(np.radians(angle_deg)), np.sin(np.radians(angle_deg))])
    xy = np.outer(np.linspace(0.0, L, n_members + 1), d)
    members = [dict(start=k, end=k + 1, E=E, A=area, I=inertia, rho=RHO)
               for k in range(n_members)]
    return xy, members


def merged(bending, axial, upto):
    """Sorted bending + axial frequencies not above ``upto``."""
    f = np.sort(np.concatenate([bending, axial]))
    return f[f <= upto * (1 + 1e-12)]


def test_static_limit_and_symmetry():
    k0 = member_dynamic_stiffness(0.0, L, E, A, I, RHO)
    ei = E * I
    kb = ei / L ** 3 * np.array([[12, 6 * L, -12, 6 * L],
                                 [6 * L, 4 * L ** 2, -6 * L, 2 * L ** 2],
                                 [-12, -6 * L, 12, -6 * L],
                                 [6 * L, 2 * L ** 2, -6 * L, 4 * L ** 2]])
    np.testing.assert_allclose(k0[np.ix_([1, 2, 4, 5], [1, 2, 4, 5])], kb)
    np.testing.assert_allclose(k0[0, [0, 3]], [E * A / L, -E * A / L])
    for w in [10.0, 3e3, 2e4, 1e6]:
        k = member_dynamic_stiffness(w, L, E, A, I, RHO)
        assert np.all(np.isfinite(k))
        np.testing.assert_allclose(k, k.T, rtol=1e-12, atol=1e-12 * abs(k).max())


def test_clamped_member_count_formula():
    """J0 jumps exactly at the clamped-clamped roots (bending and axial)."""
    def omega(nu):  # circular frequency at which beta*L = nu
        return (nu / L) ** 2 * np.sqrt(E * I / (RHO * A))

    for n, root in enumerate(CLAMPED_BL):
        below = _clamped_member_count(omega(root * (1 - 1e-9)), L, E, A, I, RHO)
        above = _clamped_member_count(omega(root * (1 + 1e-9)), L, E, A, I, RHO)
        n_axial = int(np.floor(omega(root) * L / (np.pi * C_BAR)))
        assert (below, above) == (n + n_axial, n + 1 + n_axial)


@pytest.mark.parametrize("n_members", [1, 3])
def test_cantilever(n_members):
    xy, members = line_model(n_members)
    fb = bending_hz(CANTILEVER_BL)
    fa = (2 * np.arange(1, 6) - 1) / (4 * L) * C_BAR
    expected = merged(fb, fa, fb[-1])
    assert len(expected) == 7  # two axial modes interleave
    got = natural_frequencies_hz(xy, members, [0, 1, 2], len(expected))
    np.testing.assert_allclose(got, expected, rtol=RTOL)


@pytest.mark.parametrize("n_members", [1, 3])
def test_clamped_clamped(n_members):
    xy, members = line_model(n_members, angle_deg=-70.0)
    fb = bending_hz(CLAMPED_BL)
    fa = np.arange(1, 6) / (2 * L) * C_BAR
    expected = merged(fb, fa, fb[-1])
    last = 3 * n_members
    got = natural_frequencies_hz(xy, members, [0, 1, 2, last, last + 1,
                                               last + 2], len(expected))
    np.testing.assert_allclose(got, expected, rtol=RTOL)


def _slender():
    area, inertia = 0.02 * 0.01, 0.02 * 0.01 ** 3 / 12.0
    xy, members = line_model(2, angle_deg=0.0, area=area, inertia=inertia)
    return xy, members, area, inertia


def _roots(func, n):
    grid = np.linspace(0.5, 12.0, 2000)
    vals = [func(x) for x in grid]
    out = [brentq(func, a, b, xtol=1e-14) for a, b, fa, fb in
           zip(grid[:-1], grid[1:], vals[:-1], vals[1:]) if fa * fb < 0]
    return np.array(out[:n])


def test_cantilever_tip_mass():
    xy, members, area, inertia = _slender()
    ratio = 0.7
    m_tip = ratio * RHO * area * L

    def eq(x):
        return (1 + np.cos(x) * np.cosh(x) + ratio * x * (
            np.cos(x) * np.sinh(x) - np.sin(x) * np.cosh(x)))

    expected = bending_hz(_roots(eq, 3), area=area, inertia=inertia)
    got = natural_frequencies_hz(xy, members, [0, 1, 2], 3,
                                 node_masses={2: (m_tip, 0.0)})
    assert expected[-1] < 0.1 * C_BAR / L  # axial modes far above
    np.testing.assert_allclose(got, expected, rtol=RTOL)


def test_cantilever_tip_spring():
    """Transverse tip spring: 1 + cC + kappa/x^3 (sC - cS) = 0."""
    xy, members, area, inertia = _slender()
    kappa = 50.0
    k_spring = kappa * E * inertia / L ** 3

    def eq(x):
        return (1 + np.cos(x) * np.cosh(x) + kappa / x ** 3 * (
            np.sin(x) * np.cosh(x) - np.cos(x) * np.sinh(x)))

    expected = bending_hz(_roots(eq, 3), area=area, inertia=inertia)
    got = natural_frequencies_hz(xy, members, [0, 1, 2, 6], 3,
                                 grounded_springs={7: k_spring})
    np.testing.assert_allclose(got, expected, rtol=RTOL)


def test_portal_reference_is_consistent():
    ref = portal_frame_reference()
    f = ref["frequencies_hz"]
    assert f.shape == (6,) and np.all(np.diff(f) > 0)
    # the same frame with every member split in two gives the same answer
    xy = np.vstack([ref["node_xy"], [[0, 0.25], [0.3, 0.5], [0.6, 0.25]]])
    sec = {k: ref["members"][0][k] for k in ("E", "A", "I", "rho")}
    pairs = [(0, 4), (4, 1), (1, 5), (5, 2), (2, 6), (6, 3)]
    members = [dict(start=a, end=b, **sec) for a, b in pairs]
    np.testing.assert_allclose(
        natural_frequencies_hz(xy, members, ref["fixed_dofs"], 6), f, rtol=RTOL)

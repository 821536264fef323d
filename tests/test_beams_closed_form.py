"""Beam frequencies against closed forms, and the convergence rate of the elements."""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
import pytest
from conftest import ALUMINIUM, CLAMP, bar_section, straight_beam

from workbench.model.assembly import assemble
from workbench.model.modal import model_modes

# Roots of 1 + cos(bL) cosh(bL) = 0 (cantilever) and 1 - cos cosh = 0 (clamped-clamped).
CANTILEVER_BL = [1.8751040687, 4.6940911330, 7.8547574382, 10.9955407349, 14.1371683910]
CLAMPED_BL = [4.7300407449, 7.8532046241, 10.9956078380, 14.1371654913, 17.2787596574]


def euler_bernoulli_hz(beta_l: list[float], length: float, section: dict) -> np.ndarray:
    ei = ALUMINIUM["youngs_modulus"] * section["second_moment"]
    rho_a = ALUMINIUM["density"] * section["area"]
    return np.array(beta_l) ** 2 / (2 * math.pi * length**2) * math.sqrt(ei / rho_a)


def bending_frequencies(frame, count: int) -> np.ndarray:
    """Frequencies of the first ``count`` modes of a beam along x that have no axial motion."""
    model = assemble(frame)
    modes = model_modes(model, count + 4)
    ux = model.expand(modes.shapes)[0::3]
    axial = np.linalg.norm(ux, axis=0) > 1e-6 * np.linalg.norm(modes.shapes, axis=0)
    return modes.frequency_hz[~axial][:count]


@pytest.mark.parametrize("supports, beta_l", [
    ([{"point": "a", **CLAMP}], CANTILEVER_BL),
    ([{"point": "a", **CLAMP}, {"point": "b", **CLAMP}], CLAMPED_BL),
], ids=["cantilever", "clamped-clamped"])
def test_euler_bernoulli_beams_within_0p1_percent(supports, beta_l):
    frame = straight_beam(0.8, supports)
    got = bending_frequencies(frame, 5)
    expected = euler_bernoulli_hz(beta_l, 0.8, bar_section())
    np.testing.assert_allclose(got, expected, rtol=1e-3)
    # and in fact far closer with 80 cubic elements (h^4 convergence, see below)
    np.testing.assert_allclose(got, expected, rtol=3e-6)


def test_cantilever_eigenvalue_error_shrinks_as_h_to_the_fourth():
    expected = euler_bernoulli_hz(CANTILEVER_BL, 1.0, bar_section())[2]
    sizes = np.array([1 / 4, 1 / 8, 1 / 16, 1 / 32])
    errors = [abs((bending_frequencies(straight_beam(1.0, [{"point": "a", **CLAMP}], element_length=h), 3)[2]
                   / expected) ** 2 - 1) for h in sizes]
    slope = np.polyfit(np.log(sizes), np.log(errors), 1)[0]
    assert 3.8 < slope < 4.2, (errors, slope)


def timoshenko_simply_supported_hz(n: int, length: float, section: dict) -> float:
    """Exact bending frequency of mode n of a simply supported Timoshenko beam (lower root)."""
    e, rho, nu = ALUMINIUM["youngs_modulus"], ALUMINIUM["density"], ALUMINIUM["poisson_ratio"]
    a, i, kappa = section["area"], section["second_moment"], section["shear_coefficient"]
    kga = kappa * e / (2 * (1 + nu)) * a
    k = n * math.pi / length
    # rho A rho I x^2 - (kGA k^2 rho I + rho A (E I k^2 + kGA)) x + kGA E I k^4 = 0, x = omega^2
    coefficients = [rho * a * rho * i, -(kga * k**2 * rho * i + rho * a * (e * i * k**2 + kga)), kga * e * i * k**4]
    return math.sqrt(min(np.roots(coefficients).real)) / (2 * math.pi)


SIMPLY_SUPPORTED = [{"point": "a", "ux": "fixed", "uy": "fixed"}, {"point": "b", "uy": "fixed"}]


def test_thick_timoshenko_beam_against_closed_form():
    section = bar_section(width=0.03, thickness=0.06)  # length / depth = 5
    expected = np.array([timoshenko_simply_supported_hz(n, 0.3, section) for n in (1, 2, 3, 4)])
    errors = []
    for h in (0.006, 0.003):
        frame = straight_beam(0.3, SIMPLY_SUPPORTED, element_length=h, theory="timoshenko", section=section)
        got = bending_frequencies(frame, 4)
        errors.append(np.abs(got / expected - 1))
    np.testing.assert_array_less(errors[1], 1e-3)
    # The interdependent-interpolation element holds only static solutions, so where shear
    # matters its eigenvalues converge as h^2 (not h^4 as for Euler-Bernoulli): halving h
    # divides the error by about 4.
    assert np.all((errors[0] / errors[1] > 3.8) & (errors[0] / errors[1] < 4.2)), errors
    # shear and rotary inertia matter here: Euler-Bernoulli is more than 5 % stiff on mode 2
    euler = bending_frequencies(straight_beam(0.3, SIMPLY_SUPPORTED, element_length=0.003, section=section), 4)
    assert euler[1] > 1.05 * got[1]


def test_timoshenko_tends_to_euler_bernoulli_as_the_beam_gets_slender():
    gaps = []
    for thickness in (0.06, 0.02, 0.005, 0.001):
        section = bar_section(thickness=thickness)
        t = bending_frequencies(straight_beam(0.3, SIMPLY_SUPPORTED, element_length=0.005,
                                              theory="timoshenko", section=section), 3)
        e = bending_frequencies(straight_beam(0.3, SIMPLY_SUPPORTED, element_length=0.005, section=section), 3)
        gaps.append(np.max(np.abs(t / e - 1)))
    assert all(g1 > g2 for g1, g2 in zip(gaps, gaps[1:])), gaps
    # shear and rotary inertia corrections scale as (thickness / length)^2
    scaled = np.array(gaps[1:]) / np.array([0.02, 0.005, 0.001]) ** 2
    assert abs(scaled[-1] / scaled[-2] - 1) < 0.02, scaled  # constant in the slender limit
    assert gaps[-1] < 3e-4


def test_axial_tension_stiffens_a_simply_supported_beam_as_closed_form():
    # omega_n^2 = (n pi / L)^4 EI / rho A + (n pi / L)^2 N / rho A for a pinned-pinned beam
    section, length = bar_section(), 0.6
    ei = ALUMINIUM["youngs_modulus"] * section["second_moment"]
    rho_a = ALUMINIUM["density"] * section["area"]
    n_crit = math.pi**2 * ei / length**2
    for force in (0.5 * n_crit, -0.5 * n_crit):
        got = bending_frequencies(straight_beam(length, SIMPLY_SUPPORTED, axial_force=force), 3)
        k = np.arange(1, 4) * math.pi / length
        expected = np.sqrt((k**4 * ei + k**2 * force) / rho_a) / (2 * math.pi)
        np.testing.assert_allclose(got, expected, rtol=1e-5)


def test_compression_beyond_buckling_is_refused():
    section, length = bar_section(), 0.6
    n_crit = math.pi**2 * ALUMINIUM["youngs_modulus"] * section["second_moment"] / length**2
    with pytest.raises(ValueError, match="singular model"):
        model_modes(assemble(straight_beam(length, SIMPLY_SUPPORTED, axial_force=-1.5 * n_crit)), 3)


def _locked(frame, force: float):
    return replace(frame, members=tuple(replace(m, locked_force=force) for m in frame.members))


def test_locked_force_equals_a_frame_force_where_the_chord_cannot_turn():
    # pinned-pinned: the chord is held, so a force locked in between the ends is the same load as one the
    # supports carry (the closed form above)
    section, length = bar_section(), 0.6
    n_crit = math.pi**2 * ALUMINIUM["youngs_modulus"] * section["second_moment"] / length**2
    carried = bending_frequencies(straight_beam(length, SIMPLY_SUPPORTED, axial_force=-0.5 * n_crit), 3)
    locked = bending_frequencies(_locked(straight_beam(length, SIMPLY_SUPPORTED), -0.5 * n_crit), 3)
    np.testing.assert_allclose(locked, carried, rtol=1e-9)


@pytest.mark.parametrize("angle", [0.0, 0.65, math.pi / 2])
def test_a_cantilever_tied_to_its_root_buckles_at_the_pinned_columns_load(angle):
    # a compressive force P that always points at the root (a tie from root to tip), tip deflection d:
    # EI v'' + P v = P d x / L, v(0) = v'(0) = 0, v(L) = d, so v = d (x / L - sin(kx) / kL) and sin kL = 0:
    # P = (pi / L)^2 EI, four times a free tip's (pi / 2L)^2 EI, which the same force carried by the clamp gives
    section, length = bar_section(), 0.6
    pinned = math.pi**2 * ALUMINIUM["youngs_modulus"] * section["second_moment"] / length**2
    def tilted(frame):  # the same beam at ``angle`` in the plane: the chord's stiffness is rotated with it
        return replace(frame, points={**frame.points, "b": (length * math.cos(angle), length * math.sin(angle))})

    beam = tilted(straight_beam(length, [{"point": "a", **CLAMP}]))
    assert model_modes(assemble(_locked(beam, -0.97 * pinned)), 2).frequency_hz[0] > 0.0
    for frame in (_locked(beam, -1.03 * pinned), tilted(straight_beam(length, [{"point": "a", **CLAMP}],
                                                                      axial_force=-0.3 * pinned))):
        with pytest.raises(ValueError, match="singular model"):
            model_modes(assemble(frame), 2)

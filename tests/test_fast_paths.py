"""Fast paths that large models need, against the plain definitions they replace.

- `points_on_member` (all points at once) against `locate_point` (one point) on a generated frame;
- the joint pattern built in one pass against the sum of the joints' matrices;
- `_x_minus_log1p` (a short series below 0.01) against 50-digit decimal arithmetic;
- the circle fit's written-out Jacobians against central differences of its residuals, at the start
  and at the solution of every least-squares problem a noisy two-mode fit poses;
- the two-pole fit's variable-projection Jacobian (Golub-Pereyra) against central differences, on
  and off the solution, noise-free and noisy.
"""

from __future__ import annotations

from decimal import Decimal, getcontext

import numpy as np
import pytest
import scipy.sparse as sp
from scipy.optimize._numdiff import approx_derivative

from workbench.extraction import circle_geometry, circlefit, multimode
from workbench.model.assembly import assemble
from workbench.model.frame import locate_point, points_on_member
from workbench.model.generate import multibay_frame
from workbench.model.modal import Modes, add_noise, modal_frf
from workbench.uq.sqrt_moments import _x_minus_log1p


def test_points_on_member_is_locate_point_for_every_point():
    frame = multibay_frame(3, 2, element_length=0.05)
    for member in frame.members:
        one_by_one = {name: locate_point(frame.points, member, xy) for name, xy in frame.points.items()}
        assert points_on_member(frame.points, member) == {k: v for k, v in one_by_one.items() if v is not None}


def test_the_joint_pattern_gives_the_sum_of_the_joint_matrices():
    model = assemble(multibay_frame(2, 2, element_length=0.05))
    gamma = np.linspace(0.5, 1.5, len(model.joint_names))
    expected = model.stiffness_rest + sum((g * k for g, k in zip(gamma, model.stiffness_joints)),
                                          sp.csr_matrix(model.stiffness_rest.shape))
    assert abs(model.stiffness(gamma) - expected).max() <= 1e-12 * abs(expected).max()


def test_x_minus_log1p_to_the_last_digits():
    getcontext().prec = 50
    x = np.concatenate([np.logspace(-12, 2, 300), -np.logspace(-12, np.log10(0.9), 150)])
    exact = np.array([float(Decimal(float(v)) - (Decimal(1) + Decimal(float(v))).ln()) for v in x])
    assert np.max(np.abs(_x_minus_log1p(x) / exact - 1.0)) < 5e-14


def test_circle_fit_jacobians_are_the_derivatives_of_its_residuals(monkeypatch):
    checked = []
    plain = circlefit.lm

    def checking(fun, x0, jac, **options):
        sol = plain(fun, x0, jac, **options)
        for x in (np.asarray(x0, float), sol.x):
            numeric = approx_derivative(fun, x, method="3-point")
            assert np.allclose(jac(x), numeric, rtol=1e-5, atol=1e-6 * np.abs(numeric).max())
        checked.append(len(x0))
        return sol

    monkeypatch.setattr(circlefit, "lm", checking)
    monkeypatch.setattr(circle_geometry, "lm", checking)  # the geometric circle and the sweep (`fit_sweep`)
    f = np.linspace(80.0, 130.0, 400)
    modes = Modes(eigenvalues=(2.0 * np.pi * np.array([100.0, 112.0])) ** 2, shapes=np.array([[1.0, 0.6],
                                                                                               [0.4, -1.0]]))
    clean = modal_frf(modes, f, np.array([0]), 0, np.array([0.01, 0.004]), "accelerance")
    h = add_noise(clean, 40.0, np.random.default_rng(3))
    for band in ((96.0, 104.0), (110.0, 114.0)):
        fit = circlefit.circle_fit(f, h[0], band, "accelerance")
        assert abs(fit.frequency_hz / np.mean(band) - 1.0) < 0.01
    assert {3} < set(checked) and max(checked) > 6  # the sweep and the joint refinement with trend terms


@pytest.mark.parametrize("noise", [0.0, 0.01, 0.3])
def test_the_pole_fit_jacobian_is_the_derivative_of_the_projected_residual(noise):
    rng = np.random.default_rng(1)
    omega = 2.0 * np.pi * np.linspace(90.0, 120.0, 300)
    x = np.log([2.0 * np.pi * 100.0, 2.0 * np.pi * 104.0, 0.01, 0.008])
    clean = multimode._basis(omega, x, 2) @ (rng.normal(size=(4, 3)) + 1j * rng.normal(size=(4, 3)))
    data = clean + noise * np.abs(clean).mean() * (rng.normal(size=clean.shape) + 1j * rng.normal(size=clean.shape))

    def residual(p):
        r = multimode._solve(omega, data, p, 2)[1].ravel()
        return np.concatenate([r.real, r.imag])

    for p in (x, x + np.array([0.001, -0.002, 0.05, -0.03])):
        numeric = approx_derivative(residual, p, method="3-point")
        assert np.abs(multimode._projection_jacobian(omega, data, p, 2) - numeric).max() < 1e-4 * np.abs(numeric).max()

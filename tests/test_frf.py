"""FRF synthesis by modal superposition against a direct solve and the single-mode formula."""

from __future__ import annotations

import numpy as np
import pytest
import scipy.linalg as sla

from workbench.model.assembly import assemble
from workbench.model.generate import multibay_frame
from workbench.model.modal import Modes, modal_frf, model_modes, solve_modes
from workbench.model.structure import structure_frf


@pytest.fixture(scope="module")
def small():
    return assemble(multibay_frame(1, 1, element_length=0.05))


def test_modal_sum_with_all_modes_equals_the_direct_solve(small):
    # With every mode and C = M Phi diag(2 zeta omega) Phi^T M, the modal sum is exact.
    n = small.size
    k, m = small.stiffness().toarray(), small.mass.toarray()
    modes = solve_modes(k, m, n, "dense")
    zeta = np.linspace(0.002, 0.03, n)
    c = m @ modes.shapes @ np.diag(2 * zeta * modes.omega) @ modes.shapes.T @ m
    f_hz = np.array([3.0, 40.0, 97.5, 333.0, 1200.0])
    out, exc = [small.dof("n1_1", "ux"), small.dof("n1_0", "uy")], small.dof("drive", "ux")
    direct = []
    for f in f_hz:
        w = 2 * np.pi * f
        force = np.zeros(n)
        force[exc] = 1.0
        direct.append(sla.solve(k - w**2 * m + 1j * w * c, force)[out])
    direct = np.array(direct).T
    np.testing.assert_allclose(modal_frf(modes, f_hz, out, exc, zeta, "receptance"), direct, rtol=1e-7)
    w = 2 * np.pi * f_hz
    np.testing.assert_allclose(modal_frf(modes, f_hz, out, exc, zeta, "mobility"), 1j * w * direct, rtol=1e-7)
    np.testing.assert_allclose(modal_frf(modes, f_hz, out, exc, zeta, "accelerance"), -(w**2) * direct, rtol=1e-7)


def test_lightly_damped_peak_is_at_the_mode_with_the_modal_height(small):
    modes = model_modes(small, 12)
    zeta = np.full(12, 0.002)
    resp, exc = small.dof("n1_1", "ux"), small.dof("drive", "ux")
    r = 0  # first mode: well separated
    fr = modes.frequency_hz[r]
    grid = fr * (1 + np.linspace(-0.01, 0.01, 40001))
    h = modal_frf(modes, grid, [resp], exc, zeta, "receptance")[0]
    peak = grid[np.abs(h).argmax()]
    assert peak == pytest.approx(fr * np.sqrt(1 - 2 * zeta[r] ** 2), rel=2e-5)
    constant = modes.shapes[resp, r] * modes.shapes[exc, r]
    single_mode_height = abs(constant) / (2 * zeta[r] * modes.omega[r] ** 2)
    assert np.abs(h).max() == pytest.approx(single_mode_height, rel=0.02)
    # at resonance the mode's receptance is -i times its height (phase -90 degrees)
    h_r = modal_frf(Modes(modes.eigenvalues[[r]], modes.shapes[:, [r]]), [fr], [resp], exc, zeta[[r]])[0, 0]
    assert h_r == pytest.approx(-1j * constant / (2 * zeta[r] * modes.omega[r] ** 2), rel=1e-12)


def test_frame_frf_uses_the_frame_sensors_and_damping(small):
    modes = model_modes(small, 6)
    frf = structure_frf(small, modes, np.linspace(0, 500, 11), "accelerance")
    assert frf.responses == ("top",) and frf.values.shape == (1, 11) and frf.quantity == "accelerance"
    assert frf.values[0, 0] == 0  # accelerance vanishes at 0 Hz
    with pytest.raises(ValueError, match="quantity"):
        modal_frf(modes, [1.0], [0], 0, np.full(6, 0.01), "compliance")
    with pytest.raises(ValueError, match="damping_ratios: expected 6"):
        modal_frf(modes, [1.0], [0], 0, np.full(3, 0.01))

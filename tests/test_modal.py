"""Modal analysis: invariants, dense against sparse, and the joint decomposition of eq. (3)-(4)."""

from __future__ import annotations

import numpy as np
import pytest
import scipy.sparse as sp
from conftest import shared_path

from workbench.model.assembly import assemble, element_energies, strain_energy
from workbench.model.frame_file import read_frame
from workbench.model.generate import multibay_for_dofs, multibay_frame
from workbench.model.modal import mac, model_modes, solve_modes


@pytest.fixture(scope="module")
def bolted():
    """A 2 x 2 bolted multi-bay frame: 8 joints, springs and masses, about 1 000 dofs."""
    return assemble(multibay_frame(2, 2, element_length=0.02))


def test_matrices_are_symmetric_and_mass_is_positive_definite(bolted):
    for a in (bolted.mass, bolted.stiffness_rest, *bolted.stiffness_joints):
        assert abs(a - a.T).max() <= 1e-12 * abs(a).max()
    assert np.linalg.eigvalsh(bolted.mass.toarray()).min() > 0


def test_total_mass_is_the_bars_plus_the_lumped_masses():
    frame = multibay_frame(2, 1, element_length=0.05)
    model = assemble(frame)
    length = sum(np.hypot(*np.subtract(frame.points[m.end], frame.points[m.start])) for m in frame.members)
    section, material = frame.sections["bar"], frame.materials["aluminium"]
    expected = material.density * section.area * length + sum(p.mass for p in frame.masses)
    ux = np.zeros(model.mesh.dof_count)
    ux[0::3] = 1.0
    free_ux = ux[model.free_dofs]
    # the clamped base nodes carry a share of the bars' mass on fixed dofs; count it back
    full = assemble(frame.__class__(**{**frame.__dict__, "supports": ()}))
    ux_full = np.zeros(full.size)
    ux_full[0::3] = 1.0
    assert ux_full @ full.mass @ ux_full == pytest.approx(expected, rel=1e-12)
    assert free_ux @ model.mass @ free_ux < expected


def test_free_free_frame_has_three_rigid_modes():
    frame = multibay_frame(1, 1, element_length=0.02)
    free = assemble(frame.__class__(**{**frame.__dict__, "supports": ()}))
    for method in ("dense", "sparse"):
        modes = solve_modes(free.stiffness(), free.mass, 6, method)
        assert np.all(np.abs(modes.frequency_hz[:3]) < 1e-3 * modes.frequency_hz[3])
        assert modes.frequency_hz[3] > 1.0


def test_mass_normalised_and_stiffness_diagonal(bolted):
    modes = model_modes(bolted, 12)
    np.testing.assert_allclose(modes.shapes.T @ bolted.mass @ modes.shapes, np.eye(12), atol=1e-10)
    k = modes.shapes.T @ bolted.stiffness() @ modes.shapes
    np.testing.assert_allclose(k, np.diag(modes.eigenvalues), atol=1e-9 * modes.eigenvalues.max())


def test_stiffness_is_linear_in_the_joint_moduli(bolted, rng):
    gamma = rng.gamma(1 / 0.09**2, 0.09**2, len(bolted.stiffness_joints))
    explicit = bolted.stiffness_rest + sum(g * k for g, k in zip(gamma, bolted.stiffness_joints))
    assert abs(bolted.stiffness(gamma) - explicit).max() <= 1e-14 * abs(explicit).max()
    # a joint at the rest material's modulus is the monolithic member: gamma_j = E_bar / E_j
    frame = bolted.frame
    monolithic = assemble(frame.__class__(**{**frame.__dict__, "joints": ()}))
    ratio = frame.materials["aluminium"].youngs_modulus / np.array([j.youngs_modulus for j in frame.joints])
    # (same nodes, numbered differently: compare the spectra)
    np.testing.assert_allclose(model_modes(bolted, 8, gamma=ratio).eigenvalues,
                               model_modes(monolithic, 8).eigenvalues, rtol=1e-11)


def test_stiffness_rejects_bad_gamma(bolted):
    with pytest.raises(ValueError, match="expected 8 values"):
        bolted.stiffness(np.ones(3))
    with pytest.raises(ValueError, match="finite and positive"):
        bolted.stiffness(np.r_[np.ones(7), np.nan])


def test_softer_joints_lower_every_frequency(bolted):
    nominal = model_modes(bolted, 8).frequency_hz
    soft = model_modes(bolted, 8, gamma=np.full(8, 0.5)).frequency_hz
    assert np.all(soft < nominal)


def test_element_energies_sum_to_phi_k_phi(bolted, rng):
    v = rng.standard_normal((bolted.size, 3))
    np.testing.assert_allclose(strain_energy(bolted, v), np.einsum("ik,ik->k", v, bolted.stiffness() @ v),
                               rtol=1e-12)
    modes = model_modes(bolted, 4)
    per_element = element_energies(bolted, modes.shapes)
    assert per_element.shape == (len(bolted.mesh.connectivity), 4) and per_element.min() >= 0


def test_dense_and_sparse_agree(bolted):
    dense, sparse = model_modes(bolted, 10, method="dense"), model_modes(bolted, 10, method="sparse")
    np.testing.assert_allclose(sparse.eigenvalues, dense.eigenvalues, rtol=1e-10)
    np.testing.assert_allclose(np.diag(mac(dense.shapes, sparse.shapes)), 1.0, atol=1e-10)


@pytest.mark.slow
def test_dense_and_sparse_agree_on_20000_dofs():
    model = assemble(multibay_for_dofs(20000))
    assert model.size >= 20000
    dense, sparse = model_modes(model, 10, method="dense"), model_modes(model, 10, method="sparse")
    np.testing.assert_allclose(sparse.eigenvalues, dense.eigenvalues, rtol=1e-8)


def test_mac_properties(rng):
    a = rng.standard_normal((30, 4))
    m = mac(a, a)
    np.testing.assert_allclose(np.diag(m), 1.0)
    assert np.all((m >= 0) & (m <= 1 + 1e-12))
    np.testing.assert_allclose(mac(3.0 * a, -a), m)  # scale-invariant
    q, _ = np.linalg.qr(a)
    np.testing.assert_allclose(mac(q, q), np.eye(4), atol=1e-12)


def test_singular_model_is_refused():
    frame = multibay_frame(1, 1, element_length=0.05)
    model = assemble(frame)
    with pytest.raises(ValueError, match="count"):
        solve_modes(model.stiffness(), model.mass, model.size + 1)
    with pytest.raises(ValueError, match="singular model"):
        solve_modes(model.stiffness(), sp.csr_matrix(model.mass.shape), 3, "dense")


def test_sensor_on_a_fixed_dof_is_named():
    model = assemble(read_frame(shared_path("examples", "independent-two-test-campaign", "frame.toml")))
    with pytest.raises(ValueError, match="ux at point 'base_left' is a fixed support dof"):
        model.dof("base_left", "ux")


def test_a_span_ending_a_rounding_error_before_a_member_end_keeps_the_members_connected():
    from workbench.model.frame_file import parse_frame

    # member "low" is 0.04000000000000002 m long; its joint span ends at 0.04
    frame = parse_frame({
        "name": "two collinear bars", "element_length": 0.01,
        "materials": {"al": {"youngs_modulus": 70e9, "density": 2700.0}},
        "sections": {"s": {"area": 2.4e-4, "second_moment": 1.28e-9}},
        "points": {"a": [0.0, 0.23], "b": [0.0, 0.27], "c": [0.0, 0.5], "o": [0.0, 0.0]},
        "members": [{"name": "base", "start": "o", "end": "a", "material": "al", "section": "s"},
                    {"name": "low", "start": "a", "end": "b", "material": "al", "section": "s"},
                    {"name": "up", "start": "b", "end": "c", "material": "al", "section": "s"}],
        "joints": [{"name": "J", "member": "low", "span": [0.0, 0.04], "youngs_modulus": 30e9}],
        "supports": [{"point": "o", "ux": "fixed", "uy": "fixed", "rz": "fixed"}],
    })
    modes = model_modes(assemble(frame), 3)
    assert modes.frequency_hz.min() > 1.0  # no disconnected, rigid part

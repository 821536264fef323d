"""A frame's manufacturing tolerances as latent factors (`workbench.model.tolerance`,
`workbench.identify.members`): the factors scale sections as a flat bar's, and the forward model's
first-order terms in them predict exact solves of the moved frame."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from workbench.identify.anchored import anchored_forward, forward_at, tracked_nominal
from workbench.identify.members import member_factors, with_member_derivatives
from workbench.model.assembly import assemble
from workbench.model.frame_file import read_frame
from workbench.model.structure import structure_modes
from workbench.model.tolerance import Tolerances, frame_with_factors, tolerance_factors

FOUR_BOLT = Path(__file__).resolve().parents[1] / "frames" / "four_bolt.toml"


def test_factors_scale_each_members_section_as_a_flat_bar_and_each_material():
    frame = read_frame(FOUR_BOLT)
    names, sd = tolerance_factors(frame, Tolerances(0.002, 0.004))
    assert len(names) == 2 * (len(frame.materials) + len(frame.members)) == sd.size
    assert np.allclose(sd[:2 * len(frame.materials)], 0.004) and np.allclose(sd[2 * len(frame.materials):], 0.002)
    logs = np.zeros(len(names))
    member = frame.members[1]
    logs[names.index(f"{member.name}.width")] = np.log(1.02)
    logs[names.index(f"{member.name}.thickness")] = np.log(0.99)
    logs[names.index(f"{next(iter(frame.materials))}.density")] = np.log(1.01)
    moved = frame_with_factors(frame, logs)
    before, after = frame.sections[member.section], moved.sections[moved.members[1].section]
    assert after.area / before.area == pytest.approx(1.02 * 0.99)
    assert after.second_moment / before.second_moment == pytest.approx(1.02 * 0.99**3)
    other = moved.sections[moved.members[0].section]  # the other members keep the nominal section's values
    assert other.area == frame.sections[frame.members[0].section].area
    (name, material), = frame.materials.items()
    assert moved.materials[name].density == pytest.approx(1.01 * material.density)
    assert [j.youngs_modulus for j in moved.joints] == [j.youngs_modulus for j in frame.joints]  # joints keep theirs
    with pytest.raises(ValueError, match="factors"):
        frame_with_factors(frame, logs[:-1])
    with pytest.raises(ValueError, match="section_sd"):
        Tolerances(section_sd=0.0)


def test_first_order_factors_predict_exact_solves_of_the_moved_frame():
    # the forward model's terms in m against the moved frame solved exactly, at a test's own moduli:
    # a draw three tolerances wide moves the frequencies by about a percent, and what the first-order
    # terms leave must be of second order (under 5 % of the move)
    frame = read_frame(FOUR_BOLT)
    model = assemble(frame)
    modes = np.arange(8)
    nominal = tracked_nominal(model, modes)
    rng = np.random.default_rng(5)
    anchors = 0.2 * rng.standard_normal((2, len(frame.joints)))
    forward = with_member_derivatives(forward_at(model, nominal, modes, anchors),
                                      member_factors(model, Tolerances()), nominal, modes)
    m = 3 * 0.003 * rng.standard_normal(forward.factor_count)
    moved = forward_at(assemble(frame_with_factors(frame, m)), nominal, modes, anchors)
    exact = np.sqrt(moved.rest + moved.joints.sum(axis=-1)) / (2 * np.pi)
    before = np.asarray(forward(anchors))
    predicted = np.asarray(forward(anchors, m=m))
    move = np.abs(exact / before - 1.0)
    assert move.max() > 3e-3  # the draw moves the frame
    assert np.max(np.abs(predicted / exact - 1.0)) < 0.05 * move.max()
    # away from the anchor in z too: the joint energies' terms in m hold there (eq. 5's Rayleigh quotient)
    z = anchors + 0.1
    solved = structure_modes(assemble(frame_with_factors(frame, m)), 12, np.exp(z[0]))
    assert np.asarray(forward(z, m=m))[0, 0] == pytest.approx(np.sqrt(solved.eigenvalues[0]) / (2 * np.pi), rel=2e-3)


def test_a_matrix_model_has_no_members_to_give_tolerances_to():
    class Matrices:  # what member_factors reads of a matrix model: its source
        source = "model.mtx"

    with pytest.raises(ValueError, match="model.mtx: tolerances: a matrix model has no members"):
        member_factors(Matrices(), Tolerances())  # type: ignore[arg-type]


def test_anchored_forward_model_without_factors_is_unchanged():
    frame = read_frame(FOUR_BOLT)
    model = assemble(frame)
    modes = np.arange(6)
    nominal = tracked_nominal(model, modes)
    f_obs = nominal.frequency_hz[modes][None].repeat(2, axis=0)
    forward = anchored_forward(model, nominal, f_obs, np.ones_like(f_obs, bool), modes)
    assert forward.factor_count == 0
    np.testing.assert_array_equal(forward(forward.anchor), forward(forward.anchor, m=np.zeros(3)))


def test_tolerances_known_exactly_leave_the_likelihood_as_it_was():
    # a factor whose prior is a near-delta adds nothing: its Laplace terms (prior's normaliser and the
    # Schur complement's determinant) cancel, and the tests' latents settle where they did without it
    from test_bayes import ONE_BOLT, synthetic

    from workbench.identify.laplace import laplace_likelihood

    model, data, _ = synthetic(ONE_BOLT, [24e9], [0.09], 6, 5e-4, 3, count=4)
    plain, _ = laplace_likelihood(model, data)
    tight, _ = laplace_likelihood(model, data, tolerances=Tolerances(1e-7, 1e-7))
    loose, _ = laplace_likelihood(model, data, tolerances=Tolerances(0.01, 0.01))
    assert tight.factor_sd.size == 2 * (len(model.frame.materials) + len(model.frame.members))
    theta = np.r_[0.0, np.log(0.09), np.full(4, np.log(5e-4)), np.log(2e-3), np.log(4e-3)]
    assert float(tight.log_likelihood(theta)[0]) == pytest.approx(float(plain.log_likelihood(theta)[0]), abs=1e-3)
    # with a real tolerance the factors take up part of what the discrepancy did: a different likelihood
    assert abs(float(loose.log_likelihood(theta)[0]) - float(plain.log_likelihood(theta)[0])) > 1e-2


def test_the_factors_are_expanded_again_about_a_new_centre():
    # expanded about c, the forward model at m = c is the frame moved by c solved exactly (Rayleigh quotients
    # are exact at their anchor), and its prior still measures the factors from the drawing
    from test_bayes import ONE_BOLT, synthetic

    from workbench.identify.laplace import laplace_likelihood

    model, data, _ = synthetic(ONE_BOLT, [24e9], [0.09], 4, 5e-4, 3, count=4)
    lm, _ = laplace_likelihood(model, data, tolerances=Tolerances())
    centre = 0.004 * np.random.default_rng(2).standard_normal(lm.factor_sd.size)
    forward, _ = lm.refit(lm.z_start, centre)
    gamma = np.exp(lm.z_start[0]) * lm.reference_pa[0] / model.frame.joints[0].youngs_modulus  # z is from Y0
    solved = structure_modes(assemble(frame_with_factors(model.frame, centre)), 8, gamma)
    np.testing.assert_allclose(np.asarray(forward(lm.z_start))[0], solved.frequency_hz[:4], rtol=1e-9)
    theta = np.r_[0.0, np.log(0.09), np.full(4, np.log(5e-4)), np.log(2e-3), np.log(4e-3)]
    moved = type(lm)(**{**lm.__dict__, "table": forward, "factor_centre": centre})
    mode, _ = moved.shared_latents(theta)
    assert np.all(np.abs(mode[0, -centre.size:]) < 4 * lm.factor_sd)  # the drawing's prior pulls them back

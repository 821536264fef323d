"""Stochastic FRF bands and the section 5 transfer (workbench.uq.prediction), against the nominal FRF,
the exact quadrature moments, independent per-sample solves, a one-mode closed form and hand numbers."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
from conftest import REPO

from workbench.model.assembly import assemble
from workbench.model.frame_file import read_frame
from workbench.model.joints import frame_with_joint_models, model_at_moduli
from workbench.model.modal import model_modes
from workbench.model.structure import structure_frf
from workbench.uq import prediction
from workbench.uq.prediction import compare_frequencies, frf_band
from workbench.uq.stochastic import FrequencyMoments, JointModel, joint_model, quadrature_reference

AXIS = np.arange(0.5, 1250.0, 0.5)  # Hz; 0 Hz left out, where the accelerance is 0
FLOAT32_SUMS = 1e-3  # relative accuracy of float32 modal sums at the deepest anti-resonance of these axes
# the same draws' magnitudes on another cut of the axis: float32 products of the modal sums whose BLAS kernel may
# round a block's edge columns otherwise (bit for bit on one processor, 1.3e-8 apart on an AMD EPYC's Haswell kernel)
FLOAT32_CHUNKS = 1e-6


@pytest.fixture(scope="module")
def vertical():
    return assemble(read_frame(REPO / "frames" / "one_bolt_vertical.toml"))


@pytest.fixture(scope="module")
def four_frame():
    return read_frame(REPO / "frames" / "four_bolt.toml")


@pytest.fixture(scope="module")
def band(vertical):
    return frf_band(vertical, joint_model(vertical.frame), AXIS, [0.005], samples=60, seed=3)


def test_tiny_cov_collapses_onto_the_nominal_frf(vertical):
    joints = JointModel(vertical.joint_names, np.array([1e-6]))
    b = frf_band(vertical, joints, AXIS, [0.005], samples=20, seed=0)
    nominal = np.abs(b.nominal)
    for stat in (b.mean, b.lower, b.upper, b.p05, b.p95):
        # the band's magnitudes are float32 sums (workbench.model.modal.modal_magnitude): 6e-8 relative per
        # term, times the cancellation of some 1e3 between terms at an anti-resonance
        np.testing.assert_allclose(stat, nominal, rtol=FLOAT32_SUMS)
    # the nominal FRF is the frame's own, at the band's mode count
    reference = structure_frf(vertical, model_modes(vertical, b.natural_hz.shape[1]), AXIS, "accelerance",
                          np.full(b.natural_hz.shape[1], 0.005))
    np.testing.assert_allclose(b.nominal, reference.values, rtol=1e-12)
    assert b.sensors == tuple(s.name for s in vertical.frame.sensors)


def test_default_mode_count_covers_the_axis_and_four_more(vertical, band):
    nominal = model_modes(vertical, 20).frequency_hz
    assert band.natural_hz.shape == (60, int(np.sum(nominal <= AXIS.max())) + 4)


def test_band_is_ordered_and_seeded(vertical, band):
    assert np.all(band.lower <= band.p05) and np.all(band.p05 <= band.p95) and np.all(band.p95 <= band.upper)
    assert np.all(band.lower <= band.mean) and np.all(band.mean <= band.upper)
    again = frf_band(vertical, joint_model(vertical.frame), AXIS, [0.005], samples=60, seed=3)
    for field in ("nominal", "mean", "lower", "upper", "p05", "p95", "natural_hz"):
        assert np.array_equal(getattr(band, field), getattr(again, field)), field
    other = frf_band(vertical, joint_model(vertical.frame), AXIS, [0.005], samples=60, seed=4)
    assert not np.array_equal(band.mean, other.mean)
    assert (band.samples, band.seed, other.seed) == (60, 3, 4)


def test_sample_frequencies_match_the_quadrature_moments(vertical):
    # exact moments by a 9-point Gauss rule (no sampling noise) against the band's 400 samples
    joints = joint_model(vertical.frame)
    b = frf_band(vertical, joints, np.linspace(1.0, 1200.0, 50), [0.005], samples=400, seed=11)
    exact = quadrature_reference(vertical, joints, 10)
    f = b.natural_hz[:, :10]
    n = f.shape[0]
    x = f - f.mean(axis=0)
    var = (x**2).mean(axis=0)
    se_mean = np.sqrt(var / n)
    se_std = np.sqrt(var * ((x**4).mean(axis=0) / var**2 - 1.0) / (4.0 * n))
    assert np.all(np.abs(f.mean(axis=0) - exact.mean_hz) < 4 * se_mean)
    assert np.all(np.abs(f.std(axis=0, ddof=1) - exact.std_hz) < 4 * se_std)


def test_each_sample_is_the_frame_frf_of_its_own_modulus(vertical):
    # two samples: the envelope is then exactly the two FRFs; each rebuilt from model_modes at the
    # sample's gamma (sorted modes, Rayleigh-quotient eigenvalues) rather than solve + MAC tracking
    joints = joint_model(vertical.frame)
    zeta = np.linspace(0.002, 0.02, 14)
    b = frf_band(vertical, joints, AXIS, zeta, quantity="mobility", samples=2, seed=5, method="mc")
    gammas = joints.sample(2, np.random.default_rng(5))
    count = b.natural_hz.shape[1]
    curves = []
    for s, gamma in enumerate(gammas):
        modes = model_modes(vertical, count, gamma)
        assert np.all(np.diff(b.natural_hz[s]) > 0)  # no swap, so sorted order is tracked order
        np.testing.assert_allclose(b.natural_hz[s], modes.frequency_hz, rtol=1e-9)
        curves.append(np.abs(structure_frf(vertical, modes, AXIS, "mobility", zeta[:count]).values))
    np.testing.assert_allclose(b.lower, np.minimum(*curves), rtol=FLOAT32_SUMS)
    np.testing.assert_allclose(b.upper, np.maximum(*curves), rtol=FLOAT32_SUMS)


def test_mean_peak_is_flattened_as_the_one_mode_closed_form_says(vertical):
    # At the drive point, at nominal resonance k, |H| of a sample is close to one mode's
    # |H_k| 2 zeta w_k^2 / |w_s^2 - w_k^2 + 2i zeta w_s w_k|: the mean of that over the sample
    # frequencies predicts how much the scatter lowers the mean peak (Figure 12).
    zeta = 0.005
    nominal_hz = model_modes(vertical, 10).frequency_hz
    b = frf_band(vertical, joint_model(vertical.frame), nominal_hz, [zeta], samples=200, seed=1)
    w = b.natural_hz[:, :10]
    expected = np.mean(2 * zeta * nominal_hz**2 / np.abs(w**2 - nominal_hz**2 + 2j * zeta * w * nominal_hz), axis=0)
    drive = b.sensors.index(vertical.frame.excitation.point)
    ratio = b.mean[drive] / np.abs(b.nominal[drive])
    assert np.all(ratio < 0.99)
    np.testing.assert_allclose(ratio, expected, rtol=0.02)


def test_chunked_frequency_axis_gives_the_same_band(vertical, band, monkeypatch):
    monkeypatch.setattr(prediction, "MEMORY_BYTES", 4 * 60 * 5 * 97)  # 97 lines a chunk
    chunked = frf_band(vertical, joint_model(vertical.frame), AXIS, [0.005], samples=60, seed=3)
    for field in ("mean", "lower", "upper", "p05", "p95"):
        np.testing.assert_allclose(getattr(chunked, field), getattr(band, field), rtol=FLOAT32_CHUNKS, atol=0.0)


def test_progress_reports_every_sample_and_prints_nothing(vertical, capsys):
    calls = []
    frf_band(vertical, joint_model(vertical.frame), AXIS[:10], [0.005], samples=3, method="mc",
             progress=lambda label, done, total: calls.append((label, done, total)))
    assert calls == [("FRF band", 1, 3), ("FRF band", 2, 3), ("FRF band", 3, 3), ("FRF band lines", 10, 10)]
    captured = capsys.readouterr()
    assert captured.err == "" and captured.out == ""


def test_the_command_line_turns_progress_into_a_bar_on_stderr(capsys):
    from workbench.cli import ProgressBars

    bars = ProgressBars()
    for done in (1, 2, 3):
        bars("FRF band", done, 3)
    captured = capsys.readouterr()
    assert "FRF band" in captured.err and captured.out == "" and bars.bars == {}


@pytest.mark.parametrize("change, message", [
    ({"damping_ratio": [0.01, np.nan]}, "damping_ratio"),
    ({"damping_ratio": []}, "damping_ratio"),
    ({"frequency_hz": np.array([])}, "frequency_hz"),
    ({"frequency_hz": np.array([1.0, np.inf])}, "frequency_hz"),
    ({"samples": 1}, "samples"),
    ({"quantity": "inertance"}, "quantity"),
    ({"joints": JointModel(("A",), np.array([0.0]))}, "no joint has a random"),
    ({"joints": JointModel(("L1",), np.array([0.1]))}, "does not match"),
    ({"modes": 0}, "modes"),
    ({"method": "pce"}, "method"),
    ({"check_samples": 6}, "check_samples"),
])
def test_bad_input_is_a_one_line_value_error(vertical, change, message):
    args = {"joints": joint_model(vertical.frame), "frequency_hz": AXIS, "damping_ratio": [0.005], "samples": 5}
    args.update(change)
    extra = {k: args.pop(k) for k in ("samples", "quantity", "modes", "method", "check_samples") if k in args}
    with pytest.raises(ValueError, match=message) as info:
        frf_band(vertical, args["joints"], args["frequency_hz"], args["damping_ratio"], **extra)
    assert "\n" not in str(info.value)


def test_one_bolt_groups_transfer_to_the_four_bolt_frame(four_frame):
    one_bolt = {j.group for name in ("one_bolt_vertical", "one_bolt_horizontal")
                for j in read_frame(REPO / "frames" / f"{name}.toml").joints}
    assert one_bolt == {j.group for j in four_frame.joints} == {"vertical", "horizontal"}
    new = frame_with_joint_models(four_frame, {"vertical": (20e9, 0.05), "horizontal": (60e9, 0.3)})
    assert {j.name: (j.youngs_modulus, j.cov) for j in new.joints} == {
        "L1": (20e9, 0.05), "L2": (60e9, 0.3), "L3": (60e9, 0.3), "L4": (20e9, 0.05)}
    assert new.joints[0].group == "vertical" and four_frame.joints[0].youngs_modulus == 24e9  # a copy
    np.testing.assert_array_equal(joint_model(new).cov, [0.05, 0.3, 0.3, 0.05])
    # the moduli reach the matrices: the assembled copy is the original scaled zone by zone
    scaled = model_at_moduli(assemble(four_frame), np.array([20e9, 60e9, 60e9, 20e9])).stiffness()
    assert abs(assemble(new).stiffness() - scaled).max() <= 1e-9 * abs(scaled).max()


def test_joint_name_wins_over_its_group_and_unnamed_joints_keep_the_file(four_frame):
    new = frame_with_joint_models(four_frame, {"horizontal": (60e9, 0.3), "L3": (50e9, 0.1)})
    values = {j.name: (j.youngs_modulus, j.cov) for j in new.joints}
    assert values == {"L1": (24e9, 0.09), "L2": (60e9, 0.3), "L3": (50e9, 0.1), "L4": (24e9, 0.09)}
    assert dataclasses.replace(new, joints=four_frame.joints) == four_frame


@pytest.mark.parametrize("models, message", [
    ({"diagonal": (20e9, 0.1)}, r"'diagonal'.*known: L1, L2, L3, L4, horizontal, vertical"),
    ({"vertical": (-1.0, 0.1)}, "finite positive modulus"),
    ({"L2": (20e9, np.nan)}, "cov"),
])
def test_unknown_names_and_bad_models_are_rejected(four_frame, models, message):
    with pytest.raises(ValueError, match=message):
        frame_with_joint_models(four_frame, models)


def test_compare_frequencies_against_hand_numbers():
    measured = np.array([[10.0, 20.0, np.nan, 40.0],
                         [12.0, np.nan, 31.0, np.nan],
                         [14.0, 24.0, 33.0, np.nan]])
    predicted = FrequencyMoments(np.array([12.6, 22.0, 30.0]), np.array([1.0, np.sqrt(8.0), 2 * np.sqrt(2.0)]),
                                 "test", np.array([12.0, 22.0, 30.0]))
    c = compare_frequencies(predicted, measured)
    np.testing.assert_array_equal(c.modes, [1, 2, 3])  # mode 4 has no prediction
    np.testing.assert_allclose(c.measured_mean_hz, [12.0, 22.0, 32.0])
    np.testing.assert_allclose(c.measured_std_hz, [2.0, np.sqrt(8.0), np.sqrt(2.0)])
    np.testing.assert_allclose(c.mean_rel_error, [0.05, 0.0, -0.0625])
    np.testing.assert_allclose(c.std_ratio, [0.5, 1.0, 2.0])
    picked = compare_frequencies(predicted, measured, modes=[3, 1])
    np.testing.assert_array_equal(picked.modes, [3, 1])
    np.testing.assert_allclose(picked.predicted_mean_hz, [30.0, 12.6])
    np.testing.assert_allclose(picked.measured_std_hz, [np.sqrt(2.0), 2.0])
    # a mode found once has a mean but no std
    once = compare_frequencies(FrequencyMoments(np.ones(4), np.ones(4), "test", np.ones(4)), measured, modes=[4])
    assert once.measured_mean_hz[0] == 40.0 and np.isnan(once.measured_std_hz[0])
    for bad in ([0], [4], [1.5]):
        with pytest.raises(ValueError, match="modes"):
            compare_frequencies(predicted, measured, modes=bad)


@pytest.fixture(scope="module")
def horizontal():
    return assemble(read_frame(REPO / "frames" / "one_bolt_horizontal.toml"))


def test_smr_draws_are_the_exact_modes_of_the_same_draws(horizontal):
    # CoV 0.22, where SMR2's own per-mode Rayleigh quotient is off by up to 6e-3 in the tails: the
    # Rayleigh-Ritz on SMR2's whole basis (workbench.uq.reduced) against full solves of the same draws
    joints = joint_model(horizontal.frame)
    b = frf_band(horizontal, joints, AXIS, [0.005], samples=100, seed=2, check_samples=100)
    assert b.method == "smr" and b.check is not None and b.check.samples == 100
    assert b.check.frequency_rel_error < 1e-6
    assert b.check.quantile_rel_error.shape == (len(b.sensors), b.check.lines_hz.size)
    assert b.check.quantile_rel_error.max() < 5 * FLOAT32_SUMS


def test_the_smr_band_is_the_exact_band_of_the_same_draws(horizontal):
    joints = joint_model(horizontal.frame)
    smr = frf_band(horizontal, joints, AXIS, [0.005], samples=60, seed=9)
    exact = frf_band(horizontal, joints, AXIS, [0.005], samples=60, seed=9, method="mc")
    assert exact.method == "mc" and exact.check is None
    np.testing.assert_allclose(smr.natural_hz, exact.natural_hz, rtol=1e-6)
    for field in ("mean", "lower", "upper", "p05", "p95"):
        np.testing.assert_allclose(getattr(smr, field), getattr(exact, field), rtol=5 * FLOAT32_SUMS)


def test_band_lines_keep_the_nominal_peaks_and_thin_the_rest(vertical, band):
    thin = frf_band(vertical, joint_model(vertical.frame), AXIS, [0.005], samples=60, seed=3, quiet_lines=100)
    kept = np.flatnonzero(np.isin(AXIS, thin.frequency_hz))
    assert kept.size == thin.frequency_hz.size < AXIS.size // 2
    assert kept[0] == 0 and kept[-1] == AXIS.size - 1
    nominal = model_modes(vertical, thin.natural_hz.shape[1]).frequency_hz
    for f0 in nominal[nominal < AXIS.max()]:
        near = AXIS[np.abs(AXIS - f0) <= prediction.PEAK_HALF_WIDTHS * 0.005 * f0]
        assert np.isin(near, thin.frequency_hz).all(), f0
    # each line's statistics are its own: the same numbers as on the full axis (to float32 rounding, FLOAT32_CHUNKS)
    for field in ("nominal", "mean", "lower", "upper", "p05", "p95"):
        np.testing.assert_allclose(getattr(thin, field), getattr(band, field)[:, kept], rtol=FLOAT32_CHUNKS, atol=0.0)


def test_the_compressed_basis_of_many_joints_gives_the_exact_modes_of_each_draw():
    """24 random joints: each mode's sensitivities compressed to their principal directions
    (workbench.uq.reduced), against full solves of the same draws; the joint matrices projected on
    the rows they touch give the full products."""
    from workbench.model.generate import multibay_frame
    from workbench.uq.reduced import _project, reduced_basis, reduced_modes

    frame = multibay_frame(4, 3, element_length=0.05)
    model, joints = assemble(frame), joint_model(frame)
    nominal = model_modes(model, 10)
    draws = joints.sample(20, np.random.default_rng(4))
    exact = np.array([model_modes(model, 10, g).frequency_hz for g in draws])
    compressed = reduced_basis(model, nominal, joints, compress=True)
    natural, _ = reduced_modes(compressed, draws, np.array([0]))
    assert compressed.size < nominal.count * (1 + len(frame.joints))
    assert np.max(np.abs(natural / exact - 1.0)) < 1e-6
    basis = compressed.basis
    np.testing.assert_allclose(basis.T @ (model.mass @ basis), np.eye(compressed.size), atol=1e-9)
    for k in (model.stiffness_rest, *model.stiffness_joints[:3]):
        full = basis.T @ (k @ basis)
        assert np.abs(_project(k, list(compressed.blocks)) - full).max() <= 1e-9 * np.abs(full).max()

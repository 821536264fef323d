"""The diagnosis's FRF-level channel (`workbench.diagnose.frf_levels`) against closed forms and its own rules.

Unit tests build modal constants whose levels are known by construction (a mass-normalised mode scaled by a known
factor, tests phased and signed at random, noise of a known size) and check the channel reads them back; the
physics test checks the premise on a closed form (a mass lowers a mode's constants as its frequency, a stiffness
change does not), on the workbench's own beam model, against Rayleigh's quotient.
"""

from __future__ import annotations

import json
from dataclasses import replace

import numpy as np
import pytest

from tests.conftest import REPO
from workbench.diagnose.frf_levels import (
    LEVEL_ALPHA,
    LEVEL_FLOOR,
    MIN_MAC,
    level_test,
    measured_levels,
    sensor_constants,
    track,
)
from workbench.diagnose.verdict import diagnose, diagnosis_record
from workbench.extraction.records import MeasuredModes
from workbench.model.assembly import assemble
from workbench.model.frame import Frame
from workbench.model.frame_file import read_frame
from workbench.model.modal import model_modes
from workbench.model.structure import response_dofs
from workbench.rig.effects import ADDED_MASS, SUPPORT_COMPLIANCE, UNEXPLAINED, Effect, apply_effect


def _campaign(constants: np.ndarray, tests: int, noise: float, rng: np.random.Generator) -> np.ndarray:
    """(tests, n_modes, n_sensors) complex: ``constants`` (n_modes, n_sensors) times a random phase and sign per test
    and mode (a circle fit's), plus real noise of ``noise`` times each mode's RMS constant per entry.
    """
    phase = np.exp(1j * rng.uniform(0, 2 * np.pi, (tests, constants.shape[0], 1)))
    sign = rng.choice([-1.0, 1.0], (tests, constants.shape[0], 1))
    rms = np.sqrt(np.mean(constants**2, axis=1))[None, :, None]
    return (constants[None] + noise * rms * rng.standard_normal((tests, *constants.shape))) * sign * phase


def test_levels_read_back_a_known_scale_with_the_standard_error_of_the_scatter():
    rng = np.random.default_rng(1)
    nominal = rng.standard_normal((4, 6))
    scale = np.array([1.0, 0.9, 1.05, 0.8])
    got = measured_levels(_campaign(nominal * scale[:, None], 400, 0.02, rng), nominal)
    np.testing.assert_allclose(got.level, scale, rtol=3e-3)
    np.testing.assert_allclose(got.mac, 1.0, atol=1e-3)
    # the least-squares scale's error: 0.02 * rms / |a| per test (|a| = sqrt(6) rms), over sqrt(400) tests
    np.testing.assert_allclose(got.se, scale * 0.02 / np.sqrt(6) / 20, rtol=0.2)


def test_a_test_that_missed_a_sensor_is_left_out_of_that_modes_level():
    rng = np.random.default_rng(2)
    nominal = rng.standard_normal((2, 5))
    constants = _campaign(0.9 * nominal, 6, 1e-4, rng)
    constants[0, 0] *= 2.0  # a test that would pull mode 1's level up, had it seen every sensor
    constants[0, 0, 3] = np.nan
    got = measured_levels(constants, nominal)
    np.testing.assert_allclose(got.level, 0.9, rtol=1e-3)
    assert got.seen.all()  # the sensor is read from the five tests that saw it


def test_a_mode_the_sensors_do_not_see_is_left_out_whatever_its_noise_draws():
    """Pure noise signed by the nominal shape would average into it; signed by its own principal direction, its
    scales scatter about zero and the standard error rules it out.
    """
    rng = np.random.default_rng(7)
    nominal = rng.standard_normal((3, 6))
    kept = 0
    for _ in range(200):
        constants = _campaign(nominal, 12, 0.01, rng)
        constants[:, 1, :] = 1e-3 * (rng.standard_normal((12, 6)) + 1j * rng.standard_normal((12, 6)))
        got = level_test(measured_levels(constants, nominal), nominal, nominal, np.arange(1, 4))
        kept += got is not None and 2 in got.modes
    assert kept <= 10  # 5 % of the draws at most


def test_a_common_scale_is_not_an_effect_but_a_mode_by_mode_change_is():
    rng = np.random.default_rng(3)
    nominal = rng.standard_normal((6, 8))
    calibration = 1.07  # a force gauge 7 % off scales every mode alike
    measured = measured_levels(_campaign(calibration * nominal, 12, 0.01, rng), nominal)
    same = level_test(measured, nominal, nominal, np.arange(1, 7))
    assert same is not None and same.chi2 < 2 * same.dof and not same.contradicted
    # a candidate that lowers modes 2 and 5 by 15 % where the structure did not move them
    changed = nominal * np.array([1.0, 0.85, 1.0, 1.0, 0.85, 1.0])[:, None]
    impostor = level_test(measured, nominal, changed, np.arange(1, 7))
    assert impostor is not None and impostor.p_value < LEVEL_ALPHA
    assert impostor.chi2 > impostor.nominal_chi2 and impostor.contradicted
    np.testing.assert_allclose(impostor.predicted, [1.0, 0.85, 1.0, 1.0, 0.85, 1.0], rtol=1e-12)


def test_a_candidate_that_explains_the_level_change_is_not_contradicted():
    rng = np.random.default_rng(4)
    nominal = rng.standard_normal((6, 8))
    factor = np.array([0.97, 0.8, 1.0, 0.95, 0.85, 1.0])
    measured = measured_levels(_campaign(nominal * factor[:, None], 12, 0.01, rng), nominal)
    right = level_test(measured, nominal, nominal * factor[:, None], np.arange(1, 7))
    assert right is not None and not right.contradicted and right.chi2 < 0.1 * right.nominal_chi2
    # within the floor the levels say nothing: a candidate 1 % off every mode's level passes
    near = level_test(measured, nominal, nominal * (factor * (1 + 0.5 * LEVEL_FLOOR))[:, None], np.arange(1, 7))
    assert near is not None and not near.contradicted


def test_modes_the_nominal_model_does_not_recognise_and_noisy_ones_are_left_out():
    rng = np.random.default_rng(5)
    nominal = rng.standard_normal((4, 6))
    truth = nominal.copy()
    across = np.linalg.svd(nominal[[1]])[2][-1]  # a unit vector orthogonal to the nominal mode
    truth[1] = (across + 0.3 * nominal[1] / np.linalg.norm(nominal[1])) * np.linalg.norm(nominal[1])  # MAC 0.08
    constants = _campaign(truth, 12, 0.01, rng)
    constants[:, 2, :] = _campaign(nominal[[2]], 12, 50.0, rng)[:, 0, :]  # a mode lost in noise
    measured = measured_levels(constants, nominal)
    assert measured.mac[1] < MIN_MAC
    got = level_test(measured, nominal, nominal, np.array([1, 2, 3, 4]))
    assert got is not None and list(got.modes) == [1, 4]


def test_tracking_follows_modes_that_swap_order():
    rng = np.random.default_rng(6)
    nominal = rng.standard_normal((5, 7))
    hz = np.array([10.0, 20.0, 21.0, 40.0, 80.0])
    order = np.array([0, 2, 1, 3, 4])
    changed = nominal[order] + 0.02 * rng.standard_normal((5, 7))
    assert list(track(nominal, hz, changed, np.array([9.8, 19.0, 19.5, 39.0, 79.0]))) == [0, 2, 1, 3, 4]


def test_a_mass_lowers_the_fundamentals_constants_as_rayleigh_says_and_a_softer_support_otherwise():
    """Closed form: a small point mass ``m`` where the mass-normalised fundamental mode is ``phi_p`` takes the share
    ``m phi_p^2`` of ``omega^2`` (first order) and, the shape of a well separated mode nearly unchanged, the same
    share of its constants. A softer support that lowers the frequency changes the constants through the shape
    alone, here the other way. (Higher modes mix with their neighbours at the sensors and their levels move by
    more than the closed form says: the diagnosis compares models, not this formula.)
    """
    frame = read_frame(REPO / "frames" / "one_bolt_vertical.toml")
    sensors = tuple(s.name for s in frame.sensors)
    a0, hz0 = sensor_constants(frame, sensors, 6)

    def fundamental(changed: Frame) -> tuple[float, float]:
        """(share of omega^2 lost, share of level lost) of the fundamental mode."""
        a1, hz1 = sensor_constants(changed, sensors, 8)
        k = track(a0, hz0, a1, hz1)[0]
        return 1.0 - (hz1[k] / hz0[0]) ** 2, 1.0 - abs(a1[k] @ a0[0]) / (a0[0] @ a0[0])

    drop, level = fundamental(apply_effect(frame, ADDED_MASS.effect("beam", mass=0.005, position=0.5)))
    assert drop > 0.002 and level == pytest.approx(drop, rel=0.1)
    support = frame.supports[0].point
    drop, level = fundamental(apply_effect(frame, Effect(SUPPORT_COMPLIANCE.name, support, {"rz": 2000.0})))
    assert drop > 0.01 and level < 0.0  # the constants rise: the mass's sign is the other


def _frequencies(article: Frame, tests: int, rng: np.random.Generator) -> MeasuredModes:
    """Frequencies of ``article``, a little joint scatter and noise per test (the constants are added by the test)."""
    model = assemble(article)
    rows = []
    for _ in range(tests):
        gamma = np.exp(0.01 * rng.standard_normal(len(article.joints)))
        rows.append(model_modes(model, 8, gamma).frequency_hz * (1 + 1e-4 * rng.standard_normal(8)))
    return MeasuredModes(np.array(rows))


def _constants_of(frame: Frame, tests: int, rng: np.random.Generator) -> np.ndarray:
    """Receptance modal constants of ``frame``'s first 8 modes at its sensors, as `_campaign` measures them."""
    model = assemble(frame)
    modes = model_modes(model, 8)
    sensors, excitation, _ = response_dofs(model)
    return _campaign((modes.shapes[sensors] * modes.shapes[excitation][None, :]).T, tests, 0.01, rng)


def test_the_levels_keep_a_mass_whose_constants_fell_and_take_it_away_where_they_did_not():
    """The same frequencies (a 50 g mass on a column of the one-bolt frame), two sets of levels: the article's, whose
    constants fell with the mass, and the nominal frame's, as a stiffness change of the same frequencies would
    leave them. The first keeps the name; the second makes the mass the partial explanation of an unexplained gap.
    """
    frame = read_frame(REPO / "frames" / "one_bolt_vertical.toml")
    frame = replace(frame, joints=tuple(replace(j, cov=0.0) for j in frame.joints))
    article = apply_effect(frame, ADDED_MASS.effect("right_column", mass=0.05, position=0.437))
    rng = np.random.default_rng(12)
    frequencies = _frequencies(article, 6, rng)
    kept = diagnose(frame, replace(frequencies, modal_constants=_constants_of(article, 6, rng)))
    assert kept.verdict == ADDED_MASS.name
    assert kept.frf_levels is not None and not kept.frf_levels["contradicted"]
    taken = diagnose(frame, replace(frequencies, modal_constants=_constants_of(frame, 6, rng)))
    record = diagnosis_record("levels", taken)["verdict"]
    assert record["effect"] == UNEXPLAINED and record["partial"]["effect"] == ADDED_MASS.name
    test = record["partial"]["frf_levels"]
    assert test["contradicted"] and test["chi2"] > test["nominal_chi2"] and test["p_value"] < LEVEL_ALPHA
    assert json.loads(json.dumps(record)) == record  # plain JSON: no numpy type, no NaN

"""`MeasuredModes`, the one record of measured modes: its moments against numpy's, its checks, `select`."""

from __future__ import annotations

import numpy as np
import pytest

from workbench.extraction.records import MeasuredModes

F = np.array([[10.0, 20.0, np.nan], [10.2, np.nan, 31.0], [9.9, 20.4, 30.0]])


def test_moments_over_the_tests_are_numpys_nan_aware_ones():
    m = MeasuredModes(F, tests=("a", "b", "c"))
    np.testing.assert_array_equal(m.mean_hz, np.nanmean(F, axis=0))
    np.testing.assert_array_equal(m.std_hz, np.nanstd(F, axis=0, ddof=1))
    np.testing.assert_array_equal(m.cov, m.std_hz / m.mean_hz)
    assert m.has_tests and not m.published and m.count == 3
    np.testing.assert_array_equal(m.modes, [1, 2, 3])


def test_published_moments_are_one_row_of_means_and_their_std():
    m = MeasuredModes(np.array([[25.0, 120.0]]), published_std_hz=np.array([0.1, 0.5]), tests_count=9)
    assert m.published and not m.has_tests
    np.testing.assert_array_equal(m.mean_hz, [25.0, 120.0])
    np.testing.assert_array_equal(m.std_hz, [0.1, 0.5])


def test_amplitude_is_relative_to_the_lowest_and_all_nan_damping_is_none():
    m = MeasuredModes(F, amplitude=np.array([2.0, 10.0, 2.0]), damping_ratio=np.full(F.shape, np.nan))
    np.testing.assert_array_equal(m.amplitude, [1.0, 5.0, 1.0])
    assert m.damping_ratio is None


@pytest.mark.parametrize("kwargs, message", [
    ({"frequency_hz": np.full((2, 2), np.nan)}, "no measured frequency"),
    ({"frequency_hz": np.array([[1.0, -2.0]])}, "finite and positive"),
    ({"frequency_hz": F, "damping_ratio": np.ones((2, 3))}, "damping_ratio"),
    ({"frequency_hz": F, "amplitude": np.array([1.0, 2.0])}, "amplitude"),
    ({"frequency_hz": F, "tests": ("a",)}, "tests"),
    ({"frequency_hz": F, "modes": np.array([1, 2])}, "modes"),
    ({"frequency_hz": F, "published_std_hz": np.ones(3)}, "std_hz"),
])
def test_inconsistent_records_are_refused(kwargs, message):
    with pytest.raises(ValueError, match=message):
        MeasuredModes(**kwargs)


def test_select_keeps_every_field_of_the_chosen_modes():
    flags = ((("weak",), (), ()), ((), ("close_mode",), ()), ((), (), ("edge_of_band",)))
    constants = np.arange(18, dtype=complex).reshape(3, 3, 2)
    m = MeasuredModes(F, damping_ratio=F / 1000, flags=flags, modal_constants=constants, tests=("a", "b", "c"),
                      frequency_scatter_hz=F / 100, modes=np.array([1, 2, 4]))
    kept = m.select(np.array([True, False, True]))
    np.testing.assert_array_equal(kept.modes, [1, 4])
    np.testing.assert_array_equal(kept.frequency_hz, F[:, [0, 2]])
    np.testing.assert_array_equal(kept.damping_ratio, F[:, [0, 2]] / 1000)
    np.testing.assert_array_equal(kept.frequency_scatter_hz, F[:, [0, 2]] / 100)
    np.testing.assert_array_equal(kept.modal_constants, constants[:, [0, 2]])
    assert kept.flags == ((("weak",), ()), ((), ()), ((), ("edge_of_band",)))
    assert kept.tests == m.tests

"""Close modes and the extraction's 95 % intervals (workbench.extraction.multimode, .modes, .circlefit).

Truth: FRFs synthesised by modal superposition (`workbench.model.modal.modal_superposition`) with
known frequencies, damping ratios and modal constants, accelerance, circular Gaussian noise
(`add_noise`, SNR over each curve's RMS), seeded by ``numpy.random.default_rng(seed)``.

Thresholds were decided on a development seed range (0-199, or 0-49 where said) and are checked
here on another (from 1000); the figures measured on both are in each test's docstring.
"""

from __future__ import annotations

import numpy as np
import pytest
from scipy.stats import binomtest

from workbench.extraction import modes as ex
from workbench.extraction import multimode as mm
from workbench.model.modal import add_noise, modal_superposition

CHECK_SEEDS = 1000  # first seed of the checking range (the development range started at 0)

# ------------------------------------------------------------------------------------------
# the multi-mode fit against its closed form


def test_pole_fit_recovers_two_noise_free_poles_exactly():
    """Two poles 2 % apart, three curves of different shapes, residual terms added: the variable
    projection fit returns the poles and the constants of the synthesis."""
    f = np.arange(200.0, 300.0, 0.25)
    natural, zeta = np.array([250.0, 255.0]), np.array([0.01, 0.012])
    constants = np.array([[1.0, 0.5], [0.7, -0.9], [-0.4, 1.0]])
    w = 2 * np.pi * f
    h = modal_superposition(f, natural, zeta, constants, "accelerance") - w**2 * (1e-7 - 2.0 / w**2)
    fit = mm.pole_fit(f, h, (230.0, 275.0), "accelerance", np.full(3, 1e-6), [[(249.0, 0.02), (256.0, 0.02)]])
    assert np.allclose(fit.frequency_hz, natural, rtol=1e-9)
    assert np.allclose(fit.damping_ratio, zeta, rtol=1e-7)
    assert np.allclose(fit.modal_constants, constants, rtol=1e-6)
    assert np.allclose(fit.residual_upper, 1e-7, rtol=1e-5) and np.allclose(fit.residual_lower, 2.0, rtol=1e-5)


# ------------------------------------------------------------------------------------------
# coverage of the 95 % intervals

# (natural Hz, damping, line spacing Hz): lines in the half-power band 2 zeta f / df
COVERAGE_CASES = {"resolved, 20 lines": (250.0, 0.01, 0.25), "coarse, 2 lines": (600.0, 0.001, 0.6),
                  "coarse, 3 lines": (600.0, 0.001, 0.4), "coarse, 4.8 lines": (250.0, 0.002, 0.25)}
COVERAGE_SHAPES = np.array([[1.0], [0.6], [-0.4]])  # three sensors


def coverage(case: str, seeds) -> np.ndarray:
    """Per seed: truth inside (curve 0's frequency, its damping, combined frequency, combined
    damping) intervals. The grid is shifted by a random fraction of a line per seed (where the
    peak falls between lines matters on a coarse grid); 30 dB SNR over 0.5-1.5 f_r."""
    fr, zeta, df = COVERAGE_CASES[case]
    out = []
    for seed in seeds:
        rng = np.random.default_rng(seed)
        f = np.arange(0.5 * fr, 1.5 * fr, df) + rng.uniform(0.0, df)
        h = add_noise(modal_superposition(f, [fr], [zeta], COVERAGE_SHAPES, "accelerance"), 30.0, rng)
        half = max(6 * zeta * fr, 4 * df)
        row = ex.fit_modes(f, h, "accelerance", [(fr - half, fr + half)])[0]
        mode = ex.combine(row)
        out.append([row[0].frequency_ci95_hz[0] <= fr <= row[0].frequency_ci95_hz[1],
                    row[0].damping_ci95[0] <= zeta <= row[0].damping_ci95[1],
                    mode.frequency_ci95_hz[0] <= fr <= mode.frequency_ci95_hz[1],
                    mode.damping_ci95[0] <= zeta <= mode.damping_ci95[1]])
    return np.array(out)


def test_interval_coverage_well_resolved_and_coarse():
    """Share of 95 % intervals holding the truth, 50 seeds per case (1000-1049), one curve's
    circle fit and the three sensors combined.

    Development (seeds 0-199, per case: curve frequency, curve damping, combined frequency,
    combined damping): resolved 0.955 0.950 0.985 0.970; 2 lines 0.945 0.970 0.965 0.960;
    3 lines 0.965 0.960 0.975 0.970; 4.8 lines 0.915 0.970 0.960 0.985. The combined intervals
    are a little conservative (the Birge ratio of three curves is noisy and only ever widens).
    Threshold: at least 0.85 in every case (the issue's floor), 0.90 pooled.
    """
    pooled = []
    for case in COVERAGE_CASES:
        inside = coverage(case, range(CHECK_SEEDS, CHECK_SEEDS + 50))
        assert np.all(inside.mean(axis=0) >= 0.85), (case, inside.mean(axis=0))
        pooled.append(inside)
    assert np.all(np.concatenate(pooled).mean(axis=0) >= 0.90), np.concatenate(pooled).mean(axis=0)


@pytest.mark.slow
def test_interval_coverage_200_seeds():
    """200 seeds per case (1000-1199); measured: see the report of this change. Every case's
    coverage has a Wilson 95 % interval reaching 0.95 or is at least 0.90."""
    for case in COVERAGE_CASES:
        inside = coverage(case, range(CHECK_SEEDS, CHECK_SEEDS + 200))
        for column in inside.T:
            k = int(column.sum())
            high = binomtest(k, column.size).proportion_ci(0.95, method="wilson").high
            assert high >= 0.95 or k / column.size >= 0.90, (case, inside.mean(axis=0))


# ------------------------------------------------------------------------------------------
# close pairs: found as two modes

F_PAIR = np.arange(0.25, 500.0, 0.25)
PAIR_SHAPES = np.array([[1.0, 0.3, 0.8], [0.7, 1.0, -0.9], [0.4, -0.6, 1.0], [-0.9, 0.8, 0.5]])


def pair_case(separation: float, zeta: float, seed: int):
    """A 100 Hz mode and a pair at 250 Hz and 250 (1 + separation) Hz, 3 or 4 sensors of different
    shape ratios, SNR drawn in 30-40 dB."""
    rng = np.random.default_rng(seed)
    snr, sensors = rng.uniform(30.0, 40.0), 3 + seed % 2
    natural = np.array([100.0, 250.0, 250.0 * (1 + separation)])
    damping = np.array([0.01, zeta, zeta])
    h = add_noise(modal_superposition(F_PAIR, natural, damping, PAIR_SHAPES[:sensors] * (100 * damping),
                                      "accelerance"), snr, rng)
    return h, natural, damping


def pair_results(cases):
    """Per case and mode of the pair: (frequency error, truth inside the damping interval, flags,
    the band was listed twice)."""
    out = []
    for separation, zeta, seed in cases:
        h, natural, damping = pair_case(separation, zeta, seed)
        bands, estimates = ex.extract_tests({0: F_PAIR}, {0: h}, "accelerance")
        modes = estimates[0]
        assert len(bands) == len(modes) == 3, (separation, zeta, seed, bands)
        freqs = [m.frequency_hz for m in modes]
        assert freqs == sorted(freqs)
        for k in (1, 2):
            m = modes[k]
            out.append((abs(m.frequency_hz / natural[k] - 1), m.damping_ci95[0] <= damping[k] <= m.damping_ci95[1],
                        m.flags, bands[1] == bands[2]))
    return out


def test_close_pairs_are_found_as_two_modes():
    """Separations 2, 3, 4, 6 % at damping 0.5, 1, 1.5 %: both modes found, numbered in increasing
    frequency, within 0.1 %; the damping truth inside its interval for at least 90 % of the 24
    modes. Where one band holds both, both carry close_mode.

    Development (seeds 0-3, 48 cases): every pair found, frequency errors below 2e-5, damping
    truth inside its interval for 93/96 modes.
    """
    cases = [(s, z, CHECK_SEEDS + i) for i, (s, z) in enumerate(
        (s, z) for s in (0.02, 0.03, 0.04, 0.06) for z in (0.005, 0.01, 0.015))]
    results = pair_results(cases)
    assert max(r[0] for r in results) < 1e-3, [r[0] for r in results]
    assert np.mean([r[1] for r in results]) >= 0.9, [r[1] for r in results]
    assert all("close_mode" in r[2] for r in results if r[3])


def test_a_close_mode_weak_at_one_sensor_is_measured_on_the_others():
    """A pair 3 % apart at 0.5 % damping, four sensors, the first at a node of the upper mode (its constant
    1e-3 of the others'): both modes are measured (no ``weak`` nor ``poor_circle`` on the combined
    estimate, which the diagnosis would leave out), within 0.1 %, and the node's fit gets no weight.

    A sensor where one mode of a pair is weak flags its fit, and ``close_mode`` flags every fit of the pair;
    counted as flagged alike, every fit was used, the estimate carried the node's flags and the diagnosis
    dropped the pair (proving-ground seed 9001, case 40: the two-bay frame's 210/216 Hz pair, found within
    0.1 % by five sensors of seven). The frequencies are the two-pole fit's, common to every sensor: the
    flags are what the rule changes.
    """
    shapes = np.array([[1.0, 0.9, 1e-3], [0.7, -1.0, 0.8], [0.3, 0.5, -1.0], [-0.6, 0.4, 0.6]])
    natural = np.array([100.0, 250.0, 257.5])
    damping = np.array([0.01, 0.005, 0.005])
    for seed in range(CHECK_SEEDS, CHECK_SEEDS + 4):
        rng = np.random.default_rng(seed)
        h = add_noise(modal_superposition(F_PAIR, natural, damping, shapes * (100 * damping), "accelerance"),
                      35.0, rng)
        bands, estimates = ex.extract_tests({0: F_PAIR}, {0: h}, "accelerance")
        modes = estimates[0]
        assert len(modes) == 3 and bands[1] == bands[2], (seed, bands)
        for k in (1, 2):
            assert abs(modes[k].frequency_hz / natural[k] - 1.0) < 1e-3, (seed, k, modes[k])
            assert not {"weak", "poor_circle"} & set(modes[k].flags), (seed, k, modes[k].flags)
        assert modes[2].weights[0] == 0.0  # the node's fit is not averaged in


def test_a_mode_under_a_line_wide_weak_at_one_sensor_is_measured_on_the_others():
    """A 600 Hz mode at 0.02 % damping on a 0.6 Hz grid (0.4 lines across its half-power band: every fit
    ``few_points``), four sensors, one at its node (its fit ``weak``): the combined estimate is usable (no
    ``weak`` nor ``poor_circle``), within 0.05 %, and the node's fit gets no weight. Before, ``few_points``
    counted a fit flagged alike with ``weak``: every fit was used, the estimate carried the node's ``weak`` and
    the diagnosis left the mode out (proving-ground seed 9001, case 20)."""
    shapes = np.array([[1e-5, 1.0], [1.0, 0.5], [0.6, -0.8], [-0.4, 0.7]])  # and a 450 Hz mode the node sees
    fr, zeta, df = 600.0, 0.0002, 0.6
    for seed in range(CHECK_SEEDS, CHECK_SEEDS + 4):
        rng = np.random.default_rng(seed)
        f = np.arange(0.5 * fr, 1.5 * fr, df) + 0.3 * df  # the peak between two lines
        h = add_noise(modal_superposition(f, [fr, 450.0], [zeta, 0.01], shapes, "accelerance"), 35.0, rng)
        row = ex.fit_modes(f, h, "accelerance", [(fr - 4 * df, fr + 4 * df)])[0]
        assert all(x.flags == ("few_points",) for x in row[1:]) and "weak" in row[0].flags, [x.flags for x in row]
        mode = ex.combine(row)
        assert not {"weak", "poor_circle"} & set(mode.flags), (seed, mode.flags)
        assert mode.weights[0] == 0.0 and abs(mode.frequency_hz / fr - 1.0) < 5e-4, (seed, mode)


@pytest.mark.slow
def test_close_pairs_four_seeds_each():
    cases = [(s, z, CHECK_SEEDS + seed) for s in (0.02, 0.03, 0.04, 0.06) for z in (0.005, 0.01, 0.015)
             for seed in range(4)]
    results = pair_results(cases)
    assert max(r[0] for r in results) < 1e-3
    assert np.mean([r[1] for r in results]) >= 0.9


# ------------------------------------------------------------------------------------------
# no false second mode

F_WIDE = np.arange(0.25, 1250.0, 0.25)
SINGLE = (np.array([100.0, 250.0, 600.0]), np.array([0.03, 0.01, 0.001]))
SINGLE_SHAPES = np.array([[1.0, 0.6, 0.2], [0.7, -1.0, 0.9], [0.3, 0.5, -1.0]])


def false_splits(seeds) -> tuple[int, int]:
    """(bands split, bands) over ``seeds`` for three well-separated single modes, 3 sensors."""
    natural, damping = SINGLE
    split = total = 0
    for seed in seeds:
        rng = np.random.default_rng(seed)
        h = add_noise(modal_superposition(F_WIDE, natural, damping, SINGLE_SHAPES * (100 * damping), "accelerance"),
                      rng.uniform(30.0, 40.0), rng)
        bands = ex.find_mode_bands(F_WIDE, h)
        assert len(bands) == 3
        split += len(ex.split_bands([F_WIDE], [h], "accelerance", bands)) - len(bands)
        total += len(bands)
    return split, total


def test_single_modes_are_not_split():
    """50 noise seeds (1000-1049), 150 bands: no second mode. Development (seeds 0-49): 0/150."""
    split, total = false_splits(range(CHECK_SEEDS, CHECK_SEEDS + 50))
    assert (split, total) == (0, 150)


# ------------------------------------------------------------------------------------------
# a lightly damped free-free beam, slightly distorted: no close_mode

BEAM = np.array([112.0, 302.0, 492.0, 682.0])   # Hz, 190 Hz apart
BEAM_ZETA = 0.001
BEAM_SHAPES = np.array([[1.0, -0.8, 0.7, -0.6], [0.6, 0.9, -0.4, 0.8], [-0.8, 0.5, 0.9, 0.4]])


def beam_frf(kind: str, amount: float) -> tuple[np.ndarray, np.ndarray]:
    """Accelerance of the beam on a constant-percentage grid of 2.5 lines per half-power band (so
    every mode, not only the lowest, is seen through 2-3 lines), distorted by ``kind``:
    ``"softening"``, each mode's frequency falls with its own response level (a cubic-softening
    skew, ``omega_eff^2 = omega_r^2 (1 - amount (|q| / |q|_peak)^2)``, solved by fixed point), or
    ``"leakage"``, a share ``amount`` of each line's two neighbours leaks into it."""
    f = 100.0 * (1 + 0.8 * BEAM_ZETA) ** np.arange(int(np.log(7.5) / np.log(1 + 0.8 * BEAM_ZETA)))
    omega, wr = 2 * np.pi * f, 2 * np.pi * BEAM
    constants = BEAM_SHAPES * (100 * BEAM_ZETA)
    if kind == "softening":
        h = np.zeros((BEAM_SHAPES.shape[0], f.size), complex)
        for r in range(BEAM.size):
            w_eff = np.full_like(omega, wr[r])
            for _ in range(20):
                q = 1 / (w_eff**2 - omega**2 + 2j * BEAM_ZETA * w_eff * omega)
                w_eff = wr[r] * np.sqrt(1 - amount * (np.abs(q) * 2 * BEAM_ZETA * wr[r] ** 2) ** 2)
            h += np.outer(constants[:, r], q)
        return f, -(omega**2) * h
    h = modal_superposition(f, BEAM, np.full(BEAM.size, BEAM_ZETA), constants, "accelerance")
    h[:, 1:-1] = (1 - amount) * h[:, 1:-1] + amount / 2 * (h[:, :-2] + h[:, 2:])
    return f, h


@pytest.mark.parametrize("kind, amount", [("softening", 0.001), ("leakage", 0.03)])
def test_distorted_light_beam_has_no_close_mode(kind, amount):
    """0.1 % damping, 2.5 lines per half-power band, 35 dB: every mode found within 0.1 % and none
    flagged close_mode (the circle misfit is systematic, but no second pole explains it).
    Development (seeds 0-9, five modes): no close_mode, frequencies within 5e-4 (softening 0.001:
    the peak itself moves by 0.05 %) and 5e-6 (leakage 0.03)."""
    f, clean = beam_frf(kind, amount)
    for seed in range(CHECK_SEEDS, CHECK_SEEDS + 2):
        h = add_noise(clean, 35.0, np.random.default_rng(seed))
        bands, estimates = ex.extract_tests({0: f}, {0: h}, "accelerance")
        modes = estimates[0]
        assert len(modes) == BEAM.size, bands
        for m, fr in zip(modes, BEAM):
            assert abs(m.frequency_hz / fr - 1) < 1e-3
            assert "close_mode" not in m.flags, m.flags


# ------------------------------------------------------------------------------------------
# the intervals widen where they should


def test_intervals_widen_with_noise_few_lines_and_distortion():
    """Properties, one mode at 250 Hz / 0.5 %, three sensors: the damping interval of the combined
    mode widens with the noise (30 against 50 dB), with a
    coarser grid (2.5 against 10 lines in the half-power band, same SNR), and when the curve is
    distorted (on the 2.5-line grid, 10 % leakage of each line's neighbours: a systematic misfit, so the half-power
    bandwidth is known to `LEAKAGE_LINES` lines only, `damping_model_form` > 0). A milder leakage
    (5 % on that grid) leaves a near-perfect circle of a 3 % higher damping: no fit can see it, and
    the interval does not cover it (measured at 50 dB; a limit, not a property)."""
    fr, zeta = 250.0, 0.005

    def width(df: float, snr: float, leak: float = 0.0) -> tuple[float, float, float]:
        f = np.arange(200.0, 300.0, df)
        h = modal_superposition(f, [fr], [zeta], COVERAGE_SHAPES, "accelerance")
        h[:, 1:-1] = (1 - leak) * h[:, 1:-1] + leak / 2 * (h[:, :-2] + h[:, 2:])
        h = add_noise(h, snr, np.random.default_rng(CHECK_SEEDS))
        mode = ex.combine(ex.fit_modes(f, h, "accelerance", [(fr - 8.0, fr + 8.0)])[0])
        assert mode.damping_ci95[0] < mode.damping_ratio < mode.damping_ci95[1]
        return (np.log(mode.damping_ci95[1] / mode.damping_ci95[0]),
                mode.frequency_ci95_hz[1] - mode.frequency_ci95_hz[0], max(x.damping_model_form for x in mode.fits))

    base = width(0.25, 50.0)
    noisy, coarse = width(0.25, 30.0), width(1.0, 50.0)
    assert noisy[0] > 5 * base[0] and noisy[1] > 5 * base[1]   # 20 dB: ten times the noise
    assert coarse[0] > base[0] and coarse[1] > base[1]
    leaky = width(1.0, 50.0, 0.1)
    assert coarse[2] == 0.0 and leaky[2] > 0.0 and leaky[0] > 5 * coarse[0]


def test_a_start_outside_the_pole_range_is_brought_to_its_edge():
    """A wide one-pole fit (zeta 0.5) gives two-pole starts at f (1 - 2 zeta) = 0 Hz: no log(0), and
    the poles stay within the band widened by its width (pure noise: nothing to find)."""
    f = np.arange(0.0, 1250.25, 0.25)
    rng = np.random.default_rng(0)
    h = rng.normal(size=(3, f.size)) + 1j * rng.normal(size=(3, f.size))
    band = (25.5, 27.5)
    fit = mm.pole_fit(f, h, band, "accelerance", mm.noise_level(h), [[(0.0, 0.25), (59.0, 0.25)]])
    width = band[1] - band[0]
    assert np.all((fit.frequency_hz >= band[0] - width - 1e-9) & (fit.frequency_hz <= band[1] + width + 1e-9))


# ------------------------------------------------------------------------------------------
# one mode followed from test to test


def test_modes_that_move_between_levels_are_one_mode_each_in_every_test():
    """Eight tests at two levels, two modes 3 % lower at the high level (a joint softening with the amplitude),
    0.4 % damping: the bands found across all tests hold each at two places, each in half of the tests.
    Followed per test, each is one mode, fitted in every test within 0.05 % of its truth; a mode that does not
    move and two modes 3 % apart in every test are left as they are."""
    f = np.arange(50.0, 450.0, 0.25)
    constants = np.array([[1.0, 0.8, 0.5, 0.6, 0.5], [0.6, -0.7, 1.0, -0.4, 0.8], [-0.5, 1.0, 0.7, 0.9, -0.6]])
    zeta = np.full(5, 0.004)
    rng = np.random.default_rng(CHECK_SEEDS + 7)
    truth, frequency_hz, frfs = [], {}, {}
    for t in range(8):
        soft = 0.97 if t % 2 else 1.0
        natural = np.array([100.0, 200.0 * soft, 300.0 * soft, 400.0, 412.0])
        clean = modal_superposition(f, natural, zeta, constants, "accelerance")
        truth.append(natural)
        frequency_hz[t], frfs[t] = f, add_noise(clean, 40.0, rng)
    bands, estimates = ex.extract_tests(frequency_hz, frfs, "accelerance")
    assert len(bands) == 5, bands
    got = np.array([[e.frequency_hz for e in estimates[t]] for t in range(8)])
    np.testing.assert_allclose(got, np.array(truth), rtol=5e-4)

"""Importers of the real data sets (workbench.io.real_data) and their frame files.

The data are not in the repository (their licences forbid redistribution): the tests that read
them fail when ``../shared/data/real`` is absent (skip with WORKBENCH_ALLOW_NO_SHARED=1). The
reference numbers below were measured on
those files (FRF peak lines, 0.0625 Hz resolution for UNESP-BERT, 0.05 Hz for the Brake-Reuss
beam) when the importers were written; the model numbers come from ``frames/*.toml``.
"""

from __future__ import annotations

import numpy as np
import pytest
from conftest import REPO, SHARED
from scipy.stats import spearmanr

from workbench.io.campaign import load_campaign, write_campaign
from workbench.io.real_data import import_brake_reuss, import_unesp_bert
from workbench.model.assembly import assemble
from workbench.model.frame_file import read_frame
from workbench.model.modal import model_modes

REAL = SHARED / "data" / "real"
UNESP = REAL / "unesp-bert-bolted-beam"
BRB = REAL / "rice-brb-brake-reuss-beam"
UNESP_FRAME = REPO / "frames" / "unesp_bert.toml"
BRB_FRAME = REPO / "frames" / "brake_reuss.toml"
needs_unesp = pytest.mark.shared("data/real/unesp-bert-bolted-beam")
needs_brb = pytest.mark.shared("data/real/rice-brb-brake-reuss-beam")

# measured on the 0.05 V random test (Acc1 peaks) and the lowest force-controlled run (Accel 3 peak)
UNESP_MEASURED_HZ = (18.8125, 98.4375)
BRB_MEASURED_HZ = 80.25


def curve(campaign, test_id, sensor):
    rows = campaign.frf[(campaign.frf["test_id"] == test_id) & (campaign.frf["sensor"] == sensor)]
    return rows["frequency_hz"].to_numpy(), rows["real"].to_numpy() + 1j * rows["imag"].to_numpy()


def peak(f, h, band):
    inside = (f >= band[0]) & (f <= band[1])
    return float(f[inside][np.argmax(np.abs(h[inside]))])


def half_power_damping(f, h, band):
    """Half-power bandwidth / (2 f_peak) on |h|, edges interpolated between lines."""
    inside = (f >= band[0]) & (f <= band[1])
    f, a = f[inside], np.abs(h[inside])
    k = int(np.argmax(a))
    level = a[k] / np.sqrt(2)
    lo = k - np.argmax(a[k::-1] < level)
    hi = k + np.argmax(a[k:] < level)
    f_lo = np.interp(level, [a[lo], a[lo + 1]], [f[lo], f[lo + 1]])
    f_hi = np.interp(level, [a[hi], a[hi - 1]], [f[hi], f[hi - 1]])
    return (f_hi - f_lo) / (2 * f[k])


@pytest.fixture(scope="module")
def unesp():
    return import_unesp_bert(UNESP, UNESP_FRAME)


@needs_unesp
def test_unesp_campaign_is_a_valid_contract_campaign(unesp, tmp_path):
    loaded = load_campaign(write_campaign(unesp, tmp_path / "unesp"))
    assert loaded.quantity == "accelerance" and loaded.reference == "voltage" and not loaded.synthetic
    factor = loaded.factor("amplitude")
    assert factor.kind == "amplitude"
    assert list(factor.levels) == ["0.05", "0.10", "0.15", "0.20", "0.25", "0.30"]
    assert loaded.test_ids == ["Rand0p05", "Rand0p10", "Rand0p15", "Rand0p20", "Rand0p25", "Rand0p30"]
    assert sorted(loaded.frf["sensor"].unique()) == ["acc1", "acc2", "acc3", "acc4"]
    # 0.0625 Hz lines of the excited band (0, 110] Hz: 1760 per test and sensor
    assert loaded.frf.groupby(["test_id", "sensor"]).size().eq(1760).all()
    assert "CC BY-NC-SA" in loaded.source and "UNESP/Ilha Solteira" in loaded.source


@needs_unesp
def test_unesp_mode2_softens_and_its_damping_grows_with_level(unesp):
    # Acc1 (at the tip) converted to mobility, whose |.| half-power band gives the damping
    peaks, damping = [], []
    for test_id in unesp.test_ids:
        f, h = curve(unesp, test_id, "acc1")
        mobility = h / (2j * np.pi * f)
        assert peak(f, h, (15, 23)) == pytest.approx(UNESP_MEASURED_HZ[0], abs=0.2)  # mode 1 hardly moves
        peaks.append(peak(f, mobility, (90, 106)))
        damping.append(half_power_damping(f, mobility, (90, 106)))
    # measured: 98.44, 98.00, 97.75, 97.56, 97.56, 97.44 Hz; 1.09, 1.18, 1.23, 1.27, 1.35, 1.41 %
    assert peaks[0] == pytest.approx(UNESP_MEASURED_HZ[1])
    assert peaks[0] - peaks[-1] >= 0.75
    assert spearmanr(range(len(peaks)), peaks).statistic < -0.9
    assert np.all(np.diff(damping) > 0) and 0.009 < damping[0] < damping[-1] < 0.02


@needs_unesp
def test_unesp_laser_channel_is_mobility(tmp_path):
    campaign = import_unesp_bert(UNESP, UNESP_FRAME, channels="laser")
    assert campaign.quantity == "mobility" and campaign.frf["sensor"].unique().tolist() == ["laser"]
    accel = import_unesp_bert(UNESP, UNESP_FRAME, which="Chirp70to110Hz")
    assert accel.frf["frequency_hz"].min() > 70.0 and len(accel.test_ids) == 6
    load_campaign(write_campaign(campaign, tmp_path / "laser"))


@needs_brb
@pytest.mark.parametrize("control, tests", [("force", 4), ("response", 8)])
def test_brake_reuss_campaign_is_valid_and_peaks_near_80_hz(tmp_path, control, tests):
    campaign = import_brake_reuss(BRB, BRB_FRAME, control=control)
    loaded = load_campaign(write_campaign(campaign, tmp_path / control))
    assert loaded.quantity == "accelerance" and loaded.reference == "force"
    assert len(loaded.test_ids) == tests and loaded.frf["sensor"].unique().tolist() == ["accel3"]
    assert loaded.frf.groupby("test_id").size().eq(41).all()
    levels = [float(k) for k in loaded.factor("amplitude").levels]
    assert levels == sorted(levels)
    peaks = [peak(*curve(loaded, t, "accel3"), (78.0, 82.0)) for t in loaded.test_ids]
    # measured: force control 80.25, 80.05, 80.30, 80.35 Hz; response control 80.35 ... 80.50 Hz
    assert all(80.0 <= p <= 80.55 for p in peaks)
    # the peak accelerance per newton drops as the level rises (damping grows): 140 -> 48 (m/s2)/N
    heights = [np.abs(curve(loaded, t, "accel3")[1]).max() for t in loaded.test_ids]
    assert np.all(np.diff(heights) < 0)


def model_hz(name, count):
    return model_modes(assemble(read_frame(REPO / "frames" / f"{name}.toml")), count).frequency_hz


def test_unesp_frame_first_modes_match_the_measured_peaks():
    hz = model_hz("unesp_bert", 2)  # 18.82 and 98.47 Hz
    np.testing.assert_allclose(hz, UNESP_MEASURED_HZ, rtol=0.15)
    np.testing.assert_allclose(hz, UNESP_MEASURED_HZ, rtol=0.01)  # the calibration's actual fit


def test_brake_reuss_frame_is_free_free_with_three_rigid_modes():
    hz = model_hz("brake_reuss", 5)  # 0, 0, 0, 80.34, 318.3 Hz
    assert np.all(hz[:3] < 1e-3)
    assert hz[3] == pytest.approx(BRB_MEASURED_HZ, rel=0.15)
    assert hz[3] == pytest.approx(BRB_MEASURED_HZ, rel=0.01)
    assert hz[4] == pytest.approx(298.0, rel=0.15)  # the hammer test's second peak (provenance notes)


def test_importers_name_what_is_missing(tmp_path):
    with pytest.raises(ValueError, match=r"no Data/T5Nm/Rand directory"):
        import_unesp_bert(tmp_path / "nowhere", UNESP_FRAME)
    with pytest.raises(ValueError, match=r"missing\.toml: cannot read the frame file"):
        import_brake_reuss(tmp_path, tmp_path / "missing.toml")

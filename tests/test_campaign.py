"""Campaign files (CONTRACTS.md section 2): tidy tables, every rejection with its message, files
never changed, and random valid campaigns round-tripping through write and load unchanged."""

from __future__ import annotations

import hashlib
import shutil
from dataclasses import replace

import numpy as np
import pandas as pd
import pytest
from conftest import SHARED
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from workbench.io.campaign import Campaign, CampaignError, Factor, frf_set, load_campaign, write_campaign
from workbench.model.generate import multibay_frame

EXAMPLE = SHARED / "examples" / "independent-two-test-campaign"


def small_campaign(tests: int = 3, lines: int = 5) -> Campaign:
    frame = multibay_frame(1, 1, element_length=0.05)
    factors = (Factor("bolt", "tightening", {"1": "hand-tight", "2": "1800 N", "3": "6000 N"}, frame.joints[0].name),
               Factor("amplitude", "amplitude", {"low": "linear", "high": "five times low"}))
    design = pd.DataFrame({"test_id": np.arange(1, tests + 1),
                           "bolt": [str(1 + k % 3) for k in range(tests)],
                           "amplitude": ["low" if k % 2 == 0 else "high" for k in range(tests)]})
    f = np.linspace(10.0, 50.0, lines)
    rows = [(t, "top", fk, np.cos(fk) * t, np.sin(fk)) for t in range(1, tests + 1) for fk in f]
    frf = pd.DataFrame(rows, columns=["test_id", "sensor", "frequency_hz", "real", "imag"])
    return Campaign(name="small", frame=frame, synthetic=True, quantity="receptance", factors=factors,
                    design=design, frf=frf, source="tests")


@pytest.fixture
def campaign_dir(tmp_path):
    return write_campaign(small_campaign(), tmp_path / "c")


def digest(directory) -> dict:
    return {p.name: hashlib.sha256(p.read_bytes()).hexdigest() for p in sorted(directory.iterdir())}


def test_loads_tidy_tables(campaign_dir):
    c = load_campaign(campaign_dir)
    assert list(c.frf.columns) == ["test_id", "sensor", "frequency_hz", "real", "imag"]
    assert len(c.frf) == 3 * 5 and c.frf["test_id"].dtype == np.int64  # one observation a row
    assert c.design.set_index("test_id").loc[2, "bolt"] == "2"
    assert c.factor("bolt").joint == c.frame.joints[0].name and list(c.factor("bolt").levels) == ["1", "2", "3"]
    frfs = frf_set(c, 2)
    assert frfs.values.shape == (1, 5) and frfs.quantity == "receptance"
    # a pandas user's one-liner works: mean |FRF| per test
    assert c.frf.assign(mag=np.hypot(c.frf.real, c.frf.imag)).groupby("test_id")["mag"].mean().shape == (3,)


@pytest.mark.shared("examples/independent-two-test-campaign")
def test_reads_the_campaign_written_by_another_program():
    before = digest(EXAMPLE)
    c = load_campaign(EXAMPLE)
    assert c.synthetic and c.quantity == "accelerance" and c.test_ids == [1, 2]
    assert frf_set(c, 1).values.shape == (3, 2501) and len(c.modes) == 20
    assert digest(EXAMPLE) == before


def edit(path, old, new, count=1):
    text = path.read_text()
    assert old in text, (path, old)
    path.write_text(text.replace(old, new, count))


def set_field(path, line, column, value):
    lines = path.read_text().splitlines()
    fields = lines[line - 1].split(",")
    fields[column] = value
    lines[line - 1] = ",".join(fields)
    path.write_text("\n".join(lines) + "\n")


# (what, how to break the campaign, the file and the problem the message must name)
REJECTIONS = [
    ("no campaign.toml", lambda d: (d / "campaign.toml").unlink(), "campaign.toml: required file is missing"),
    ("unknown key", lambda d: edit(d / "campaign.toml", 'name = "small"', 'name = "small"\nnam = "x"'),
     "campaign.toml: nam: unknown key"),
    ("synthetic not stated", lambda d: edit(d / "campaign.toml", "synthetic = true\n", ""),
     "campaign.toml: synthetic: required key is missing"),
    ("bad quantity", lambda d: edit(d / "campaign.toml", '"receptance"', '"compliance"'),
     "quantity: 'compliance' is not one of"),
    ("tightening factor on an unknown joint", lambda d: edit(d / "campaign.toml", 'joint = "J1_0_L"', 'joint = "Z"'),
     "factors.bolt.joint: 'Z' is not a joint of"),
    ("undeclared level", lambda d: edit(d / "design.csv", "2,2,high", "2,7,high"),
     "design.csv: line 3: bolt = '7' is not a declared level"),
    ("duplicated test", lambda d: edit(d / "design.csv", "3,3,low", "2,3,low"),
     "design.csv: line 4: duplicated row (test_id = 2)"),
    ("a test without FRF rows", lambda d: edit(d / "design.csv", "3,3,low", "3,3,low\n4,1,low"),
     "frf.csv: test 4 of design.csv has no rows"),
    ("FRF rows of an unknown test", lambda d: edit(d / "design.csv", "\n3,3,low", ""),
     "frf.csv: line 12: test_id 3 is not in design.csv"),
    ("duplicated FRF row", lambda d: edit(d / "frf.csv", "1,top,20,", "1,top,10,"),
     "frf.csv: line 3: duplicated row (test_id = 1, sensor = top, frequency_hz = 10.0)"),
    ("non-monotonic frequencies", lambda d: edit(d / "frf.csv", "1,top,30,", "1,top,15,"),
     "frf.csv: line 4: frequency_hz = 15 does not increase within test 1, sensor top"),
    ("NaN value", lambda d: set_field(d / "frf.csv", 4, 3, "nan"),
     "frf.csv: line 4: real = 'nan' is not a finite number"),
    ("infinite value", lambda d: set_field(d / "frf.csv", 9, 4, "-inf"),
     "frf.csv: line 9: imag = '-inf' is not a finite number"),
    ("unknown sensor", lambda d: edit(d / "frf.csv", "2,top,10,", "2,tip,10,"),
     "frf.csv: line 7: sensor 'tip' is not a sensor of"),
    ("unknown column", lambda d: (d / "frf.csv").write_text("test_id,sensor,frequency_hz,real,imag,phase\n"
                                                            "1,top,1,0,0,0\n"),
     "frf.csv: unknown column(s) phase"),
    ("ragged row", lambda d: edit(d / "frf.csv", "imag\n", "imag\n1,top,1,0,0,0\n"),
     "frf.csv: cannot be read as a table"),
    ("missing column", lambda d: (d / "frf.csv").write_text("test_id,sensor,frequency_hz,real\n1,top,1,0\n"),
     "frf.csv: missing column(s) imag"),
    ("FRFs without a design", lambda d: (d / "design.csv").unlink(), "design.csv: required file is missing"),
    ("both FRF formats", lambda d: (d / "frf.parquet").write_bytes(b"x"), "holds both frf.csv and frf.parquet"),
    ("damping of one in modes.csv",
     lambda d: (d / "modes.csv").write_text("test_id,mode,frequency_hz,damping_ratio\n1,1,20.0,1.0\n"),
     "modes.csv: line 2: damping_ratio = 1 must be in [0, 1)"),
    ("broken frame file", lambda d: edit(d / "frame.toml", "density = 2700.0", "density = -2700.0"),
     "frame.toml: materials.aluminium.density: must be positive"),
]


@pytest.mark.parametrize("breaker, expected", [(b, m) for _, b, m in REJECTIONS], ids=[w for w, _, _ in REJECTIONS])
def test_malformed_campaign_is_rejected_with_one_line(campaign_dir, breaker, expected):
    breaker(campaign_dir)
    before = digest(campaign_dir)
    with pytest.raises(CampaignError) as info:
        load_campaign(campaign_dir)
    message = str(info.value)
    assert expected in message and "\n" not in message
    assert digest(campaign_dir) == before  # loading never changes the files


def test_writing_is_all_or_nothing(campaign_dir):
    before = digest(campaign_dir)
    with pytest.raises(FileExistsError):
        write_campaign(small_campaign(tests=2), campaign_dir)
    assert digest(campaign_dir) == before
    write_campaign(small_campaign(tests=2), campaign_dir, force=True)
    assert load_campaign(campaign_dir).test_ids == [1, 2]


def test_parquet_float32_is_accepted_and_small(tmp_path):
    c = small_campaign(tests=4, lines=2000)
    csv_dir = write_campaign(c, tmp_path / "csv")
    pq_dir = write_campaign(c, tmp_path / "pq", frf_format="parquet", frf_dtype="float32")
    back = load_campaign(pq_dir)
    np.testing.assert_array_equal(back.frf["frequency_hz"], c.frf["frequency_hz"])
    np.testing.assert_allclose(back.frf["real"], c.frf["real"], rtol=1e-7, atol=1e-7)
    assert (pq_dir / "frf.parquet").stat().st_size < 0.5 * (csv_dir / "frf.csv").stat().st_size


level = st.text(alphabet="abcdefgh0123456789", min_size=1, max_size=4)
number = st.floats(allow_nan=False, allow_infinity=False, width=64, min_value=-1e12, max_value=1e12)


@settings(max_examples=25, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(levels=st.lists(level, min_size=1, max_size=4, unique=True), tests=st.integers(1, 4),
       lines=st.integers(1, 6), data=st.data(), parquet=st.booleans())
def test_random_valid_campaigns_round_trip_unchanged(tmp_path_factory, levels, tests, lines, data, parquet):
    frame = multibay_frame(1, 1, element_length=0.1)
    factor = Factor("amp", "amplitude", {lv: f"level {lv}" for lv in levels})
    design = pd.DataFrame({"test_id": np.arange(1, tests + 1),
                           "amp": [data.draw(st.sampled_from(levels)) for _ in range(tests)]})
    f = np.cumsum(data.draw(st.lists(st.floats(0.01, 100.0), min_size=lines, max_size=lines)))
    rows = [(t, "top", fk, data.draw(number), data.draw(number)) for t in range(1, tests + 1) for fk in f]
    frf = pd.DataFrame(rows, columns=["test_id", "sensor", "frequency_hz", "real", "imag"])
    modes = pd.DataFrame({"test_id": np.arange(1, tests + 1), "mode": 1,
                          "frequency_hz": data.draw(st.floats(0.1, 2000.0)), "damping_ratio": 0.01})
    c = Campaign(name=data.draw(st.text(min_size=1, max_size=20).filter(str.strip)), frame=frame, synthetic=True,
                 quantity="mobility", factors=(factor,), design=design, frf=frf, modes=modes,
                 description=data.draw(st.text(max_size=30)))
    directory = tmp_path_factory.mktemp("rt") / "c"
    write_campaign(c, directory, frf_format="parquet" if parquet else "csv")
    back = load_campaign(directory)
    for name in ("design", "frf", "modes"):
        pd.testing.assert_frame_equal(getattr(back, name), getattr(c, name), check_dtype=False)
    assert (back.name, back.description, back.factors, back.frame) == (c.name, c.description, c.factors, c.frame)
    shutil.rmtree(directory)


def test_measured_modes_from_modes_moments_or_frfs(tmp_path):
    from conftest import REPO

    from workbench.model.frame_file import read_frame
    from workbench.rig.simulate import RigSettings, simulate_campaign
    from workbench.workflow.measured import measured_modes

    table3 = measured_modes(load_campaign(REPO / "campaigns" / "paper_table3_one_bolt_vertical"), None, "identify from")
    assert not table3.has_tests and table3.modes.tolist() == list(range(1, 10))
    assert table3.mean_hz[0] == 26.00 and table3.std_hz[8] == 4.66

    frame = read_frame(REPO / "frames" / "one_bolt_vertical.toml")
    factor = Factor("bolt_A", "tightening", {"1": "hand-tight", "2": "1800 N", "3": "6000 N"}, "A")
    campaign, truth = simulate_campaign(frame, (factor,), [{"bolt_A": lv} for lv in "123"], RigSettings(), seed=8)
    from_frfs = measured_modes(campaign, 6, "identify from")
    true = np.array([t["frequency_hz"][:6] for t in truth["tests"]])
    np.testing.assert_allclose(from_frfs.frequency_hz, true, rtol=2e-4)
    np.testing.assert_allclose(from_frfs.mean_hz, true.mean(axis=0), rtol=2e-4)
    with_modes = replace(campaign, modes=pd.DataFrame(
        [(k + 1, m + 1, f, 0.01) for k, row in enumerate(true) for m, f in enumerate(row)],
        columns=["test_id", "mode", "frequency_hz", "damping_ratio"]))
    np.testing.assert_array_equal(measured_modes(with_modes, None, "identify from").frequency_hz, true)

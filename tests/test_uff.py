"""UFF dataset 58 exchange (workbench.io.uff): exact round trips, foreign files, rejected files."""

from __future__ import annotations

import dataclasses
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
from conftest import REPO, SHARED

from workbench.io.campaign import Campaign, Factor, load_campaign, write_campaign
from workbench.io.uff import DIRECTION_CODES, campaign_from_uff, export_frfs, import_frfs, uff_quantity
from workbench.model.frame_file import parse_frame

pyuff = pytest.importorskip("pyuff")


def portal_frame():
    """A small portal frame with ux, uy and rz sensors (every direction code)."""
    return parse_frame({
        "name": "portal for UFF tests",
        "materials": {"al": {"youngs_modulus": 70e9, "density": 2700.0}},
        "sections": {"bar": {"area": 2.4e-4, "second_moment": 1.28e-9}},
        "points": {"base_left": [0.0, 0.0], "drive": [0.0, 0.1], "top_left": [0.0, 0.4],
                   "mid_beam": [0.2, 0.4], "top_right": [0.4, 0.4], "base_right": [0.4, 0.0]},
        "members": [{"name": "left", "start": "base_left", "end": "top_left", "material": "al", "section": "bar"},
                    {"name": "beam", "start": "top_left", "end": "top_right", "material": "al", "section": "bar"},
                    {"name": "right", "start": "base_right", "end": "top_right", "material": "al",
                     "section": "bar"}],
        "supports": [{"point": "base_left", "ux": "fixed", "uy": "fixed", "rz": "fixed"},
                     {"point": "base_right", "ux": "fixed", "uy": "fixed", "rz": "fixed"}],
        "excitation": {"point": "drive", "dof": "ux"},
        "sensors": [{"name": "s_top", "point": "top_left", "dof": "ux"},
                    {"name": "s_mid", "point": "mid_beam", "dof": "uy"},
                    {"name": "s_rot", "point": "top_right", "dof": "rz"}],
    })


def random_campaign(rng, quantity="accelerance", axis=None, tests=("t1", "t2"), reference="force"):
    """FRFs of full float64 precision (random mantissas, magnitudes over 12 decades)."""
    frame = portal_frame()
    axis = np.linspace(1.0, 200.0, 37) if axis is None else axis
    rows = []
    for test in tests:
        for sensor in frame.sensors:
            values = rng.standard_normal(axis.size) + 1j * rng.standard_normal(axis.size)
            values *= 10.0 ** rng.uniform(-8, 4, axis.size)
            rows.append(pd.DataFrame({"test_id": test, "sensor": sensor.name, "frequency_hz": axis,
                                      "real": values.real, "imag": values.imag}))
    frf = pd.concat(rows, ignore_index=True)
    factor = Factor("amplitude", "amplitude", {"low": "linear", "high": "ten times"})
    design = pd.DataFrame({"test_id": list(tests), "amplitude": ["low", "high"][:len(tests)]})
    return Campaign(name="UFF round trip", frame=frame, synthetic=True, quantity=quantity, reference=reference,
                    factors=(factor,), design=design, frf=frf)


AXES = {
    "even": np.arange(0, 64) * 0.0625,                        # LMS-like lines: minimum + k * increment exactly
    "even_offset": 85.0 + np.arange(41) * 0.5,                # a stepped-sine grid
    "uneven": np.sort(np.random.default_rng(7).uniform(5.0, 150.0, 29)),
    "linspace": np.linspace(1.0, 200.0, 37),                  # uniform but not rebuilt bit for bit: stored
}


@pytest.mark.parametrize("quantity", ["receptance", "mobility", "accelerance"])
@pytest.mark.parametrize("axis", list(AXES))
def test_round_trip_keeps_every_value_exactly(tmp_path, rng, quantity, axis):
    campaign = random_campaign(rng, quantity, AXES[axis])
    path = export_frfs(campaign, tmp_path / "frf.uff")
    table = import_frfs(path, campaign.frame)
    pd.testing.assert_frame_equal(table, campaign.frf, check_exact=True)
    assert uff_quantity(path) == (quantity, "force")
    spacing = [d["abscissa_spacing"] for d in pyuff.UFF(str(path)).read_sets(header_only=True)]
    assert set(spacing) == {1 if axis.startswith("even") else 0}


def test_header_codes_follow_the_frame(tmp_path, rng):
    campaign = random_campaign(rng, "mobility", reference="voltage")
    sets = pyuff.UFF(str(export_frfs(campaign, tmp_path / "frf.uff"))).read_sets()
    assert len(sets) == 2 * 3
    points = list(campaign.frame.points)
    first = sets[0]
    assert (first["func_type"], first["ord_data_type"], first["ordinate_spec_data_type"],
            first["abscissa_spec_data_type"]) == (4, 6, 11, 18)
    assert (first["ref_node"], first["ref_dir"]) == (points.index("drive") + 1, DIRECTION_CODES["ux"])
    codes = {(d["rsp_node"], d["rsp_dir"]) for d in sets}
    assert codes == {(points.index(s.point) + 1, DIRECTION_CODES[s.dof]) for s in campaign.frame.sensors}
    assert first["id2"] == "test_id=t1" and first["id4"] == "sensor=s_top"
    assert uff_quantity(tmp_path / "frf.uff") == ("mobility", "voltage")


def test_campaign_round_trip_through_a_directory(tmp_path, rng):
    campaign = random_campaign(rng, tests=("1", "2"))
    campaign = dataclasses.replace(campaign, frf=campaign.frf.assign(test_id=campaign.frf["test_id"].astype(int)),
                                   design=campaign.design.assign(test_id=[1, 2]))
    path = export_frfs(campaign, tmp_path / "frf.uff")
    again = campaign_from_uff(path, campaign.frame, "again", factors=campaign.factors, design=campaign.design,
                              synthetic=True)
    loaded = load_campaign(write_campaign(again, tmp_path / "campaign"))
    pd.testing.assert_frame_equal(loaded.frf, campaign.frf, check_exact=True)
    assert loaded.quantity == "accelerance" and loaded.reference == "force"


def test_ascii_keeps_twelve_digits(tmp_path, rng):
    campaign = random_campaign(rng, "receptance", AXES["even"])
    table = import_frfs(export_frfs(campaign, tmp_path / "frf.uff", binary=False), campaign.frame)
    for column in ("real", "imag"):
        np.testing.assert_allclose(table[column], campaign.frf[column], rtol=1e-11, atol=0)
    np.testing.assert_array_equal(table["frequency_hz"], campaign.frf["frequency_hz"])


def write_foreign(path, frame, nodes, quantity_code=12, directions=None, **override):
    """An FRF file as other software writes it: pyuff directly, its own node numbers, one test."""
    f = np.arange(1, 51) * 0.5
    dsets = []
    for k, (sensor, node) in enumerate(nodes.items()):
        s = next(x for x in frame.sensors if x.name == sensor)
        h = (k + 1) / (100.0 - f**2 + 2j * f)
        dset = pyuff.prepare_58(binary=0, func_type=4, rsp_node=node,
                                rsp_dir=(directions or {}).get(sensor, DIRECTION_CODES[s.dof]),
                                ref_node=list(frame.points).index(frame.excitation.point) + 1,
                                ref_dir=DIRECTION_CODES[frame.excitation.dof], abscissa_spacing=1,
                                abscissa_spec_data_type=18,
                                ordinate_spec_data_type=quantity_code, orddenom_spec_data_type=13,
                                data=h, x=f, id1=f"Point{node}")
        dset.update(override)
        dsets.append(dset)
    pyuff.UFF(str(path)).write_sets(dsets, mode="overwrite")
    return f


def test_file_written_by_other_software_imports_through_a_sensor_map(tmp_path):
    frame = portal_frame()
    path = tmp_path / "lab.uff"
    nodes = {"s_top": 101, "s_mid": 2047, "s_rot": 55}
    f = write_foreign(path, frame, nodes, directions={"s_mid": -2})
    table = import_frfs(path, frame, sensor_map={(n, abs(DIRECTION_CODES[next(x for x in frame.sensors
                                                                            if x.name == s).dof])): s
                                                 for s, n in nodes.items()}, test_id=7)
    assert table["sensor"].unique().tolist() == list(nodes)
    assert (table["test_id"] == 7).all()
    mid = table[table["sensor"] == "s_mid"]
    expected = -2 / (100.0 - f**2 + 2j * f)  # -Y response: sign flipped into the frame's +y
    np.testing.assert_allclose(mid["real"] + 1j * mid["imag"], expected, rtol=1e-10)
    np.testing.assert_array_equal(mid["frequency_hz"], f)
    with pytest.raises(ValueError, match=r"lab\.uff: dataset 0 .*unknown response node 101 direction 1"):
        import_frfs(path, frame)
    campaign = campaign_from_uff(path, frame, "lab", sensor_map={(101, 1): "s_top", (2047, 2): "s_mid",
                                                                 (55, 6): "s_rot"})
    assert campaign.quantity == "accelerance" and campaign.test_ids == [1]


def test_units_dataset_rescales_to_si(tmp_path):
    frame = portal_frame()
    path = tmp_path / "mm.uff"
    pyuff.UFF(str(path)).write_sets(pyuff.prepare_164(units_code=5, units_description="mm", temp_mode=1,
                                                      length=1000.0, force=1000.0, temp=1.0, temp_offset=273.15),
                                    mode="overwrite")
    f = np.arange(1, 21) * 1.0
    pyuff.UFF(str(path)).write_sets(pyuff.prepare_58(binary=0, func_type=4, rsp_node=3, rsp_dir=1, ref_node=2,
                                                     ref_dir=1, abscissa_spacing=1, ordinate_spec_data_type=8,
                                                     orddenom_spec_data_type=13, data=(1 + 1j) * f, x=f),
                                    mode="add")
    table = import_frfs(path, frame)
    # mm/mN -> m/N: times force factor / length factor = 1
    np.testing.assert_allclose(table["real"], f)


BAD = {
    "not an FRF": (dict(func_type=1), r"function type 1 is not an FRF"),
    "unknown direction": (dict(rsp_dir=3), r"unknown response node \d+ direction 3"),
    "unknown node": (dict(rsp_node=999), r"unknown response node 999"),
    "quantity unknown": (dict(ordinate_spec_data_type=0), r"ordinate type is unknown"),
    "not a frequency axis": (dict(abscissa_spec_data_type=17), r"not frequency"),
}


@pytest.mark.parametrize("case", list(BAD))
def test_bad_files_are_rejected_with_one_line(tmp_path, case):
    frame = portal_frame()
    override, message = BAD[case]
    path = tmp_path / "bad.uff"
    points = list(frame.points)
    nodes = {s.name: points.index(s.point) + 1 for s in frame.sensors}
    write_foreign(path, frame, nodes)
    dsets = pyuff.UFF(str(path)).read_sets()
    dsets[1].update(override)
    dsets[1]["binary"] = 0
    pyuff.UFF(str(path)).write_sets(dsets, mode="overwrite")
    with pytest.raises(ValueError, match=r"bad\.uff: dataset 1 .*" + message) as err:
        import_frfs(path, frame)
    assert "\n" not in str(err.value)


@pytest.mark.parametrize("binary", [False, True], ids=["ascii", "binary"])
def test_a_file_cut_anywhere_inside_a_dataset_is_refused(tmp_path, rng, binary):
    # pyuff drops a dataset cut short without a word: 35 of 40 cut points imported fewer FRFs, exit 0
    campaign = random_campaign(rng, axis=AXES["uneven"])
    whole = export_frfs(campaign, tmp_path / "whole.uff", binary=binary)
    data = whole.read_bytes()
    rows = len(import_frfs(whole, campaign.frame))
    assert rows == len(campaign.frf)
    cut = tmp_path / "cut.uff"
    for end in np.linspace(0.02, 0.998, 40) * len(data):
        cut.write_bytes(data[:int(end)])
        with pytest.raises(ValueError, match="cut.uff") as err:
            import_frfs(cut, campaign.frame)
        assert "\n" not in str(err.value)


def test_inconsistent_quantity_and_nan_are_rejected(tmp_path):
    frame = portal_frame()
    points = list(frame.points)
    nodes = {s.name: points.index(s.point) + 1 for s in frame.sensors}
    path = tmp_path / "mixed.uff"
    write_foreign(path, frame, nodes)
    dsets = pyuff.UFF(str(path)).read_sets()
    dsets[2]["ordinate_spec_data_type"] = 11
    pyuff.UFF(str(path)).write_sets(dsets, mode="overwrite")
    with pytest.raises(ValueError, match=r"mixed\.uff: dataset 2 .*inconsistent quantity: mobility after accelerance"):
        import_frfs(path, frame)
    write_foreign(path, frame, nodes)
    with pytest.raises(ValueError, match=r"dataset 0 .*inconsistent quantity: the dataset holds accelerance, "
                                         r"receptance was asked for"):
        import_frfs(path, frame, quantity="receptance")

    nan_path = tmp_path / "nan.uff"
    write_foreign(nan_path, frame, nodes)
    text = nan_path.read_text().splitlines(keepends=True)
    first_data = next(i for i, line in enumerate(text) if i > 13 and len(line) > 60)
    text[first_data] = f"{'nan':>20}" + text[first_data][20:]
    nan_path.write_text("".join(text))
    with pytest.raises(ValueError, match=r"nan\.uff: dataset 0 .*NaN or infinite value"):
        import_frfs(nan_path, frame)


def test_not_a_universal_file(tmp_path):
    path = tmp_path / "empty.uff"
    path.write_text("hello\n")
    with pytest.raises(ValueError, match=r"empty\.uff: holds no dataset 58"):
        import_frfs(path, portal_frame())
    with pytest.raises(ValueError, match=r"no such UFF file"):
        import_frfs(tmp_path / "absent.uff", portal_frame())


def test_export_refuses_nan_instead_of_writing_zero(tmp_path, rng):
    campaign = random_campaign(rng)
    frf = campaign.frf.copy()
    frf.loc[3, "real"] = np.nan
    with pytest.raises(ValueError, match=r"test t1, sensor s_top: NaN"):
        export_frfs(dataclasses.replace(campaign, frf=frf), tmp_path / "x.uff")
    assert not list(tmp_path.iterdir())


def real_uff_files() -> list[Path]:
    root = SHARED / "data"
    if not root.is_dir():
        return []
    return sorted(p for p in root.rglob("*") if p.suffix.lower() in (".uff", ".unv", ".uf"))


@pytest.mark.shared("data")
def test_a_real_uff_file_imports():
    files = real_uff_files()
    if not files:
        pytest.skip("no .uff/.unv/.uf file under ../shared/data (checked: none there at the time of writing)")
    path = files[0]
    sets = [d for d in pyuff.UFF(str(path)).read_sets(header_only=True) if d.get("type") == 58]
    # a frame with one sensor per (node, direction) of the file, along a line
    keys = sorted({(d["rsp_node"], abs(d["rsp_dir"])) for d in sets})
    names = {k: f"n{k[0]}d{k[1]}" for k in keys}
    dof = {1: "ux", 2: "uy", 6: "rz"}
    points = {f"p{k}": [0.01 * k, 0.0] for k in range(len(keys) + 1)}
    frame = parse_frame({
        "name": "line", "materials": {"m": {"youngs_modulus": 1e9, "density": 1e3}},
        "sections": {"s": {"area": 1e-4, "second_moment": 1e-9}}, "points": points,
        "members": [{"name": "b", "start": "p0", "end": f"p{len(keys)}", "material": "m", "section": "s"}],
        "excitation": {"point": "p0", "dof": "ux"},
        "sensors": [{"name": names[k], "point": f"p{i + 1}", "dof": dof.get(k[1], "ux")} for i, k in enumerate(keys)],
    })
    table = import_frfs(path, frame, sensor_map=names)
    assert len(table) > 0 and np.isfinite(table[["real", "imag"]].to_numpy()).all()


UNESP = SHARED / "data" / "real" / "unesp-bert-bolted-beam"


@pytest.mark.shared("data/real/unesp-bert-bolted-beam")
def test_measured_campaign_round_trips_through_uff(tmp_path):
    """24 datasets of 1760 measured lines (LMS float32 values, 0.0625 Hz grid: even spacing)."""
    from workbench.io.real_data import import_unesp_bert

    campaign = import_unesp_bert(UNESP, REPO / "frames" / "unesp_bert.toml")
    path = export_frfs(campaign, tmp_path / "unesp.uff")
    assert {d["abscissa_spacing"] for d in pyuff.UFF(str(path)).read_sets(header_only=True)} == {1}
    pd.testing.assert_frame_equal(import_frfs(path, campaign.frame), campaign.frf, check_exact=True)
    assert uff_quantity(path) == ("accelerance", "voltage")


def _numbered_frame():
    """The portal with points named by UFF node numbers, as an FE export would name them."""
    frame = portal_frame()
    names = {"base_left": "10", "drive": "11", "top_left": "12", "mid_beam": "13", "top_right": "14",
             "base_right": "15"}
    data = {"name": "numbered portal", "materials": {"al": {"youngs_modulus": 70e9, "density": 2700.0}},
            "sections": {"bar": {"area": 2.4e-4, "second_moment": 1.28e-9}},
            "points": {names[p]: list(xy) for p, xy in frame.points.items()},
            "members": [{"name": m.name, "start": names[m.start], "end": names[m.end], "material": "al",
                         "section": "bar"} for m in frame.members],
            "supports": [{"point": names[s.point], "ux": "fixed", "uy": "fixed", "rz": "fixed"}
                         for s in frame.supports],
            "excitation": {"point": "11", "dof": "ux"},
            "sensors": [{"name": s.name, "point": names[s.point], "dof": s.dof} for s in frame.sensors]}
    return parse_frame(data)


def _dataset(rsp, ref, h, f):
    return pyuff.prepare_58(binary=0, func_type=4, rsp_node=rsp[0], rsp_dir=rsp[1], ref_node=ref[0],
                            ref_dir=ref[1], abscissa_spacing=1, abscissa_spec_data_type=18,
                            ordinate_spec_data_type=12, orddenom_spec_data_type=13, data=h, x=f)


def test_nodes_are_the_points_named_by_their_number_and_a_roving_hammer_reads_by_reciprocity(tmp_path):
    # CONTRACTS.md section 3: node 12 is the point named "12"; a roving-hammer export keeps the response
    # at the excitation (node 11, +X) and moves the force: by reciprocity, response at the force's point
    frame = _numbered_frame()
    f = np.arange(1, 41) * 0.5
    h = {name: (k + 1) / (50.0 - f**2 + 1j * f) for k, name in enumerate(("s_top", "s_mid", "s_rot"))}
    shaker, hammer = tmp_path / "shaker.uff", tmp_path / "hammer.uff"
    pyuff.UFF(str(shaker)).write_sets([_dataset((12, 1), (11, 1), h["s_top"], f),
                                       _dataset((13, -2), (11, 1), h["s_mid"], f)], mode="overwrite")
    pyuff.UFF(str(hammer)).write_sets([_dataset((11, 1), (12, 1), h["s_top"], f),
                                       _dataset((11, 1), (14, 6), h["s_rot"], f)], mode="overwrite")
    table = import_frfs(shaker, frame)
    assert table["sensor"].tolist()[::f.size] == ["s_top", "s_mid"]
    mid = table[table["sensor"] == "s_mid"]
    np.testing.assert_allclose(mid["real"] + 1j * mid["imag"], -h["s_mid"], rtol=1e-10)  # -Y flipped
    roving = import_frfs(hammer, frame)
    assert roving["sensor"].tolist()[::f.size] == ["s_top", "s_rot"]
    rot = roving[roving["sensor"] == "s_rot"]
    np.testing.assert_allclose(rot["real"] + 1j * rot["imag"], h["s_rot"], rtol=1e-10)
    stray = tmp_path / "stray.uff"
    pyuff.UFF(str(stray)).write_sets([_dataset((12, 1), (13, 2), h["s_top"], f)], mode="overwrite")
    with pytest.raises(ValueError, match=r"stray\.uff: dataset 0 .*not the frame's excitation \(node 11"):
        import_frfs(stray, frame)


def _labelled(path, labels: dict, units_164: tuple[float, float] | None = None):
    """One accelerance record at s_top (node 3, +X) of the portal, with the given axis units labels."""
    f = np.arange(1, 21) * 2.0
    sets = []
    if units_164 is not None:
        sets.append(pyuff.prepare_164(units_code=5, units_description="file units", temp_mode=1,
                                      length=units_164[0], force=units_164[1], temp=1.0, temp_offset=273.15))
    dset = pyuff.prepare_58(binary=0, func_type=4, rsp_node=3, rsp_dir=1, ref_node=2, ref_dir=1,
                            abscissa_spacing=1, abscissa_spec_data_type=18, ordinate_spec_data_type=12,
                            orddenom_spec_data_type=13, data=(1 + 2j) * f, x=f)
    dset.update(labels)
    sets.append(dset)
    pyuff.UFF(str(path)).write_sets(sets, mode="overwrite")
    return f


@pytest.mark.parametrize("labels, factor, hz", [
    ({"ordinate_axis_units_lab": "mm/s^2", "orddenom_axis_units_lab": "N"}, 1e-3, 1.0),
    ({"ordinate_axis_units_lab": "g", "orddenom_axis_units_lab": "lbf"}, 9.80665 / 4.4482216152605, 1.0),
    ({"ordinate_axis_units_lab": "g/N", "orddenom_axis_units_lab": ""}, 9.80665, 1.0),
    ({"ordinate_axis_units_lab": "m/s2", "orddenom_axis_units_lab": "kN", "abscissa_axis_units_lab": "rad/s"},
     1e-3, 1 / (2 * np.pi)),
], ids=["mm/s^2 per N", "g per lbf", "g/N in one label", "per kN over rad/s"])
def test_axis_labels_convert_to_si(tmp_path, labels, factor, hz):
    f = _labelled(tmp_path / "lab.uff", labels)
    table = import_frfs(tmp_path / "lab.uff", portal_frame())
    np.testing.assert_allclose(table["real"] + 1j * table["imag"], (1 + 2j) * f * factor, rtol=1e-10)
    np.testing.assert_allclose(table["frequency_hz"], f * hz, rtol=1e-12)


@pytest.mark.parametrize("labels, units_164, message", [
    ({"ordinate_axis_units_lab": "m/s2"}, (1000.0, 1.0), "contradicts the units dataset 164"),
    ({"orddenom_axis_units_lab": "N"}, (1.0, 1000.0), "contradicts the units dataset 164"),
    ({"ordinate_axis_units_lab": "furlong/fortnight^2"}, None, "not a unit of accelerance"),
    ({"abscissa_axis_units_lab": "s"}, None, "not a frequency unit"),
], ids=["length", "force", "unknown unit", "time axis"])
def test_labels_that_contradict_or_name_no_unit_are_refused(tmp_path, labels, units_164, message):
    _labelled(tmp_path / "lab.uff", labels, units_164)
    with pytest.raises(ValueError, match=r"lab\.uff: dataset 0 .*" + message) as err:
        import_frfs(tmp_path / "lab.uff", portal_frame())
    assert "\n" not in str(err.value)

"""Property-based robustness of the inputs (issue 19): mutated frames, campaigns and UFF files.

Each example starts from a valid input, mutates it (truncation, NaN, duplication, type changes,
permutations, a deleted key or column) and asserts the contract's promise: the command exits 0 with
finite outputs, or exits 2 with one line on standard error; never a traceback, a hang, or a changed
input file. The default profile is quick (derandomised, so CI is repeatable); set
``WORKBENCH_FUZZ=long`` for a long random run (``WORKBENCH_FUZZ_EXAMPLES`` sets the count).
"""

from __future__ import annotations

import copy
import csv
import io
import math
import os
import re
import shutil
import tomllib
from pathlib import Path

import numpy as np
import pytest
from conftest import REPO, cut_example_campaign, digest, dump_toml, error_lines, run_cli, tree
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

LONG = os.environ.get("WORKBENCH_FUZZ") == "long"
EXAMPLES = int(os.environ.get("WORKBENCH_FUZZ_EXAMPLES", 400 if LONG else 20))
FUZZ = settings(max_examples=EXAMPLES, deadline=None, derandomize=not LONG, database=None,
                suppress_health_check=[HealthCheck.function_scoped_fixture, HealthCheck.too_slow,
                                       HealthCheck.data_too_large])

WEIRD = [math.nan, math.inf, -math.inf, 0, 0.0, -1.0, 1e30, 1e-30, 10**20, "x", "", True, [], {}]
CELL_WEIRD = ["", "nan", "inf", "-inf", "-1", "0", "abc", "1e400", " ", "1,5", "0x10", "None"]


# ------------------------------------------------------------------ running and judging a command

def assert_honest(status: int, stderr: str, out: Path) -> None:
    """Exit 0 with finite numbers in every CSV written, or exit 2 with one line."""
    assert status in (0, 2), f"exit {status}: {stderr}"
    if status == 2:
        lines = error_lines(stderr)
        assert len(lines) == 1, f"exit 2 must give one line, got {lines}"
        assert "Traceback" not in stderr
        return
    for table in out.glob("*.csv"):
        for row in csv.DictReader(io.StringIO(table.read_text())):
            for key, value in row.items():
                if re.fullmatch(r"[-+]?(\d+\.?\d*|\.\d+)([eE][-+]?\d+)?|[-+]?(nan|inf)", value or "", re.I):
                    assert math.isfinite(float(value)), f"{table.name}: {key} = {value} with exit 0"


def leaves(data, path=()):
    """Every (path, value) below ``data``: dict keys and list indices."""
    items = data.items() if isinstance(data, dict) else enumerate(data) if isinstance(data, list) else ()
    for key, value in items:
        yield (*path, key), value
        yield from leaves(value, (*path, key))


def _parent(data, path):
    for key in path[:-1]:
        data = data[key]
    return data


@st.composite
def mutated_dict(draw, base: dict) -> dict:
    """``base`` with one to three mutations: a value replaced, a key or element deleted, a list
    element duplicated, or a list permuted."""
    data = copy.deepcopy(base)
    for _ in range(draw(st.integers(1, 3))):
        paths = [p for p, _ in leaves(data)]
        if not paths:
            break
        path = draw(st.sampled_from(paths))
        parent, key = _parent(data, path), path[-1]
        action = draw(st.sampled_from(["replace", "replace", "delete", "duplicate", "permute"]))
        if action == "replace":
            parent[key] = draw(st.sampled_from(WEIRD))
        elif action == "delete":
            del parent[key]
        elif action == "duplicate" and isinstance(parent, list):
            parent.insert(key, copy.deepcopy(parent[key]))
        elif action == "permute" and isinstance(parent[key], list) and len(parent[key]) > 1:
            parent[key] = draw(st.permutations(parent[key]))
    return data


# ------------------------------------------------------------------ frames

FRAME = REPO / "frames" / "one_bolt_vertical.toml"
FRAME_DATA = tomllib.loads(FRAME.read_text())


@FUZZ
@given(data=mutated_dict(FRAME_DATA))
def test_mutated_frames_are_refused_in_one_line_or_give_finite_modes(tmp_path_factory, data):
    work = tmp_path_factory.mktemp("frame")
    frame = work / "frame.toml"
    frame.write_text(dump_toml(data))
    before = digest([frame])
    status, stderr = run_cli(["modes", str(frame), "--out", str(work / "out"), "--count", "4"])
    assert_honest(status, stderr, work / "out")
    assert digest([frame]) == before


@FUZZ
@given(cut=st.integers(0, len(FRAME.read_bytes())))
def test_truncated_frames_are_refused_or_read_whole(tmp_path_factory, cut):
    work = tmp_path_factory.mktemp("frame")
    frame = work / "frame.toml"
    frame.write_bytes(FRAME.read_bytes()[:cut])
    status, stderr = run_cli(["modes", str(frame), "--out", str(work / "out"), "--count", "4"])
    assert_honest(status, stderr, work / "out")


def test_member_order_does_not_change_the_frequencies(tmp_path):
    """A property that must hold: the frame is the same structure whatever the order of its members."""
    reordered = copy.deepcopy(FRAME_DATA)
    reordered["members"] = reordered["members"][::-1]
    results = []
    for name, data in (("given", FRAME_DATA), ("reversed", reordered)):
        path = tmp_path / f"{name}.toml"
        path.write_text(dump_toml(data))
        status, stderr = run_cli(["modes", str(path), "--out", str(tmp_path / name), "--count", "6"])
        assert status == 0, stderr
        rows = list(csv.DictReader(io.StringIO((tmp_path / name / "modes.csv").read_text())))
        results.append(np.array([float(r["frequency_hz"]) for r in rows]))
    np.testing.assert_allclose(results[1], results[0], rtol=1e-9)


# ------------------------------------------------------------------ campaigns

@pytest.fixture(scope="module")
def small_campaign(tmp_path_factory) -> Path:
    return cut_example_campaign(tmp_path_factory.mktemp("campaign") / "campaign")


def _rows(path: Path) -> list[list[str]]:
    return list(csv.reader(io.StringIO(path.read_text())))


@st.composite
def mutated_table(draw, rows: list[list[str]]) -> list[list[str]]:
    """A CSV table with one mutation: a cell made weird, a row dropped, duplicated or moved, a column
    dropped or renamed, the columns permuted (header with them), or a test id re-spelt."""
    rows = [list(r) for r in rows]
    action = draw(st.sampled_from(["cell", "cell", "drop_row", "dup_row", "swap_rows", "drop_column",
                                   "rename_column", "permute_columns", "respell_id"]))
    data_rows = range(1, len(rows))
    if action == "cell" and len(rows) > 1:
        i, j = draw(st.sampled_from(data_rows)), draw(st.integers(0, len(rows[0]) - 1))
        rows[i][j] = draw(st.sampled_from(CELL_WEIRD))
    elif action == "drop_row" and len(rows) > 1:
        del rows[draw(st.sampled_from(data_rows))]
    elif action == "dup_row" and len(rows) > 1:
        i = draw(st.sampled_from(data_rows))
        rows.insert(i, list(rows[i]))
    elif action == "swap_rows" and len(rows) > 2:
        i, j = draw(st.sampled_from(data_rows)), draw(st.sampled_from(data_rows))
        rows[i], rows[j] = rows[j], rows[i]
    elif action == "drop_column":
        j = draw(st.integers(0, len(rows[0]) - 1))
        rows = [r[:j] + r[j + 1:] for r in rows]
    elif action == "rename_column":
        rows[0][draw(st.integers(0, len(rows[0]) - 1))] = draw(st.sampled_from(["", "id", "Frequency", "x"]))
    elif action == "permute_columns":
        order = draw(st.permutations(range(len(rows[0]))))
        rows = [[r[j] for j in order] for r in rows]
    elif action == "respell_id":
        old = draw(st.sampled_from(sorted({r[0] for r in rows[1:]})))
        new = draw(st.sampled_from(["0" + old, "00" + old, old + " ", "1.0"]))
        rows = [rows[0]] + [[new if k == 0 and c == old else c for k, c in enumerate(r)] for r in rows[1:]]
    return rows


def _write_rows(path: Path, rows: list[list[str]]) -> None:
    with path.open("w", newline="") as f:
        csv.writer(f, lineterminator="\n").writerows(rows)


def _extract(campaign: Path, out: Path) -> tuple[int, str]:
    inputs = tree(campaign)
    before = digest(inputs)
    status, stderr = run_cli(["extract", str(campaign), "--out", str(out)])
    assert digest(inputs) == before, "an input file changed"
    assert tree(campaign) == inputs, "a file was written into the campaign"
    return status, stderr


@FUZZ
@given(data=st.data())
def test_mutated_campaign_tables_are_refused_in_one_line_or_extracted(small_campaign, tmp_path_factory, data):
    work = tmp_path_factory.mktemp("camp")
    campaign = work / "campaign"
    shutil.copytree(small_campaign, campaign)
    name = data.draw(st.sampled_from(["frf.csv", "frf.csv", "design.csv"]))
    _write_rows(campaign / name, data.draw(mutated_table(_rows(campaign / name))))
    status, stderr = _extract(campaign, work / "out")
    assert_honest(status, stderr, work / "out")


@FUZZ
@given(data=st.data())
def test_mutated_campaign_toml_is_refused_in_one_line_or_extracted(small_campaign, tmp_path_factory, data):
    work = tmp_path_factory.mktemp("camp")
    campaign = work / "campaign"
    shutil.copytree(small_campaign, campaign)
    settings_data = tomllib.loads((campaign / "campaign.toml").read_text())
    (campaign / "campaign.toml").write_text(dump_toml(data.draw(mutated_dict(settings_data))))
    status, stderr = _extract(campaign, work / "out")
    assert_honest(status, stderr, work / "out")


@FUZZ
@given(fraction=st.floats(0.0, 1.0))
def test_truncated_frf_csv_is_refused_or_read_as_fewer_lines(small_campaign, tmp_path_factory, fraction):
    work = tmp_path_factory.mktemp("camp")
    campaign = work / "campaign"
    shutil.copytree(small_campaign, campaign)
    text = (campaign / "frf.csv").read_bytes()
    (campaign / "frf.csv").write_bytes(text[:int(fraction * len(text))])
    status, stderr = _extract(campaign, work / "out")
    assert_honest(status, stderr, work / "out")


# ------------------------------------------------------------------ UFF files

@pytest.fixture(scope="module")
def uff_files(small_campaign, tmp_path_factory) -> dict[str, Path]:
    from workbench.io.campaign import load_campaign
    from workbench.io.uff import export_frfs

    campaign = load_campaign(small_campaign)
    folder = tmp_path_factory.mktemp("uff")
    return {kind: export_frfs(campaign, folder / f"{kind}.uff", binary=kind == "binary")
            for kind in ("ascii", "binary")}


@st.composite
def mutated_bytes(draw, text: bytes) -> bytes:
    """A UFF file truncated, with a line deleted or duplicated, or a number replaced by junk."""
    action = draw(st.sampled_from(["truncate", "delete_line", "dup_line", "junk"]))
    if action == "truncate":
        return text[:draw(st.integers(0, len(text) - 1))]
    lines = text.split(b"\n")
    i = draw(st.integers(0, len(lines) - 1))
    if action == "delete_line":
        del lines[i]
    elif action == "dup_line":
        lines.insert(i, lines[i])
    else:
        number = rb"[-+]?\d+\.?\d*(E[-+]\d+)?"
        numbers = [(k, m) for k, line in enumerate(lines[:200]) for m in re.finditer(number, line)]
        if numbers:
            k, m = draw(st.sampled_from(numbers))
            junk = draw(st.sampled_from([b"nan", b"abc", b"-1", b"9" * m.end()]))[: max(1, m.end() - m.start())]
            lines[k] = lines[k][:m.start()] + junk.ljust(m.end() - m.start()) + lines[k][m.end():]
    return b"\n".join(lines)


@FUZZ
@given(data=st.data())
def test_mutated_uff_files_are_refused_in_one_line_or_read_finite(uff_files, small_campaign, tmp_path_factory, data):
    from workbench.io.uff import import_frfs
    from workbench.model.frame_file import read_frame

    kind = data.draw(st.sampled_from(sorted(uff_files)))
    path = tmp_path_factory.mktemp("uff") / f"{kind}.uff"
    path.write_bytes(data.draw(mutated_bytes(uff_files[kind].read_bytes())))
    frame = read_frame(small_campaign / "frame.toml")
    try:
        table = import_frfs(path, frame)
    except (ValueError, KeyError) as exc:
        message = str(exc)
        assert "\n" not in message.strip() and message.strip(), f"not one line: {message!r}"
        return
    values = table[["frequency_hz", "real", "imag"]].to_numpy(float)
    assert np.isfinite(values).all()
    assert len(table) > 0

"""The catalogue of bad inputs (issue 19): each is refused with exit 2 and one line naming the problem.

Every case starts from valid inputs copied into a fresh folder (a frame file, a small campaign written
by another program, a UFF export, a matrix model), breaks one thing as a careless user or a faulty
exporter would, runs the command line, and checks: exit 2; one line on standard error holding the
expected fragment (the file, field or option, and the problem); no input file changed and nothing
written (the lock file of ``--out`` aside). The fragments were written from the contract's wording
before the cases were run, then adjusted only where the message said the same thing in other words.

The `--out` cases here include the lock of a concurrent run; the runs killed mid-write (SIGKILL during
the commit and at random moments, then checked to hold the old set or the new one) and the two truly
concurrent processes live in ``tests/test_outputs_safety.py``, because they need real processes.
"""

from __future__ import annotations

import shutil
import tomllib
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import pytest
from conftest import REPO, cut_example_campaign, digest, dump_toml, error_lines, run_cli
from test_matrix_model import (
    N,
    asymmetric,
    chain_matrices,
    dofs_text,
    indefinite_mass,
    model_data,
    negative_joint,
    with_value,
    write_model,
)

FRAME = REPO / "frames" / "one_bolt_vertical.toml"


@dataclass(frozen=True)
class Case:
    """A bad input: ``build(work)`` writes it under ``work`` and returns the command line."""

    name: str
    fragment: str
    build: Callable[[Path], list[str]]


CASES: list[Case] = []


def case(name: str, fragment: str):
    def register(build: Callable[[Path], list[str]]) -> Callable[[Path], list[str]]:
        CASES.append(Case(name, fragment, build))
        return build
    return register


@pytest.fixture(scope="module")
def pristine_campaign(tmp_path_factory) -> Path:
    return cut_example_campaign(tmp_path_factory.mktemp("pristine") / "campaign")


_PRISTINE: list[Path] = []


# ------------------------------------------------------------------ helpers that break things

def frame_with(work: Path, edit: Callable[[dict], None] | None = None, text: str | None = None) -> Path:
    """A copy of the one-bolt frame under ``work``, its TOML data edited (or replaced by ``text``)."""
    path = work / "frame.toml"
    if text is not None:
        path.write_text(text)
        return path
    data = tomllib.loads(FRAME.read_text())
    if edit is not None:
        edit(data)
    path.write_text(dump_toml(data))
    return path


def modes(work: Path, frame: Path, *extra: str) -> list[str]:
    return ["modes", str(frame), "--out", str(work / "out"), *extra]


def campaign_copy(work: Path) -> Path:
    target = work / "campaign"
    shutil.copytree(_PRISTINE[0], target)
    return target


def edit_csv(path: Path, edit: Callable[[list[list[str]]], list[list[str]] | None]) -> None:
    rows = [line.split(",") for line in path.read_text().splitlines()]
    rows = edit(rows) or rows
    path.write_text("".join(",".join(r) + "\n" for r in rows))


def edit_toml(path: Path, edit: Callable[[dict], None]) -> None:
    data = tomllib.loads(path.read_text())
    edit(data)
    path.write_text(dump_toml(data))


def extract(work: Path, campaign: Path, *extra: str) -> list[str]:
    return ["extract", str(campaign), "--out", str(work / "out"), *extra]


# ------------------------------------------------------------------ frame files (CONTRACTS.md section 1)

def _member(index: int, key: str, value) -> Callable[[dict], None]:
    return lambda d: d["members"][index].__setitem__(key, value)


FRAME_CASES = {
    "frame: not TOML": (None, "name = [unclosed", "TOML"),
    "frame: empty file": (None, "", "required key is missing"),
    "frame: name missing": (lambda d: d.pop("name"), None, "name"),
    "frame: unknown top-level key": (lambda d: d.__setitem__("colour", "red"), None, "colour"),
    "frame: unknown beam theory": (lambda d: d.__setitem__("beam_theory", "kirchhoff"), None, "beam_theory"),
    "frame: element length zero": (lambda d: d.__setitem__("element_length", 0.0), None, "element_length"),
    "frame: element length negative": (lambda d: d.__setitem__("element_length", -0.01), None, "element_length"),
    "frame: element length of a micrometre": (lambda d: d.__setitem__("element_length", 1e-6), None,
                                              "element_length"),
    "frame: element length as text": (lambda d: d.__setitem__("element_length", "1 cm"), None, "element_length"),
    "frame: density negative": (lambda d: d["materials"]["aluminium"].__setitem__("density", -2700.0), None,
                                "density"),
    "frame: Young's modulus NaN": (lambda d: d["materials"]["aluminium"].__setitem__("youngs_modulus",
                                                                                    float("nan")), None,
                                   "youngs_modulus"),
    "frame: section area zero": (lambda d: d["sections"]["flat_bar"].__setitem__("area", 0.0), None, "area"),
    "frame: point with three coordinates": (lambda d: d["points"].__setitem__("drive", [0.0, 0.1, 0.0]), None,
                                            "points.drive"),
    "frame: point coordinate infinite": (lambda d: d["points"].__setitem__("drive", [0.0, float("inf")]), None,
                                         "points.drive"),
    "frame: member to an unknown point": (_member(1, "end", "nowhere"), None, "nowhere"),
    "frame: member of an unknown material": (_member(0, "material", "steel"), None, "steel"),
    "frame: member of an unknown section": (_member(2, "section", "tube"), None, "tube"),
    "frame: member of zero length": (_member(1, "end", "top_left"), None, "members[1]"),
    "frame: duplicated member name": (_member(2, "name", "beam"), None, "beam"),
    "frame: joint on an unknown member": (lambda d: d["joints"][0].__setitem__("member", "pillar"), None,
                                          "pillar"),
    "frame: joint span outside its member": (lambda d: d["joints"][0].__setitem__("span", [0.40, 0.60]), None,
                                             "span"),
    "frame: joint cov negative": (lambda d: d["joints"][0].__setitem__("cov", -0.1), None, "cov"),
    "frame: support on an unknown point": (lambda d: d["supports"][0].__setitem__("point", "floor"), None,
                                           "floor"),
    "frame: support with an unknown dof": (lambda d: d["supports"][0].__setitem__("uz", "fixed"), None, "uz"),
    "frame: spring stiffness negative": (lambda d: d["springs"][0].__setitem__("stiffness", -5.0), None,
                                         "stiffness"),
    "frame: mass negative": (lambda d: d["masses"][0].__setitem__("mass", -0.2), None, "mass"),
    "frame: excitation on an unknown point": (lambda d: d["excitation"].__setitem__("point", "shaker"), None,
                                              "shaker"),
    "frame: sensor dof unknown": (lambda d: d["sensors"][0].__setitem__("dof", "uz"), None, "sensors[0].dof"),
    "frame: duplicated sensor name": (lambda d: d["sensors"][1].__setitem__("name", "drive"), None, "drive"),
    "frame: damping ratio negative": (lambda d: d["damping"].__setitem__("ratios", [-0.01]), None, "damping"),
    "frame: a floating member": (lambda d: (d["points"].update(loose_a=[1.0, 1.0], loose_b=[1.2, 1.0]),
                                            d["members"].append({**d["members"][1], "name": "loose",
                                                                 "start": "loose_a", "end": "loose_b"})),
                                 None, "'loose'"),
    "frame: coordinates in millimetres": (lambda d: d.__setitem__("points", {
        k: [1000.0 * c for c in xy] for k, xy in d["points"].items()}) or d["joints"][0].__setitem__(
        "span", [403.448, 423.448]), None, "mm"),
}

for _name, (_edit, _text, _fragment) in FRAME_CASES.items():
    case(_name, _fragment)(lambda work, e=_edit, t=_text: modes(work, frame_with(work, e, t)))


@case("frame: the file does not exist", "missing.toml")
def _(work):
    return modes(work, work / "missing.toml")


@case("frame: a directory instead of a file", "frame")
def _(work):
    (work / "frame").mkdir()
    return modes(work, work / "frame")


# ------------------------------------------------------------------ campaigns (CONTRACTS.md section 2)

@case("campaign: directory does not exist", "no_such_campaign")
def _(work):
    return extract(work, work / "no_such_campaign")


@case("campaign: campaign.toml missing", "campaign.toml")
def _(work):
    camp = campaign_copy(work)
    (camp / "campaign.toml").unlink()
    return extract(work, camp)


@case("campaign: campaign.toml not TOML", "campaign.toml")
def _(work):
    camp = campaign_copy(work)
    (camp / "campaign.toml").write_text("name = 'x\n")
    return extract(work, camp)


@case("campaign: unknown quantity", "quantity")
def _(work):
    camp = campaign_copy(work)
    edit_toml(camp / "campaign.toml", lambda d: d.__setitem__("quantity", "velocity"))
    return extract(work, camp)


@case("campaign: frame file named but absent", "frame")
def _(work):
    camp = campaign_copy(work)
    edit_toml(camp / "campaign.toml", lambda d: d.__setitem__("frame", "model_v2.toml"))
    return extract(work, camp)


@case("campaign: factor of unknown kind", "kind")
def _(work):
    camp = campaign_copy(work)
    edit_toml(camp / "campaign.toml", lambda d: d["factors"]["bolt_A"].__setitem__("kind", "torque"))
    return extract(work, camp)


@case("campaign: tightening factor on an unknown joint", "joint")
def _(work):
    camp = campaign_copy(work)
    edit_toml(camp / "campaign.toml", lambda d: d["factors"]["bolt_A"].__setitem__("joint", "Z"))
    return extract(work, camp)


@case("campaign: design.csv missing", "design.csv")
def _(work):
    camp = campaign_copy(work)
    (camp / "design.csv").unlink()
    return extract(work, camp)


@case("campaign: undeclared level in design.csv", "level")
def _(work):
    camp = campaign_copy(work)
    edit_csv(camp / "design.csv", lambda rows: rows.__setitem__(1, [rows[1][0], "7"]))
    return extract(work, camp)


@case("campaign: duplicated test id in design.csv", "design.csv")
def _(work):
    camp = campaign_copy(work)
    edit_csv(camp / "design.csv", lambda rows: rows.append(list(rows[1])))
    return extract(work, camp)


@case("campaign: a design test without FRF rows", "no rows")
def _(work):
    camp = campaign_copy(work)
    edit_csv(camp / "design.csv", lambda rows: rows.append(["3", "2"]))
    return extract(work, camp)


@case("campaign: FRF rows of a test not in design.csv", "not in design.csv")
def _(work):
    camp = campaign_copy(work)
    edit_csv(camp / "frf.csv", lambda rows: [rows[0]] + [["9", *r[1:]] if r[0] == "2" else r for r in rows[1:]])
    return extract(work, camp)


@case("campaign: frf.csv column missing", "imag")
def _(work):
    camp = campaign_copy(work)
    edit_csv(camp / "frf.csv", lambda rows: [r[:4] for r in rows])
    return extract(work, camp)


@case("campaign: frf.csv empty", "frf.csv")
def _(work):
    camp = campaign_copy(work)
    (camp / "frf.csv").write_text("")
    return extract(work, camp)


@case("campaign: frf.csv header only", "frf.csv")
def _(work):
    camp = campaign_copy(work)
    (camp / "frf.csv").write_text("test_id,sensor,frequency_hz,real,imag\n")
    return extract(work, camp)


@case("campaign: NaN in an FRF value", "real")
def _(work):
    camp = campaign_copy(work)
    edit_csv(camp / "frf.csv", lambda rows: rows[10].__setitem__(3, "nan"))
    return extract(work, camp)


@case("campaign: text in a numeric FRF column", "imag")
def _(work):
    camp = campaign_copy(work)
    edit_csv(camp / "frf.csv", lambda rows: rows[10].__setitem__(4, "n/a"))
    return extract(work, camp)


@case("campaign: frequency axis not increasing", "frequency_hz")
def _(work):
    camp = campaign_copy(work)
    edit_csv(camp / "frf.csv", lambda rows: rows.__setitem__(slice(20, 22), [rows[21], rows[20]]))
    return extract(work, camp)


@case("campaign: duplicated FRF row", "duplicated")
def _(work):
    camp = campaign_copy(work)
    edit_csv(camp / "frf.csv", lambda rows: rows.insert(30, list(rows[30])))
    return extract(work, camp)


@case("campaign: unknown sensor in frf.csv", "s9")
def _(work):
    camp = campaign_copy(work)
    edit_csv(camp / "frf.csv", lambda rows: [rows[0]] + [[r[0], "s9", *r[2:]] if r[0] == "2" else r
                                                        for r in rows[1:]])
    return extract(work, camp)


@case("campaign: both frf.csv and frf.parquet", "frf.parquet")
def _(work):
    camp = campaign_copy(work)
    (camp / "frf.parquet").write_bytes(b"PAR1")
    return extract(work, camp)


@case("campaign: moments.csv with a negative std", "std_hz")
def _(work):
    camp = campaign_copy(work)
    (camp / "moments.csv").write_text("mode,mean_hz,std_hz\n1,23.5,-0.1\n2,97.0,0.3\n")
    return ["identify", str(camp), "--method", "moments", "--out", str(work / "out")]


@case("campaign: a dead channel (all-zero FRF)", "no resonance")
def _(work):
    camp = campaign_copy(work)
    edit_csv(camp / "frf.csv", lambda rows: [rows[0]] + [[*r[:3], "0", "0"] if r[0] == "2" else r for r in rows[1:]])
    return extract(work, camp)


@case("campaign: test 001 in design.csv, 1 in frf.csv", "not in design.csv")
def _(work):
    camp = campaign_copy(work)
    edit_csv(camp / "design.csv", lambda rows: [rows[0]] + [["001" if r[0] == "1" else r[0], *r[1:]] for r in rows[1:]])
    return extract(work, camp)


def test_001_01_and_1_are_three_tests(tmp_path, pristine_campaign):
    """CONTRACTS.md section 2: test ids are strings; a leading zero makes another test."""
    camp = tmp_path / "campaign"
    shutil.copytree(pristine_campaign, camp)
    rows = [line.split(",") for line in (camp / "frf.csv").read_text().splitlines()]
    test_one = [r for r in rows[1:] if r[0] == "1"]
    frf = rows[:1] + [[tid, *r[1:]] for tid in ("001", "01", "1") for r in test_one]
    (camp / "frf.csv").write_text("".join(",".join(r) + "\n" for r in frf))
    (camp / "design.csv").write_text("test_id,bolt_A\n001,1\n01,2\n1,3\n")
    status, stderr = run_cli(["extract", str(camp), "--out", str(tmp_path / "out"), "--count", "1"])
    assert status == 0, stderr
    ids = [line.split(",")[0] for line in (tmp_path / "out" / "modes.csv").read_text().splitlines()[1:]]
    assert ids == ["001", "01", "1"]


# ------------------------------------------------------------------ matrix models (CONTRACTS.md section 4)

def matrix_model(work: Path, fmt: str = "matrix-market", matrices=None, data=None,
                 dofs: str | None = None) -> list[str]:
    """The spring-mass chain of tests/test_matrix_model.py as a model folder, broken as asked, then `modes`."""
    path = write_model(work / "model", fmt, matrices=matrices, data=data)
    if dofs is not None:
        (work / "model" / "dofs.csv").write_text(dofs)
    return modes(work, path, "--count", "3")


def _changed(key: str, change) -> dict:
    matrices = chain_matrices()
    matrices[key] = change(matrices[key].copy())
    return matrices


def _data(change, fmt: str = "matrix-market") -> dict:
    data = model_data(fmt)
    change(data)
    return data


MATRIX_CASES = {
    "matrix model: mass key missing": (lambda w: matrix_model(w, data=_data(lambda d: d.pop("mass"))), "mass"),
    "matrix model: unknown format": (lambda w: matrix_model(w, data=_data(lambda d: d.__setitem__("format", "hdf5"))),
                                     "format"),
    "matrix model: stiffness not symmetric": (lambda w: matrix_model(w, matrices=_changed("stiffness_rest",
                                                                                          asymmetric)), "symmetric"),
    "matrix model: mass not positive definite": (lambda w: matrix_model(w, matrices=_changed("mass", indefinite_mass)),
                                                 "positive definite"),
    "matrix model: joint stiffness negative": (lambda w: matrix_model(w, matrices=_changed("A", negative_joint)),
                                               "semi-definite"),
    "matrix model: NaN in a matrix": (lambda w: matrix_model(w, matrices=_changed("stiffness_rest",
                                                                                  with_value(2, 2, float("nan")))),
                                      "non-finite"),
    "matrix model: sizes disagree with dofs.csv": (lambda w: matrix_model(w, dofs=dofs_text(
        [(i, i + 1, "ux", 0.1 * i, 0.0, 0.0) for i in range(N + 1)])), "dofs.csv"),
    "matrix model: dof index given twice": (lambda w: matrix_model(w, dofs=dofs_text(
        [(0, 1, "ux", 0, 0, 0)] + [(i - 1, i + 1, "ux", 0.1 * i, 0.0, 0.0) for i in range(1, N)])), "index"),
    "matrix model: sensor on an unknown node": (lambda w: matrix_model(w, data=_data(
        lambda d: d["sensors"][0].__setitem__("node", 99))), "sensors[0]"),
    "matrix model: op4 matrix name absent": (lambda w: matrix_model(w, "op4", data=_data(
        lambda d: d["joints"][0].__setitem__("stiffness", "KJC"), "op4")), "KJC"),
}

for _name, (_build, _fragment) in MATRIX_CASES.items():
    case(_name, _fragment)(_build)


# ------------------------------------------------------------------ the command line (CONTRACTS.md section 3)

@case("option: --count zero", "--count")
def _(work):
    return modes(work, frame_with(work), "--count", "0")


@case("option: --count not a number", "--count")
def _(work):
    return modes(work, frame_with(work), "--count", "ten")


@case("option: unknown propagation method", "--method")
def _(work):
    return ["propagate", str(frame_with(work)), "--method", "smr3", "--out", str(work / "out")]


@case("option: --samples negative", "--samples")
def _(work):
    return ["propagate", str(frame_with(work)), "--method", "mc", "--samples", "-5", "--out", str(work / "out")]


@case("option: --out missing", "--out")
def _(work):
    return ["modes", str(frame_with(work))]


@case("option: unknown command", "invalid choice")
def _(work):
    return ["modal", str(frame_with(work)), "--out", str(work / "out")]


@case("option: identify without --method", "--method")
def _(work):
    return ["identify", str(campaign_copy(work)), "--out", str(work / "out")]


@case("identify: an estimate at its search bound", "upper bound")
def _(work):
    camp = work / "table3"
    shutil.copytree(REPO / "campaigns" / "paper_table3_one_bolt_vertical", camp)

    def scatter(rows):  # 40 times Table 3's scatter: no CoV inside the search interval explains it
        column = rows[0].index("std_hz")
        for row in rows[1:]:
            row[column] = repr(40 * float(row[column]))
    edit_csv(camp / "moments.csv", scatter)
    return ["identify", str(camp), "--method", "moments", "--out", str(work / "out")]


@case("diagnose: a single test", "scatter")
def _(work):
    camp = campaign_copy(work)
    edit_csv(camp / "design.csv", lambda rows: rows[:2])
    edit_csv(camp / "frf.csv", lambda rows: [r for r in rows if r[0] in ("test_id", rows[1][0])])
    return ["diagnose", str(camp), "--out", str(work / "out")]


for _address in ("localhost", "http://head:8786", "tcp://head", "two words:1"):
    case(f"option: --scheduler {_address!r}", "--scheduler")(
        lambda work, a=_address: ["propagate", str(frame_with(work)), "--method", "mc", "--samples", "10",
                                  "--scheduler", a, "--out", str(work / "out")])


@case("propagate: no joint varies", "cov")
def _(work):
    return ["propagate", str(frame_with(work, lambda d: d["joints"][0].__setitem__("cov", 0.0))),
            "--method", "smr1", "--out", str(work / "out")]


for _method in ("smr1", "smr2", "adaptive", "pert2"):
    case(f"propagate: {_method} with a CoV of 1.2", "joints[0].cov")(
        lambda work, m=_method: ["propagate", str(frame_with(work, lambda d: d["joints"][0].__setitem__("cov", 1.2))),
                                 "--method", m, "--out", str(work / "out")])


def _square(work: Path) -> Path:
    from test_repeated_eigenvalues import SQUARE
    path = work / "square.toml"
    path.write_text(dump_toml(SQUARE))
    return path


@case("propagate: pert2 on a repeated eigenvalue", "modes 2 and 3")
def _(work):
    return ["propagate", str(_square(work)), "--method", "pert2", "--count", "4", "--out", str(work / "out")]


# ------------------------------------------------------------------ import (UFF 58 and CSV exports)

def _uff(work: Path, binary: bool = True) -> Path:
    """The pristine campaign's FRFs as one universal file (the workbench's own export)."""
    from workbench.io.campaign import load_campaign
    from workbench.io.uff import export_frfs
    return export_frfs(load_campaign(_PRISTINE[0]), work / "lab.uff", binary=binary)


def _import(work: Path, *files: Path, extra: tuple[str, ...] = ()) -> list[str]:
    return ["import", *map(str, files), "--frame", str(_PRISTINE[0] / "frame.toml"), *extra,
            "--out", str(work / "out")]


for _binary in (False, True):
    case(f"uff: {'binary' if _binary else 'ASCII'} file cut inside a dataset", "truncated")(
        lambda work, b=_binary: _import(work, _cut(_uff(work, b))))


def _cut(path: Path) -> Path:
    data = path.read_bytes()
    path.write_bytes(data[:int(len(data) * 0.6)])
    return path


@case("uff: not a universal file", "no dataset 58")
def _(work):
    (work / "notes.uff").write_text("measured on Tuesday\n")
    return _import(work, work / "notes.uff")


@case("import: unknown file type", ".xlsx")
def _(work):
    (work / "frf.xlsx").write_bytes(b"PK")
    return _import(work, work / "frf.xlsx")


@case("import: the same test and sensor in two files", "already read")
def _(work):
    first = _uff(work)
    second = work / "again.uff"
    shutil.copy(first, second)
    return _import(work, first, second)


def _csv_test(work: Path, sensor: str) -> Path:
    """A two-line tidy FRF CSV of one test at ``sensor``."""
    path = work / "t1.csv"
    path.write_text(f"sensor,frequency_hz,real,imag\n{sensor},1.0,0.1,0.2\n{sensor},2.0,0.2,0.1\n")
    return path


@case("import: CSV without --quantity", "--quantity")
def _(work):
    return _import(work, _csv_test(work, "s1"))


@case("import: CSV of a sensor the frame lacks", "'s9'")
def _(work):
    return _import(work, _csv_test(work, "s9"), extra=("--quantity", "accelerance"))


@case("import: design without a test of the files", "no row")
def _(work):
    (work / "design.csv").write_text("test_id,bolt_A\n1,1\n")
    return _import(work, _uff(work), extra=("--design", str(work / "design.csv")))


# ------------------------------------------------------------------ --out (CONTRACTS.md section 3: output rules)

@case("out: the empty string", "--out")
def _(work):
    return ["modes", str(frame_with(work)), "--out", ""]


@case("out: the campaign itself", "input")
def _(work):
    camp = campaign_copy(work)
    return extract(work, camp)[:-1] + [str(camp)]


@case("out: inside the campaign", "input")
def _(work):
    camp = campaign_copy(work)
    return ["extract", str(camp), "--out", str(camp / "results")]


@case("out: holds the input campaign", "input")
def _(work):
    camp = campaign_copy(work)
    return ["extract", str(camp), "--out", str(work), "--force"]


@case("out: another campaign", "campaign or model folder")
def _(work):
    camp = campaign_copy(work)
    return ["modes", str(frame_with(work)), "--out", str(camp), "--force"]


@case("out: the frame file's folder", "input")
def _(work):
    return ["modes", str(frame_with(work)), "--out", str(work)]


@case("out: an existing file", "not a directory")
def _(work):
    (work / "out").write_text("notes\n")
    return modes(work, frame_with(work))


@case("out: an earlier run's set without --force", "--force")
def _(work):
    (work / "out").mkdir()
    (work / "out" / "modes.csv").write_text("mode,frequency_hz\n1,1.0\n")
    return modes(work, frame_with(work))


@case("out: a folder of other files, even with --force", "does not write")
def _(work):
    (work / "out").mkdir()
    (work / "out" / "thesis.tex").write_text("\\chapter{}\n")
    return modes(work, frame_with(work), "--force")


@case("out: locked by a run in progress", "another workbench run")
def _(work):
    import filelock

    lock = filelock.FileLock(work / ".out.lock", timeout=0)
    lock.acquire()
    _HELD.append(lock)  # released by the test after the run
    return modes(work, frame_with(work), "--force")


_HELD: list = []


# ------------------------------------------------------------------ running the catalogue

def _files(root: Path) -> set[Path]:
    # --out's lock file lives beside --out, by design (CONTRACTS.md section 3: a second run must refuse)
    return {p for p in root.rglob("*") if not p.name.endswith(".lock")}


def test_the_catalogue_is_large_and_its_names_distinct():
    names = [c.name for c in CASES]
    assert len(set(names)) == len(names)
    assert len(CASES) >= 60, f"{len(CASES)} cases"


@pytest.mark.parametrize("bad", CASES, ids=[c.name for c in CASES])
def test_bad_input_is_refused_in_one_line_and_nothing_is_written(bad: Case, tmp_path, pristine_campaign):
    _PRISTINE[:] = [pristine_campaign]
    argv = bad.build(tmp_path)
    before_files, before = _files(tmp_path), digest(sorted(_files(tmp_path)))
    try:
        status, stderr = run_cli(argv)
    finally:
        while _HELD:
            _HELD.pop().release()
    lines = error_lines(stderr)
    assert status == 2, f"exit {status}, stderr: {stderr!r}"
    assert len(lines) == 1, f"expected one line, got {lines}"
    assert bad.fragment.lower() in lines[0].lower(), lines[0]
    assert _files(tmp_path) == before_files, sorted(map(str, _files(tmp_path) - before_files))
    assert digest(sorted(before_files)) == before, "an input file changed"

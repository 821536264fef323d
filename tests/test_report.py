"""The identification report (workbench report): one self-contained page, honest about what is absent.

Small rig campaigns (one-bolt and two-bolt frames, 0-500 Hz, 4 tests) keep the default suite fast;
`workbench demo` on the bundled campaigns is in `tests/test_cli.py` (slow).
"""

from __future__ import annotations

import dataclasses
import subprocess
import sys
from html.parser import HTMLParser

import numpy as np
import pytest
from conftest import REPO

from workbench.cli import main
from workbench.diagnose.decision import NAME_CONFIDENCE
from workbench.io.campaign import Factor
from workbench.model.frame_file import read_frame
from workbench.report.page import SECTION_TITLES, render_report, report_files
from workbench.report.tables import csv_name, declared_files
from workbench.rig.simulate import RigSettings, simulate_campaign, write_with_truth
from workbench.workflow.measured import load_and_extract
from workbench.workflow.runs import Run
from workbench.workflow.study import JointSource, predict_campaign

SMALL = RigSettings(f_max_hz=500.0)  # modes 1-5 of the one-bolt frames, 2001 lines


class Page(HTMLParser):
    """The parts of a page the checks need: tags with attributes, headings, tables, banners."""

    def __init__(self) -> None:
        super().__init__()
        self.tags: list[tuple[str, dict]] = []
        self.headings: list[str] = []
        self.tables: list[list[list[str]]] = []
        self.banners: list[str] = []
        self.absent: list[str] = []
        self._text: list[str] | None = None
        self._into: str | None = None

    def handle_starttag(self, tag, attrs):
        attrs = dict(attrs)
        self.tags.append((tag, attrs))
        if tag in ("h2", "h3"):
            self._text, self._into = [], "heading"
        elif tag == "div" and "banner" in attrs.get("class", ""):
            self._text, self._into = [], "banner"
        elif tag == "p" and attrs.get("class") == "absent":
            self._text, self._into = [], "absent"
        elif tag == "table":
            self.tables.append([])
        elif tag == "tr":
            self.tables[-1].append([])
        elif tag in ("td", "th"):
            self._text, self._into = [], "cell"

    def handle_endtag(self, tag):
        if self._text is None:
            return
        text = "".join(self._text).strip()
        if tag in ("h2", "h3") and self._into == "heading":
            self.headings.append(text)
        elif tag == "div" and self._into == "banner":
            self.banners.append(text)
        elif tag == "p" and self._into == "absent":
            self.absent.append(text)
        elif tag in ("td", "th") and self._into == "cell":
            self.tables[-1][-1].append(text)
        else:
            return
        self._text = self._into = None

    def handle_data(self, data):
        if self._text is not None:
            self._text.append(data)


def parse(text: str) -> Page:
    page = Page()
    page.feed(text)
    page.close()
    return page


def rig_campaign(directory, frame_name: str, joints: dict[str, str], preloads=("100", "500", "1800", "6000"),
                 seed: int = 11):
    """A rig campaign on ``frames/<frame_name>.toml``, one tightening factor per joint, written to ``directory``."""
    frame = read_frame(REPO / "frames" / f"{frame_name}.toml")
    factors = tuple(Factor(f"bolt_{j}", "tightening", {p: f"preload {p} N" for p in preloads}, j) for j in joints)
    design = [{f"bolt_{j}": preloads[(i + k) % len(preloads)] for k, j in enumerate(joints)}
              for i in range(len(preloads))]
    campaign, truth = simulate_campaign(frame, factors, design, SMALL, seed=seed)
    write_with_truth(campaign, truth, directory)
    return directory


@pytest.fixture(scope="module")
def one_bolt(tmp_path_factory):
    return rig_campaign(tmp_path_factory.mktemp("c") / "one_bolt", "one_bolt_vertical", {"A": "vertical"})


@pytest.fixture(scope="module")
def report(one_bolt, tmp_path_factory):
    out = tmp_path_factory.mktemp("r") / "report"
    status = main(["report", str(one_bolt), "--out", str(out), "--samples", "40", "--steps", "120", "--seed", "3"])
    return status, out


def test_report_is_one_self_contained_page(report):
    status, out = report
    assert status == 0
    written = sorted(p.name for p in out.iterdir())
    assert "index.html" in written and all(p.is_file() for p in out.iterdir())
    assert set(written) <= {"index.html", *declared_files("report")}  # the output set declared them all
    text = (out / "index.html").read_text(encoding="utf-8")
    page = parse(text)
    images = [attrs for tag, attrs in page.tags if tag == "img"]
    assert len(images) >= 7 and all(a["src"].startswith("data:image/png;base64,") for a in images)
    for tag, attrs in page.tags:
        for name in ("src", "href"):
            assert not attrs.get(name, "").startswith(("http", "//")), (tag, attrs.get(name))
        assert tag not in ("script", "link", "iframe", "object")
    assert 'src="http' not in text and 'href="http' not in text


def test_report_has_every_section_and_the_synthetic_banner(report):
    _, out = report
    page = parse((out / "index.html").read_text(encoding="utf-8"))
    for key in ("design", "frf", "modes", "shapes", "nominal", "joints", "posterior", "accuracy", "band", "done",
                "limits"):
        assert any(SECTION_TITLES[key] in h for h in page.headings), key
    assert "section 5" not in " ".join(page.headings).lower()  # no --joints-from, no prediction
    assert page.banners and page.banners[0].startswith("SYNTHETIC - virtual test rig")
    assert not any(b.startswith("MEASURED") for b in page.banners)
    assert page.absent == []  # a synthetic one-joint campaign with FRFs: every section is there


def test_moments_only_campaign_says_why_the_frf_sections_are_absent(tmp_path):
    out = tmp_path / "r"
    campaign = REPO / "campaigns" / "paper_table3_one_bolt_vertical"
    assert main(["report", str(campaign), "--out", str(out), "--samples", "30"]) == 0
    page = parse((out / "index.html").read_text(encoding="utf-8"))
    assert page.banners == ["MEASURED - real test data: paper_table3_one_bolt_vertical."]
    absent = " ".join(page.absent)
    assert absent.count("no FRFs") >= 2 and "no measured FRFs" in absent  # FRF overlay, circle fit, band
    assert "only published moments" in absent  # Bayesian estimator and its posterior
    assert any(SECTION_TITLES["nominal"] in h for h in page.headings)
    images = [a for t, a in page.tags if t == "img"]
    assert len(images) == 2  # the joint models' forest plot and the Figure 11 bars


def test_bad_campaign_exits_2_with_one_line_and_writes_nothing(tmp_path, capsys):
    out = tmp_path / "r"
    assert main(["report", str(tmp_path / "missing"), "--out", str(out)]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and err.startswith("workbench report: ") and "missing" in err
    assert not out.exists() or not any(out.iterdir())


def test_existing_report_is_kept_without_force(report, capsys):
    _, out = report
    before = (out / "index.html").read_bytes()
    assert main(["report", str(REPO / "campaigns" / "paper_table3_one_bolt_vertical"), "--out", str(out)]) == 2
    assert "from an earlier run; pass --force" in capsys.readouterr().err
    assert (out / "index.html").read_bytes() == before


@pytest.mark.slow
def test_section5_measured_columns_are_the_nan_aware_statistics_of_the_circle_fits(tmp_path):
    directory = rig_campaign(tmp_path / "two_bolt", "two_bolt", {"A": "vertical", "B": "horizontal"}, seed=12)
    campaign, extraction = load_and_extract(directory)
    # one fit marked unusable: the statistics must skip it, not average it in
    test = extraction.tests[1]
    weak = [dataclasses.replace(e, flags=("weak",)) if k == 2 else e for k, e in enumerate(extraction.estimates[test])]
    extraction = dataclasses.replace(extraction, estimates={**extraction.estimates, test: weak})
    sources = {"vertical": JointSource("vertical", 24e9, 0.07, None, None, "hand"),
               "horizontal": JointSource("horizontal", 73.5e9, 0.22, None, None, "hand")}
    prediction = predict_campaign(campaign, extraction, sources, seed=1)

    f = np.array([[e.frequency_hz if not {"weak", "poor_circle"} & set(e.flags) else np.nan
                   for e in extraction.estimates[t]] for t in extraction.tests])
    assert np.isnan(f[1, 2]) and np.isfinite(f).sum() == f.size - 1
    c = prediction.comparison
    np.testing.assert_allclose(c.measured_mean_hz, np.nanmean(f, axis=0), rtol=1e-13)
    np.testing.assert_allclose(c.measured_std_hz, np.nanstd(f, axis=0, ddof=1), rtol=1e-12)

    run = Run("section 5 check", (), (prediction,), (), 1, 20, 0)
    page = parse(render_report(run))
    assert any(SECTION_TITLES["section5"] in h for h in page.headings)
    table = next(t for t in page.tables if t and t[0][:3] == ["mode", "predicted mean (Hz)", "measured mean (Hz)"])
    header, rows = table[0], table[1:]
    mean = [float(r[header.index("measured mean (Hz)")]) for r in rows]
    std = [float(r[header.index("measured std (Hz)")]) for r in rows]
    used = [r[header.index("tests used")] for r in rows]
    np.testing.assert_allclose(mean, np.nanmean(f, axis=0), atol=0.0051)
    np.testing.assert_allclose(std, np.nanstd(f, axis=0, ddof=1), atol=0.00051)
    assert used[2] == f"{f.shape[0] - 1}/{f.shape[0]}" and used[0] == f"{f.shape[0]}/{f.shape[0]}"
    # the figures drawn in a pool of processes (workbench.report.pieces.figure_pool) are the same bytes
    assert report_files(run, None, 2) == report_files(run, None, 1)


@pytest.mark.slow  # 25-35 s: in CI's slow step (.ci/slow_tests)
def test_report_with_joints_from_predicts_the_multi_bolt_frame(tmp_path):
    vertical = rig_campaign(tmp_path / "v", "one_bolt_vertical", {"A": "vertical"}, seed=21)
    horizontal = rig_campaign(tmp_path / "h", "one_bolt_horizontal", {"B": "horizontal"}, seed=22)
    two_bolt = rig_campaign(tmp_path / "t", "two_bolt", {"A": "vertical", "B": "horizontal"}, seed=23)
    out = tmp_path / "r"
    assert main(["report", str(two_bolt), "--out", str(out), "--samples", "20", "--no-bayes",
                 "--joints-from", str(vertical), "--joints-from", str(horizontal), "--workers", "2"]) == 0
    page = parse((out / "index.html").read_text(encoding="utf-8"))
    assert any(SECTION_TITLES["section5"] in h for h in page.headings)
    sources = next(t for t in page.tables if t and t[0][0] == "joint group")
    assert [r[0] for r in sources[1:]] == ["vertical", "horizontal"]
    assert [r[-1] for r in sources[1:]] == ["v (moments)", "h (moments)"]
    assert any("skipped on request" in a for a in page.absent)


@pytest.mark.parametrize("module", ["workbench.workflow.study", "workbench.workflow.measured"])
def test_report_numbers_do_not_import_matplotlib(module):
    # pandas is allowed here since the workflow layer reads campaigns (workbench.io); the numerical
    # sub-packages stay free of it (tests/test_layering.py)
    code = (f"import sys, {module}; print(','.join(m for m in ('matplotlib',) "
            "if m in sys.modules))")
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert done.stdout.strip() == ""


# ------------------------------------------------------------------ summary, units, CSV, shapes, inputs

IDENTIFIERS = {"mode", "model mode", "measured mode", "test", "tests used", "tests flagged", "tests averaged",
               "campaign", "joint group", "joints", "estimator", "group / estimator", "factor", "kind", "joint",
               "levels", "parameter (unit)", "sensor", "step", "detail", "seed", "identified on", "region",
               "mechanism", "rank", "effect", "where", "item", "finding"}


def named_tables(page: Page) -> dict[str, list[list[str]]]:
    """The page's tables by their ``data-table`` name."""
    names = [attrs.get("data-table") for tag, attrs in page.tags if tag == "table"]
    return dict(zip(names, page.tables))


def visible_text(text: str) -> str:
    """The page's text as a reader sees it: no tags, no embedded images."""
    parser = HTMLParser()
    chunks: list[str] = []
    parser.handle_data = chunks.append  # type: ignore[method-assign]
    parser.feed(text)
    return " ".join(chunks)


def read_csv(path) -> tuple[list[str], list[list[str]]]:
    import csv

    with open(path, newline="", encoding="utf-8") as handle:
        rows = list(csv.reader(handle))
    return rows[0], rows[1:]


def check_units(text: str) -> None:
    """No modulus in Pa, kPa or MPa anywhere a reader looks, and a unit on every numeric column."""
    import re

    seen = visible_text(text)
    assert re.findall(r"\w*(?<!G)Pa\b", seen) == [], "a modulus outside GPa"
    for name, table in named_tables(parse(text)).items():
        if name.endswith("design"):  # its columns are the tests' ids
            continue
        for header in table[0]:
            assert header in IDENTIFIERS or re.search(r"\([^)]+\)$", header), (name, header)


def test_every_table_is_a_linked_csv_beside_the_page(report):
    _, out = report
    text = (out / "index.html").read_text(encoding="utf-8")
    page = parse(text)
    tables = named_tables(page)
    links = {attrs.get("href") for tag, attrs in page.tags if tag == "a"}
    assert len(tables) >= 10 and None not in tables
    for name, table in tables.items():
        path = out / csv_name(name)
        assert path.is_file() and csv_name(name) in links, name
        header, rows = read_csv(path)
        assert len(rows) == len(table) - 1, name
        # an interval column of the page is two columns of the CSV, "low" and "high"
        assert len(header) == len(table[0]) + sum(" low" in h for h in header), name
    assert {p.name for p in out.iterdir()} == {"index.html", *(csv_name(n) for n in tables)}


def test_summary_box_gives_each_estimator_in_gpa_and_percent(report, one_bolt, tmp_path):
    """The summary's moment-matching row against `workbench identify` on the same data (another command)."""
    _, out = report
    text = (out / "index.html").read_text(encoding="utf-8")
    assert text.index('id="summary"') < text.index("<nav>")  # at the top, before the contents
    header, rows = read_csv(out / csv_name("summary"))
    assert header[3:] == ["E (GPa)", "E 95 % interval low (GPa)", "E 95 % interval high (GPa)", "CoV (%)",
                          "CoV 95 % interval low (%)", "CoV 95 % interval high (%)"]
    assert [r[2] for r in rows] == ["moment matching", "Bayesian (emcee)"]  # one row per estimator
    assert main(["identify", str(one_bolt), "--method", "moments", "--seed", "3", "--out", str(tmp_path / "i")]) == 0
    import json

    (joint,) = json.loads((tmp_path / "i" / "identification.json").read_text())["joints"].values()  # A, vertical
    moments = dict(zip(header, rows[0]))
    np.testing.assert_allclose(float(moments["E (GPa)"]), joint["youngs_modulus"] / 1e9, rtol=1e-9)
    np.testing.assert_allclose(float(moments["CoV (%)"]), 100 * joint["cov"], rtol=1e-9)
    np.testing.assert_allclose([float(moments["E 95 % interval low (GPa)"]),
                                float(moments["E 95 % interval high (GPa)"])],
                               np.array(joint["youngs_modulus_ci95"]) / 1e9, rtol=1e-9)
    summary = visible_text(text[text.index('id="summary"'):text.index("<nav>")])
    assert "5 measured modes" in summary and "4 tests" in summary and "flagged" in summary


def test_units_are_gpa_hz_and_percent_with_every_column_headed_by_its_unit(report):
    _, out = report
    text = (out / "index.html").read_text(encoding="utf-8")
    check_units(text)
    seen = visible_text(text)
    for unit in ("(GPa)", "(Hz)", "(%)"):
        assert unit in seen
    posterior = named_tables(parse(text))["1_posterior"]
    assert [r[0] for r in posterior[1:3]] == ["E vertical (GPa)", "CoV vertical (%)"]


def test_mac_and_shapes_are_shown_and_the_paired_modes_agree(report):
    """On rig data made from the frame file's own modes, each measured shape matches its model mode."""
    _, out = report
    page = parse((out / "index.html").read_text(encoding="utf-8"))
    assert any(a.get("alt") == "MAC matrix test against model" for t, a in page.tags if t == "img")
    header, rows = read_csv(out / csv_name("1_mac"))
    mac = np.array([[float(v) if v else np.nan for v in r[1:]] for r in rows])
    assert mac.shape[0] == 5 and np.all((mac >= 0) & (mac <= 1 + 1e-12))
    assert np.all(np.diag(mac) > 0.9)  # measured mode k against model mode k (paired by order)


def test_shape_comparison_of_the_model_with_itself_is_exact():
    """Model constants turned by arbitrary phases are recovered exactly; their MAC diagonal is 1."""
    from workbench.extraction.records import MeasuredModes
    from workbench.io.campaign import Campaign
    from workbench.model.assembly import assemble
    from workbench.model.modal import dominant_real, mac, model_modes
    from workbench.workflow.report_inputs import shape_comparison

    frame = read_frame(REPO / "frames" / "one_bolt_vertical.toml")
    model = assemble(frame)
    modes = model_modes(model, 6)
    rows = [model.dof(s.point, s.dof) for s in frame.sensors]
    exc = model.dof(frame.excitation.point, frame.excitation.dof)
    exact = (modes.shapes[rows][:, :5] * modes.shapes[exc, :5]).T  # (5 modes, n_sensors)
    rng = np.random.default_rng(4)
    phases = np.exp(1j * rng.uniform(-np.pi, np.pi, (3, 5, 1)))
    data = MeasuredModes(np.tile(modes.frequency_hz[:5], (3, 1)), modal_constants=exact[None] * phases)
    campaign = Campaign("self", frame, synthetic=True)
    shapes = shape_comparison(campaign, data, [s.name for s in frame.sensors])
    assert shapes is not None
    np.testing.assert_allclose(np.abs(shapes.measured), np.abs(exact), rtol=1e-10, atol=1e-14)
    np.testing.assert_allclose(np.diag(shapes.mac[:, :5]), 1.0, rtol=1e-10)
    np.testing.assert_allclose(shapes.mac[:, :5], mac(exact.T, exact.T), atol=1e-10)
    np.testing.assert_allclose(np.abs(dominant_real(exact[0] * 1j)), np.abs(exact[0]))
    # a sensor whose fits are all unusable for a mode (NaN): that mode's MAC is taken on the other sensors
    lost = data.modal_constants.copy()
    lost[:, 0, 1] = np.nan
    shapes = shape_comparison(campaign, data, [s.name for s in frame.sensors], constants=lost)
    assert shapes is not None and np.isnan(shapes.measured[0, 1])
    np.testing.assert_allclose(shapes.mac[0, 0], 1.0, rtol=1e-10)


@pytest.fixture(scope="module")
def with_modes_csv(one_bolt, tmp_path_factory):
    """The one-bolt campaign with a modes.csv beside its FRFs, shifted 1 % so that its use shows."""
    import pandas as pd

    from workbench.io.campaign import load_campaign, write_campaign

    campaign, extraction = load_and_extract(one_bolt)
    f = extraction.frequency_hz() * 1.01
    z = extraction.damping_ratio()
    table = pd.DataFrame([(t, k + 1, f[i, k], z[i, k]) for i, t in enumerate(extraction.tests)
                          for k in range(f.shape[1]) if np.isfinite(f[i, k])],
                         columns=["test_id", "mode", "frequency_hz", "damping_ratio"])
    directory = tmp_path_factory.mktemp("m") / "with_modes"
    write_campaign(dataclasses.replace(load_campaign(one_bolt), modes=table), directory)
    return directory, f


def test_report_reads_modes_csv_instead_of_a_circle_fit(with_modes_csv, tmp_path):
    directory, f = with_modes_csv
    out = tmp_path / "r"
    assert main(["report", str(directory), "--out", str(out), "--no-bayes", "--samples", "20"]) == 0
    text = (out / "index.html").read_text(encoding="utf-8")
    page = parse(text)
    assert any("modes.csv" in a and "not redone" in a for a in page.absent)
    header, rows = read_csv(out / csv_name("1_nominal"))
    measured = [float(r[header.index("measured mean (Hz)")]) for r in rows]
    np.testing.assert_allclose(measured, np.nanmean(f, axis=0), rtol=1e-12)
    check_units(text)


@pytest.mark.slow
def test_report_bands_set_the_circle_fit(with_modes_csv, tmp_path, capsys):
    directory, _ = with_modes_csv
    out = tmp_path / "r"
    assert main(["report", str(directory), "--out", str(out), "--no-bayes", "--samples", "20",
                 "--bands", "20:35,115:145"]) == 0
    header, rows = read_csv(out / csv_name("1_modes"))
    bands = [(float(r[header.index("band low (Hz)")]), float(r[header.index("band high (Hz)")])) for r in rows]
    assert bands == [(20.0, 35.0), (115.0, 145.0)]
    assert main(["report", str(directory), "--out", str(tmp_path / "bad"), "--bands", "35:20"]) == 2
    assert "--bands" in capsys.readouterr().err


# ------------------------------------------------------------------------------ the diagnosis page

@pytest.fixture(scope="module")
def diagnosed():
    """An exact joint-stiffness shift on the one-bolt frame, diagnosed (about 10 s): its top candidate is exact."""
    from test_diagnosis import ONE_BOLT, _data, _deterministic

    from workbench.diagnose.verdict import diagnose, diagnosis_record
    from workbench.rig.effects import Effect

    frame = _deterministic(ONE_BOLT)
    found = diagnose(frame, _data(frame, Effect("joint_stiffness_shift", "A", {"factor": 1.5}), count=5, tests=4))
    return found, diagnosis_record("shifted joint", found)


def _diagnosis_page(record, found, tmp_path):
    from workbench.io.outputs import write_outputs
    from workbench.report.diagnosis_page import diagnosis_files

    files = diagnosis_files(record, found, True, "test")
    write_outputs(tmp_path, files)
    return files["index.html"]


def test_diagnosis_page_opens_with_its_verdict_and_lists_every_candidate(diagnosed, tmp_path):
    found, record = diagnosed
    assert record["verdict"]["effect"] == "joint_stiffness_shift"  # the injected effect, as test_diagnosis checks
    text = _diagnosis_page(record, found, tmp_path)
    assert text.index('id="summary"') < text.index("Where the model misses")
    summary = dict(read_csv(tmp_path / csv_name("summary"))[1])
    assert summary["verdict"].startswith("joint_stiffness_shift") and summary["where"] == "A"
    assert summary["shrinkage"].startswith(f"{100 * record['verdict']['shrinkage']:.1f} %")
    assert "confidence" in summary
    header, rows = read_csv(tmp_path / csv_name("candidates"))
    assert len(rows) == len(record["ranking"]) > 8  # all of them, not the first few
    for row, entry in zip(rows, record["ranking"]):
        values = dict(zip(header, row))
        assert (values["effect"], values["where"]) == (entry["effect"], entry["where"] or "-")
        assert float(values["held-out RMS rel. frequency error (%)"]) == 100 * entry["heldout_freq_rms_rel_error"]
    # the residual figure's dots are the verdict's own fit, and the caption names it
    assert "the verdict's own effect, joint_stiffness_shift @ A, fitted" in visible_text(text)
    # the rules as the decision applies them: the naming bar is the decision's own
    assert f"more than {100 * NAME_CONFIDENCE:g} % of the weight" in " ".join(visible_text(text).split())
    check_units(text)


def test_an_exact_candidate_is_never_worded_as_unexplained_zero(diagnosed, tmp_path):
    found, record = diagnosed
    text = visible_text(_diagnosis_page(record, found, tmp_path / "accepted"))
    assert "unexplained 0 %" not in text and "leaves 0 %" not in text
    top = record["ranking"][0]["heldout_freq_rms_rel_error"] / found.baseline.heldout_freq_rms_rel_error
    # near exact (the fit weighs the modes by the measurement error and the model discrepancy, so about 1 % of
    # the baseline's RMS error stays), and the share left said as it is
    said = f"leaves {100 * top:.2g} %" if top < 0.005 else f"leaves {100 * top:.1f} %"
    assert top < 0.02 and said in text
    # the same data with the verdict withheld: the page says no shrinkage was accepted and what the best candidate
    # would leave, never "0 %"
    refused = dataclasses.replace(found, verdict="unexplained", where=None, shrinkage=0.0, best_hz=None)
    record = {**record, "verdict": {"effect": "unexplained", "where": None, "shrinkage": 0.0}}
    text = visible_text(_diagnosis_page(record, refused, tmp_path / "refused"))
    assert "unexplained 0 %" not in text and "no candidate effect was accepted" in text
    assert "not accepted" in text and said in text
    # withheld for want of weight (`decision._unexplained`): the page says how much it had and the bar
    top = record["ranking"][0]
    partial = {"effect": top["effect"], "where": top["where"], "shrinkage": 0.4, "at_bound": False, "weight": 0.62}
    record = {**record, "verdict": {**record["verdict"], "partial": partial, "confidence": 0.38}}
    text = " ".join(visible_text(_diagnosis_page(record, refused, tmp_path / "weight")).split())
    assert (f"carries 62 % of the candidates' weight, under the {100 * NAME_CONFIDENCE:g} % a name needs"
            in text)


def test_a_damping_candidate_is_judged_on_its_damping_error(diagnosed, tmp_path):
    """A joint's damping leads an ``unexplained`` ranking: the page states the share of the held-out damping
    error it leaves, not the frequencies' (which a damping candidate leaves untouched, 100 %).
    """
    found, record = diagnosed
    top = record["ranking"][0]
    damping = {**top, "effect": "joint_damping", "where": "A", "heldout_damping_rms_error": 0.0015,
               "heldout_freq_rms_rel_error": found.baseline.heldout_freq_rms_rel_error}
    baseline = dataclasses.replace(found.baseline, heldout_damping_rms_error=0.002)
    refused = dataclasses.replace(found, verdict="unexplained", where=None, shrinkage=0.0, best_hz=None,
                                  baseline=baseline)
    record = {**record, "verdict": {"effect": "unexplained", "where": None, "shrinkage": 0.0},
              "ranking": [damping, *record["ranking"][1:]]}
    text = visible_text(_diagnosis_page(record, refused, tmp_path))
    said = "leaves 75.0 % of the nominal model's held-out error (held-out damping-ratio RMS 0.15 % against 0.2 %)"
    assert said in text
    assert "leaves 100.0 %" not in text


def test_the_page_says_when_the_levels_moved_the_place():
    # the levels placed the effect (`decision._placed_by_levels`): the page names the place the frequencies
    # preferred and why it was not named
    from workbench.report.diagnosis_page import _frf_levels_text

    test = {"modes": [1, 2], "measured": [1.02, 0.95], "predicted": [1.01, 0.96], "chi2": 1.5, "nominal_chi2": 9.0,
            "dof": 1, "p_value": 0.22, "contradicted": False, "level": 0.01,
            "instead_of": {"effect": "support_compliance", "where": "base_right", "form": "ux", "p_value": 3e-9}}
    text = _frf_levels_text(test)
    assert "preferred support_compliance at base_right" in text and "p = 3e-09" in text
    assert text.endswith("consistent with the verdict")
    assert "preferred" not in _frf_levels_text({k: v for k, v in test.items() if k != "instead_of"})

"""The report and diagnosis pages in a real headless browser (Chromium, driven by Python playwright).

A small rig campaign (one-bolt frame, 4 tests, 4 modes, an added mass the nominal model lacks) is
reported (`report_run`, no Bayes, few samples) with its diagnosis as part of the run, and its gap
diagnosed; both pages are written with their CSV tables as the commands write them, then opened
in the system's Chromium (``/usr/bin/chromium``; the browser is not downloadable here, so no
``playwright install``: ``.ci/run`` installs the Debian package when it is missing). Each page
must load with no console error and no page error, ask for nothing but ``file:`` and ``data:``
addresses, open with its summary box, and show its units; the report also its MAC matrix.

A missing browser or playwright fails the test with a message that says what to install. Set
``WORKBENCH_NO_BROWSER=1`` to skip it deliberately (a machine without Chromium); CI never sets it.
"""

from __future__ import annotations

import dataclasses
import os
import shutil
from pathlib import Path

import pytest
from conftest import REPO

from workbench.diagnose.verdict import diagnose, diagnosis_record
from workbench.io.campaign import Factor, write_campaign
from workbench.io.outputs import write_outputs
from workbench.model.frame_file import read_frame
from workbench.report.diagnosis_page import diagnosis_files
from workbench.report.page import report_files
from workbench.rig.effects import Effect
from workbench.rig.simulate import RigSettings, simulate_campaign
from workbench.workflow.runs import report_run

CHROMIUM = os.environ.get("WORKBENCH_CHROMIUM", "/usr/bin/chromium")
# as benchmarks/screenshot_report.py: no GPU, no network side channels of the browser itself, so
# that any request seen comes from the page
ARGS = ["--headless", "--no-sandbox", "--disable-gpu", "--disable-quic", "--no-first-run",
        "--disable-background-networking", "--disable-component-update", "--disable-sync"]
LOCAL = ("file:", "data:")
PRELOADS_N = ("300", "1000", "2500", "6000")

pytestmark = pytest.mark.skipif(os.environ.get("WORKBENCH_NO_BROWSER") == "1",
                                reason="WORKBENCH_NO_BROWSER=1: the headless-browser check is skipped on request")


def _browser():
    """playwright's sync API, or a failure that says what is missing."""
    try:
        from playwright.sync_api import sync_playwright
    except ImportError:
        pytest.fail("playwright is not installed: pip install -e '.[test]' (WORKBENCH_NO_BROWSER=1 skips this test)")
    if shutil.which(CHROMIUM) is None:
        pytest.fail(f"no Chromium at {CHROMIUM}: apt-get install -y chromium (as .ci/run does), or set "
                    "WORKBENCH_CHROMIUM; WORKBENCH_NO_BROWSER=1 skips this test")
    return sync_playwright


@pytest.fixture(scope="module")
def pages(tmp_path_factory) -> dict[str, Path]:
    root = tmp_path_factory.mktemp("browser")
    frame = read_frame(REPO / "frames" / "one_bolt_vertical.toml")
    factors = (Factor("bolt_A", "tightening", {k: f"preload {k} N" for k in PRELOADS_N}, "A"),)
    settings = RigSettings(f_max_hz=300.0, df_hz=0.25, mode_count=4)
    campaign, _ = simulate_campaign(frame, factors, [{"bolt_A": k} for k in PRELOADS_N], settings, seed=11,
                                    effect=Effect("added_mass", "top_right", {"mass": 0.05}))
    write_campaign(campaign, root / "campaign")
    run = report_run(root / "campaign", bayes=False, samples=20, seed=2)
    study = run.studies[0]
    found = diagnose(study.campaign.frame, study.data)
    record = diagnosis_record(campaign.name, found)
    write_outputs(root / "report", report_files(dataclasses.replace(run, diagnosis=record), 1.0))
    write_outputs(root / "diagnosis", diagnosis_files(record, found, True, "the virtual test rig"))
    return {"report": root / "report" / "index.html", "diagnosis": root / "diagnosis" / "index.html"}


def _open(path: Path) -> dict:
    """Load ``path`` in Chromium; what the checks need: problems, requests, summary text, body text, images."""
    sync_playwright = _browser()
    problems: list[str] = []
    requests: list[str] = []
    with sync_playwright() as p:
        browser = p.chromium.launch(executable_path=CHROMIUM, args=ARGS)
        try:
            page = browser.new_page(viewport={"width": 1280, "height": 900})
            page.on("console", lambda m: problems.append(f"console {m.type}: {m.text}") if m.type == "error" else None)
            page.on("pageerror", lambda e: problems.append(f"page error: {e}"))
            page.on("request", lambda r: requests.append(r.url))
            page.on("requestfailed", lambda r: problems.append(f"failed request: {r.url[:120]}"))
            page.goto(path.resolve().as_uri(), wait_until="load")
            seen = {
                "summary": page.locator("section#summary").inner_text() if page.locator("section#summary").count()
                else "",
                "first": page.evaluate("() => document.querySelector('main > section, main > h2')?.id || ''"),
                "text": page.locator("main").inner_text(),
                "images": page.evaluate("() => Array.from(document.images).map(i => [i.alt, i.naturalWidth])"),
                "tables": page.evaluate("() => Array.from(document.querySelectorAll('table[data-table]'))"
                                        ".map(t => t.dataset.table)"),
                "links": page.evaluate("() => Array.from(document.querySelectorAll('a[href$=\".csv\"]'))"
                                       ".map(a => a.getAttribute('href'))"),
            }
        finally:
            browser.close()
    seen["problems"] = problems
    seen["outside"] = [u for u in requests if not u.startswith(LOCAL)]
    return seen


def _common(seen: dict, folder: Path) -> None:
    assert seen["problems"] == []
    assert seen["outside"] == []
    assert seen["first"] == "summary"  # the summary box opens the page
    assert all(width > 0 for _, width in seen["images"]), seen["images"]  # every figure decoded and drawn
    for name in seen["links"]:
        assert (folder / name).is_file(), name  # each linked CSV is there beside the page
    assert len(seen["links"]) == len(seen["tables"])


@pytest.mark.slow  # the report and diagnosis pages are built first: 20 s
def test_report_page_in_a_browser(pages):
    seen = _open(pages["report"])
    _common(seen, pages["report"].parent)
    summary = seen["summary"]
    assert "E (GPa)" in summary and "CoV (%)" in summary and "moment matching" in summary
    assert "measured modes" in summary and "Diagnosis of" in summary and "confidence" in summary
    for unit in ("GPa", "Hz", "%"):
        assert unit in seen["text"]
    assert any(alt == "MAC matrix test against model" for alt, _ in seen["images"])
    assert "1_mac" in seen["tables"]


@pytest.mark.slow
def test_diagnosis_page_in_a_browser(pages):
    seen = _open(pages["diagnosis"])
    _common(seen, pages["diagnosis"].parent)
    summary = seen["summary"]
    for item in ("verdict", "where", "confidence", "shrinkage"):
        assert item in summary
    assert "unexplained 0 %" not in seen["text"]
    assert "(Hz)" in seen["text"] and "(%)" in seen["text"]
    assert "candidates" in seen["tables"]

"""Open a report in headless Chromium: console errors, outside requests, and a full-page screenshot.

Fails (exit 1) on any console error, page error, failed request, request to anything but a
``file:`` or ``data:`` address (the report must be self-contained and open offline), or a page
without its summary box. tests/test_report_browser.py runs the same checks in the test suite. Prints what it
found, and saves a full-page PNG beside the report (or ``--png``). Not part of CI.

Drives the system's Chromium (Debian: ``apt-get install chromium``) with Python playwright
(``pip install -e ".[screenshot]"``; no ``playwright install``: the browser is not downloaded)::

    python benchmarks/screenshot_report.py out/demo/index.html [--png out/demo/screenshot.png]
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

CHROMIUM = "/usr/bin/chromium"
# no GPU, no network side channels of the browser itself: any request then comes from the page
ARGS = ["--headless", "--no-sandbox", "--disable-gpu", "--disable-quic", "--no-first-run",
        "--disable-background-networking", "--disable-component-update", "--disable-sync"]
LOCAL = ("file:", "data:")


def inspect(report: Path, png: Path, executable: str = CHROMIUM, width: int = 1280) -> list[str]:
    """Load ``report``, screenshot it to ``png``; returns the problems found (empty: clean)."""
    from playwright.sync_api import sync_playwright

    problems: list[str] = []
    console: list[str] = []
    requests: list[str] = []
    with sync_playwright() as p:
        browser = p.chromium.launch(executable_path=executable, args=ARGS)
        page = browser.new_page(viewport={"width": width, "height": 900})
        page.on("console", lambda m: console.append(f"{m.type}: {m.text}"))
        page.on("pageerror", lambda e: problems.append(f"page error: {e}"))
        page.on("request", lambda r: requests.append(r.url))
        page.on("requestfailed", lambda r: problems.append(f"failed request: {r.url[:120]} ({r.failure})"))
        page.goto(report.resolve().as_uri(), wait_until="load")
        if not page.locator("section#summary").count():
            problems.append("no summary box (section#summary) at the top of the page")
        images = page.evaluate("""() => Array.from(document.images).map(i => [i.alt, i.naturalWidth, i.complete])""")
        height = page.evaluate("() => document.documentElement.scrollHeight")
        overflow = page.evaluate("""() => { const edge = document.querySelector('main').getBoundingClientRect().right;
            return Array.from(document.querySelectorAll('table'))
                .filter(t => t.getBoundingClientRect().right > edge + 1).length; }""")
        png.parent.mkdir(parents=True, exist_ok=True)
        page.screenshot(path=str(png), full_page=True)
        browser.close()
    outside = [u for u in requests if not u.startswith(LOCAL)]
    problems += [f"console {c}" for c in console if c.startswith("error")]
    problems += [f"request outside file:/data:: {u[:120]}" for u in outside]
    problems += [f"image not rendered: {alt!r}" for alt, w, done in images if not (done and w > 0)]
    print(f"{report}: {len(images)} images, page {width} x {height} px, {len(requests)} requests "
          f"({len(requests) - len(outside)} file:/data:), {len(console)} console messages")
    for c in console:
        print(f"  console {c}")
    if overflow:
        print(f"  note: {overflow} table(s) wider than the page's column (they scroll horizontally)")
    print(f"  screenshot: {png}")
    return problems


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("report", type=Path, help="the report's index.html")
    parser.add_argument("--png", type=Path, help="screenshot path (default: screenshot.png beside the report)")
    parser.add_argument("--chromium", default=CHROMIUM, help=f"Chromium executable (default {CHROMIUM})")
    args = parser.parse_args(argv)
    if not args.report.is_file():
        print(f"screenshot_report: {args.report}: no such file", file=sys.stderr)
        return 2
    problems = inspect(args.report, args.png or args.report.with_name("screenshot.png"), args.chromium)
    for problem in problems:
        print(f"  PROBLEM {problem}")
    print("clean: no console error, no request outside file:/data:" if not problems else
          f"{len(problems)} problem(s)")
    return 1 if problems else 0


if __name__ == "__main__":
    sys.exit(main())

"""The committed one-page HTML report of the default run (``results/report.html``, ``make report``):
it is the report of the committed tables and figures, and it renders in a real headless browser.

The browser comes from ``profiles/browser/install.sh`` (Chromium on PATH, or Debian's, installed
with apt-get when missing). Without one the browser tests are skipped, unless
``FEEDER_REQUIRE_BROWSER=1`` (CI sets it), which turns a missing browser into a failure.

Snakemake's report is a single-page app: the page lists the categories, and a figure or caption
is drawn when its entry is opened. So the browser is asked three things: that the app itself
renders (its menu names every category of the report, and a screenshot is not blank), that every
figure embedded in the report is drawn pixel for pixel as its PNG, and that every caption's HTML
renders to its text.
"""

from __future__ import annotations

import base64
import html
import json
import os
import re
import subprocess
from pathlib import Path

import cv2
import numpy as np
import pytest
from workflow_helpers import ROOT

REPORT = ROOT / "results" / "report.html"
INSTALL = ROOT / "profiles" / "browser" / "install.sh"
CAPTIONS = ROOT / "workflow" / "report"
BROWSER_TIMEOUT_S = 180
INSTALL_TIMEOUT_S = 900
MIN_FIGURES = 11  # the study's figures (Figs. 4-6, 9, 12-14, S1, S11, the DKW bands, the cost by stage)


def embedded(text: str, name: str):
    """The JSON value of the report's ``<script id="name"> var name = ...;`` block."""
    m = re.search(rf'<script id="{name}">\s*var {name} = (.*?);?\s*</script>', text, re.S)
    assert m, f"the report has no {name} block"
    return json.loads(m.group(1))


def data_bytes(uri: str) -> bytes:
    head, _, payload = uri.partition(",")
    assert head.endswith(";base64"), head[:80]
    return base64.b64decode(payload)


@pytest.fixture(scope="module")
def report() -> tuple[str, dict]:
    assert REPORT.is_file(), "results/report.html is missing: make report"
    text = REPORT.read_text(errors="replace")
    return text, embedded(text, "results")


def test_report_is_that_of_the_committed_results(report):
    """Every entry is the committed file byte for byte (a report of stale results fails), has a
    caption from workflow/report/, and the study's figures are all there."""
    _, results = report
    first_words = {" ".join(r.read_text().split()[:4]) for r in CAPTIONS.glob("*.rst")}
    figures = 0
    for path, entry in results.items():
        committed = ROOT / path
        assert committed.is_file(), f"{path} is in the report but not committed"
        assert data_bytes(entry["data_uri"]) == committed.read_bytes(), (
            f"{path} differs from the committed file: rebuild the report (make report)"
        )
        caption = visible_text(entry["caption"])
        assert any(caption.startswith(w) for w in first_words), f"{path}: caption {caption[:60]!r} is not one of ours"
        figures += entry["mime_type"] == "image/png"
    assert figures >= MIN_FIGURES


@pytest.fixture(scope="module")
def browser() -> str:
    required = os.environ.get("FEEDER_REQUIRE_BROWSER") == "1"
    try:
        proc = subprocess.run([str(INSTALL)], capture_output=True, text=True, timeout=INSTALL_TIMEOUT_S)
        path, reason = proc.stdout.strip().splitlines()[-1:], proc.stderr.strip()[-500:]
        if proc.returncode == 0 and path:
            return path[0]
    except (OSError, subprocess.TimeoutExpired) as exc:
        reason = str(exc)
    if required:
        pytest.fail(f"FEEDER_REQUIRE_BROWSER=1 but no browser could be had: {reason}")
    pytest.skip(f"no headless browser could be installed here: {reason}")


def headless(browser: str, tmp_path: Path, page: Path, *args: str) -> str:
    """Run the browser headless on ``page`` with ``args``; its stdout."""
    cmd = [
        browser,
        "--headless",
        "--no-sandbox",  # tests run as root in CI
        "--disable-gpu",
        "--hide-scrollbars",
        f"--user-data-dir={tmp_path / 'profile'}",
        "--virtual-time-budget=20000",  # let the app's scripts finish before the dump/screenshot
        *args,
        page.as_uri(),
    ]
    proc = subprocess.run(cmd, capture_output=True, text=True, timeout=BROWSER_TIMEOUT_S)
    assert proc.returncode == 0, proc.stderr[-2000:]
    return proc.stdout


def visible_text(dom: str) -> str:
    dom = re.sub(r"<(script|style)\b.*?</\1>", " ", dom, flags=re.S)
    dom = re.sub(r"<!--.*?(-->|$)", " ", dom, flags=re.S)  # a comment's text is not shown
    return " ".join(html.unescape(re.sub(r"<[^>]+>", " ", dom)).split())


def test_report_app_renders_its_menu_in_a_browser(browser, report, tmp_path):
    text, _ = report
    dom = headless(browser, tmp_path, REPORT, "--dump-dom")
    app = re.search(r'<div id="app">(.*)', dom, re.S)
    assert app, "the report's app element is missing"
    shown = visible_text(app.group(1))
    for category in embedded(text, "categories"):
        assert category in shown, f"category {category!r} is not in the rendered menu"
    assert "Loading Snakemake Report" not in shown

    shot = tmp_path / "report.png"
    headless(browser, tmp_path, REPORT, f"--screenshot={shot}", "--window-size=1400,900")
    img = cv2.imread(str(shot), cv2.IMREAD_GRAYSCALE)
    assert img is not None and img.shape == (900, 1400)
    assert float(img.std()) > 10.0, "the rendered report is blank"


def test_every_figure_of_the_report_renders_in_a_browser(browser, report, tmp_path):
    """Each embedded figure alone on a page of its own size, screenshot by the browser: the
    pixels the browser drew equal the PNG's own (decoded by OpenCV) within rounding; a figure
    the browser cannot decode, or draws only in part, differs."""
    _, results = report
    figures = {p: e for p, e in sorted(results.items()) if e["mime_type"] == "image/png"}
    assert len(figures) >= MIN_FIGURES
    for i, (path, entry) in enumerate(figures.items()):
        own = cv2.imdecode(np.frombuffer(data_bytes(entry["data_uri"]), np.uint8), cv2.IMREAD_COLOR)
        assert own is not None, f"{path}: not a PNG OpenCV can decode"
        h, w = own.shape[:2]
        page, shot = tmp_path / f"figure{i}.html", tmp_path / f"figure{i}.png"
        page.write_text(
            '<!DOCTYPE html><html><body style="margin:0;background:#ff00ff">'
            f'<img style="display:block" src="{entry["data_uri"]}"></body></html>'
        )
        headless(
            browser, tmp_path, page, f"--screenshot={shot}", f"--window-size={w},{h}", "--force-device-scale-factor=1"
        )
        drawn = cv2.imread(str(shot), cv2.IMREAD_COLOR)
        assert drawn is not None and drawn.shape == own.shape, (
            f"{path}: the browser drew {None if drawn is None else drawn.shape}"
        )
        diff = np.abs(drawn.astype(np.int16) - own.astype(np.int16))
        assert float(diff.mean()) < 2.0 and float((diff > 16).mean()) < 0.001, f"{path} does not render as its PNG"


def test_every_caption_of_the_report_renders_in_a_browser(browser, report, tmp_path):
    """All captions' HTML on one page: the browser's DOM shows each caption's text."""
    _, results = report
    page = tmp_path / "captions.html"
    items = [f'<div id="c{i}">{e["caption"]}</div>' for i, (_, e) in enumerate(sorted(results.items()))]
    page.write_text("<!DOCTYPE html><html><body>" + "".join(items) + "</body></html>")
    shown = visible_text(headless(browser, tmp_path, page, "--dump-dom"))
    for path, entry in sorted(results.items()):
        words = visible_text(entry["caption"]).split()[:6]
        assert words and " ".join(words) in shown, f"the caption of {path} does not render"

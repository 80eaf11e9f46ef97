"""The HTML report in a real headless Chromium: it renders, fits the page, and prints."""

from __future__ import annotations

import json
import re
import shutil
import subprocess
from pathlib import Path

import pytest

from grader.report import write_html

CHROMIUM = next((p for p in ("/usr/bin/chromium", shutil.which("chromium"),
                             shutil.which("chromium-browser")) if p and Path(p).exists()), None)

pytestmark = [
    pytest.mark.skipif(CHROMIUM is None, reason="chromium is not installed "
                       "(apt-get install chromium); the HTML report is only checked statically"),
]

# appended to a *copy* of the report (reports themselves contain no script): measures layout
PROBE = """<script>
const de = document.documentElement;
const tooWide = [...document.querySelectorAll('main *')]
  .filter(e => e.getBoundingClientRect().right > de.clientWidth + 1).map(e => e.tagName);
de.setAttribute('data-probe', JSON.stringify({
  scrollWidth: de.scrollWidth, clientWidth: de.clientWidth, tooWide: tooWide.slice(0, 5),
  plots: [...document.querySelectorAll('svg.plot')].filter(s => s.getBoundingClientRect().width > 100).length,
  rows: document.querySelectorAll('tr.item').length,
  auto: document.querySelector('[data-score=automatic] b').textContent}));
</script>"""


def chromium(tmp_path: Path, *args: str) -> subprocess.CompletedProcess[str]:
    return subprocess.run(
        [CHROMIUM, "--headless", "--no-sandbox", "--disable-gpu", "--disable-background-networking",
         "--disable-component-update", "--disable-sync", "--no-first-run",
         f"--user-data-dir={tmp_path / 'profile'}", *args],
        capture_output=True, text=True, timeout=90, check=False)


@pytest.mark.parametrize("width", [1200, 420])
def test_dom_has_score_rows_and_fits_the_window(tmp_path, lab3, lab3_result, width):
    page = write_html(tmp_path, "alice", lab3_result)
    probe = page.with_name("probe.html")
    probe.write_text(page.read_text().replace("</body>", PROBE + "</body>"))
    run = chromium(tmp_path, f"--window-size={width},900", "--dump-dom", probe.as_uri())
    assert run.returncode == 0, run.stderr[-2000:]
    dom = run.stdout
    assert "Grade report: <span" in dom and ">47 / 50<" in dom
    assert len(re.findall(r'<tr class="item"', dom)) == len(lab3.items)
    match = re.search(r"data-probe=\"([^\"]*)\"", dom)
    assert match, dom[:500]
    probe_data = json.loads(match.group(1).replace("&quot;", '"'))
    assert probe_data["rows"] == len(lab3.items) and probe_data["auto"] == "47 / 50"
    assert probe_data["plots"] == 2
    assert probe_data["scrollWidth"] <= probe_data["clientWidth"], probe_data   # no sideways scroll


@pytest.mark.slow          # two browser launches; ~2-3 s on a loaded 2-core machine
def test_screenshot_and_print(tmp_path, lab3_result):
    page = write_html(tmp_path, "alice", lab3_result)
    shot, pdf = tmp_path / "shot.png", tmp_path / "report.pdf"
    run = chromium(tmp_path, "--window-size=1200,1600", f"--screenshot={shot}", page.as_uri())
    assert run.returncode == 0 and shot.read_bytes()[:4] == b"\x89PNG", run.stderr[-2000:]
    assert shot.stat().st_size > 50_000        # a blank page compresses to a few kB
    run = chromium(tmp_path, "--no-pdf-header-footer", f"--print-to-pdf={pdf}", page.as_uri())
    assert run.returncode == 0 and pdf.read_bytes()[:5] == b"%PDF-", run.stderr[-2000:]
    assert len(re.findall(rb"/Type\s*/Page[^s]", pdf.read_bytes())) >= 2

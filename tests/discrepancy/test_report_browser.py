"""The diagnose HTML report as a user sees it: rendered by headless Chromium, images included.

Skips when Chromium is absent (Debian package ``chromium``, installed by ``.ci/run``).
"""
import html.parser
import json
import shutil
import subprocess

import numpy as np
import pytest
from PIL import Image
from typer.testing import CliRunner

from vjm.cli import app

CHROMIUM = next((shutil.which(n) for n in ("chromium", "chromium-browser", "google-chrome") if shutil.which(n)), None)
pytestmark = [pytest.mark.chromium,
              pytest.mark.skipif(CHROMIUM is None, reason="headless Chromium not installed: "
                                 "install the Debian package chromium (.ci/run does)")]

WINDOW = (1100, 2400)
# after the page's load event, record what the browser made of every <img>
PROBE = ('<script>window.addEventListener("load", () => {document.body.setAttribute("data-images", '
         'JSON.stringify([...document.images].map(i => [i.getAttribute("src"), i.complete, '
         'i.naturalWidth, i.naturalHeight])))})</script>')


class _Images(html.parser.HTMLParser):
    def __init__(self):
        super().__init__()
        self.src = []

    def handle_starttag(self, tag, attrs):
        if tag == "img":
            self.src.append(dict(attrs)["src"])


def _chromium(tmp_path, *args):
    cmd = [CHROMIUM, "--headless", "--no-sandbox", "--disable-gpu", "--hide-scrollbars",
           f"--user-data-dir={tmp_path / 'profile'}", "--virtual-time-budget=10000", *args]
    return subprocess.run(cmd, capture_output=True, text=True, timeout=180, check=True)


@pytest.fixture(scope="module")
def report(tmp_path_factory):
    """A real report: simulated measurements with a hidden weight, diagnosed through the CLI."""
    d = tmp_path_factory.mktemp("report")
    runner = CliRunner()
    r = runner.invoke(app, ["simulate", "data/orthoglide/puu.yaml", "--effect", "gravity:weight=15",
                            "--poses", "random:12", "--loads", "axes:100", "--noise-t", "0.001", "--seed", "1",
                            "--out", str(d / "d.csv")])
    assert r.exit_code == 0, r.output
    r = runner.invoke(app, ["diagnose", "data/orthoglide/puu.yaml", str(d / "d.csv"), "--effect", "gravity",
                            "--out", str(d / "rep")])
    assert r.exit_code == 0, r.output
    return d / "rep"


def test_every_image_of_the_report_loads_in_chromium(report, tmp_path):
    page = (report / "report.html").read_text(encoding="utf-8")
    parser = _Images()
    parser.feed(page)
    assert parser.src, "the report has no image"
    probe = report / "probe.html"  # same folder, so relative image paths resolve as in report.html
    probe.write_text(page.replace("</body>", PROBE + "</body>"), encoding="utf-8")
    try:
        dom = _chromium(tmp_path, "--dump-dom", probe.as_uri()).stdout
    finally:
        probe.unlink()
    start = dom.index('data-images="') + len('data-images="')
    seen = json.loads(html.unescape(dom[start:dom.index('"', start)]))
    assert [s[0] for s in seen] == parser.src
    for src, complete, w, h in seen:
        with Image.open(report / src) as im:
            assert complete and (w, h) == im.size, f"{src}: the browser decoded {w}x{h}, the file is {im.size}"


def test_screenshot_shows_the_figures(report, tmp_path):
    shot = tmp_path / "shot.png"
    _chromium(tmp_path, f"--window-size={WINDOW[0]},{WINDOW[1]}", f"--screenshot={shot}",
              (report / "report.html").as_uri())
    img = np.asarray(Image.open(shot).convert("RGB"), dtype=float) / 255.0
    assert img.shape[:2] == (WINDOW[1], WINDOW[0])
    # text and tables are black on white; the figures bring colour (saturated pixels)
    sat = img.max(axis=2) - img.min(axis=2)
    dark = img.max(axis=2) < 0.3
    assert dark.sum() > 2000, "no text rendered"
    assert (sat > 0.3).sum() > 5000, "no coloured figure rendered"

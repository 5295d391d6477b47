"""The documentation site as a reader gets it: built once per session with ``mkdocs build --strict`` (as
``make test`` builds it), then read as files and in headless Chromium.

* the API pages show cross-references, not Sphinx roles (docs/tools/griffe_roles.py), and the strict
  build resolves every one of them;
* search works: the search plugin's index holds the pages' text;
* the guide pages are split by task ("Run it" first) and show the pictures docs/tools/docs_pictures.py
  makes from the project's own commands;
* in Chromium: the home page renders, a guide page's picture loads (naturalWidth > 0), the API page
  shows no raw role.

Chromium: the Debian package ``chromium`` (.ci/run installs it); the browser tests skip without it.
"""
from __future__ import annotations

import html
import json
import os
import re
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from PIL import Image

ROOT = Path(__file__).resolve().parents[1]
DOCS = ROOT / "docs"
sys.path.insert(0, str(DOCS / "tools"))
#: a Sphinx role as the page would show it unrendered: the role, then its target as code or in backticks
RAW_ROLE = re.compile(r":(?:class|func|meth|mod|data|attr|exc|obj):(?:<code>|`)")
#: the pictures of the docs, each made by docs/tools/docs_pictures.py, and a page that shows it
PICTURES = {"link_mesh_frame.png": "linkfea_compute.md", "map_k_tran.png": "vjm_map.md",
            "map_ratio.png": "vjm_map.md", "robot_joint_map.png": "vjm_robots.md",
            "diagnose_report.png": "vjm_diagnose.md"}
CHROMIUM = next((shutil.which(n) for n in ("chromium", "chromium-browser", "google-chrome") if shutil.which(n)), None)


def needs_chromium(test):
    """Marked ``chromium``; skipped, saying why, where headless Chromium is not installed."""
    skip = pytest.mark.skipif(CHROMIUM is None, reason="headless Chromium not installed: install the Debian "
                              "package chromium (.ci/run does)")
    return pytest.mark.chromium(skip(test))


# after the page's load event, record what the browser made of every <img>
PROBE = ('<script>window.addEventListener("load", () => {document.body.setAttribute("data-images", '
         'JSON.stringify([...document.images].map(i => [i.getAttribute("src"), i.complete, '
         'i.naturalWidth, i.naturalHeight])))})</script>')


@pytest.fixture(scope="session")
def site(tmp_path_factory):
    """The site, built once: ``mkdocs build --strict`` (a broken link or an unresolved reference fails); under
    ``make test``, the site its strict build wrote just before (``DOCS_SITE``)."""
    made = os.environ.get("DOCS_SITE")
    if made and (Path(made) / "index.html").is_file():
        return Path(made)
    out = tmp_path_factory.mktemp("site")
    env = dict(os.environ, NO_MKDOCS_2_WARNING="1",
               PYTHONPATH=os.pathsep.join([str(ROOT / "src"), os.environ.get("PYTHONPATH", "")]))
    r = subprocess.run([sys.executable, "-m", "mkdocs", "build", "--strict", "--site-dir", str(out)], cwd=ROOT,
                       env=env, capture_output=True, text=True, timeout=900)
    assert r.returncode == 0, r.stderr[-4000:]
    return out


def _text(page: str) -> str:
    """The visible text of an HTML page (tags dropped, entities read)."""
    return html.unescape(re.sub(r"<[^>]+>", "", page))


# ------------------------------------------------------------------ the built files


def test_api_pages_show_cross_references_not_roles(site):
    links = 0
    for name in ("api_vjm.html", "api_linkfea.html"):
        page = (site / name).read_text(encoding="utf-8")
        raw = RAW_ROLE.findall(page) + re.findall(r":(?:class|func|meth|mod):`", _text(page))
        assert not raw, f"{name}: {len(raw)} raw roles, e.g. {raw[:3]}"
        links += len(re.findall(r'<a class="autorefs autorefs-(?:internal|external)"', page))
    assert links > 600  # the docstrings' ~1,000 roles, most of them objects the pages show


def test_roles_resolve_in_the_docstrings_scope():
    """Each form of role the docstrings use, resolved as Python would resolve the name there."""
    import griffe
    from griffe_roles import convert_roles

    loader = griffe.GriffeLoader(search_paths=[str(ROOT / "src")])
    loader.load("vjm")
    loader.resolve_aliases(implicit=False)
    col = loader.modules_collection
    compute, cli = col["vjm.maps.compute"], col["vjm.cli"]
    assert convert_roles(":class:`~vjm.maps.grid.Grid`", compute, col) == "[`Grid`][vjm.maps.grid.Grid]"
    assert convert_roles(":func:`compute_map`", compute, col) == "[`compute_map`][vjm.maps.compute.compute_map]"
    assert convert_roles(":meth:`plot`", compute["StiffnessMap"], col) == \
        "[`plot`][vjm.maps.compute.StiffnessMap.plot]"
    assert convert_roles(":mod:`.common`", cli, col) == "[`common`][vjm.cli.common]"
    # a constant documented by a comment only is not on the page: plain code, never a dangling link
    assert convert_roles(":data:`LOG_SPAN`", compute, col) == "`LOG_SPAN`"
    assert convert_roles(":func:`no_such_thing`", compute, col) == "`no_such_thing`"
    # examples stay as they are
    assert convert_roles("```pycon\n>>> ':class:`x`'\n```", compute, col) == "```pycon\n>>> ':class:`x`'\n```"


def test_search_index_finds_a_term(site):
    """The search plugin's index holds every page; a term of a guide finds its page and section."""
    doc = json.loads((site / "search" / "search_index.json").read_text(encoding="utf-8"))
    where = {d["location"] for d in doc["docs"] if "backlash" in d["text"].lower()}
    assert any(loc.startswith("vjm_diagnose.html") for loc in where), sorted(where)[:10]
    where = {d["location"] for d in doc["docs"] if "--compare" in d["text"]}
    assert "vjm_map.html#compare-two-maps" in where, sorted(where)
    assert list((site / "assets" / "javascripts" / "workers").glob("search*.js")), "no search worker"


@pytest.mark.parametrize("page", ["vjm_diagnose.md", "vjm_robots.md", "vjm_map.md", "vjm_calibrate.md",
                                  "vjm_calibrate_parallel.md", "vjm_path.md", "vjm_stiffness.md",
                                  "linkfea_compute.md", "linkfea_sweep.md"])
def test_guide_pages_are_split_by_task(page):
    """H2 sections, "Run it" first, no wall of text (a paragraph or list item of at most 250 words)."""
    text = (DOCS / page).read_text(encoding="utf-8")
    h2 = re.findall(r"^## (.+)$", text, re.M)
    assert h2 and h2[0] == "Run it" and len(h2) >= 5, h2
    prose = re.sub(r"^```.*?^```", "", text, flags=re.S | re.M)
    longest = max(len(p.split()) for p in re.split(r"\n\s*\n|\n(?=[*-] )", prose))
    assert longest <= 250, (page, longest)


def test_pictures_are_small_and_shown(site):
    """Each picture: made by docs/tools/docs_pictures.py, small, shown by its page on the built site."""
    script = (DOCS / "tools" / "docs_pictures.py").read_text(encoding="utf-8")
    for name, page in PICTURES.items():
        path = DOCS / "img" / name
        assert name in script, name
        assert path.stat().st_size < 250_000, (name, path.stat().st_size)
        with Image.open(path) as im:
            assert 300 <= im.width <= 1000 and im.height >= 200, (name, im.size)
        built = (site / page.replace(".md", ".html")).read_text(encoding="utf-8")
        assert f'src="img/{name}"' in built, (page, name)
        assert (site / "img" / name).is_file()


# ------------------------------------------------------------------ in the browser


def _chromium(tmp_path, *args) -> str:
    cmd = [CHROMIUM, "--headless", "--no-sandbox", "--disable-gpu", "--hide-scrollbars",
           f"--user-data-dir={tmp_path / 'profile'}", "--virtual-time-budget=10000", *args]
    return subprocess.run(cmd, capture_output=True, text=True, timeout=180, check=True).stdout


def _dom_with_images(site, page: str, tmp_path) -> tuple[str, list]:
    """The DOM Chromium builds of ``page`` and what it made of each image (src, complete, width, height)."""
    probe = site / f"probe_{page}"  # same folder: relative paths resolve as on the page
    probe.write_text((site / page).read_text(encoding="utf-8").replace("</body>", PROBE + "</body>"),
                     encoding="utf-8")
    try:
        dom = _chromium(tmp_path, "--dump-dom", probe.as_uri())
    finally:
        probe.unlink()
    start = dom.index('data-images="') + len('data-images="')
    return dom, json.loads(html.unescape(dom[start:dom.index('"', start)]))


def _screenshot(site, page: str, tmp_path, size=(1200, 1800)) -> np.ndarray:
    shot = tmp_path / f"{page}.png"
    _chromium(tmp_path, f"--window-size={size[0]},{size[1]}", f"--screenshot={shot}", (site / page).as_uri())
    return np.asarray(Image.open(shot).convert("RGB"), dtype=float) / 255.0


@needs_chromium
def test_home_page_renders(site, tmp_path):
    img = _screenshot(site, "index.html", tmp_path)
    dark = img.max(axis=2) < 0.3
    assert dark.sum() > 3000, "no text rendered"
    dom, _ = _dom_with_images(site, "index.html", tmp_path)
    assert "linkfea" in _text(dom) and "vjm" in _text(dom)


@needs_chromium
def test_guide_page_shows_its_picture(site, tmp_path):
    _, seen = _dom_with_images(site, "vjm_diagnose.html", tmp_path)
    report = [s for s in seen if s[0] == "img/diagnose_report.png"]
    assert report, seen
    with Image.open(DOCS / "img" / "diagnose_report.png") as im:
        assert all(complete and w > 0 and (w, h) == im.size for _, complete, w, h in report), report
    img = _screenshot(site, "vjm_diagnose.html", tmp_path, size=(1200, 2400))
    sat = img.max(axis=2) - img.min(axis=2)
    assert (sat > 0.3).sum() > 2000, "the report's picture does not show"


@needs_chromium
def test_api_page_in_the_browser_has_no_raw_role(site, tmp_path):
    dom, _ = _dom_with_images(site, "api_vjm.html", tmp_path)
    assert ":class:`" not in dom and not RAW_ROLE.search(dom)
    assert dom.count('class="autorefs autorefs-internal"') > 300
    assert "StiffnessMap" in _text(dom)

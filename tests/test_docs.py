"""The docs site's pages hold code that runs: every ```python block of docs/ (any depth), as tests/test_readme.py
does for the README.

Each block runs in a process of its own from a scratch folder (a block may register an effect or set a
backend: nothing leaks into the other tests), with this checkout's ``src`` first on the path and the mesh
cache in the scratch folder; the process is forked from one that has imported the heavy packages once
(tests/freshrun.py), not a new interpreter that imports them again for every block.  Two kinds of block do not run here, each for a stated reason:

* a block whose only line is a snippet include of a script of ``docs/examples/`` (``--8<-- "docs/
  examples/NAME.py"``): tests/test_examples.py runs those scripts and checks what they print;
* a block right after the line ``<!-- norun: REASON -->``: a template that cannot run as it stands
  (a file of the package with relative imports, say).  The reason is required.

The site itself is built with ``mkdocs build --strict`` by ``make test`` (links, anchors, the API pages) and
checked as a reader sees it by tests/test_docs_site.py.
"""
from __future__ import annotations

import os
import re
import sys
from pathlib import Path

import freshrun
import pytest

ROOT = Path(__file__).resolve().parents[1]
DOCS = ROOT / "docs"
FENCE = re.compile(r"^```python\n(.*?)^```", flags=re.S | re.M)
NORUN = re.compile(r"<!-- norun: (.*?) -->\n$")
INCLUDE = re.compile(r'^--8<-- "docs/examples/([\w.]+)"$')
sys.path.insert(0, str(DOCS / "tools"))
from readme_sections import for_site, section  # noqa: E402


def blocks():
    """(page, number, code, norun reason or None) of every ```python block of the pages under docs/."""
    out = []
    for page in sorted(DOCS.rglob("*.md")):
        text = page.read_text(encoding="utf-8")
        for k, m in enumerate(FENCE.finditer(text), 1):
            reason = NORUN.search(text[:m.start()][-300:])
            out.append((page.relative_to(DOCS).as_posix(), k, m.group(1), reason.group(1) if reason else None))
    return out


BLOCKS = blocks()
RUN = [b for b in BLOCKS if b[3] is None and not INCLUDE.match(b[2].strip())]


def test_docs_have_python_blocks_that_run():
    assert len(RUN) >= 7, [b[:2] for b in RUN]  # the README's former blocks among them


def test_skipped_blocks_say_why():
    """Only templates are skipped, each with its reason; includes name an example that exists."""
    for page, k, code, reason in BLOCKS:
        if reason is not None:
            assert len(reason.split()) >= 3, (page, k, reason)
        elif INCLUDE.match(code.strip()):
            assert (DOCS / "examples" / INCLUDE.match(code.strip()).group(1)).is_file(), (page, k)
    assert sum(b[3] is not None for b in BLOCKS) <= 2  # a third template needs a look, not a marker


@pytest.mark.parametrize("page,k,code", [b[:3] for b in RUN], ids=[f"{b[0]}:block{b[1]}" for b in RUN])
def test_docs_block_runs(page, k, code, tmp_path):
    env = dict(os.environ, MPLBACKEND="Agg", LINKFEA_CACHE_DIR=str(tmp_path / "meshes"),
               PYTHONPATH=os.pathsep.join([str(ROOT / "src"), os.environ.get("PYTHONPATH", "")]))
    script = tmp_path / f"{Path(page).stem}_block{k}.py"
    script.write_text(code, encoding="utf-8")
    res = freshrun.script(script, tmp_path, env)
    assert res.returncode == 0, f"{page} block {k}:\n{res.stderr[-3000:]}"


def test_site_pages_take_readme_sections_with_site_links():
    """The site shows the README's own sections (one copy); their links are made site links."""
    readme = (ROOT / "README.md").read_text(encoding="utf-8")
    marks = [t for p in DOCS.rglob("*.md") for t in re.findall(r"^<!-- README: (.+?) -->$", p.read_text(), re.M)]
    assert {"Conventions", "Your files", "Documentation"} <= set(marks)
    for title in marks:
        body = for_site(section(readme, title))
        assert body.strip() and "](docs/" not in body and "](#your-files)" not in body, title
    conv = for_site(section(readme, "Conventions"))
    assert "](bad_inputs.md)" in conv and "](your_files.md)" in conv
    with pytest.raises(ValueError, match="no section"):
        section(readme, "No such section")


def test_readme_is_a_front_door():
    """About 200 lines (at most 250), the two commands, and no hand-kept module list."""
    readme = (ROOT / "README.md").read_text(encoding="utf-8")
    assert len(readme.splitlines()) <= 250
    assert "make demo" in readme and "make test" in readme
    assert "## Layout" not in readme


def test_api_fences_doctests():
    """The API pages show the docstrings' ``>>>`` examples as code (docs/tools/griffe_doctest.py)."""
    from griffe_doctest import fence_doctests

    text = 'Rows:\n\n>>> rows[0]["seed_k_tran"]\n0.5\n\nAfter.\n>>> 1\n1'
    assert fence_doctests(text) == ('Rows:\n\n```pycon\n>>> rows[0]["seed_k_tran"]\n0.5\n```\n\nAfter.\n'
                                    '```pycon\n>>> 1\n1\n```')

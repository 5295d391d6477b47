"""MkDocs hook: a page line ``<!-- README: Title -->`` becomes the README's section of that title.

The README keeps the text a newcomer needs first (what the tools are, the conventions, what they promise
about your files, the map of the docs); the site shows the same sections from that one copy.  Links are
rewritten for the site: ``docs/x.md`` becomes ``x.md``, ``CHANGELOG.md`` the page ``changelog.md``, a README anchor of a section that has a page of
its own becomes that page.  Loaded by ``mkdocs.yml`` (``hooks:``).
"""
from __future__ import annotations

import re
from pathlib import Path

README = Path(__file__).resolve().parents[2] / "README.md"
MARK = re.compile(r"^<!-- README: (.+?) -->$", re.M)
#: README anchors whose section is a page of the site
PAGES = {"#your-files": "your_files.md", "#conventions": "getting_started.md#conventions"}


def section(text: str, title: str) -> str:
    """The body of the README's section ``title`` (any level), up to the next heading of level 2 or above."""
    lines = text.splitlines()
    heads = [i for i, ln in enumerate(lines) if re.match(r"^#{1,2} ", ln)]
    start = next((i for i in heads if lines[i].lstrip("#").strip() == title), None)
    if start is None:
        raise ValueError(f"README.md has no section {title!r}")
    end = next((i for i in heads if i > start), len(lines))
    return "\n".join(lines[start + 1:end]).strip("\n") + "\n"


def for_site(body: str) -> str:
    """README links made site links."""
    body = re.sub(r"\]\(docs/", "](", body)
    body = body.replace("](CHANGELOG.md)", "](changelog.md)")  # the site's page that includes it
    for anchor, page in PAGES.items():
        body = body.replace(f"]({anchor})", f"]({page})")
    return body


def on_page_markdown(markdown: str, **kwargs: object) -> str:
    if "<!-- README:" not in markdown:
        return markdown
    text = README.read_text(encoding="utf-8")
    return MARK.sub(lambda m: for_site(section(text, m.group(1))), markdown)

"""Griffe extension for the API pages: fence the docstrings' ``>>>`` examples as ``pycon`` code.

The docstrings of ``src/`` are markdown prose with doctest examples (which pytest runs,
``--doctest-modules``).  Unfenced, markdown would read ``>>>`` as nested quotes and ``rows[0]["k"]`` as a
link reference; fenced, they show as the console session they are.  Loaded by ``mkdocs.yml``.
"""
from __future__ import annotations

import griffe


def fence_doctests(text: str) -> str:
    """``text`` with every run of doctest lines (``>>>`` and what follows up to a blank line) fenced.

    >>> print(fence_doctests("Use it:\\n\\n>>> 1 + 1\\n2\\n\\nDone."))
    Use it:
    <BLANKLINE>
    ```pycon
    >>> 1 + 1
    2
    ```
    <BLANKLINE>
    Done.
    """
    out: list[str] = []
    inside = False
    for line in text.splitlines():
        if not inside and line.lstrip().startswith(">>>"):
            out.append("```pycon")
            inside = True
        elif inside and not line.strip():
            out.append("```")
            inside = False
        out.append(line)
    if inside:
        out.append("```")
    return "\n".join(out)


class DoctestFences(griffe.Extension):
    """Fence the examples of every docstring griffe loads."""

    def on_object(self, *, obj: griffe.Object, **kwargs: object) -> None:
        if obj.docstring is not None and ">>>" in obj.docstring.value:
            obj.docstring.value = fence_doctests(obj.docstring.value)

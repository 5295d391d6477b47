"""Write docs/bad_inputs.md: every case of the bad-input table (tests/bad_inputs.py) and the message it gets.

Run from the project root: ``.venv/bin/python docs/tools/bad_inputs_table.py``.  The same list is checked by
tests/test_bad_inputs.py, so the table says what the tools print today.
"""
from __future__ import annotations

import sys
import tempfile
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
# the helpers of tests/ (bad_inputs), after src/: the test folders tests/vjm and tests/linkfea must not
# shadow the packages of the same names
sys.path[:0] = [str(ROOT / "src"), str(ROOT / "tests")]

from bad_inputs import CASES, run  # noqa: E402

HEAD = """# Bad inputs and what they get

Every bad input below was run by `docs/tools/bad_inputs_table.py` (the same list that
`tests/test_bad_inputs.py` checks: exit status 2, exactly one `error:` line on stderr, no traceback,
no phrase said twice, nothing written).  Files a case needs are made in an empty folder first;
`{puu}` is the bundled `data/orthoglide/puu.yaml`.  The column *issue* names the item of the issue the
case comes from.  To add a case: one line in `tests/bad_inputs.py`, then rerun this script.

| # | issue | command | input files | exit | message (stderr) |
|---|---|---|---|---|---|
"""


def _cell(text: str) -> str:
    return text.replace("|", "\\|").replace("\n", " ")


def _text(text: str) -> str:
    """A cell of plain markdown text (not code): brackets escaped, so that ``[+ ox,oy,oz]`` is no link."""
    return _cell(text).replace("[", "\\[").replace("]", "\\]")


def _files(case) -> str:
    if case.note:
        return case.note
    out = []
    enc = case.files.get("encoding", "utf-8")
    for name, text in case.files.items():
        if name == "encoding":
            continue
        lines = text.strip("\ufeff").splitlines()
        head = "<br>".join(f"`{ln[:70]}{'...' if len(ln) > 70 else ''}`" for ln in lines[:4])
        out.append(f"`{name}`{' (' + enc + ')' if enc != 'utf-8' else ''}:<br>{head}{'<br>...' if len(lines) > 4 else ''}")
    out += [f"`{name}` -> `{target}`" for name, target in case.links.items()]
    return "<br>".join(out)


def main() -> int:
    rows = []
    i = 0
    for case in CASES:
        i = case.number or i + 1
        with tempfile.TemporaryDirectory() as d:
            res = run(case, Path(d))
        rows.append(f"| {i} | {case.issue} | `{_cell(case.command)}` | {_cell(_files(case))} | {res.status} | "
                    f"{_text(res.stderr.strip())} |")
    out = ROOT / "docs" / "bad_inputs.md"
    out.write_text(HEAD + "\n".join(rows) + "\n", encoding="utf-8")
    print(f"wrote {out} ({len(rows)} cases)")
    return 0


if __name__ == "__main__":
    sys.exit(main())

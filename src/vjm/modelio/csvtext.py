"""The header lines of the CSV files vjm writes (sim.csv, commands.csv, map.csv): names of joints and frames
taken from a model file, so anything a URDF allows.

Cells are quoted by the CSV rules (a ``,`` or ``"`` in a name stays in its cell, and vjm's readers read it
back), and a name a spreadsheet would run as a formula (a leading ``= + - @``) is written with a ``'`` before
it, as spreadsheets expect; vjm's pose reader drops that ``'`` again
(:func:`vjm.calibration.poses.undefused`).
"""
from __future__ import annotations

import csv
import io

#: the first characters that make a spreadsheet read a cell as a formula
FORMULA = ("=", "+", "-", "@")


def cell(name) -> str:
    """A name as a header cell: a leading ``= + - @`` defused with ``'``."""
    s = str(name)
    return "'" + s if s.startswith(FORMULA) else s


def header(names) -> str:
    """One CSV line (no line end) of the defused, quoted names."""
    buf = io.StringIO()
    csv.writer(buf, lineterminator="").writerow([cell(n) for n in names])
    return buf.getvalue()

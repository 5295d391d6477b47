"""The beam-versus-FEA comparison as typed values that serialise to compare.json.

:class:`Comparison` holds one field per top-level key of compare.json, in the file's order, and
:class:`BeamFit` one per key of an entry of its ``beams`` list; ``to_dict()`` gives the
dictionary that is written, ``from_dict()`` reads it back (``Comparison.from_dict(json.load(f))``).
:class:`ErrorTable` is the error table read from them.  The comparison itself is run by
:mod:`linkfea.beam.compare`.
"""
from __future__ import annotations

import dataclasses
import html
from dataclasses import dataclass, field

import numpy as np

from ..runtime.errors import LinkFeaError
from .report import ERROR_COLUMNS, error_rows, plot_error_vs_n, write_outputs


@dataclass(frozen=True)
class ErrorTable:
    """The errors of every beam model against the FEA, one row per (model, N).

    Errors are fractions (not percent), angles in degrees; ``table["C22"]`` is a column as
    an array, ``table.rows`` the tuples, ``table.to_markdown()`` the table in percent.
    """

    columns: tuple
    rows: tuple

    def __len__(self) -> int:
        return len(self.rows)

    def __getitem__(self, column: str) -> np.ndarray:
        k = self.columns.index(column)
        return np.array([r[k] for r in self.rows])

    def records(self) -> list[dict]:
        return [dict(zip(self.columns, r)) for r in self.rows]

    def _cells(self, row) -> list[str]:
        return [c if isinstance(c, str) else str(c) if isinstance(c, (int, np.integer)) else
                (f"{c:.1f}" if name == "max angle (deg)" else f"{100 * c:+.1f}%")
                for name, c in zip(self.columns, row)]

    def to_markdown(self) -> str:
        lines = ["| " + " | ".join(self.columns) + " |", "|---" * len(self.columns) + "|"]
        lines += ["| " + " | ".join(self._cells(r)) + " |" for r in self.rows]
        return "\n".join(lines) + "\n"

    def __repr__(self) -> str:
        cells = [list(self.columns)] + [self._cells(r) for r in self.rows]
        w = [max(len(row[k]) for row in cells) for k in range(len(self.columns))]
        return "\n".join("  ".join(c.rjust(w[k]) for k, c in enumerate(row)) for row in cells)

    def _repr_html_(self) -> str:
        head = "".join(f"<th>{html.escape(c)}</th>" for c in self.columns)
        body = "".join("<tr>" + "".join(f"<td>{html.escape(c)}</td>" for c in self._cells(r)) + "</tr>"
                       for r in self.rows)
        return f"<table><tr>{head}</tr>{body}</table>"


def _key(f: dataclasses.Field) -> str:
    """The compare.json key of a field (its name unless the field says otherwise)."""
    return f.metadata.get("key", f.name)


@dataclass(frozen=True)
class BeamFit:
    """One N-beam model of the link and its errors against the FEA (an entry of compare.json's ``beams``).

    Matrices are nested lists (6x6, link frame, units of :data:`linkfea.beam.compare.UNITS`); the
    errors are :func:`linkfea.beam.metrics.compare_compliance` of the FEA and this model.
    """

    n: int
    stations: list  # beam-axis stations of the N sections, mm
    sections: list  # the section properties at each station (``Section.to_dict()``)
    compliance_timoshenko: list
    compliance_euler_bernoulli: list
    timoshenko: dict  # errors of the Timoshenko model
    euler_bernoulli: dict  # errors of the Euler-Bernoulli model

    def to_dict(self) -> dict:
        return {f.name: getattr(self, f.name) for f in dataclasses.fields(self)}

    @classmethod
    def from_dict(cls, d: dict) -> "BeamFit":
        return cls(**{f.name: d[f.name] for f in dataclasses.fields(cls)})


@dataclass(frozen=True, eq=False)
class Comparison:
    """Beam models against the FEA compliance of one link (what ``linkfea compare`` writes).

    One field per key of compare.json (``fea_run`` is its ``"fea"``: the FEA compliance and how
    it was computed).  :attr:`errors` is the error table, :meth:`beam` an N-beam compliance,
    :attr:`fea` the FEA one, :meth:`plot` draws the error versus N on a matplotlib Axes,
    :meth:`save` writes compare.json, compare.md and compare.png, :meth:`to_dict` is compare.json.
    """

    link: str
    source: str
    params: dict
    material: dict  # name, E, nu, units
    frame: dict  # the link frame (``Frame.to_dict()``)
    beam_axis: list  # unit vector, link-frame components
    beam_length: float  # mm
    base_station: float  # mm along the beam axis
    tip_station: float
    units: dict
    order: str
    fea_run: dict = field(metadata={"key": "fea"})  # compliance (6x6, link frame) and the run's mesh, mode...
    beams: tuple[BeamFit, ...]
    definitions: dict

    def to_dict(self) -> dict:
        """The compare.json dictionary (keys in the file's order)."""
        return {_key(f): [b.to_dict() for b in self.beams] if f.name == "beams" else getattr(self, f.name)
                for f in dataclasses.fields(self)}

    @classmethod
    def from_dict(cls, d: dict) -> "Comparison":
        """The comparison of a compare.json dictionary."""
        missing = [_key(f) for f in dataclasses.fields(cls) if _key(f) not in d]
        if missing:
            raise LinkFeaError(f"not a comparison record: no {', '.join(missing)}")
        values: dict = {f.name: d[_key(f)] for f in dataclasses.fields(cls)}
        values["beams"] = tuple(BeamFit.from_dict(b) for b in d["beams"])
        return cls(**values)

    @property
    def fea(self) -> np.ndarray:
        """The FEA compliance in the link frame (6x6)."""
        return np.array(self.fea_run["compliance"])

    def beam(self, n: int, theory: str = "timoshenko") -> np.ndarray:
        """The ``n``-beam compliance (``theory`` timoshenko or euler_bernoulli) in the link frame."""
        for m in self.beams:
            if m.n == n:
                return np.array(getattr(m, f"compliance_{theory}"))
        raise LinkFeaError(f"no {n}-beam model in this comparison (N = {[m.n for m in self.beams]})")

    @property
    def errors(self) -> ErrorTable:
        return ErrorTable(ERROR_COLUMNS, tuple(error_rows(self.to_dict())))

    def plot(self, ax=None):
        """Largest principal error (%) of the translation and rotation blocks versus N; returns the Axes."""
        if ax is None:
            import matplotlib.pyplot as plt

            _, ax = plt.subplots(figsize=(5, 3.6))
        return plot_error_vs_n(self.to_dict(), ax)

    def save(self, out_dir, force: bool = False) -> dict:
        """Write compare.json, compare.md and compare.png into ``out_dir`` (one set; see
        :func:`linkfea.beam.report.write_outputs`); their paths by name."""
        return write_outputs(self.to_dict(), out_dir, force=force)

    def __repr__(self) -> str:
        return f"Comparison({self.link!r}, N = {[m.n for m in self.beams]})\n{self.errors!r}"

    def _repr_html_(self) -> str:
        return f"<p><b>{html.escape(self.link)}</b>: beam models vs FEA</p>" + self.errors._repr_html_()

"""The outcome of ``vjm path``: deflection along the path, worst points, pass/fail, compensation.

A :class:`PathResult` is a frozen value: ``summary()`` is the text the CLI
prints, ``table()`` the CSV along the path, ``plot_deflection(ax=)`` and
``plot_plan(ax=)`` draw on matplotlib Axes and return them.
"""
from __future__ import annotations

import csv
import io
from collections.abc import Callable
from dataclasses import dataclass
from typing import IO

import numpy as np

from ..compensation import Compensation
from .points import Toolpath, format_rows
from .uncertainty import Band


@dataclass(frozen=True, eq=False)
class PathResult:
    """Deflection of the TCP along a toolpath.

    toolpath : the programmed path;  wrench : (n, 6) at the TCP (N, N mm), world axes
    deflection : (n, 6) TCP deflection dx dy dz (mm) rx ry rz (rad), world axes
    method : "linear" or "nonlinear";  tolerance : mm or None
    compensation : commanded poses and residual, or None;  band : uncertainty band or None
    after : (n, 6) TCP error of the compensated program from the programmed path at the sampled points
        (first order between the written end points; NaN on rapid moves)
    notes : lines for the summary (assumptions, effects used, warnings)
    compensated : the compensated program: its text, or a function writing it to a text file as it
        goes (a long CSV or G-code program is never held whole as text); ``compensated_text`` gives the
        text either way
    """

    toolpath: Toolpath
    wrench: np.ndarray
    deflection: np.ndarray
    method: str
    tolerance: float | None = None
    compensation: Compensation | None = None
    band: Band | None = None
    after: np.ndarray | None = None
    notes: tuple = ()
    compensated: str | Callable[[IO[str]], None] | None = None

    @property
    def compensated_text(self) -> str | None:
        """The compensated program's text (None without compensation)."""
        if self.compensated is None or isinstance(self.compensated, str):
            return self.compensated
        buf = io.StringIO()
        self.compensated(buf)
        return buf.getvalue()

    def write_compensated(self, fh: IO[str]) -> None:
        """Write the compensated program to the text file ``fh`` (in pieces when it is long)."""
        if isinstance(self.compensated, str):
            fh.write(self.compensated)
        elif self.compensated is not None:
            self.compensated(fh)

    @property
    def error(self) -> np.ndarray:
        """(n,) magnitude of the TCP's translation from the programmed point, mm."""
        return np.linalg.norm(self.deflection[:, :3], axis=1)

    @property
    def passed(self) -> bool | None:
        """Every point within ``tolerance`` (None if no tolerance was given); after compensation when
        there is one, counting the uncertainty band when there is one."""
        if self.tolerance is None:
            return None
        e = self.error if self.after is None else _norm(self.after)
        if self.band is not None:  # what the calibration does not know adds to either
            e = e + self.band.norm
        return bool(np.all(e[np.isfinite(e)] <= self.tolerance))

    def worst(self, k: int = 5) -> list[dict]:
        """The ``k`` points of largest error on distinct source lines: index, line, point, error (mm)."""
        order, seen = [], set()
        for i in np.argsort(-self.error, kind="stable"):
            if int(self.toolpath.lines[i]) not in seen:
                seen.add(int(self.toolpath.lines[i]))
                order.append(i)
                if len(order) == k:
                    break
        return [{"index": int(i), "line": int(self.toolpath.lines[i]),
                 "x": float(self.toolpath.points[i, 0]), "y": float(self.toolpath.points[i, 1]),
                 "z": float(self.toolpath.points[i, 2]), "error_mm": float(self.error[i])} for i in order]

    def summary(self) -> str:
        tp = self.toolpath
        e = self.error
        lines = [f"{tp.source}: {tp.n} points, {tp.arc_length()[-1]:.4g} mm of path; {self.method} deflection "
                 f"of the TCP: max {e.max():.4g} mm, mean {e.mean():.4g} mm"]
        if self.band is not None:
            i = int(np.argmax(e))
            lines.append(f"calibration uncertainty ({self.band.z:.3g} sigma): +-{self.band.norm[i]:.3g} mm at the "
                         f"worst point, up to +-{self.band.norm.max():.3g} mm along the path")
        for w in self.worst(3):
            lines.append(f"  worst: line {w['line']} ({w['x']:.4g}, {w['y']:.4g}, {w['z']:.4g}) "
                         f"{w['error_mm']:.4g} mm")
        if self.compensation is not None:
            c = self.compensation
            lines.append(f"compensated: residual max {c.residual.max():.3g} mm at the written points "
                         f"({c.equilibria + 1} nonlinear equilibria per point)")
            if self.after is not None:
                lines.append(f"compensated program along the cutting moves: max {np.nanmax(_norm(self.after)):.3g} "
                             f"mm from the programmed path")
        lines += list(self.notes)
        if self.tolerance is not None:
            lines.append(f"{'PASS' if self.passed else 'FAIL'}: tolerance {self.tolerance:g} mm"
                         + (" (after compensation)" if self.compensation is not None else "")
                         + (" (with the uncertainty band)" if self.band is not None else ""))
        return "\n".join(lines)

    def table(self) -> str:
        """CSV along the path: line, arc length, programmed point, wrench, deflection, norm [, band, after]."""
        buf = io.StringIO()
        self.write_table(buf)
        return buf.getvalue()

    def write_table(self, fh: IO[str], rows: int = 16384) -> None:
        """Write :meth:`table` to the text file ``fh``, ``rows`` at a time (bounded memory on long paths)."""
        w = csv.writer(fh, lineterminator="\n")
        head = ["line", "s_mm", "x", "y", "z", "Fx", "Fy", "Fz", "Mx", "My", "Mz",
                "dx", "dy", "dz", "rx", "ry", "rz", "error_mm"]
        if self.band is not None:
            head += ["band_mm"]
        if self.after is not None:
            head += ["error_after_mm"]
        w.writerow(head)
        tp, last = self.toolpath, 0.0
        for a in range(0, tp.n, rows):
            b = min(a + rows, tp.n)
            # the arc length as Toolpath.arc_length sums it (in order), piece by piece
            d = np.linalg.norm(np.diff(tp.points[max(a - 1, 0):b], axis=0), axis=1)
            s = np.cumsum(np.concatenate([[last], d]))[1 if a else 0:]
            last = s[-1]
            e = _norm(self.deflection[a:b])
            after = None if self.after is None else _norm(self.after[a:b])
            cols = [tp.lines[a:b], s, tp.points[a:b], self.wrench[a:b], self.deflection[a:b], e]
            fmt = ["%d", "%.6g"] + ["%.6f"] * tp.points.shape[1] + ["%.6g"] * 6 + ["%.6e"] * 7
            if self.band is not None:
                cols.append(self.band.norm[a:b])
                fmt.append("%.3e")
            if after is not None:
                cols.append(after)
                fmt.append("%.3e")
            fh.write(format_rows(fmt, np.column_stack(cols)))

    def plot_deflection(self, ax=None):
        """Deflection magnitude against arc length (before and, if compensated, after), with the band."""
        import matplotlib.pyplot as plt

        if ax is None:
            _, ax = plt.subplots(figsize=(7, 3.5))
        s = self.toolpath.arc_length()
        e = self.error * 1e3
        ax.plot(s, e, lw=1.2, label=f"programmed path ({self.method})")
        if self.band is not None:
            b = self.band.norm * 1e3
            ax.fill_between(s, e - b, e + b, alpha=0.25, lw=0, label=f"+-{self.band.z:.3g} sigma (calibration)")
        if self.after is not None:
            a = _norm(self.after) * 1e3
            ax.plot(s, a, lw=1.2, label=f"compensated program (max {np.nanmax(a):.2g} um)")
        if self.tolerance is not None:
            ax.axhline(self.tolerance * 1e3, color="red", ls="--", lw=1, label="tolerance")
        ax.set_xlabel("arc length [mm]")
        ax.set_ylabel("TCP error [um]")
        ax.set_title(f"{self.toolpath.source}: TCP deflection along the path")
        ax.legend(fontsize=8, loc="best")
        ax.grid(alpha=0.3)
        return ax

    def plot_plan(self, ax=None):
        """The path in plan (x, y), coloured by the error magnitude (um)."""
        import matplotlib.pyplot as plt
        from matplotlib.collections import LineCollection

        if ax is None:
            _, ax = plt.subplots(figsize=(5.5, 4.5))
        p = self.toolpath.points
        seg = np.stack([p[:-1, :2], p[1:, :2]], axis=1)
        e = self.error * 1e3
        lc = LineCollection(list(seg), cmap="viridis", lw=2)
        lc.set_array(0.5 * (e[:-1] + e[1:]))
        ax.add_collection(lc)
        ax.figure.colorbar(lc, ax=ax, label="TCP error [um]")
        ax.set_xlim(p[:, 0].min() - 1, p[:, 0].max() + 1)
        ax.set_ylim(p[:, 1].min() - 1, p[:, 1].max() + 1)
        ax.set_aspect("equal")
        ax.set_xlabel("x [mm]")
        ax.set_ylabel("y [mm]")
        ax.set_title(f"{self.toolpath.source}: error in plan")
        return ax


def _norm(t) -> np.ndarray:
    return np.linalg.norm(np.asarray(t)[:, :3], axis=1)

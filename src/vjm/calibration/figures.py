"""The pictures of an absolute-pose report (report.html): drawn headless (matplotlib's Agg canvas, no pyplot
state) and embedded in the page as base64 PNG, so that report.html is one file that opens anywhere.

- the position error per pose, with the registration only and calibrated (mm, the fitted rows in file order);
- a histogram of those errors;
- each named effect's size: what it does to the tool, mean and largest at the measured poses and at home (mm),
  the effect's and each of its joints' (:mod:`vjm.calibration.sizes`);
- the fitted parameters with their 95 % intervals, one panel per unit.

Each function takes the report's mapping (report.json's) and, for the first two, the rows' errors, and returns
a :class:`matplotlib.figure.Figure`; :func:`figures` gives them all with their captions, :func:`png` the bytes.
"""
from __future__ import annotations

import base64
import io
from collections.abc import Mapping

import numpy as np

Z95 = 1.959963984540054
DPI = 100
BEFORE, AFTER = "tab:red", "tab:blue"


def _figure(w: float, h: float, left: float = 0.8, bottom: float = 0.55, top: float = 0.35, hspace: float = 0.0):
    """A figure of w x h inches on an Agg canvas, its margins in inches (set, not computed by a layout engine:
    that would draw every text twice, a third of the time of a report's pictures)."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    fig = Figure(figsize=(w, h), dpi=DPI)
    FigureCanvasAgg(fig)
    fig.subplots_adjust(left=left / w, right=1.0 - 0.2 / w, bottom=bottom / h, top=1.0 - top / h, hspace=hspace)
    return fig


def _text_inches(labels, size: float) -> float:
    """About how long the longest of ``labels`` is (inches) at font ``size`` (points)."""
    return 0.6 * size / 72.0 * max((len(str(x)) for x in labels), default=0)


def per_pose(before: np.ndarray, after: np.ndarray):
    """The position error of each fitted row (mm), registration only and calibrated."""
    fig = _figure(9.0, 3.2)
    ax = fig.add_subplot()
    x = np.arange(1, len(after) + 1)
    size = 3.0 if len(x) < 2000 else 1.5
    ax.plot(x, before, ".", ms=size, color=BEFORE, label="registration only")
    ax.plot(x, after, ".", ms=size, color=AFTER, label="calibrated")
    ax.set_xlabel("pose (fitted rows, in the file's order)")
    ax.set_ylabel("position error [mm]")
    ax.set_title("error per pose, before and after")
    ax.set_ylim(bottom=0)
    ax.legend(fontsize=8, markerscale=3, loc="upper right")   # "best" would search among every point
    return fig


def histogram(before: np.ndarray, after: np.ndarray):
    """Histograms of the fitted rows' position errors (mm), registration only and calibrated."""
    fig = _figure(6.0, 3.2)
    ax = fig.add_subplot()
    top = float(max(np.max(before, initial=0.0), np.max(after, initial=0.0))) or 1.0
    bins = np.linspace(0.0, top, 41)
    ax.hist(before, bins, histtype="stepfilled", alpha=0.45, color=BEFORE, label="registration only")
    ax.hist(after, bins, histtype="stepfilled", alpha=0.6, color=AFTER, label="calibrated")
    ax.set_xlabel("position error [mm]")
    ax.set_ylabel("poses")
    ax.set_title("histogram of the errors")
    ax.legend(fontsize=8)
    return fig


def _bars(rep: Mapping) -> list:
    """[(label, mean, max, home or nan)] of the named effects' sizes and their parts."""
    out = []
    for e in rep["effects"]:
        s = e.get("size")
        if not s:
            continue
        for part, label in [(s["total"], e["effect"])] + [(p, f"{e['effect']}: {p['name']}") for p in s["parts"]]:
            h = part["home_mm"]
            out.append((label, part["mean_mm"], part["max_mm"], np.nan if h is None else h))
    return out


def contributions(rep: Mapping):
    """Each named effect's size (and its joints'): mean and largest displacement of the tool at the measured
    poses, and at home (mm); None when no effect is named."""
    bars = _bars(rep)
    if not bars:
        return None
    labels = [b[0] for b in bars]
    below = 0.5 * _text_inches(labels, 8) + 0.6   # the labels turned by 30 degrees, then the axis' name
    fig = _figure(max(6.0, 0.55 * len(bars) + 2.5), 2.8 + below, left=0.8, bottom=below)
    ax = fig.add_subplot()
    x = np.arange(len(bars))
    w = 0.27
    for k, (what, colour) in enumerate((("mean at the measured poses", "tab:blue"),
                                        ("largest at the measured poses", "tab:orange"), ("at home", "tab:green"))):
        ax.bar(x + (k - 1) * w, [b[k + 1] for b in bars], w, color=colour, label=what)
    ax.set_xticks(x, labels, rotation=30, ha="right", rotation_mode="anchor", fontsize=8)
    ax.set_xlabel("effect (and its joints)")
    ax.set_ylabel("tool displacement [mm]")
    ax.set_title("what each named effect does to the tool")
    ax.legend(fontsize=8)
    return fig


def parameters(rep: Mapping):
    """The fitted robot or machine parameters with their 95 % intervals (value +- 1.96 std), one panel per
    unit; None when there are none."""
    pars = rep["parameters"]
    units: dict = {}
    for name, p in pars.items():
        units.setdefault(p["unit"], []).append((name, p["value"], p["std"]))
    if not units:
        return None
    n = sum(len(v) for v in units.values())
    left = _text_inches(pars, 7) + 0.65
    h = 1.0 * len(units) + 0.24 * n + 0.8
    k, gap = len(units), 0.65   # inches between panels: the upper one's ticks and axis name
    axes_h = (h - 0.9 - (k - 1) * gap) / k
    fig = _figure(max(7.5, left + 4.0), h, left=left, hspace=gap / axes_h)
    axs = fig.subplots(len(units), 1, squeeze=False, height_ratios=[len(v) + 2 for v in units.values()])[:, 0]
    for ax, (unit, rows) in zip(axs, units.items()):
        y = np.arange(len(rows))[::-1]
        v = np.array([r[1] for r in rows], dtype=float)
        s = np.array([np.nan if r[2] is None else r[2] for r in rows], dtype=float)
        ax.errorbar(v, y, xerr=Z95 * np.nan_to_num(s), fmt="o", ms=5, color="tab:blue", ecolor="tab:blue", elinewidth=2,
                    capsize=4)
        ax.axvline(0.0, color="k", lw=0.6)
        ax.locator_params(axis="x", nbins=5)   # long tick labels (1e-4 rad) side by side
        ax.set_yticks(y, [r[0] for r in rows], fontsize=7)
        ax.set_xlabel(f"value [{unit}], 95 % interval")
        ax.set_ylabel("parameter")
    axs[0].set_title("fitted parameters")
    return fig


def figures(rep: Mapping, before=None, after=None) -> list:
    """[(caption, figure)] of a report: the errors per pose and their histogram (with the rows' errors
    ``before`` and ``after``), the effects' sizes and the parameters (those that have something to show)."""
    out = []
    if before is not None and after is not None and len(after):
        out += [("Position error per pose, registration only and calibrated (mm)", per_pose(before, after)),
                ("Histogram of the position errors (mm)", histogram(before, after))]
    for caption, fig in (("What each named effect does to the tool (mm): mean and largest at the measured poses, "
                          "and at home", contributions(rep)),
                         ("Fitted parameters with their 95 % intervals", parameters(rep))):
        if fig is not None:
            out.append((caption, fig))
    return out


def png(fig) -> bytes:
    """The figure as PNG bytes (at :data:`DPI`)."""
    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=DPI)
    return buf.getvalue()


def embedded(rep: Mapping, before=None, after=None) -> list:
    """[(caption, base64 PNG text)] of :func:`figures`."""
    return [(caption, base64.b64encode(png(fig)).decode("ascii")) for caption, fig in figures(rep, before, after)]

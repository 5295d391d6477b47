"""Rendering of a beam-versus-FEA comparison record: Markdown, PNG and the output folder.

The report over all bundled links, ``docs/beam_vs_fea.md``, is made by ``docs/tools/beam_vs_fea_report.py``.
"""
from __future__ import annotations

import io
import itertools
import json
from pathlib import Path

import numpy as np

LABELS = ("x", "y", "z", "rx", "ry", "rz")


def markdown_table(record: dict) -> str:
    """The comparison as Markdown: one row per model, errors in percent."""
    lines = [f"### {record['link']}: beam models vs FEA", "",
             f"Beam length {record['beam_length']:.1f} mm along the link x axis; material "
             f"{record['material']['name']} (E = {record['material']['E']:g} MPa, nu = {record['material']['nu']:g}). "
             "Errors in % (signed entry errors relative to sqrt(Cii Cjj) of the FEA; principal errors on the "
             "translational / rotational 3x3 blocks).", "",
             "| model | N | max principal err | transl. | rot. | max angle (deg) | "
             + " | ".join(f"C{i}{i}" for i in range(1, 7)) + " | C26 | C35 | max coupling |",
             "|---|---:|---:|---:|---:|---:|" + "---:|" * 9]
    for m in record["beams"]:
        for key, name in (("euler_bernoulli", "Euler-Bernoulli"), ("timoshenko", "Timoshenko")):
            r = m[key]
            s = r["summary"]
            d = r["diagonal_error"]
            c = r["coupling_error"]
            lines.append(
                f"| {name} | {m['n']} | {100 * s['max_principal_error']:.1f} | "
                f"{100 * s['max_principal_error_translation']:.1f} | {100 * s['max_principal_error_rotation']:.1f} | "
                f"{s['max_angle_deg']:.1f} | " + " | ".join(f"{100 * v:+.1f}" for v in d)
                + f" | {100 * c['C26 (dy-Mz)']:+.1f} | {100 * c['C35 (dz-My)']:+.1f} | "
                f"{100 * s['max_abs_coupling_error']:.1f} |")
    return "\n".join(lines) + "\n"


def figure_png(record: dict) -> bytes:
    """PNG: heatmaps of the signed Timoshenko entry errors for each N, and error versus N."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    models = record["beams"]
    k = len(models)
    fig, axs = plt.subplots(1, k + 1, figsize=(3.2 * k + 4.2, 3.6), gridspec_kw={"width_ratios": [1] * k + [1.3]})
    im = None
    # One colour scale for all N, from 5 % to 100 %, so that small errors stay visible.
    vmax = float(np.clip(max(100.0 * np.max(np.abs(m["timoshenko"]["entry_error"])) for m in models), 5.0, 100.0))
    fmt = "{:.1f}" if vmax < 20 else "{:.0f}"
    for ax, m in zip(axs[:k], models):
        E = 100.0 * np.array(m["timoshenko"]["entry_error"])
        im = ax.imshow(np.clip(E, -vmax, vmax), cmap="RdBu_r", vmin=-vmax, vmax=vmax)
        for i, j in itertools.product(range(6), range(6)):
            ax.text(j, i, fmt.format(E[i, j] + 0.0), ha="center", va="center", fontsize=6)
        ax.set_xticks(range(6), LABELS, fontsize=7)
        ax.set_yticks(range(6), LABELS, fontsize=7)
        ax.set_title(f"N = {m['n']} (Timoshenko)", fontsize=9)
    fig.colorbar(im, ax=list(axs[:k]), shrink=0.8, label="entry error, % of sqrt(Cii Cjj)")
    plot_error_vs_n(record, axs[k])
    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=110, bbox_inches="tight")
    plt.close(fig)
    return buf.getvalue()


def plot_error_vs_n(record: dict, ax):
    """Largest principal compliance error (%) of the translation and rotation blocks versus N, on ``ax``."""
    models = record["beams"]
    ns = [m["n"] for m in models]
    # Log scale: errors of a few % and of several hundred % occur on the same link.  Floor at 0.01 %
    # so that an exact model (error 0) still plots.
    for key, style, nm in (("timoshenko", "-o", "Timoshenko"), ("euler_bernoulli", "--s", "Euler-Bernoulli")):
        for blk in ("translation", "rotation"):
            ax.plot(ns, [max(100 * m[key]["summary"][f"max_principal_error_{blk}"], 1e-2) for m in models], style,
                    label=f"{blk}, {nm}")
    ax.set_xscale("log", base=2)
    ax.set_yscale("log")
    ax.set_xticks(ns, [str(n) for n in ns])
    ax.set_xlabel("N beams")
    ax.set_ylabel("max principal compliance error, %")
    ax.grid(True, alpha=0.3)
    ax.legend(fontsize=6)
    ax.set_title(record["link"], fontsize=9)
    return ax


ERROR_COLUMNS = ("model", "N", "max principal", "translation", "rotation", "max angle (deg)", "C11", "C22", "C33",
                 "C44", "C55", "C66", "C26", "C35", "max coupling")


def error_rows(record: dict) -> list[tuple]:
    """One row per beam model and N: the columns :data:`ERROR_COLUMNS`, errors as fractions (angles in deg)."""
    rows = []
    for m in record["beams"]:
        for key, name in (("euler_bernoulli", "Euler-Bernoulli"), ("timoshenko", "Timoshenko")):
            r = m[key]
            s, c = r["summary"], r["coupling_error"]
            rows.append((name, int(m["n"]), s["max_principal_error"], s["max_principal_error_translation"],
                         s["max_principal_error_rotation"], s["max_angle_deg"], *r["diagonal_error"],
                         c["C26 (dy-Mz)"], c["C35 (dz-My)"], s["max_abs_coupling_error"]))
    return rows


COMPARE_FILES = ("compare.json", "compare.md", "compare.png")


def write_outputs(record: dict, out_dir, force: bool = False) -> dict:
    """Write compare.json, compare.md and compare.png into ``out_dir`` as one set (:mod:`linkfea.files.outputs`).

    Everything is rendered in memory first; the folder then holds the three new files or the
    old ones, and files of other origin in it are refused (or, with ``force``, left alone).
    """
    from ..files.outputs import OutputSet, check_folder

    check_folder(out_dir, COMPARE_FILES, force=force)
    blobs = {
        "compare.json": json.dumps(record, indent=1, allow_nan=False).encode(),
        "compare.md": markdown_table(record).encode(),
        "compare.png": figure_png(record),
    }
    with OutputSet(out_dir, "linkfea compare") as s:
        for name, data in blobs.items():
            Path(s.path(name)).write_bytes(data)
    return {name: str(Path(out_dir) / name) for name in blobs}

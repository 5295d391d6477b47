"""The sweep's picture: compliance entries against each swept parameter."""
from __future__ import annotations

from typing import Sequence

from ..mechanics.compliance import TWIST, WRENCH
from ..runtime.errors import LinkFeaError

#: compliance columns of the table: C_<twist>_<wrench>, t = C w
C_COLUMNS = [f"C_{t}_{w}" for t in TWIST for w in WRENCH]
DIAGONAL = [f"{t}_{w}" for t, w in zip(TWIST, WRENCH)]


def check_entries(entries) -> None:
    bad = [e for e in entries if f"C_{e}" not in C_COLUMNS]
    if bad:
        raise LinkFeaError(f"--plot: unknown compliance entries {bad}; use twist_wrench such as dy_Fy or rz_Fy")


def plot_sweep(rows: list[dict], names: Sequence[str], entries: Sequence[str], path) -> None:
    """Compliance entries (rows of panels) against each swept parameter (columns).

    Points that share the other parameters' values are joined, so a grid shows one curve per
    combination of the other parameters; word-valued parameters are categorical axes.
    """
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    check_entries(entries)
    ok = [r for r in rows if r["status"] == "ok"]
    names = list(names) or ["index"]
    fig, axes = plt.subplots(len(entries), len(names), figsize=(3.6 * len(names) + 0.8, 2.4 * len(entries) + 0.6),
                             squeeze=False)
    for j, nm in enumerate(names):
        col = "index" if nm == "index" else f"param_{nm}"
        vals = [r[col] for r in ok]
        cats = sorted({v for v in vals if isinstance(v, str)})
        x_of = cats.index if cats else float
        others = [f"param_{n}" for n in names if n != nm and nm != "index"]
        groups: dict = {}
        for r in ok:
            groups.setdefault(tuple(r[o] for o in others), []).append(r)
        for i, e in enumerate(entries):
            ax = axes[i, j]
            for label, g in groups.items():
                g = sorted(g, key=lambda r: x_of(r[col]))
                ax.plot([x_of(r[col]) for r in g], [r[f"C_{e}"] for r in g], "o-", ms=3, lw=0.8,
                        label=", ".join(f"{o[6:]}={v}" for o, v in zip(others, label)))
            if i == 0 and others and 1 < len(groups) <= 8:
                ax.legend(fontsize=6)
            ys = [r[f"C_{e}"] for r in ok if r[f"C_{e}"] is not None and r[f"C_{e}"] > 0]
            if ys and max(ys) > 10 * min(ys):
                ax.set_yscale("log")
            if cats:
                ax.set_xticks(range(len(cats)), cats)
            unit = _unit(e)
            ax.set_ylabel(f"C {e} ({unit})", fontsize=8)
            ax.tick_params(labelsize=7)
            if i == len(entries) - 1:
                ax.set_xlabel(nm, fontsize=8)
    if not ok:
        fig.text(0.5, 0.5, "no successful design", ha="center")
    fig.suptitle(f"compliance in the link frame, {len(ok)} of {len(rows)} designs", fontsize=9)
    fig.tight_layout()
    fig.savefig(path, dpi=110, format="png")
    plt.close(fig)


def _unit(entry: str) -> str:
    t, w = entry.split("_")
    return {("d", "F"): "mm/N", ("r", "M"): "rad/(N mm)", ("d", "M"): "1/N", ("r", "F"): "rad/N"}[(t[0], w[0])]

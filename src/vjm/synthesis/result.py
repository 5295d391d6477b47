"""What ``vjm design`` answers: :class:`DesignResult` (typed, frozen) and the files it writes.

``DIR/design.json`` (schema ``vjm.design/1``) holds the optimum's ``parameters`` ({link: {param:
value}}), ``moving_mass_kg``, ``k_tran_max`` (mm/N) and ``k_rot_max`` (rad/(N mm)) over the grid,
each constraint's value, FEA error bar (the value with every link at the top of its bar, minus the
nominal value) and slack (limit - value, positive when met), ``feasible``, ``message``,
``fea_runs`` (link designs the search used, from the cache or computed), ``fea_computed`` (computed
by this run) and ``history`` (every link design in evaluation order).  Beside it: ``convergence.png``
(the incumbent's mass and first constraint against the runs), ``report.html``, and the optimum's
links: ``optimum_<link>.json`` (the FEA result; a beam's closed-form compliance) and, for a CAD link,
``optimum_<link>.step`` ready for the CAD system.  With targets: ``front.csv`` and ``front.png``.
All are one output set: the new ones or the old ones, never a mix.
"""
from __future__ import annotations

import base64
import html
import json
from dataclasses import dataclass, field
from pathlib import Path

from .spec import UNITS

#: what ``vjm design`` writes (``links/`` holds the FEA cache: one ``linkfea sweep`` folder per link)
DESIGN_FILES = ("design.json", "convergence.png", "report.html", "front.csv", "front.png", "links/")


@dataclass(frozen=True)
class ConstraintValue:
    """One constraint at the reported design: value, FEA error bar and slack, in ``units``."""

    quantity: str
    limit: float
    value: float
    error_bar: float
    slack: float
    units: str
    poses: tuple | None = None

    @property
    def met(self) -> bool:
        return self.slack >= 0


@dataclass(frozen=True)
class DesignResult:
    """The verified optimum (or, when none is feasible, the design nearest to it) and how it was found."""

    feasible: bool
    message: str
    parameters: dict
    moving_mass_kg: float
    k_tran_max: float
    k_rot_max: float
    constraints: tuple
    fea_runs: int
    fea_computed: int
    budget: int
    stop: str
    active_bounds: tuple
    history: tuple
    rounds: tuple
    front: tuple = ()
    conservative: bool = False
    spec: str = ""
    machine: str = ""
    optimum: dict = field(default_factory=dict)   # link -> {"kind", "result" (path) or "beam" ...}

    def to_dict(self) -> dict:
        from linkfea.files.atomic import plain

        return plain({"schema": "vjm.design/1", "spec": self.spec, "machine": self.machine,
                      "feasible": self.feasible, "message": self.message, "parameters": self.parameters,
                      "moving_mass_kg": self.moving_mass_kg, "k_tran_max": self.k_tran_max,
                      "k_rot_max": self.k_rot_max,
                      "constraints": [vars(c) for c in self.constraints], "conservative": self.conservative,
                      "fea_runs": self.fea_runs, "fea_computed": self.fea_computed, "budget": self.budget,
                      "stop": self.stop, "active_bounds": list(self.active_bounds),
                      "history": list(self.history), "rounds": list(self.rounds), "front": list(self.front),
                      "units": {"moving_mass_kg": "kg (the free links, counted as vjm sweep counts them)",
                                "k_tran_max": "mm/N", "k_rot_max": "rad/(N mm)", **UNITS,
                                "params": "mm for dimensions (as the scripts take them)"}})

    def summary(self) -> str:
        lines = [self.message]
        for link, p in self.parameters.items():
            lines.append(f"  {link}: " + ", ".join(f"{k}={_fmt(v)}" for k, v in p.items()))
        for c in self.constraints:
            lines.append(f"  {c.quantity}{'' if c.poses is None else ' at poses'} = {c.value:.4g} +{c.error_bar:.2g} "
                         f"(limit {c.limit:g} {c.units}, slack {c.slack:.3g})")
        lines.append(f"  {self.fea_runs} runs of {self.budget} ({self.fea_computed} computed now); {self.stop}")
        return "\n".join(lines)

    def __repr__(self) -> str:
        return (f"DesignResult({'feasible' if self.feasible else 'infeasible'}, {self.moving_mass_kg:.4g} kg, "
                f"k_tran_max {self.k_tran_max:.4g} mm/N, {self.fea_runs} runs)")

    def _repr_html_(self) -> str:
        return _html(self, [])

    def save(self, out, force: bool = False, files: dict | None = None) -> Path:
        """Write ``design.json``, the pictures, ``report.html`` and the optimum's links under ``out``."""
        return write(self, out, force, files or {})


def _fmt(v) -> str:
    return f"{v:.4g}" if isinstance(v, float) else str(v)


def _figure(w: float, h: float):
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    fig = Figure(figsize=(w, h), dpi=100)
    FigureCanvasAgg(fig)
    return fig


def convergence_png(res: DesignResult) -> bytes:
    """The incumbent's mass and first constraint's value against the runs."""
    fig = _figure(6.4, 4.6)
    ax1, ax2 = fig.subplots(2, 1, sharex=True)
    runs = [r["runs"] for r in res.rounds]
    ax1.step(runs, [r["mass_kg"] for r in res.rounds], where="post", color="C0")
    ax1.scatter(runs, [r["mass_kg"] for r in res.rounds], c=["C0" if r["feasible"] else "C3" for r in res.rounds],
                s=16, zorder=3)
    ax1.set_ylabel("incumbent mass (kg)")
    if not all(r["feasible"] for r in res.rounds):
        ax1.set_title("red: no feasible design yet (the one nearest to feasible)", fontsize=8)
    c = res.constraints[0]
    key = c.quantity + ("" if c.poses is None else f" at {len(c.poses)} poses")
    ax2.step(runs, [r.get(key, float("nan")) for r in res.rounds], where="post", color="C1")
    ax2.axhline(c.limit, color="0.4", ls="--", lw=1, label=f"limit {c.limit:g}")
    ax2.set_ylabel(f"{c.quantity} ({c.units})")
    ax2.set_xlabel("runs (link designs evaluated)")
    from matplotlib.ticker import MaxNLocator

    ax2.xaxis.set_major_locator(MaxNLocator(integer=True))
    ax2.legend(fontsize=8)
    fig.tight_layout()
    return _png(fig)


def front_png(res: DesignResult) -> bytes:
    fig = _figure(6.0, 4.2)
    ax = fig.subplots()
    ok = [r for r in res.front if r["feasible"]]
    ax.plot([r["moving_mass_kg"] for r in ok], [r["k_tran_max"] for r in ok], "o-", color="C3", label="verified optimum")
    for r in res.front:
        ax.axhline(r["target"], color="0.8", lw=0.8)
    bad = [r for r in res.front if not r["feasible"]]
    if bad:
        ax.scatter([r["moving_mass_kg"] for r in bad], [r["k_tran_max"] for r in bad], marker="x", c="0.3",
                   label="target not reached (stiffest found)")
    ax.set_xlabel("moving mass of the free links (kg)")
    ax.set_ylabel("worst-case k_tran over the workspace (mm/N)")
    ax.legend(fontsize=8)
    fig.tight_layout()
    return _png(fig)


def _png(fig) -> bytes:
    from ..calibration.figures import png

    return png(fig)


def _html(res: DesignResult, pictures: list) -> str:
    e = html.escape
    rows = "".join(f"<tr><td>{e(link)}</td><td>{e(k)}</td><td>{e(_fmt(v))}</td></tr>"
                   for link, p in res.parameters.items() for k, v in p.items())
    cons = "".join(f"<tr><td>{e(c.quantity)}{'' if c.poses is None else ' (poses)'}</td><td>{c.value:.4g}</td>"
                   f"<td>+{c.error_bar:.2g}</td><td>{c.limit:g}</td><td>{c.slack:.3g}</td><td>{e(c.units)}</td></tr>"
                   for c in res.constraints)
    figs = "".join(f'<figure><img src="data:image/png;base64,{base64.b64encode(p).decode("ascii")}" '
                   f'alt="{e(cap)}"><figcaption>{e(cap)}</figcaption></figure>' for cap, p in pictures)
    return (f"<!doctype html><html><head><meta charset='utf-8'><title>vjm design</title></head><body>"
            f"<h1>vjm design</h1><p>{e(res.message)}</p>"
            f"<p>moving mass {res.moving_mass_kg:.4g} kg; {res.fea_runs} runs of a budget of {res.budget} "
            f"({res.fea_computed} computed by this run); {e(res.stop)}</p>"
            f"<h2>Parameters</h2><table><tr><th>link</th><th>parameter</th><th>value</th></tr>{rows}</table>"
            f"<h2>Constraints</h2><table><tr><th>quantity</th><th>value (FEA)</th><th>FEA error bar</th>"
            f"<th>limit</th><th>slack</th><th>units</th></tr>{cons}</table>{figs}</body></html>")


def write(res: DesignResult, out, force: bool, files: dict) -> Path:
    """The output set; ``files`` maps extra member names (``optimum_foot.json`` ...) to writers ``f(path)``."""
    from linkfea.files.outputs import OutputSet, check_folder

    out = Path(out)
    check_folder(out, list(DESIGN_FILES) + list(files), force=force)
    conv = convergence_png(res)
    pictures = [("the incumbent against the runs", conv)]
    front = front_png(res) if res.front else None
    if front is not None:
        pictures.append(("the mass-stiffness front", front))
    with OutputSet(out, "vjm design") as s:  # a run without targets drops the last run's front files
        Path(s.path("design.json")).write_text(json.dumps(res.to_dict(), indent=1) + "\n", encoding="utf-8")
        Path(s.path("convergence.png")).write_bytes(conv)
        Path(s.path("report.html")).write_text(_html(res, pictures), encoding="utf-8")
        if front is not None:
            Path(s.path("front.png")).write_bytes(front)
            cols = ["target", "feasible", "moving_mass_kg", "k_tran_max", "k_rot_max", "runs", "parameters"]
            lines = [",".join(cols)] + [",".join(_csv(r[c]) for c in cols) for r in res.front]
            Path(s.path("front.csv")).write_text("\n".join(lines) + "\n", encoding="utf-8")
        for name, writer in files.items():
            writer(s.path(name))
    return out / "design.json"


def _csv(v) -> str:
    if isinstance(v, dict):
        text = json.dumps(v, sort_keys=True)
        return '"' + text.replace('"', '""') + '"'
    return _fmt(v) if isinstance(v, float) else str(v)

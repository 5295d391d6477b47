"""Machine-level trade-offs: link designs from ``linkfea sweep`` combined in one machine model.

For each combination of link designs (one foot design x one leg design ...),
the model's links are replaced by the designs' compliances and one batched
:meth:`vjm.model.machine.ParallelModel.stiffness_map` over the reachable points of an N x N x N
grid of the workspace box gives the worst-case (largest) and mean ``k_tran``
(mm/N) and ``k_rot`` (rad/(N mm)): both are compliances, smaller is stiffer.
The moving mass is the mass of the swept links that move: every chain's foot
(carried by its carriage, or the Delta's arm) and its leg (two bars for a
parallelogram leg); links taken from the model file are not counted (their mass
is the same in every combination, so the Pareto set does not depend on it).

The non-dominated combinations minimise both the moving mass and the worst
k_tran: no other combination is at least as light and at least as stiff, and
strictly better in one.
"""
from __future__ import annotations

import itertools
import json
import os
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from linkfea.files.atomic import plain
from linkfea.files.outputs import OutputSet, check_folder
from linkfea.runtime.checks import integer
from linkfea.runtime.progress import Progress

from ..errors import ArgumentError, VjmError
from ..maps.compute import GRID
from ..maps.grid import SECONDS_PER_POINT, SWEEP_BYTES, grid_plan, in_chunks, plan
from ..model.links import LinkSpring
from ..model.machine import ParallelModel

ROLES = ("foot", "leg")


@dataclass(frozen=True, eq=False)
class LinkDesign:
    """One link design: its 6x6 compliance (spring frame, mm/N, rad/(N mm)), mass (kg) and origin."""

    label: str
    compliance: np.ndarray
    mass: float
    params: dict = field(default_factory=dict)
    source: str = ""


def legs_bars(model: ParallelModel) -> int:
    """Bars per leg, as the architecture declares: 2 for a parallelogram leg (each the ``leg`` design), else 1."""
    return model.arch.leg_bars


def _design_from_result(path: Path, label: str, params: dict, role: str) -> LinkDesign:
    from linkfea.result.schema import read_result

    doc = read_result(path)  # validated: finite, symmetric, positive definite 6x6
    mass = doc.get("mass_kg")
    if not (isinstance(mass, (int, float)) and np.isfinite(mass) and mass > 0):
        raise VjmError(f"--{role}: {path} has no link mass; recompute it with a linkfea that writes 'mass_kg' "
                       "(and a material with a density)")
    return LinkDesign(label, np.asarray(doc["compliance"], dtype=float), float(mass), params, str(path))


def load_designs(path, role: str = "leg") -> list[LinkDesign]:
    """The link designs of a ``linkfea sweep`` folder (its ``ok`` rows, table order) or of one result JSON."""
    p = Path(path)
    if p.is_dir():
        table = p / "sweep.parquet"
        if not table.is_file():
            raise VjmError(f"--{role}: {p} is a folder without sweep.parquet (not a `linkfea sweep` output)")
        import pyarrow.parquet as pq

        rows = [r for r in pq.read_table(table).to_pylist() if r.get("status") == "ok"]
        if not rows:
            raise VjmError(f"--{role}: the sweep in {p} has no successful design")
        return [_design_from_result(p / "results" / f"{r['key']}.json", r["key"],
                                    {k[len("param_"):]: v for k, v in r.items() if k.startswith("param_")}, role)
                for r in rows]
    if not p.is_file():
        raise VjmError(f"--{role}: {p} not found (a linkfea result JSON or a `linkfea sweep` folder)")
    return [_design_from_result(p, p.stem, {}, role)]


def workspace_points(model: ParallelModel, n: int) -> np.ndarray:
    """The reachable points (m, 3) of an n x n x n grid of the model's workspace box (:meth:`Model.grid`), mm."""
    n = integer(n, "grid", GRID, ArgumentError)
    grid_plan(n, None, "the workspace grid of a machine sweep", SWEEP_BYTES, hint="use a coarser grid")
    P = model.grid(n).points
    ok = model.reachable(P)
    if not ok.any():
        raise VjmError(f"no point of the {n}-point workspace grid is reachable by {model.architecture}")
    return P[ok]


def with_designs(model: ParallelModel, designs: dict) -> ParallelModel:
    """``model`` with its links replaced by ``designs`` (role -> LinkDesign)."""
    return model.replace(**{role: LinkSpring(d.compliance, {"linkfea": d.source}) for role, d in designs.items()})


def moving_mass(model: ParallelModel, designs: dict) -> float:
    """kg: per chain, the swept foot and the swept leg's bars (links from the model file are not counted)."""
    per_chain = sum(d.mass * (legs_bars(model) if role == "leg" else 1) for role, d in designs.items())
    return len(model.chains) * per_chain


def evaluate(model: ParallelModel, designs: dict, P: np.ndarray) -> dict:
    """Worst-case and mean k_tran, k_rot over the points P and the moving mass of one combination."""
    r = with_designs(model, designs).stiffness_map(P)
    return {"k_tran_max": float(np.max(r.k_tran)), "k_tran_mean": float(np.mean(r.k_tran)),
            "k_rot_max": float(np.max(r.k_rot)), "k_rot_mean": float(np.mean(r.k_rot)),
            "moving_mass_kg": moving_mass(model, designs), "n_points": int(len(P))}


def pareto_mask(mass, worst) -> np.ndarray:
    """Non-dominated points when minimising both ``mass`` and ``worst``.

    A point is dominated if another is <= in both and < in one.  Sorted by mass
    then worst, a point is kept iff its worst beats every lighter-or-equal point
    kept so far (equal duplicates of a kept point are kept too): O(n log n).

    >>> pareto_mask([1, 2, 3, 2], [3, 1, 2, 2]).tolist()
    [True, True, False, False]
    """
    mass, worst = np.asarray(mass, dtype=float), np.asarray(worst, dtype=float)
    keep = np.zeros(len(mass), dtype=bool)
    best, last = np.inf, None
    for i in np.lexsort((worst, mass)):
        if worst[i] < best:
            keep[i], best, last = True, worst[i], (mass[i], worst[i])
        elif last is not None and (mass[i], worst[i]) == last:
            keep[i] = True
    return keep


@dataclass
class TradeOffs:
    """One row per combination (table order: the product of the roles' design lists) and the Pareto mask."""

    rows: list
    pareto: np.ndarray
    n_points: int
    model: str


def trade_offs(model: ParallelModel, candidates: dict, grid: int, progress: Progress | None = None) -> TradeOffs:
    """Evaluate every combination of ``candidates`` (role -> list of LinkDesign) on the workspace grid.

    The work (combinations x reachable points) is estimated first; a run longer than about a
    minute says so and reports its progress through ``progress``.
    """
    if not candidates:
        raise VjmError("give link designs for at least one of the roles foot, leg")
    P = workspace_points(model, grid)
    roles = [r for r in ROLES if r in candidates]
    combos = list(itertools.product(*(candidates[r] for r in roles)))
    p = plan(f"{len(combos)} combinations on {len(P)} points", len(P), SWEEP_BYTES,
             SECONDS_PER_POINT * len(combos), hint="use a coarser grid")
    if p.long and progress is not None:
        progress(f"{p.describe()}; progress follows")
    rows: list = []

    def step(s: slice) -> None:
        for combo in combos[s]:
            rows.append(_row(model, dict(zip(roles, combo)), P))

    in_chunks(len(combos), step, progress, "combinations", chunk=1)
    mask = pareto_mask([r["moving_mass_kg"] for r in rows], [r["k_tran_max"] for r in rows])
    for r, m in zip(rows, mask):
        r["pareto"] = bool(m)
    return TradeOffs(rows, mask, len(P), model.architecture)


#: the files `vjm sweep` writes, one set
SWEEP_FILES = ("tradeoffs.parquet", "tradeoffs.csv", "pareto.csv", "pareto.json", "pareto.png")
def _row(model: ParallelModel, designs: dict, P: np.ndarray) -> dict:
    """One table row: the designs' labels, parameters and masses, and their machine's stiffness over P."""
    row = {}
    for role, d in designs.items():
        row[f"{role}"] = d.label
        row.update({f"{role}_{k}": v for k, v in d.params.items()})
        row[f"{role}_mass_kg"] = d.mass
    row.update(evaluate(model, designs, P))
    row.update({f"{role}_result": d.source for role, d in designs.items()})
    return row


UNITS = {"k_tran_*": "mm/N (largest eigenvalue of the translational 3x3 block of C)",
         "k_rot_*": "rad/(N*mm) (largest eigenvalue of the rotational block)",
         "*_mass_kg": "kg", "moving_mass_kg": "kg, the swept links of all chains (parallelogram: 2 bars per leg)",
         "max/mean": "over the reachable points of the --grid workspace grid"}


def write_trade_offs(res: TradeOffs, out, force: bool = False) -> list[Path]:
    """``tradeoffs.csv``, ``tradeoffs.parquet``, ``pareto.csv``, ``pareto.json``, ``pareto.png`` under ``out``,
    as one set (:mod:`linkfea.files.outputs`); ``force`` writes beside files of other origin."""
    import pyarrow as pa
    import pyarrow.csv as pacsv
    import pyarrow.parquet as pq

    out = Path(out)
    cols = list(res.rows[0])
    meta = {"schema": "vjm.sweep/1", "architecture": res.model, "n_points": res.n_points, "units": UNITS}

    def table(rows):
        t = pa.table({c: pa.array([r.get(c) for r in rows]) for c in cols})
        return t.replace_schema_metadata({"vjm.sweep.combine": json.dumps(meta)})

    front = [r for r in res.rows if r["pareto"]]
    front.sort(key=lambda r: r["moving_mass_kg"])
    check_folder(out, SWEEP_FILES, force=force)
    with OutputSet(out, "vjm sweep") as s:  # one set: all five from this run, or the old ones
        t = [s.path(n) for n in SWEEP_FILES]
        pq.write_table(table(res.rows), t[0])
        pacsv.write_csv(table(res.rows), t[1])
        pacsv.write_csv(table(front), t[2])
        Path(t[3]).write_text(json.dumps(plain({**meta, "pareto": front}), indent=1) + "\n", encoding="utf-8")
        plot_pareto(res, t[4])
    return [out / n for n in SWEEP_FILES]


def plot_pareto(res: TradeOffs, path) -> None:
    """Moving mass against worst-case k_tran, every combination and the non-dominated front."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    m = np.array([r["moving_mass_kg"] for r in res.rows])
    k = np.array([r["k_tran_max"] for r in res.rows])
    fig, ax = plt.subplots(figsize=(6, 4.2))
    ax.scatter(m, k, s=14, c="0.6", label=f"{len(m)} combinations")
    o = np.flatnonzero(res.pareto)
    o = o[np.argsort(m[o])]
    ax.step(m[o], k[o], where="post", color="C3", lw=1)
    ax.scatter(m[o], k[o], s=22, c="C3", label=f"non-dominated ({len(o)})", zorder=3)
    ax.set_xlabel("moving mass of the swept links (kg)")
    ax.set_ylabel("worst-case k_tran over the workspace (mm/N)")
    ax.set_title(f"{res.model}: {res.n_points} reachable grid points", fontsize=9)
    ax.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(path, dpi=110, format="png")
    plt.close(fig)


def candidates_from_args(model: ParallelModel, foot=None, leg=None, bar=None) -> dict:
    """role -> designs from the ``--foot``, ``--leg``, ``--bar`` paths (``--bar`` is the leg of a parallelogram)."""
    if bar is not None:
        if leg is not None:
            raise VjmError("give --leg or --bar, not both (--bar is the parallelogram leg's bar)")
        if legs_bars(model) != 2:
            raise VjmError(f"--bar is for parallelogram legs; {model.architecture} has a one-piece leg: use --leg")
        leg = bar
    return {role: load_designs(p, role) for role, p in (("foot", foot), ("leg", leg)) if p is not None}


def sweep(model_path, out, grid: int, foot=None, leg=None, bar=None, force: bool = False,
          progress: Progress | None = None) -> TradeOffs:
    """``vjm sweep``: check the output folder, load the model and the designs, evaluate all combinations,
    write the outputs."""
    grid = integer(grid, "grid", GRID, ArgumentError)
    from ..modelio.read import load_model

    check_folder(out, SWEEP_FILES, force=force)
    model = load_model(os.fspath(model_path))
    model.require("parallel", "vjm sweep")
    assert isinstance(model, ParallelModel)  # (for the type checker: require raised otherwise)
    res = trade_offs(model, candidates_from_args(model, foot, leg, bar), grid, progress)
    write_trade_offs(res, out, force=force)
    return res

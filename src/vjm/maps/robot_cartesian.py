"""Stiffness maps of a serial or tree robot over a Cartesian grid of tool points, through the IK.

Each grid point is a tool pose (the point, one orientation for the whole grid) solved by the damped
least squares of :mod:`vjm.robot.ik`.  The configuration of the seed is carried over the grid: the
first line of the grid is solved point after point (:func:`vjm.robot.ik.solve_path`), and every
further line starts each point from its neighbour's solution on the line before (all points of a
line in one batched solve), so that a smooth part of the workspace stays on the seed's branch
(elbow up or down, wrist flip).  A point is *unreachable* when the IK's residual stays above its
tolerance (out of reach, or the joint limits in the way) and *singular* when the tool Jacobian is
(next to) rank deficient there; both are masked (NaN) in the maps and counted.

The default box is the tool's reach: the bounding box of the tool points over random
configurations within the joint limits (a fixed random seed: the same box every run).
A :class:`CartesianMap` is a map result like :class:`vjm.maps.compute.StiffnessMap`: ``save(dir)`` (the set
``vjm map`` writes for a robot, :mod:`vjm.maps.robot_output`), ``plot``, ``summary`` and ``_repr_html_``.
"""
from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..errors import VjmError
from ..robot.ik import IKResult, pose_targets, solve
from . import robot_output
from .grid import Grid, Workspace

#: configurations sampled for the default box (the tool's reach)
REACH_SAMPLES = 4096
#: damped least-squares steps per point: from a neighbour's solution a reachable point converges in a
#: few; an unreachable one would otherwise take the IK's default 200 before it is called so
MAX_ITER = 60


def reach_box(model, tool: str | None = None) -> Workspace:
    """The bounding box (mm) of ``tool``'s point over :data:`REACH_SAMPLES` configurations drawn
    uniformly within the joint limits (a continuous joint over one turn), rounded out to 10 mm."""
    lo, hi = model.tree.limits
    lo = np.where(np.isfinite(lo), lo, -np.pi)
    hi = np.where(np.isfinite(hi), hi, np.pi)
    Q = lo + (hi - lo) * np.random.default_rng(0).random((REACH_SAMPLES, model.nq))
    P = model.forward(Q, tool)[:, :3, 3]
    return Workspace(np.floor(P.min(axis=0) / 10.0) * 10.0, np.ceil(P.max(axis=0) / 10.0) * 10.0)


def _carry(model, T: np.ndarray, seed: np.ndarray, tool) -> IKResult:
    """IK over a grid of poses ``T`` (a, b, ..., 4, 4): the first line along the last axis from the seed
    point after point, each further slice along the first axis from its neighbour in the slice before."""
    if T.ndim == 3:  # a line: point after point, each from the last one reached
        rs, q = [], seed
        for Tk in T:
            rs.append(solve(model, Tk[None], q, tool, max_iter=MAX_ITER))
            q = rs[-1].q[0] if rs[-1].reached[0] else q
        return IKResult(*(np.concatenate([getattr(r, f) for r in rs]) for f in ("q", "reached", "singular", "residual")))
    parts = [_carry(model, T[0], seed, tool)]
    for k in range(1, len(T)):
        prev = parts[-1]
        start = np.where(prev.reached[..., None], prev.q, seed)
        r = solve(model, T[k].reshape(-1, 4, 4), start.reshape(-1, model.nq), tool, max_iter=MAX_ITER)
        shape = T.shape[1:-2]
        parts.append(IKResult(r.q.reshape(shape + (model.nq,)), r.reached.reshape(shape),
                              r.singular.reshape(shape), r.residual.reshape(shape)))
    return IKResult(*(np.stack([getattr(p, f) for p in parts]) for f in ("q", "reached", "singular", "residual")))


@dataclass(frozen=True, eq=False)
class CartesianMap:
    """k_tran (mm/N), k_rot (rad/(N mm)), K and optionally the self-weight sag (mm, rad) at the points of
    a grid, reached by the IK in the seed's configuration.

    ``points`` (n, 3) mm in the order of ``np.meshgrid(*grid.axes, indexing="ij")``; per point ``q``
    (n, nq), ``reached``, ``singular``; ``ok = reached & ~singular`` is where the maps have values
    (NaN elsewhere); ``rotation`` (3, 3) the tool's orientation over the grid; ``seed`` (nq,).
    ``n``, ``slice``: the grid as asked (points per axis, ``"z=400"`` or None), ``box_from`` where its box came
    from; ``model_name``, ``model_path``, ``tool``, ``q_names`` say whose map it is."""

    name: str
    grid: Grid
    points: np.ndarray
    rotation: np.ndarray
    seed: np.ndarray
    q: np.ndarray
    reached: np.ndarray
    singular: np.ndarray
    K: np.ndarray
    k_tran: np.ndarray
    k_rot: np.ndarray
    sag: np.ndarray | None = None
    tool: str | None = None
    q_names: tuple = ()
    model_name: str = ""
    model_path: str | None = None
    n: int | None = None
    slice: str | None = None
    box_from: str = "the grid given"

    @property
    def ok(self) -> np.ndarray:
        return self.reached & ~self.singular

    def counts(self) -> dict:
        return {"points": int(len(self.points)), "evaluated": int(self.ok.sum()),
                "unreachable": int((~self.reached).sum()), "singular": int((self.reached & self.singular).sum())}

    def summary_dict(self) -> dict:
        """What summary.json holds: the model, the tool, the grid and its box, the seed, the tool's rotation,
        the points evaluated, unreachable and singular, the ranges of k_tran, k_rot (and the largest sag)."""
        fixed = self.grid.fixed
        doc = {"kind": "cartesian", "grid": self.n if self.n is not None else max(self.grid.shape),
               "slice": self.slice if self.slice is not None or fixed is None else f"{'xyz'[fixed[0]]}={fixed[1]:g}",
               "box_mm": [list(map(float, self.grid.axes[k][[0, -1]])) for k in range(3)],
               "box_from": self.box_from, "seed": self.seed.tolist(), "tool_rotation": self.rotation.tolist(),
               **self.counts()}
        return robot_output.summary_dict(self, doc)

    def summary(self) -> str:
        """One line: the points evaluated (unreachable, singular), the ranges of k_tran and k_rot (and the sag)."""
        return robot_output.line(self.summary_dict())

    def _repr_html_(self) -> str:
        return robot_output.html(f"{self.name}: Cartesian map", self.summary_dict())

    def csv_columns(self) -> tuple[list, list]:
        """map.csv's leading header and its arrays: a row per point (point, status, joint values, k_tran,
        k_rot); an unreachable point's last IK iterate is no answer (NaN)."""
        status = np.where(~self.reached, "unreachable", np.where(self.singular, "singular", "ok"))
        q = np.where(self.reached[:, None], self.q, np.nan)
        return (["x_mm", "y_mm", "z_mm", "status"],
                [self.points, status[:, None], q, self.k_tran[:, None], self.k_rot[:, None]])

    def save(self, out, force: bool = False) -> Path:
        """Write ``out/``: map.npz, map.csv, k_tran.png, k_rot.png, summary.json (and sag.png) as one set
        (:mod:`vjm.maps.robot_output`: all new, or the old ones; ``force`` writes beside files of other
        origin); returns the folder."""
        keys = ("points", "rotation", "seed", "q", "reached", "singular", "K", "k_tran", "k_rot", "sag")
        arrays = {k: getattr(self, k) for k in keys if isinstance(getattr(self, k), np.ndarray)}
        arrays.update(shape=np.array(self.grid.shape), ok=self.ok)
        return robot_output.write_set(out, self, arrays, self.summary_dict(), force)

    def stiffness_map(self):
        """k_tran and k_rot as a :class:`vjm.maps.compute.StiffnessMap` (its pictures: log scale, contours)."""
        from .compute import StiffnessMap

        return StiffnessMap(self.name, list(self.grid.axes), self.grid.fixed, self.points, self.ok, self.K,
                            self.k_tran, self.k_rot, label=robot_output.label(self))

    def plot(self, name: str = "k_tran", ax=None):
        """``k_tran`` or ``k_rot`` (:meth:`vjm.maps.compute.StiffnessMap.plot`), or ``sag``: the sag's length (mm)
        on the grid's slice (a 3-D grid: its middle z slice)."""
        if name != "sag":
            return self.stiffness_map().plot(name, ax=ax)
        if self.sag is None:
            raise VjmError("this map has no self-weight sag (cartesian grid map with self_weight=True)")
        from .views import pyplot

        shape = self.grid.shape
        k, idx = (2, shape[2] // 2) if self.grid.fixed is None else (self.grid.fixed[0], 0)
        keep = [a for a in range(3) if a != k]
        V = np.take(np.linalg.norm(self.sag[:, :3], axis=1).reshape(shape), idx, axis=k)
        if ax is None:
            _, ax = pyplot().subplots(figsize=(5.5, 4.5))
        u, v = (np.asarray(self.grid.axes[a], dtype=float) for a in keep)
        im = ax.pcolormesh(u, v, np.ma.masked_invalid(V).T, shading="nearest", cmap="viridis")
        ax.figure.colorbar(im, ax=ax, label="self-weight sag [mm]")
        ax.set_aspect("equal")
        ax.set_xlabel(f"{'xyz'[keep[0]]} [mm]")
        ax.set_ylabel(f"{'xyz'[keep[1]]} [mm]")
        ax.set_title(f"{robot_output.label(self)}\nsag, {'xyz'[k]} = {float(self.grid.axes[k][idx]):.4g} mm",
                     fontsize=9)
        return ax


def cartesian_grid_map(model, grid: Grid, seed, rotation=None, tool: str | None = None,
                       self_weight: bool = False, n: int | None = None, slice: str | None = None,
                       box_from: str = "the grid given") -> CartesianMap:
    """The stiffness (and the sag) of ``model`` at the points of ``grid``, the tool held at ``rotation``
    ((3, 3); default: the tool's orientation at the seed), through the IK carried from ``seed``; ``n``,
    ``slice`` and ``box_from`` say how the grid was asked for (its summary)."""
    seed = model.check_q(seed)[0][0]
    if rotation is None:
        rotation = model.forward(seed, tool)[:3, :3]
    P = grid.points
    T = pose_targets(P)
    T[:, :3, :3] = rotation
    ik = _carry(model, T.reshape(grid.shape + (4, 4)), seed, tool)
    q, reached, singular = (a.reshape((len(P),) + a.shape[len(grid.shape):]) for a in (ik.q, ik.reached, ik.singular))
    ok = reached & ~singular
    K = np.full((len(P), 6, 6), np.nan)
    kt, kr = np.full(len(P), np.nan), np.full(len(P), np.nan)
    sag = np.full((len(P), 6), np.nan) if self_weight else None
    if ok.any():
        r = model.stiffness(q[ok], tool)
        K[ok], kt[ok], kr[ok] = r.K, r.k_tran, r.k_rot
        if sag is not None:
            sag[ok] = model.self_weight(q[ok], tool)
    return CartesianMap(model.name or "robot", grid, P, np.asarray(rotation, dtype=float), seed, q, reached,
                        singular, K, kt, kr, sag, model._tool(tool), tuple(model.q_names), model.name, model.path,
                        n, slice, box_from)

"""Stiffness maps over a workspace grid: k_tran and k_rot per point, saved as .npz and pictures.

:meth:`vjm.model.machine.ParallelModel.map` is the one call: it lays the model's workspace grid
(:meth:`vjm.model.machine.ParallelModel.grid`, optionally one axis fixed, ``z=0``), checks that the map fits in
memory, and evaluates the batched stiffness at the reachable points (:func:`compute_map`);
:class:`StiffnessMap` carries the result with ``save`` and ``plot``.
k_tran is in mm/N, k_rot in rad/(N mm) (largest eigenvalues of the compliance blocks);
K is in world axes at the end-effector point; unreachable points hold NaN.

>>> import numpy as np, vjm
>>> m = vjm.load_model("puu")
>>> smap = m.map(grid=5, slice="z=0")
>>> smap.shape, int(smap.reachable.sum())
((5, 5, 1), 25)
>>> bool(np.isclose(smap.k_tran[12], m.stiffness(smap.points[12]).k_tran))  # same as one point at a time
True
>>> ax = smap.plot("k_tran")               # matplotlib Axes; smap.save(folder) writes map.npz and the PNGs
"""
from __future__ import annotations

import os
from dataclasses import dataclass, field
from pathlib import Path
from typing import Optional

import numpy as np

from linkfea.files.outputs import OutputSet, check_folder
from linkfea.runtime.checks import Bounds, integer
from linkfea.runtime.progress import Progress

from ..errors import ArgumentError, VjmError
from ..stiffness.linear import SPREAD_NOTE
from .grid import MAP_BYTES, grid_plan, in_chunks

#: points per axis of a workspace grid (``vjm map --grid``, ``vjm sweep --grid``)
GRID = Bounds(2)

#: the two maps: (name, unit)
MAPS = (("k_tran", "mm/N"), ("k_rot", "rad/(N mm)"))
#: the files `vjm map` writes, one set
MAP_FILES = ("map.npz", "k_tran.png", "k_rot.png")

#: a map whose max/min exceeds this gets a log colour scale
LOG_SPAN = 10.0


def contour_levels(lo: float, hi: float, log: bool) -> np.ndarray:
    """Contour values strictly inside (lo, hi): 1, 2, 5 x 10^n if ``log``, else about six round values.

    >>> contour_levels(3e-4, 9e-3, log=True).tolist()
    [0.0005, 0.001, 0.002, 0.005]
    """
    if not (np.isfinite(lo) and np.isfinite(hi) and hi > lo):
        return np.array([])
    if log:
        e = np.arange(np.floor(np.log10(lo)), np.ceil(np.log10(hi)) + 1)
        cand = (np.array([1.0, 2.0, 5.0])[None, :] * 10.0 ** e[:, None]).ravel()
    else:
        from matplotlib.ticker import MaxNLocator

        cand = np.asarray(MaxNLocator(6).tick_values(lo, hi))
    return cand[(cand > lo) & (cand < hi)]


def workspace_grid(model, n: int, slice_: Optional[str] = None):
    """Axes, points ``G`` (nx, ny, nz, 3) and the fixed axis ``(k, value)`` or None of an n-point grid
    over the model's workspace (:meth:`vjm.model.machine.ParallelModel.grid`, whose :class:`~vjm.maps.grid.Grid` is the newer form)."""
    g = model.grid(integer(n, "grid", GRID, ArgumentError), slice_)
    return list(g.axes), g.points.reshape(g.shape + (3,)), g.fixed


@dataclass(frozen=True)
class StiffnessMap:
    """k_tran, k_rot and K at the points of a grid (NaN where unreachable).

    ``points`` (n, 3) in mm, in the order of ``np.meshgrid(*axes, indexing="ij")``;
    ``fixed`` is the ``(axis, value)`` of a slice, or None for a 3-D grid.
    """

    architecture: str
    axes: list
    fixed: Optional[tuple]
    points: np.ndarray
    reachable: np.ndarray
    K: np.ndarray
    k_tran: np.ndarray
    k_rot: np.ndarray
    #: named points marked on the pictures, ``{label: (x, y, z)}`` in mm
    landmarks: dict = field(default_factory=dict)
    #: the spread of k_tran (mm/N) and k_rot (rad/(N mm)) from the links' FEA error bars
    #: (:mod:`vjm.sweep.spread`; zero if no link has an error estimate, NaN where unreachable), or None
    #: if the map was made without it
    k_tran_spread: Optional[np.ndarray] = None
    k_rot_spread: Optional[np.ndarray] = None
    #: the model and the links the map was made with (:func:`map_label`), named in the pictures' titles
    label: str = ""

    @property
    def shape(self) -> tuple[int, int, int]:
        return tuple(len(a) for a in self.axes)  # type: ignore[return-value]

    def summary(self) -> str:
        kt, kr = self.k_tran, self.k_rot
        text = (f"{self.reachable.sum()} of {len(self.points)} points reachable; "
                f"k_tran {np.nanmin(kt):.3g}..{np.nanmax(kt):.3g} mm/N, "
                f"k_rot {np.nanmin(kr):.3g}..{np.nanmax(kr):.3g} rad/(N mm)")
        if self.k_tran_spread is not None:
            rt, rr = _largest_ratio(self.k_tran_spread, kt), _largest_ratio(self.k_rot_spread, kr)
            text += (f"; spread from the links' FEA error bars: k_tran +-{100 * rt:.2g}% at most, k_rot "
                     f"+-{100 * rr:.2g}% at most" if rt or rr else "; no link carries an FEA error estimate")
        return text

    def _repr_html_(self) -> str:
        """The grid, and min / max of k_tran and k_rot with where they occur.

        >>> import vjm
        >>> html = vjm.load_model("puu").map(grid=3, slice="z=0")._repr_html_()
        >>> "k_tran min" in html and "9 of 9" in html
        True
        """
        from .views import map_html

        return map_html(self.architecture, self.shape, self.axes, self.fixed, self.points, self.reachable,
                        self.k_tran, self.k_rot)

    def save(self, out, force: bool = False) -> Path:
        """Write ``out/map.npz``, ``out/k_tran.png`` and ``out/k_rot.png`` as one set (:mod:`linkfea.files.outputs`):
        all three new, or the old ones; ``force`` writes beside files of other origin.  Returns the folder."""
        check_folder(out, MAP_FILES, force=force)
        with OutputSet(out, "vjm map") as s:
            npz, png_t, png_r = (s.path(n) for n in MAP_FILES)
            extra: dict = {} if self.k_tran_spread is None else dict(
                k_tran_spread=self.k_tran_spread, k_rot_spread=self.k_rot_spread,
                spread_note=np.array(f"k_tran_spread mm/N, k_rot_spread rad/(N mm), per point: {SPREAD_NOTE}"))
            extra["label"] = np.array(self.label)  # names this map in the title of a map compared with it
            np.savez_compressed(npz, points=self.points, K=self.K, k_tran=self.k_tran, k_rot=self.k_rot,
                                reachable=self.reachable, shape=np.array(self.shape),
                                note=np.array("K world axes at the end-effector point; k_tran mm/N, "
                                              "k_rot rad/(N mm); NaN = unreachable"), **extra)
            self.save_pictures({"k_tran": png_t, "k_rot": png_r})
        return Path(out)

    def save_pictures(self, paths: dict) -> None:
        """One PNG per map name in ``paths`` (``{"k_tran": path, "k_rot": path}``)."""
        import matplotlib
        matplotlib.use("Agg")
        import matplotlib.pyplot as plt

        for name in paths:
            fig, ax = plt.subplots(figsize=(5.5, 4.5))
            self.plot(name, ax=ax)
            fig.tight_layout()
            fig.savefig(paths[name], dpi=110)
            plt.close(fig)

    def plot(self, name: str = "k_tran", ax=None):
        """Draw map ``name`` (``k_tran`` or ``k_rot``) on ``ax`` (a new figure if None); returns the Axes.

        A 3-D grid shows its middle slice along z.  A map whose values span more than a
        decade (:data:`LOG_SPAN`) gets a log colour scale; labelled contour lines are drawn
        at 1, 2, 5 x 10^n (log) or at round values (linear).  The seed's named points
        (isotropic Q0, Q1, Q2) are marked: filled when in the plane shown, hollow (with
        their distance to it) when projected.
        """
        unit = dict(MAPS)[name]
        k, here = self._shown_slice()
        title = f"{name}, {'xyz'[k]} = {here:.4g} mm"
        return self.plot_values(getattr(self, name), name, unit,
                                f"{self.label}\n{title}" if self.label else f"{self.architecture}: {title}", ax)

    def _shown_slice(self) -> tuple[int, float]:
        """The axis fixed in the pictures and its value: the slice's, or the middle along z of a 3-D grid."""
        if self.fixed is None:
            return 2, float(np.asarray(self.axes[2])[self.shape[2] // 2])
        return self.fixed[0], float(np.asarray(self.axes[self.fixed[0]])[0])

    def plot_values(self, values, name: str, unit: str, title: str, ax=None):
        """Draw ``values`` (one per point of the grid) as :meth:`plot` draws a map, with the colour bar
        ``name [unit]`` and ``title``; returns the Axes."""
        from matplotlib.colors import LogNorm, Normalize

        from .views import pyplot

        plt = pyplot()

        axes, shape = self.axes, self.shape
        if self.fixed is None:  # 3-D grid: show the middle slice along z
            k, idx = 2, shape[2] // 2
        else:
            k, idx = self.fixed[0], 0
        keep = [a for a in range(3) if a != k]
        V = np.ma.masked_invalid(np.take(np.asarray(values, dtype=float).reshape(shape), idx, axis=k))
        if ax is None:
            _, ax = plt.subplots(figsize=(5.5, 4.8))
        u, v = (np.asarray(axes[a], dtype=float) for a in keep)
        lo, hi = (float(V.min()), float(V.max())) if V.count() else (np.nan, np.nan)
        log = bool(lo > 0 and hi / lo > LOG_SPAN)
        norm = LogNorm(lo, hi) if log else Normalize(lo, hi)
        # pixel centres on the grid points
        du = (u[-1] - u[0]) / (len(u) - 1) if len(u) > 1 else 1.0
        dv = (v[-1] - v[0]) / (len(v) - 1) if len(v) > 1 else 1.0
        im = ax.imshow(V.T, origin="lower", aspect="equal", norm=norm, cmap="viridis",
                       extent=[u[0] - du / 2, u[-1] + du / 2, v[0] - dv / 2, v[-1] + dv / 2])
        ax.figure.colorbar(im, ax=ax, label=f"{name} [{unit}]" + (", log scale" if log else ""))
        levels = contour_levels(lo, hi, log)
        if len(u) > 1 and len(v) > 1 and len(levels):
            cs = ax.contour(u, v, V.T, levels=levels, colors="white", linewidths=0.7)
            ax.clabel(cs, fmt="%.2g", fontsize=7)
        here = float(np.asarray(axes[k])[idx])
        for label, p in self.landmarks.items():
            off = float(p[k]) - here
            inside = abs(off) <= 1e-9 * max(1.0, abs(here))
            ax.plot(p[keep[0]], p[keep[1]], "o" if inside else "s", ms=7, mfc="red" if inside else "none",
                    mec="red", mew=1.5, clip_on=False)
            text = label if inside else f"{label} ({'xyz'[k]} = {float(p[k]):.4g})"
            # label towards the middle of the picture, so that corner points keep theirs in view
            right = p[keep[0]] > 0.5 * (u[0] + u[-1])
            top = p[keep[1]] > 0.5 * (v[0] + v[-1])
            ax.annotate(text, (p[keep[0]], p[keep[1]]), xytext=(-7 if right else 7, -7 if top else 7),
                        textcoords="offset points", ha="right" if right else "left",
                        va="top" if top else "bottom", color="red", fontsize=8,
                        bbox=dict(boxstyle="round,pad=0.15", fc="white", ec="none", alpha=0.8))
        ax.set_xlim(u[0] - du / 2, u[-1] + du / 2)
        ax.set_ylim(v[0] - dv / 2, v[-1] + dv / 2)
        ax.set_xlabel(f"{'xyz'[keep[0]]} [mm]")
        ax.set_ylabel(f"{'xyz'[keep[1]]} [mm]")
        ax.set_title(title, fontsize=9)
        return ax


def _largest_ratio(spread, k) -> float:
    """The largest ``spread / k`` over the finite points (0 if none)."""
    with np.errstate(invalid="ignore", divide="ignore"):
        r = np.asarray(spread) / np.asarray(k)
    r = r[np.isfinite(r)]
    return float(r.max()) if r.size else 0.0


def compute_map(model, P, axes, fixed=None, where: str = "grid", progress: Optional[Progress] = None,
                spread: bool = False) -> StiffnessMap:
    """Stiffness at the points ``P`` (n, 3) of the grid ``axes``; NaN where the model cannot reach.

    ``where`` names the grid in the error raised when no point is reachable; a run longer
    than about a minute reports through ``progress`` (:func:`vjm.maps.grid.in_chunks`);
    ``spread`` adds the spread of k_tran and k_rot from the links' FEA error bars (:mod:`vjm.sweep.spread`).
    """
    P = np.asarray(P, dtype=float)
    ok = model.reachable(P)
    if not ok.any():
        raise VjmError(f"no point of the {where} is reachable by {model.architecture}")
    kt = np.full(len(P), np.nan)
    kr = np.full(len(P), np.nan)
    K = np.full((len(P), 6, 6), np.nan)
    st, sr = (np.full(len(P), np.nan) for _ in range(2)) if spread else (None, None)
    idx = np.flatnonzero(ok)

    def step(s: slice) -> None:
        i = idx[s]
        r = model.stiffness_map(P[i], spread=spread)
        kt[i], kr[i], K[i] = r.k_tran, r.k_rot, r.K
        if st is not None and sr is not None:
            st[i], sr[i] = r.k_tran_spread, r.k_rot_spread

    in_chunks(len(idx), step, progress, "reachable points")
    return StiffnessMap(model.architecture, list(axes), fixed, P, ok, K, kt, kr, dict(model.arch.landmarks),
                        st, sr, map_label(model))


def _link_source(link) -> str:
    """How a link's spring was given, in a few words: a beam, rigid, a linkfea result (its file), a matrix."""
    src = getattr(link, "source", None) or {}
    if "linkfea" in src:
        parts = os.path.normpath(str(src["linkfea"])).split(os.sep)
        return "FEA " + "/".join(parts[-2:])
    if src.get("rigid"):
        return "rigid"
    return next(iter(src), "matrix")


def map_label(model) -> str:
    """The model and the links a map is made with, as the map's titles name them.

    >>> import vjm
    >>> map_label(vjm.load_model("puu"))
    'puu.yaml (orthoglide-3PUU); foot: beam, leg: beam'
    """
    path = getattr(model, "path", None)
    name = f"{os.path.basename(path)} ({model.architecture})" if path else model.architecture
    links = getattr(model, "links", None) or {}
    used = ", ".join(f"{k}: {_link_source(v)}" for k, v in links.items())
    return f"{name}; {used}" if used else name


def grid_map(model, n: int, slice_: Optional[str] = None, orientation=None,
             progress: Optional[Progress] = None, spread: bool = False) -> StiffnessMap:
    """:meth:`vjm.model.machine.ParallelModel.map`: the stiffness over an n-per-axis workspace grid, its memory checked first."""
    if model.dof != 6 and orientation is not None and np.any(np.asarray(orientation, dtype=float) != 0):
        # as vjm stiffness and vjm simulate --tilt: a setting the machine cannot take is not ignored
        given = ",".join(f"{v:g}" for v in np.ravel(np.asarray(orientation, dtype=float)))
        raise ArgumentError("orientation", f"{given} rad: the machine's platform only translates (3 dof); "
                                           "its map has no orientation")
    p = grid_plan(n, slice_, "the stiffness map", MAP_BYTES)
    if p.long and progress is not None:
        progress(f"{p.describe()}; progress follows")
    g = model.grid(n, slice_)
    P = g.points
    if model.dof == 6:  # a 6-dof platform's map is a slice at a fixed orientation
        rot = np.zeros(3) if orientation is None else np.asarray(orientation, dtype=float)
        if rot.shape != (3,) or not np.all(np.isfinite(rot)):
            raise VjmError(f"orientation is a rotation vector rx, ry, rz (rad), got {orientation!r}")
        P = np.hstack([P, np.broadcast_to(rot, (len(P), 3))])
    where = f"{n}-point grid{' at ' + slice_ if slice_ else ''}"
    return compute_map(model, P, g.axes, g.fixed, where=where, progress=progress, spread=spread)

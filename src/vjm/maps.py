"""Stiffness maps over a workspace grid: k_tran and k_rot per point, saved as .npz and pictures.

``workspace_grid`` lays a regular grid over the model's workspace box (optionally one
axis fixed, ``z=0``), ``compute_map`` evaluates the batched stiffness at its reachable
points, and :class:`StiffnessMap` carries the result with ``save`` and ``plot``.
k_tran is in mm/N, k_rot in rad/(N mm) (largest eigenvalues of the compliance blocks);
K is in world axes at the end-effector point; unreachable points hold NaN.

>>> import numpy as np, vjm
>>> from vjm.maps import compute_map, workspace_grid
>>> m = vjm.load_model("puu")
>>> axes, G, fixed = workspace_grid(m, 5, "z=0")
>>> smap = compute_map(m, G.reshape(-1, 3), axes, fixed)
>>> smap.shape, int(smap.reachable.sum())
((5, 5, 1), 25)
>>> bool(np.isclose(smap.k_tran[12], m.stiffness(smap.points[12]).k_tran))  # same as one point at a time
True
>>> ax = smap.plot("k_tran")               # matplotlib Axes; smap.save(folder) writes map.npz and the PNGs
"""
from __future__ import annotations

import os
from dataclasses import dataclass
from typing import Optional

import numpy as np

from linkfea.atomic import atomic_path

from .errors import VjmError

#: the two maps: (name, unit)
MAPS = (("k_tran", "mm/N"), ("k_rot", "rad/(N mm)"))


def parse_slice(text: str) -> tuple[int, float]:
    """``"z=0"`` -> ``(2, 0.0)``: the fixed axis index and its value in mm."""
    try:
        name, val = text.split("=")
        return "xyz".index(name.strip()), float(val)
    except ValueError:
        raise VjmError(f"--slice expects axis=value, e.g. z=0, got {text!r}") from None


def workspace_grid(model, n: int, slice_: Optional[str] = None):
    """Axes, points ``G`` (nx, ny, nz, 3) and the fixed axis ``(k, value)`` or None of an n-point grid.

    The grid spans the architecture's workspace box; ``slice_`` (``"z=0"``) fixes one axis.
    """
    if n < 2:
        raise VjmError("--grid must be >= 2")
    lo, hi = (np.array(v, dtype=float) for v in model.arch.workspace)
    axes = [np.linspace(lo[k], hi[k], n) for k in range(3)]
    fixed = None
    if slice_:
        fixed = parse_slice(slice_)
        axes[fixed[0]] = np.array([fixed[1]])
    G = np.stack(np.meshgrid(*axes, indexing="ij"), axis=-1)
    return axes, G, fixed


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

    @property
    def shape(self) -> tuple[int, int, int]:
        return tuple(len(a) for a in self.axes)  # type: ignore[return-value]

    def summary(self) -> str:
        kt, kr = self.k_tran, self.k_rot
        return (f"{self.reachable.sum()} of {len(self.points)} points reachable; "
                f"k_tran {np.nanmin(kt):.3g}..{np.nanmax(kt):.3g} mm/N, "
                f"k_rot {np.nanmin(kr):.3g}..{np.nanmax(kr):.3g} rad/(N mm)")

    def save(self, out) -> None:
        """Write ``out/map.npz``, ``out/k_tran.png`` and ``out/k_rot.png``: all three or none."""
        with atomic_path(os.path.join(out, "map.npz")) as npz, \
                atomic_path(os.path.join(out, "k_tran.png")) as png_t, \
                atomic_path(os.path.join(out, "k_rot.png")) as png_r:
            np.savez_compressed(npz, points=self.points, K=self.K, k_tran=self.k_tran, k_rot=self.k_rot,
                                reachable=self.reachable, shape=np.array(self.shape),
                                note=np.array("K world axes at the end-effector point; k_tran mm/N, "
                                              "k_rot rad/(N mm); NaN = unreachable"))
            self.save_pictures({"k_tran": png_t, "k_rot": png_r})

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

        A 3-D grid shows its middle slice along z.
        """
        import matplotlib.pyplot as plt

        unit = dict(MAPS)[name]
        axes, shape = self.axes, self.shape
        if self.fixed is None:  # 3-D grid: show the middle slice along z
            k, idx = 2, shape[2] // 2
        else:
            k, idx = self.fixed[0], 0
        keep = [a for a in range(3) if a != k]
        V = np.take(getattr(self, name).reshape(shape), idx, axis=k)
        if ax is None:
            _, ax = plt.subplots(figsize=(5.5, 4.5))
        im = ax.imshow(V.T, origin="lower", aspect="equal",
                       extent=[axes[keep[0]][0], axes[keep[0]][-1], axes[keep[1]][0], axes[keep[1]][-1]])
        ax.figure.colorbar(im, ax=ax, label=f"{name} [{unit}]")
        ax.set_xlabel(f"{'xyz'[keep[0]]} [mm]")
        ax.set_ylabel(f"{'xyz'[keep[1]]} [mm]")
        ax.set_title(f"{self.architecture}: {name}, {'xyz'[k]} = {np.asarray(axes[k])[idx]:.4g} mm")
        return ax


def compute_map(model, P, axes, fixed=None, where: str = "grid") -> StiffnessMap:
    """Stiffness at the points ``P`` (n, 3) of the grid ``axes``; NaN where the model cannot reach.

    ``where`` names the grid in the error raised when no point is reachable.
    """
    P = np.asarray(P, dtype=float)
    ok = model.arch.reachable(model, P)
    if not ok.any():
        raise VjmError(f"no point of the {where} is reachable by {model.architecture}")
    kt = np.full(len(P), np.nan)
    kr = np.full(len(P), np.nan)
    K = np.full((len(P), 6, 6), np.nan)
    r = model.stiffness_map(P[ok])
    kt[ok], kr[ok], K[ok] = r.k_tran, r.k_rot, r.K
    return StiffnessMap(model.architecture, list(axes), fixed, P, ok, K, kt, kr)

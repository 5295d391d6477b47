"""Two stiffness maps compared: this map's k_tran and k_rot over another map's, point by point.

``vjm map ... --compare OTHER`` reads ``OTHER/map.npz`` (a map of a parallel machine saved by
:meth:`vjm.maps.compute.StiffnessMap.save`), checks that both maps are on the same grid, and writes
``ratio.npz``, ``k_tran_ratio.png`` and ``k_rot_ratio.png`` beside this map, as one output set of their
own.  A ratio above 1 means this map is more compliant there than the other.  The other folder is only
read.
"""
from __future__ import annotations

import io
import os
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from linkfea.files.atomic import read_user_file
from linkfea.files.outputs import OutputSet, read_manifest

from ..errors import VjmError
from .compute import StiffnessMap

#: the files a comparison writes, one set
RATIO_FILES = ("ratio.npz", "k_tran_ratio.png", "k_rot_ratio.png")
#: the output set of a comparison, beside the map's own ("vjm map")
RATIO_SET = "vjm map --compare"
#: what a saved map must hold to be compared
_KEYS = ("points", "shape", "reachable", "k_tran", "k_rot")


@dataclass(frozen=True)
class SavedMap:
    """A map read back from its folder's ``map.npz``."""

    folder: Path
    points: np.ndarray
    shape: tuple
    k_tran: np.ndarray
    k_rot: np.ndarray
    label: str


def read_map(folder) -> SavedMap:
    """The map saved in ``folder`` (its ``map.npz``); VjmError naming the folder if there is none."""
    folder = Path(folder)
    path = folder / "map.npz"
    if not folder.is_dir():
        raise VjmError(f"--compare {folder}: no such folder; give the --out folder of another vjm map")
    if not path.exists():
        raise VjmError(f"--compare {folder}: holds no map.npz; give the --out folder of another vjm map")
    data = read_user_file(path, "map", error=VjmError)
    try:
        with np.load(io.BytesIO(data), allow_pickle=False) as z:
            missing = [k for k in _KEYS if k not in z.files]
            if missing:
                raise VjmError(f"--compare {path}: not a stiffness map of a parallel machine (no {missing[0]})")
            arrays = {k: np.asarray(z[k]) for k in _KEYS}
            label = str(z["label"]) if "label" in z.files else ""
    except (ValueError, OSError, EOFError):
        raise VjmError(f"--compare {path}: not a readable map.npz (not a numpy archive of arrays)") from None
    shape = tuple(int(s) for s in arrays["shape"])
    n = int(np.prod(shape)) if shape else 0
    if arrays["points"].ndim != 2 or len(arrays["points"]) != n or any(arrays[k].shape != (n,)
                                                                       for k in ("k_tran", "k_rot")):
        raise VjmError(f"--compare {path}: its arrays do not match its grid {shape}")
    return SavedMap(folder, arrays["points"].astype(float), shape, arrays["k_tran"].astype(float),
                    arrays["k_rot"].astype(float), label or folder.name)


def same_grid(this: StiffnessMap, other: SavedMap) -> None:
    """Refuse two maps whose grids differ (points per axis, box, slice or orientation)."""
    if tuple(this.shape) != tuple(other.shape):
        raise VjmError(f"--compare {other.folder}: its grid is {'x'.join(map(str, other.shape))} points, this "
                       f"map's {'x'.join(map(str, this.shape))}; compare maps made with the same --grid and --slice")
    P, Q = np.asarray(this.points, dtype=float), other.points
    scale = max(1.0, float(np.max(np.abs(P))) if P.size else 1.0)
    if P.shape != Q.shape or not np.allclose(P, Q, rtol=0, atol=1e-9 * scale):
        worst = float(np.max(np.abs(P - Q))) if P.shape == Q.shape else float("nan")
        raise VjmError(f"--compare {other.folder}: its grid points differ from this map's (by up to {worst:.3g}; "
                       "another workspace, slice or orientation); compare maps of the same grid")


def ratios(this: StiffnessMap, other: SavedMap) -> tuple[np.ndarray, np.ndarray]:
    """k_tran and k_rot of ``this`` over ``other``'s at each point (NaN where either is unreachable)."""
    same_grid(this, other)
    with np.errstate(invalid="ignore", divide="ignore"):
        return np.asarray(this.k_tran) / other.k_tran, np.asarray(this.k_rot) / other.k_rot


def check_other(out, other) -> None:
    """Refuse comparing a map with the folder it is written to: the other map would be replaced."""
    if os.path.realpath(out) == os.path.realpath(other):
        raise VjmError(f"--compare {other} is the --out folder: its map would be replaced by this one; "
                       "write this map to another folder")


def save_ratio(this: StiffnessMap, other: SavedMap, out, ratio=None) -> Path:
    """Write ``out/ratio.npz`` and the two ratio pictures as one set; the folder."""
    rt, rr = ratios(this, other) if ratio is None else ratio
    with OutputSet(out, RATIO_SET) as s:
        npz, png_t, png_r = (s.path(n) for n in RATIO_FILES)
        np.savez_compressed(npz, points=this.points, shape=np.array(this.shape), k_tran_ratio=rt, k_rot_ratio=rr,
                            this=np.array(this.label), other=np.array(other.label),
                            other_folder=np.array(os.path.abspath(other.folder)),
                            note=np.array("this map's k_tran and k_rot over the other's, point by point; "
                                          "NaN where either is unreachable"))
        _pictures(this, other, {"k_tran": (rt, png_t), "k_rot": (rr, png_r)})
    return Path(out)


def _pictures(this: StiffnessMap, other: SavedMap, what: dict) -> None:
    from .views import pyplot

    plt = pyplot()
    k = this.fixed[0] if this.fixed is not None else 2
    here = float(np.asarray(this.axes[k])[0 if this.fixed is not None else this.shape[2] // 2])
    for name, (values, path) in what.items():
        fig, ax = plt.subplots(figsize=(5.5, 5.0))
        title = f"{this.label}\nover {other.label}\n{name} ratio, {'xyz'[k]} = {here:.4g} mm"
        this.plot_values(values, f"{name} ratio", "-", title, ax=ax)
        fig.tight_layout()
        fig.savefig(path, dpi=110)
        plt.close(fig)


def drop_ratio(out) -> None:
    """Remove the ratio files of an earlier comparison in ``out`` (a new map without ``--compare`` no longer
    matches them); files the user changed stay."""
    if RATIO_SET in (read_manifest(out).get("sets") or {}):
        with OutputSet(out, RATIO_SET):
            pass

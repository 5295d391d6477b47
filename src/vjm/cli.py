"""``vjm`` command line: stiffness at a point, stiffness maps, the seed's Table 1.

Every command turns a VjmError into one line on stderr and exit status 2.
New commands register on ``app`` (see the end of this file).
"""
from __future__ import annotations

import csv
import json
import os
import sys
from pathlib import Path
from typing import Optional

import numpy as np
import typer

from linkfea.atomic import atomic_path

from .errors import VjmError, one_line, user_errors
from .resources import seed_table

app = typer.Typer(add_completion=False, help="Virtual-joint-method stiffness of parallel machines.")

SEED_TABLE = seed_table()


def _fail(exc: Exception):
    typer.echo(f"error: {one_line(exc)}", err=True)
    raise typer.Exit(2)


def _load(model: Path, foot: Optional[Path], leg: Optional[Path]):
    from .modelfile import load_model
    return load_model(model, foot=foot, leg=leg)


def _point(text: str) -> np.ndarray:
    try:
        p = np.array([float(v) for v in text.split(",")])
    except ValueError:
        raise VjmError(f"--at expects x,y,z in mm, got {text!r}") from None
    if p.shape != (3,):
        raise VjmError(f"--at expects three numbers x,y,z in mm, got {text!r}")
    return p


FOOT = typer.Option(None, "--foot", help="linkfea result JSON replacing the model's foot")
LEG = typer.Option(None, "--leg", help="linkfea result JSON replacing the model's leg (one bar for parallelograms)")


@app.command()
def stiffness(model: Path = typer.Argument(..., help="model YAML"),
              at: str = typer.Option(..., "--at", help="end-effector point x,y,z in mm"),
              as_json: bool = typer.Option(False, "--json", help="print JSON (K, C, k_tran, k_rot, rank, frame, units)"),
              foot: Optional[Path] = FOOT, leg: Optional[Path] = LEG):
    """Cartesian stiffness of MODEL at one point."""
    try:
        m = _load(model, foot, leg)
        r = m.stiffness(_point(at))
    except user_errors() as exc:
        _fail(exc)
    if as_json:
        typer.echo(json.dumps(r.to_dict(), indent=1))
        return
    np.set_printoptions(precision=4, linewidth=120)
    typer.echo(f"{m.architecture} at ({at}) mm  [world axes, at the end-effector point]")
    typer.echo(f"K (N/mm, N/rad, N mm/rad):\n{r.K}")
    typer.echo(f"k_tran = {r.k_tran:.4g} mm/N   (largest eigenvalue of C[:3,:3])")
    typer.echo(f"k_rot  = {r.k_rot:.4g} rad/(N mm)   (largest eigenvalue of C[3:,3:])")
    typer.echo(f"rank(K) = {r.rank}, rank(J_q) per chain = {np.asarray(r.chain_rank).tolist()}")


def _grid(m, n: int, slice_: Optional[str]):
    lo, hi = (np.array(v, dtype=float) for v in m.arch.workspace)
    axes = [np.linspace(lo[k], hi[k], n) for k in range(3)]
    fixed = None
    if slice_:
        try:
            name, val = slice_.split("=")
            k = "xyz".index(name.strip())
            axes[k] = np.array([float(val)])
            fixed = (k, float(val))
        except ValueError:
            raise VjmError(f"--slice expects axis=value, e.g. z=0, got {slice_!r}") from None
    G = np.stack(np.meshgrid(*axes, indexing="ij"), axis=-1)
    return axes, G, fixed


@app.command("map")
def map_cmd(model: Path = typer.Argument(..., help="model YAML"),
            grid: int = typer.Option(30, "--grid", help="points per axis"),
            slice_: Optional[str] = typer.Option(None, "--slice", help="fix one axis, e.g. z=0"),
            out: Path = typer.Option(..., "--out", help="output directory (k_tran.png, k_rot.png, map.npz)"),
            foot: Optional[Path] = FOOT, leg: Optional[Path] = LEG):
    """k_tran and k_rot over the workspace box: PNG maps and an .npz of K, k_tran, k_rot."""
    try:
        if grid < 2:
            raise VjmError("--grid must be >= 2")
        m = _load(model, foot, leg)
        axes, G, fixed = _grid(m, grid, slice_)
        P = G.reshape(-1, 3)
        ok = m.arch.reachable(m, P)
        if not ok.any():
            raise VjmError(f"no point of the {grid}-point grid{' at ' + slice_ if slice_ else ''} is reachable "
                           f"by {m.architecture}")
        kt = np.full(len(P), np.nan)
        kr = np.full(len(P), np.nan)
        K = np.full((len(P), 6, 6), np.nan)
        r = m.stiffness_map(P[ok])
        kt[ok], kr[ok], K[ok] = r.k_tran, r.k_rot, r.K
        shape = G.shape[:3]
        # all three files appear together or not at all
        with atomic_path(os.path.join(out, "map.npz")) as npz, \
                atomic_path(os.path.join(out, "k_tran.png")) as png_t, \
                atomic_path(os.path.join(out, "k_rot.png")) as png_r:
            np.savez_compressed(npz, points=P, K=K, k_tran=kt, k_rot=kr, reachable=ok, shape=np.array(shape),
                                note=np.array("K world axes at the end-effector point; k_tran mm/N, "
                                              "k_rot rad/(N mm); NaN = unreachable"))
            _plots({"k_tran": png_t, "k_rot": png_r}, axes, shape, kt, kr, fixed, m.architecture)
    except user_errors() as exc:
        _fail(exc)
    typer.echo(f"{ok.sum()} of {len(P)} points reachable; k_tran {np.nanmin(kt):.3g}..{np.nanmax(kt):.3g} mm/N, "
               f"k_rot {np.nanmin(kr):.3g}..{np.nanmax(kr):.3g} rad/(N mm); wrote {out}/k_tran.png, k_rot.png, map.npz")


def _plots(paths, axes, shape, kt, kr, fixed, title):
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    if fixed is None:  # 3-D grid: show the middle slice along z
        k, idx = 2, shape[2] // 2
    else:
        k, idx = fixed[0], 0
    keep = [a for a in range(3) if a != k]
    for name, val, unit in (("k_tran", kt, "mm/N"), ("k_rot", kr, "rad/(N mm)")):
        V = np.take(val.reshape(shape), idx, axis=k)
        fig, ax = plt.subplots(figsize=(5.5, 4.5))
        im = ax.imshow(V.T, origin="lower", aspect="equal",
                       extent=[axes[keep[0]][0], axes[keep[0]][-1], axes[keep[1]][0], axes[keep[1]][-1]])
        fig.colorbar(im, ax=ax, label=f"{name} [{unit}]")
        ax.set_xlabel(f"{'xyz'[keep[0]]} [mm]")
        ax.set_ylabel(f"{'xyz'[keep[1]]} [mm]")
        ax.set_title(f"{title}: {name}, {'xyz'[k]} = {np.asarray(axes[k])[idx]:.4g} mm")
        fig.tight_layout()
        fig.savefig(paths[name], dpi=110)
        plt.close(fig)


def read_seed_table(path=SEED_TABLE) -> list[dict]:
    if not os.path.isfile(path):
        raise VjmError(f"seed table not found: {path}")
    with open(path, encoding="utf-8") as fh:
        rows = [r for r in csv.DictReader(line for line in fh if not line.startswith("#"))]
    return rows


def table1_rows(models) -> list[dict]:
    """Our k_tran/k_rot at the seed's points next to the seed's values, for each model."""
    seed = read_seed_table()
    out = []
    for m in models:
        rows = [r for r in seed if r["architecture"] == m.architecture]
        if not rows:
            raise VjmError(f"the seed's Table 1 has no {m.architecture}")
        P = np.array([[float(r["x"]), float(r["y"]), float(r["z"])] for r in rows])
        res = m.stiffness_map(P)
        for r, kt, kr in zip(rows, res.k_tran, res.k_rot):
            st, sr = float(r["k_tran_mm_per_N"]), float(r["k_rot_rad_per_Nmm"])
            out.append(dict(architecture=m.architecture, point=r["point"], seed_k_tran=st, k_tran=float(kt),
                            seed_k_rot=sr, k_rot=float(kr)))
    return out


@app.command()
def table1(model_puu: Path = typer.Argument(..., help="3-PUU model YAML"),
           model_prpar: Path = typer.Argument(..., help="3-PRPaR model YAML"),
           foot: Optional[Path] = FOOT,
           leg: Optional[Path] = typer.Option(None, "--leg", help="linkfea JSON for the 3-PUU leg"),
           bar: Optional[Path] = typer.Option(None, "--bar", help="linkfea JSON for one 3-PRPaR bar")):
    """Seed Table 1: our k_tran and k_rot at Q0, Q1, Q2 beside the paper's."""
    try:
        models = [_load(model_puu, foot, leg), _load(model_prpar, foot, bar)]
        for m, arch, path in zip(models, ("orthoglide-3PUU", "orthoglide-3PRPaR"), (model_puu, model_prpar)):
            if m.architecture != arch:
                raise VjmError(f"{path} is a {m.architecture} model; table1 takes the 3-PUU model first, "
                               f"then the 3-PRPaR")
        rows = table1_rows(models)
    except user_errors() as exc:
        _fail(exc)
    typer.echo("k_tran [1e-4 mm/N] and k_rot [1e-7 rad/(N mm)]: ours vs seed Table 1 (ratio ours/seed)")
    typer.echo(f"{'architecture':<19}{'pt':<4}{'k_tran ours':>12}{'seed':>8}{'ratio':>7}"
               f"{'k_rot ours':>12}{'seed':>8}{'ratio':>7}")
    for r in rows:
        typer.echo(f"{r['architecture']:<19}{r['point']:<4}{r['k_tran'] * 1e4:>12.3g}{r['seed_k_tran'] * 1e4:>8.3g}"
                   f"{r['k_tran'] / r['seed_k_tran']:>7.2f}{r['k_rot'] * 1e7:>12.3g}{r['seed_k_rot'] * 1e7:>8.3g}"
                   f"{r['k_rot'] / r['seed_k_rot']:>7.2f}")
    for m in models:
        a = m.actuator
        typer.echo(f"{m.architecture}: L={m.geometry.get('L')} r={m.geometry.get('r')} d={m.geometry.get('d')} mm, "
                   f"actuator {a.stiffness:g} N/mm, foot {_describe(m.foot)}, leg {_describe(m.leg)}")
    typer.echo("The seed publishes neither link sections nor actuator stiffness: ours are chosen (docs/table1.md);"
               " the actuator is set so that k_tran(Q0) matches with the default beam links.")


def _describe(link) -> str:
    s = link.source or {}
    if link.compliance is None:
        return "rigid"
    if "beam" in s:
        b = s["beam"]
        return "beam " + " ".join(f"{k}={v}" for k, v in b.items())
    if "linkfea" in s:
        return f"linkfea {os.path.basename(s['linkfea'])}"
    return "inline compliance"


def _register_extensions():
    try:
        from .discrepancy.cli import register
    except ModuleNotFoundError:
        return
    register(app)


_register_extensions()


def main():
    sys.exit(app())


if __name__ == "__main__":
    main()

"""Command line: ``linkfea compute SPEC ... --out result.json``."""
from __future__ import annotations

import sys
from pathlib import Path
from typing import List, Optional

import numpy as np
import typer
from rich.console import Console
from rich.table import Table

from .mechanics.compliance import TWIST, WRENCH
from .runtime.clirun import HELP_SETTINGS, version_option
from .runtime.errors import LinkFeaError, LinkFeaWarning, warnings_as_lines

app = typer.Typer(add_completion=False, no_args_is_help=True, **HELP_SETTINGS,
                  help="Link compliance by finite elements: CAD -> P2 tets -> 6x6 compliance at the link's frame.")
#: Python arguments whose CLI flag is not their name with dashes (today none: ComputeOptions' names are the flags)
FLAGS: dict[str, str] = {}


@app.callback()
def _root(version: bool = version_option("linkfea")):
    """linkfea: a link's CAD to its 6x6 compliance matrix."""
    warnings_as_lines(LinkFeaWarning)


def matrix_table(M: np.ndarray, title: str, rows, cols) -> Table:
    t = Table(title=title, show_lines=False)
    t.add_column("")
    for c in cols:
        t.add_column(c, justify="right")
    for name, row in zip(rows, M):
        t.add_row(name, *(f"{v: .3e}" for v in row))
    return t


def error_table(diagonal: np.ndarray, err: np.ndarray) -> Table:
    """The diagonal with its estimated discretization error (linkfea.fem.estimate)."""
    t = Table(title=f"estimated discretization error, whole matrix {100 * float(np.max(err)):.2g}% "
                    "(C is too small by about)")
    t.add_column("")
    for tw, w in zip(TWIST, WRENCH):
        t.add_column(f"{tw}/{w}", justify="right")
    t.add_row("C_ii", *(f"{v: .3e}" for v in diagonal))
    t.add_row("error", *(f"{100 * v:.2g}%" for v in err))
    return t


def _fail(msg, traceback: bool = False) -> None:
    """One ``error:`` line, exit 2; with ``traceback``, a link script's own traceback before it."""
    from .runtime.clirun import fail

    fail(msg, FLAGS, traceback)


def _traceback_option():
    return typer.Option(False, "--traceback", help="when the link script fails, also print its traceback "
                                                   "(the script's own frames)")


@app.command()
def compute(
    spec: str = typer.Argument(..., help="cad/ script (path or name such as 'bar'), a STEP file or an STL/OBJ/PLY surface"),
    param: Optional[List[str]] = typer.Option(None, "--param", "-p", help="script parameter NAME=VALUE (repeatable)"),
    mesh_size: Optional[float] = typer.Option(None, "--mesh-size", help="target tet edge length, mm"),
    mode: str = typer.Option("rigid", "--mode", help="rigid (exact tip coupling) or block (pseudo-rigid block)"),
    block_ratio: float = typer.Option(1000.0, "--block-ratio", help="block stiffness factor E_block/E (block mode)"),
    material: Optional[str] = typer.Option(None, "--material", help="material name (steel, aluminium, ...)"),
    base: Optional[str] = typer.Option(None, "--base", help="base selector, e.g. plane:x=0 or box:x0,y0,z0,x1,y1,z1"),
    tip: Optional[str] = typer.Option(None, "--tip", help="tip selector, e.g. plane:x=200"),
    convergence: bool = typer.Option(False, "--convergence", help="3 mesh sizes + Richardson error estimate"),
    tolerance: Optional[str] = typer.Option(None, "--tolerance", help="refine (gmsh, local sizes from the error "
                                            "indicator) until every diagonal entry's estimated error is below "
                                            "this, e.g. 1%"),
    max_dofs: int = typer.Option(1_000_000, "--max-dofs", help="DOF budget of --tolerance"),
    envelope: Optional[float] = typer.Option(None, "--envelope",
                                             help="mesher envelope / bbox diagonal (default 1e-3; smaller = "
                                                  "closer to small curved faces, slower)"),
    mesher: Optional[str] = typer.Option(None, "--mesher", help="gmsh (CAD-exact faces; default for scripts and "
                                         "STEP) or pytetwild (fTetWild; default for STL/OBJ/PLY)"),
    assembler: str = typer.Option("kernel", "--assembler",
                                  help="stiffness assembly: kernel (fast) or skfem (scikit-fem's asm, reference)"),
    solver: str = typer.Option("auto", "--solver", help="linear solver: direct (PARDISO), iterative (CG + "
                               "multigrid) or auto (direct under 150k DOF, iterative from 250k, in between "
                               "direct unless its estimated memory exceeds what is free)"),
    out: Path = typer.Option(Path("out/result.json"), "--out", "-o", help="result JSON; .vtu and .png go beside it"),
    picture: bool = typer.Option(True, "--picture/--no-picture", help="write the .vtu and .png beside the JSON"),
    quiet: bool = typer.Option(False, "--quiet", "-q", help="no progress or tables"),
    traceback: bool = _traceback_option(),
):
    """Compute a link's 6x6 compliance and stiffness at its reference frame."""
    from .cad.params import parse_param_args
    from .options import ComputeOptions
    from .pipeline import compute as run
    from .pipeline import default_material_note
    from .result.fileset import check_result_out, write_result_set

    console = Console(stderr=True, quiet=quiet)
    try:
        check_result_out(out, vtu=picture, png=picture)  # before any work: the FEA may take minutes
        params = parse_param_args(param)
        tol = _fraction(tolerance) if tolerance is not None else None
        opts = ComputeOptions(mesh_size=mesh_size, mode=mode, block_ratio=block_ratio, material=material, base=base,
                              tip=tip, convergence=convergence, envelope=envelope, mesher=mesher,
                              assembler=assembler, solver=solver, tolerance=tol, max_dofs=max_dofs)
        with console.status("starting") as status:
            res = run(spec, params=params, options=opts, progress=lambda msg: status.update(f"[bold]{msg}"))
        written = write_result_set(out, res, vtu=picture, png=picture)
    except LinkFeaError as exc:
        _fail(exc, traceback)
    if not quiet:
        con = Console(width=max(Console().width, 100))
        show(res, con)
        note = default_material_note(spec, material)
        if note:
            con.print(note)
        con.print(f"wrote {', '.join(str(p) for p in written)}")
    if not (res.diagnostics.refinement or {"reached": True})["reached"]:
        raise typer.Exit(code=TOLERANCE_NOT_REACHED)  # written, with the warning line the pipeline gave


TOLERANCE_NOT_REACHED = 3
"""Exit status of ``compute --tolerance`` when the DOF budget stopped the refinement first: the result set
is written, but its estimated error is above what was asked (as ``vjm diagnose``'s 3: written, not conclusive)."""


def _fraction(text: str) -> float:
    """``"1%"`` or ``"0.01"`` -> 0.01, checked against the options' range; the message echoes ``text``."""
    from .options import TOLERANCE
    from .runtime.checks import ArgumentError, number

    t = text.strip()
    try:
        return number(float(t[:-1]) / 100.0 if t.endswith("%") else float(t), "tolerance", TOLERANCE)
    except (ValueError, ArgumentError):
        raise LinkFeaError("--tolerance must be a percentage in (0%, 100%) such as 1%, or a fraction in (0, 1) "
                           f"such as 0.01; got {text!r}") from None


def _convergence_text(solver) -> str:
    c = None if solver is None else solver.convergence
    if not c:
        return ""
    return (f" ({c['levels']} multigrid levels, CG iterations {', '.join(str(i) for i in c['iterations'])}, "
            f"largest relative residual {max(c['relative_residual']):.1e})")


def show(res, console: Console) -> None:
    """Print the compliance and stiffness tables and the diagnostics."""
    f = res.frame
    console.print(f"[bold]{res.name}[/] ({res.material.name}, mode {res.mode}), frame origin "
                  f"{np.round(f.origin, 4).tolist()} mm, x axis {np.round(f.axes[0], 4).tolist()}")
    console.print(matrix_table(res.compliance, "compliance C (t = C w; mm/N, rad/(N mm))", TWIST, WRENCH))
    console.print(matrix_table(res.stiffness, "stiffness K = C^-1 (N/mm, N mm/rad)", WRENCH, TWIST))
    err = res.error_diagonal
    if err is not None:
        console.print(error_table(np.diag(res.compliance), err))
    sharp = (res.diagnostics.sharp_edges or {}).get("note")
    if sharp:
        console.print(sharp)
    ref = res.diagnostics.refinement
    if ref:
        console.print("refinement: " + ref["note"] + "; " + ", ".join(
            f"{st['n_dofs']} DOF {100 * st['error']:.2g}%" for st in ref["steps"]) + f" ({ref['seconds']:.1f} s)")
    d = res.diagnostics
    ee = d.error_estimate
    m = res.mesh_info
    console.print(f"mesh: {m.n_nodes} vertices, {m.n_tets} tets, {m.n_dofs} DOF, "
                  f"edge {m.edge_length:.3g} mm; symmetry error {d.symmetry_error:.2e}, "
                  f"fit residual {d.fit_residual:.2e}, Richardson estimate "
                  + (f"{ee:.2e}" if ee is not None else "not computed (use --convergence)")
                  + f"; solver {res.solver and res.solver.factorizer}" + _convergence_text(res.solver))
    console.print("timing (s): " + ", ".join(f"{k} {v:.2f}" for k, v in res.timing.items()))
    if res.source_sha256:
        console.print(f"source: {res.source} (sha256 {res.source_sha256[:16]}...)")


@app.command("compare")
def compare_cmd(
    spec: str = typer.Argument(..., help="cad/ script (path or name such as 'bar') or a STEP file"),
    beams: str = typer.Option("1,2,4,8", "--beams", help="numbers of beams N, comma separated"),
    param: Optional[List[str]] = typer.Option(None, "--param", "-p", help="script parameter NAME=VALUE (repeatable)"),
    mesh_size: Optional[float] = typer.Option(None, "--mesh-size", help="FEA target tet edge length, mm"),
    mode: str = typer.Option("rigid", "--mode", help="rigid (exact tip coupling) or block (pseudo-rigid block)"),
    material: Optional[str] = typer.Option(None, "--material", help="material name (steel, aluminium, ...)"),
    base: Optional[str] = typer.Option(None, "--base", help="base selector (required for STEP files)"),
    tip: Optional[str] = typer.Option(None, "--tip", help="tip selector (required for STEP files)"),
    out: Path = typer.Option(..., "--out", "-o", help="output folder for compare.json, compare.md, compare.png"),
    force: bool = typer.Option(False, "--force", help="write into a folder that also holds other files (they are "
                                                      "never overwritten or deleted)"),
    quiet: bool = typer.Option(False, "--quiet", "-q", help="no progress or summary"),
    traceback: bool = _traceback_option(),
):
    """Beam or FEA? The FEA compliance against N-beam models cut from the CAD (see linkfea.beam.compare)."""
    from .beam.compare import compare as run
    from .cad.params import parse_param_args

    console = Console(stderr=True, quiet=quiet)
    try:
        params = parse_param_args(param)
        with console.status("starting") as status:
            cmp = run(spec, beams, params=params, mesh_size=mesh_size, mode=mode, out=out, material=material,
                      base=base, tip=tip, progress=lambda msg: status.update(f"[bold]{msg}"), force=force)
    except LinkFeaError as exc:
        _fail(exc, traceback)
    if not quiet:
        t = Table(title=f"{cmp.link}: max principal compliance error vs FEA, % (translation / rotation)")
        for c in ("N", "Euler-Bernoulli", "Timoshenko", "max angle (deg)"):
            t.add_column(c, justify="right")
        for m in cmp.beams:
            e, s = m.euler_bernoulli["summary"], m.timoshenko["summary"]
            t.add_row(str(m.n), *(f"{100 * x['max_principal_error_translation']:.1f} / "
                                     f"{100 * x['max_principal_error_rotation']:.1f}" for x in (e, s)),
                      f"{s['max_angle_deg']:.1f}")
        con = Console(width=max(Console().width, 100))
        con.print(t)
        con.print(f"wrote {', '.join(str(Path(out) / n) for n in ('compare.json', 'compare.md', 'compare.png'))}")


@app.command("sweep")
def sweep_cmd(
    spec: str = typer.Argument(..., help="cad/ script (path or name such as 'bar') or a STEP file"),
    param: Optional[List[str]] = typer.Option(None, "--param", "-p",
                                              help="NAME=SPEC, SPEC a list 10,15,20 or a range lo:hi:step "
                                                   "(repeatable: full grid)"),
    sample: Optional[int] = typer.Option(None, "--sample", help="a Latin hypercube of N designs instead of the grid"),
    seed: Optional[int] = typer.Option(None, "--seed", help="seed of the Latin hypercube"),
    mesh_size: Optional[float] = typer.Option(None, "--mesh-size", help="target tet edge length, mm"),
    mode: str = typer.Option("rigid", "--mode", help="rigid (exact tip coupling) or block (pseudo-rigid block)"),
    block_ratio: float = typer.Option(1000.0, "--block-ratio", help="block stiffness factor E_block/E (block mode)"),
    material: Optional[str] = typer.Option(None, "--material", help="material name (steel, aluminium, ...)"),
    base: Optional[str] = typer.Option(None, "--base", help="base selector (required for STEP files)"),
    tip: Optional[str] = typer.Option(None, "--tip", help="tip selector (required for STEP files)"),
    envelope: Optional[float] = typer.Option(None, "--envelope", help="mesher envelope / bbox diagonal"),
    convergence: bool = typer.Option(False, "--convergence", help="3 mesh sizes + Richardson error estimate"),
    mesher: Optional[str] = typer.Option(None, "--mesher", help="gmsh or pytetwild (default: as linkfea compute)"),
    out: Path = typer.Option(..., "--out", "-o", help="output folder: sweep.parquet, sweep.csv, sweep.png, results/"),
    force: bool = typer.Option(False, "--force", help="write into a folder that also holds other files (they are "
                                                      "never overwritten or deleted)"),
    scheduler: Optional[str] = typer.Option(None, "--scheduler", help="address of a running Dask scheduler"),
    workers: Optional[int] = typer.Option(None, "--workers", help="local worker processes (default: one per core)"),
    memory_limit: str = typer.Option("auto", "--memory-limit", help="per local worker, e.g. 4GB (auto: RAM/workers)"),
    retry_failed: bool = typer.Option(False, "--retry-failed", help="recompute designs recorded as failed"),
    plot: Optional[str] = typer.Option(None, "--plot", help="compliance entries to plot, e.g. dy_Fy,rz_Mz "
                                                            "(default: the diagonal)"),
    quiet: bool = typer.Option(False, "--quiet", "-q", help="no progress bar or summary"),
    traceback: bool = _traceback_option(),
):
    """Run the pipeline over a grid or sample of link parameters on Dask (resumable)."""
    from .files.outputs import check_folder
    from .options import ComputeOptions
    from .sweep import SWEEP_FILES, make_sweep, run_sweep

    try:
        check_folder(out, SWEEP_FILES, force=force)
        opts = ComputeOptions(mesh_size=mesh_size, mode=mode, block_ratio=block_ratio, material=material, base=base,
                              tip=tip, envelope=envelope, convergence=convergence, mesher=mesher)
        sw = make_sweep(spec, param or [], opts, sample=sample, seed=seed)
        rep = run_sweep(sw, out, scheduler=scheduler, workers=workers, memory_limit=memory_limit,
                        retry_failed=retry_failed, plot=plot.split(",") if plot else None, progress=not quiet,
                        force=force)
    except LinkFeaError as exc:
        _fail(exc, traceback)
    if not quiet or rep.interrupted:
        n_ok = sum(r["status"] == "ok" for r in rep.rows)
        print(f"{rep.n_designs} designs: {len(rep.skipped)} already done, {len(rep.computed)} computed, "
              f"{len(rep.failed)} failed, {len(rep.unfinished)} unfinished; {n_ok} ok in the table "
              f"({rep.seconds:.1f} s); wrote {out}/sweep.parquet, sweep.csv, sweep.png, results/", file=sys.stderr)
        print(f"source: {sw.spec} (sha256 {sw.source_sha[:16]}...)", file=sys.stderr)
    if rep.interrupted:
        raise typer.Exit(code=130)
    if rep.unfinished:
        print(f"error: {len(rep.unfinished)} designs unfinished (lost workers); rerun to complete them",
              file=sys.stderr)
        raise typer.Exit(code=1)


def _register() -> None:
    """The commands kept in modules of their own."""
    from .clifaces import faces

    app.command("faces")(faces)


_register()


def main(argv=None) -> int:
    """Console entry point (``linkfea``): the exit status; a usage error is one ``error:`` line."""
    from .runtime.clirun import run

    return run(app, argv, "linkfea")


if __name__ == "__main__":
    sys.exit(main())

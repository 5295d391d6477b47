"""Post-processing: the deformed mesh as .vtu and an off-screen PNG picture."""
from __future__ import annotations

from pathlib import Path

import numpy as np

from ..mechanics.compliance import WRENCH

PICTURE_CASE = 1
"""Load case drawn by default: unit Fy (lateral bending)."""


def solution_grid(res):
    """pyvista UnstructuredGrid of the P2 mesh with the 6 displacement fields as point data.

    Point arrays ``u_Fx`` ... ``u_Mz`` (mm per N or per N mm); cell array
    ``block`` (1 for reference-block cells).
    """
    import pyvista as pv

    sol = res.solution
    cells = np.asarray(sol.cells, dtype=np.int64)
    grid = pv.UnstructuredGrid({pv.CellType.QUADRATIC_TETRA: cells}, np.asarray(sol.points, dtype=float))
    for k, name in enumerate(WRENCH):
        grid.point_data[f"u_{name}"] = np.asarray(sol.displacements[k], dtype=float)
    grid.cell_data["block"] = np.asarray(res.mesh.block, dtype=np.int8)
    return grid


def write_vtu(path, res) -> Path:
    """Write the P2 mesh with the 6 unit-load displacement fields to ``path`` (written as part of
    the result's set by :mod:`linkfea.result.fileset`, which hands in a temporary path)."""
    from vtkmodules.vtkIOXML import vtkXMLUnstructuredGridWriter

    # VTK's own file output crashes the process (SIGSEGV) when the disk fills up: the XML is made in
    # memory (the bytes pyvista's save writes: binary, zlib) and written by Python, which reports the error.
    w = vtkXMLUnstructuredGridWriter()
    w.SetInputData(solution_grid(res))
    w.SetDataModeToBinary()
    w.SetCompressorTypeToZLib()
    w.SetWriteToOutputString(True)
    if not w.Write():
        raise OSError(f"VTK could not write the mesh of {res.name}")
    path = Path(path)
    try:
        with open(path, "wb") as fh:
            fh.write(w.GetOutputString().encode("ascii"))
    except OSError as exc:
        raise OSError(exc.errno, exc.strerror, str(path)) from None  # name the file (a full disk names none)
    return path


def write_png(path, res, case: int = PICTURE_CASE, scale: float | None = None,
              window_size=(1200, 800)) -> Path:
    """Off-screen picture of load case ``case`` deformed by ``scale``, written to ``path``.

    The default scale makes the largest displacement 10 % of the bounding-box
    diagonal; it is printed in the title.
    """
    path = Path(path)
    pl = plotter(solution_grid(res), res.name, case, scale=scale, off_screen=True, window_size=window_size)
    try:
        pl.screenshot(str(path))
    finally:
        pl.close()
    return path


def plotter(grid, name: str, case: int = PICTURE_CASE, scale: float | None = None, off_screen: bool | None = None,
            window_size=(1200, 800)):
    """A pyvista Plotter of load case ``case`` of ``grid`` (see :func:`solution_grid`), deformed by ``scale``."""
    import pyvista as pv
    from vtkmodules.vtkCommonCore import vtkLogger

    # Without a display VTK warns before falling back to off-screen rendering: not the user's business.
    vtkLogger.SetStderrVerbosity(vtkLogger.VERBOSITY_ERROR)
    u = grid.point_data[f"u_{WRENCH[case]}"]
    umax = float(np.linalg.norm(u, axis=1).max())
    diag = float(np.linalg.norm(np.ptp(grid.points, axis=0)))
    if scale is None:
        scale = 0.1 * diag / umax if umax > 0 else 1.0
    grid.point_data["|u|"] = np.linalg.norm(u, axis=1)
    warped = grid.warp_by_vector(f"u_{WRENCH[case]}", factor=scale)
    pl = pv.Plotter(off_screen=off_screen, window_size=list(window_size))
    pl.add_mesh(grid.extract_surface(algorithm="dataset_surface"), style="wireframe", color="grey", opacity=0.3)
    pl.add_mesh(warped.extract_surface(algorithm="dataset_surface"), scalars="|u|", show_edges=False,
                scalar_bar_args={"title": f"displacement per unit {WRENCH[case]} (mm)"})
    pl.add_text(f"{name}: unit {WRENCH[case]}, deformation x {scale:.3g}", font_size=10)
    pl.view_isometric()
    return pl

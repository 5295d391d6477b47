"""A link's computed compliance as one object: matrices, frame, mesh, diagnostics, save/load, plot.

:func:`linkfea.compute` returns a :class:`LinkResult`; :meth:`LinkResult.save` writes the
result JSON (schema ``linkfea.result/1``, see :mod:`linkfea.result.schema`) and, when the FEA fields
are at hand, the ``.vtu`` of the deformed mesh beside it; :func:`load` reads both back.
Everything the JSON holds round-trips exactly (floats are written with ``repr``).
"""
from __future__ import annotations

import html
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Optional

import numpy as np

from ..mechanics.compliance import TWIST, UNITS_SHORT, WRENCH, Compliance
from ..mechanics.frames import Frame
from ..mechanics.materials import Material
from ..runtime.errors import LinkFeaError
from ..solvers.factorization import SolverRecord
from .post import PICTURE_CASE
from .records import Diagnostics, MeshInfo


@dataclass(frozen=True, eq=False)
class LinkResult:
    """Everything the link stage produced for one link.

    Attributes
    ----------
    value : Compliance
        The checked 6x6 compliance with its frame and units: what vjm takes.
    name, source : str
        The link's name and its CAD script or STEP file.
    params : dict
        Script parameters used.
    material : Material
    mode : str
        ``rigid`` or ``block`` tip coupling.
    block_ratio : float or None
    mesh_info : MeshInfo
        mesher, n_nodes, n_tets, n_dofs, n_p2_nodes, edge_length, envelope, element, quality, cache_key.
    diagnostics : Diagnostics
        symmetry_error, fit_residual, min_eigenvalue, error_estimate (None unless convergence ran), notes;
        ``discretization_error`` (the recovered-stress estimate per diagonal entry, see
        :attr:`error_diagonal`) and ``sharp_edges`` (count of sharp re-entrant CAD edges and what it means).
    solver : SolverRecord or None
        The linear solver that ran: ``factorizer`` (pardiso, superlu, cg+p1mg) and, if PARDISO was
        wanted but failed, ``fallback_reason``; ``choice`` and ``convergence`` when there are.
    timing : dict
        Seconds per stage: cad, mesh, assemble, factor, solve, fit (finest mesh), total.
    versions : dict
        Python and package versions of the run.
    volume : float or None
        CAD volume of the link body in mm^3 (the reference block is no part of the link);
        with the material's density it gives :attr:`mass` in kg.
    source_sha256 : str
        SHA-256 of the script, STEP or surface file that was used ('' if unknown); ``source`` is
        its absolute path.
    link, mesh, solution, fit, estimate
        The CAD :class:`~linkfea.cad.link.Link`, the :class:`~linkfea.mesh.linkmesh.LinkMesh`, the
        :class:`~linkfea.fem.problem.FeaSolution`, the :class:`~linkfea.fem.fit.FittedCompliance` and the
        :class:`~linkfea.fem.estimate.ErrorEstimate` (with its per-element indicator);
        None for a result read by :func:`load` (the JSON keeps their summaries).
    path : Path or None
        The JSON this result was loaded from or last saved to.
    """

    value: Compliance
    name: str
    source: str
    params: dict
    material: Material
    mode: str
    block_ratio: Optional[float]
    mesh_info: MeshInfo
    diagnostics: Diagnostics
    solver: Optional[SolverRecord] = None
    timing: dict = field(default_factory=dict)
    versions: dict = field(default_factory=dict)
    volume: Optional[float] = None
    source_sha256: str = ""
    link: Any = field(default=None, repr=False)
    mesh: Any = field(default=None, repr=False)
    solution: Any = field(default=None, repr=False)
    fit: Any = field(default=None, repr=False)
    estimate: Any = field(default=None, repr=False)
    path: Optional[Path] = field(default=None, compare=False)

    # ------------------------------------------------------------------ values
    @property
    def compliance(self) -> np.ndarray:
        """6x6 compliance ``t = C w`` (mm/N, rad/N, mm/(N mm), rad/(N mm) by block), order Fx..Mz."""
        return self.value.matrix

    @property
    def stiffness(self) -> np.ndarray:
        """6x6 stiffness ``K = C^-1`` (N/mm, N/rad, N, N mm/rad by block)."""
        return self.value.stiffness

    @property
    def frame(self) -> Frame:
        """The reference frame of both matrices (origin and axes in CAD coordinates, mm)."""
        return self.value.frame

    @property
    def units(self) -> dict:
        return self.value.units

    @property
    def error_diagonal(self) -> Optional[np.ndarray]:
        """Estimated relative discretization error of each diagonal entry (order Fx..Mz): the
        computed compliance is too small by about this fraction (:mod:`linkfea.fem.estimate`).
        None for a result saved without it."""
        d = (self.diagnostics.discretization_error or {}).get("diagonal")
        return None if d is None else np.asarray(d, dtype=float)

    @property
    def mass(self) -> Optional[float]:
        """The link body's mass in kg (None without a volume or a material density)."""
        if self.volume is None:
            return None
        m = self.material.mass_kg(self.volume)
        return m if np.isfinite(m) else None

    # ------------------------------------------------------------------ files
    def to_dict(self) -> dict:
        """The result JSON document (schema ``linkfea.result/1``)."""
        from ..files.atomic import plain
        from .schema import SCHEMA

        return plain({
            "schema": SCHEMA,
            "name": self.name,
            "source": str(self.source),
            "source_sha256": self.source_sha256 or None,
            "params": dict(self.params),
            "material": {"name": self.material.name, "E": self.material.E, "nu": self.material.nu,
                         "density": self.material.density},
            "mode": self.mode,
            "volume_mm3": self.volume,
            "mass_kg": self.mass,
            "block_ratio": self.block_ratio,
            "compliance": self.compliance,
            "stiffness": self.stiffness,
            "order": {"wrench": WRENCH, "twist": TWIST},
            "units": self.units,
            "frame": self.frame.to_dict(),
            "mesh": self.mesh_info.to_dict(),
            "diagnostics": self.diagnostics.to_dict(),
            "solver": {} if self.solver is None else self.solver.to_dict(),
            "timing": dict(self.timing),
            "versions": dict(self.versions),
        })

    def save(self, path, vtu: bool = True) -> Path:
        """Write the result JSON to ``path`` and, if the FEA solution is at hand and ``vtu`` is true,
        the deformed P2 mesh beside it (``path`` with suffix ``.vtu``), as one set
        (:mod:`linkfea.result.fileset`).  An existing file there that is not a linkfea result is refused."""
        from .fileset import write_result_set

        path = Path(path)
        write_result_set(path, self, vtu=vtu, png=False)
        object.__setattr__(self, "path", path)
        return path

    # ------------------------------------------------------------------ pictures
    def to_pyvista(self):
        """pyvista UnstructuredGrid of the P2 mesh with point arrays ``u_Fx`` ... ``u_Mz``
        (mm per unit N or N mm) and cell array ``block``.  For a loaded result, read from the
        ``.vtu`` saved beside the JSON."""
        if self.solution is not None:
            from .post import solution_grid

            return solution_grid(self)
        vtu = self.path.with_suffix(".vtu") if self.path is not None else None
        if vtu is None or not vtu.is_file():
            raise LinkFeaError(f"result {self.name!r} has no mesh: it was loaded from JSON without the .vtu "
                               f"beside it ({vtu})")
        import pyvista as pv

        from .fileset import check_companion

        check_companion(self.path, "vtu")
        return pv.read(vtu)

    def plot(self, case=PICTURE_CASE, scale: float | None = None, off_screen: bool | None = None,
             screenshot=None, window_size=(1200, 800)):
        """Show load case ``case`` (index or name such as ``"Fy"``) on the deformed mesh.

        ``off_screen=True`` renders without a window; ``screenshot`` writes a PNG (atomic).
        The default scale makes the largest displacement 10 % of the bounding-box diagonal.
        Returns the pyvista Plotter (closed once shown or saved).
        """
        from .post import plotter

        k = WRENCH.index(case) if isinstance(case, str) else int(case)
        pl = plotter(self.to_pyvista(), self.name, k, scale=scale, off_screen=off_screen, window_size=window_size)
        if screenshot is not None:
            from ..files.atomic import atomic_path

            try:
                with atomic_path(Path(screenshot)) as tmp:
                    pl.screenshot(str(tmp))
            finally:
                pl.close()
        elif off_screen is not True:
            pl.show()
        return pl

    # ------------------------------------------------------------------ display
    def __repr__(self) -> str:
        o = np.round(self.frame.origin, 4).tolist()
        x = np.round(self.frame.axes[0], 4).tolist()
        n = self.mesh_info.n_dofs
        return (f"LinkResult({self.name!r}, {self.material.name}, mode {self.mode}, {n} DOF; "
                f"frame origin {o} mm, x axis {x})\n"
                f"compliance C ({UNITS_SHORT}):\n{np.array2string(self.compliance, precision=4, max_line_width=120)}\n"
                f"stiffness K = C^-1 (N/mm, N/rad, N, N mm/rad by block):\n"
                f"{np.array2string(self.stiffness, precision=4, max_line_width=120)}")

    def _repr_html_(self) -> str:
        def table(M, title, rows, cols):
            head = "".join(f"<th>{c}</th>" for c in cols)
            body = "".join(f"<tr><th>{r}</th>" + "".join(f"<td>{v:.4e}</td>" for v in row) + "</tr>"
                           for r, row in zip(rows, M))
            return (f"<table><caption>{html.escape(title)}</caption><tr><th></th>{head}</tr>{body}</table>")

        o = np.round(self.frame.origin, 4).tolist()
        x = np.round(self.frame.axes[0], 4).tolist()
        d = self.diagnostics
        ee = d.error_estimate
        m = self.mesh_info
        factorizer = None if self.solver is None else self.solver.factorizer
        info = (f"<p><b>{html.escape(self.name)}</b> ({html.escape(self.material.name)}, E = {self.material.E:g} MPa, "
                f"nu = {self.material.nu:g}; mode {self.mode}); frame origin {o} mm, x axis {x} (CAD coordinates)."
                f"<br>mesh: {m.n_tets} P2 tets, {m.n_dofs} DOF, edge {m.edge_length:.3g} mm; "
                f"solver {html.escape(str(factorizer))}; symmetry error "
                f"{d.symmetry_error:.2e}, fit residual {d.fit_residual:.2e}, "
                f"Richardson estimate {'not computed' if ee is None else f'{ee:.2e}'}</p>")
        return (info + self._error_html() + table(self.compliance, f"compliance C ({UNITS_SHORT})", TWIST, WRENCH)
                + table(self.stiffness, "stiffness K = C^-1 (N/mm, N/rad, N, N mm/rad by block)", WRENCH, TWIST))

    def _error_html(self) -> str:
        err = self.error_diagonal
        if err is None:
            return ""
        head = "".join(f"<th>{t}/{w}</th>" for t, w in zip(TWIST, WRENCH))
        vals = "".join(f"<td>{100 * v:.2g}%</td>" for v in err)
        sharp = (self.diagnostics.sharp_edges or {}).get("note", "")
        return (f"<table><caption>estimated discretization error of the diagonal (the computed compliance is too "
                f"small by about this much; whole matrix {100 * max(err):.2g}%)</caption><tr>{head}</tr>"
                f"<tr>{vals}</tr></table>" + (f"<p>{html.escape(sharp)}</p>" if sharp else ""))


def compliance_of(doc: dict, path) -> Compliance:
    """The Compliance (matrix, frame, units) of a document read by :func:`linkfea.result.schema.read_result`."""
    return Compliance(doc["compliance"], doc["frame_obj"], doc["units"], what=f"{path}: compliance")


def read_compliance(path) -> Compliance:
    """Only the Compliance of a result JSON (what vjm needs), through the one reader
    :func:`linkfea.result.schema.read_result`: a JSON with ``compliance``, ``frame`` and ``units`` suffices."""
    from .schema import read_result

    return compliance_of(read_result(path), path)


def load(path) -> LinkResult:
    """Read a result JSON written by :meth:`LinkResult.save` or ``linkfea compute``.

    The compliance goes through the one check (:mod:`linkfea.mechanics.compliance`); a ``.vtu`` beside
    the JSON, if present, is what :meth:`LinkResult.to_pyvista` and :meth:`LinkResult.plot` show.
    """
    from .schema import read_result

    path = Path(path)
    doc = read_result(path)
    try:
        mat = doc["material"]
        density = mat.get("density")
        material = Material(str(mat["name"]), float(mat["E"]), float(mat["nu"]),
                            None if density is None else float(density))
        return LinkResult(
            value=compliance_of(doc, path),
            name=str(doc["name"]), source=str(doc["source"]), params=dict(doc.get("params") or {}),
            material=material, mode=str(doc["mode"]), block_ratio=doc.get("block_ratio"),
            mesh_info=MeshInfo.from_dict(doc["mesh"]), diagnostics=Diagnostics.from_dict(doc["diagnostics"]),
            solver=SolverRecord.from_dict(doc["solver"]) if doc.get("solver") else None,
            timing=dict(doc.get("timing") or {}),
            versions=dict(doc.get("versions") or {}), path=path,
            volume=None if doc.get("volume_mm3") is None else float(doc["volume_mm3"]),
            source_sha256=str(doc.get("source_sha256") or ""))
    except (KeyError, TypeError, ValueError) as exc:
        raise LinkFeaError(f"{path}: not a complete linkfea result ({exc!r})") from None


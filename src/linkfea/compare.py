"""Beam or FEA?  N-beam equivalents of a CAD link and their errors against the FEA compliance.

Beam equivalent (:func:`link_beam_model`)
    The body is cut by N planes normal to the beam axis (default: the link
    frame's x) at the mid-stations of N equal segments between the base and
    the tip interface centroids (projected on the axis).  Each cut gives a
    section (sectionproperties, :mod:`linkfea.sections`); segment i is a
    prismatic Timoshenko (or eq. 14 Euler-Bernoulli) beam along a line parallel
    to the axis through that section's centroid, bending about its principal
    axes.  The segments are clamped end to end (rigid jumps between centroid
    lines) and summed as a serial chain at the link frame
    (:func:`linkfea.beam.series_compliance`).  Not modelled: shear-centre
    offsets, taper within a segment, warping restraint, the flexibility of the
    clamp region beyond the base centroid.

Error measures (:func:`compare_compliance`), all dimensionless
    * per entry: ``e_ij = (C_beam_ij - C_fea_ij) / sqrt(C_fea_ii C_fea_jj)``.
      On the diagonal this is the ordinary signed relative error; off the
      diagonal it is the error of the coupling measured against the geometric
      mean of the two direct compliances it couples (the error of the
      correlation coefficient), which stays meaningful where the FEA coupling
      itself is near zero and does not depend on the choice of units.
    * principal compliances: translation and rotation are not commensurable,
      so the 3x3 translational block (displacement of the frame origin under a
      pure force there) and the 3x3 rotational block (rotation under a pure
      couple) are eigen-decomposed separately.  Beam eigenpairs are matched to
      FEA ones by their directions; relative eigenvalue error
      ``|l_beam - l_fea| / l_fea``; direction error = angle between matched
      principal directions.  Eigenvalues closer than 2 % (in either model) form
      a cluster whose directions are not defined one by one: the angle is then
      the largest principal angle between the two clusters' subspaces.
    * summary: largest principal error of both blocks, largest direction angle,
      largest |diagonal error|, largest |coupling error|.
"""
from __future__ import annotations

import io
import itertools
import json
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from .beam import BeamSegment, series_compliance
from .errors import LinkFeaError
from .frames import Frame
from .materials import Material, get_material
from .sections import cut_section, section_constants

DEFAULT_BEAMS = (1, 2, 4, 8)
CLUSTER_TOL = 0.02
LABELS = ("x", "y", "z", "rx", "ry", "rz")
UNITS = {"compliance": "translations mm, rotations rad, forces N, moments N mm: blocks mm/N, rad/N, mm/(N mm), "
                       "rad/(N mm)", "errors": "dimensionless (fractions, not percent)", "angles": "deg"}


# --------------------------------------------------------------------------- beam models
@dataclass(frozen=True)
class BeamModel:
    """An N-beam equivalent of a link, compliances in the link frame.

    Attributes
    ----------
    n : int
    stations : ndarray (n,)
        Cut positions along the beam axis, mm from the link frame origin.
    segments : tuple of BeamSegment
        In the beam frame (x = beam axis, origin = link frame origin).
    sections : tuple of SectionConstants
        Section constants at the stations, beam-frame y-z axes.
    compliance : ndarray (6, 6)
        Timoshenko N-beam compliance in the link frame.
    compliance_eb : ndarray (6, 6)
        Euler-Bernoulli (seed eq. 14) N-beam compliance in the link frame.
    """

    n: int
    stations: np.ndarray
    segments: tuple
    sections: tuple
    compliance: np.ndarray
    compliance_eb: np.ndarray


def beam_frame(frame: Frame, axis=None) -> Frame:
    """The beam frame: the link frame's origin, x along ``axis`` (link-frame components)."""
    if axis is None:
        return frame
    a = np.asarray(axis, dtype=float).reshape(-1)
    if a.size != 3 or not np.all(np.isfinite(a)) or np.linalg.norm(a) == 0:
        raise LinkFeaError(f"beam axis must be a non-zero 3-vector, got {axis}")
    a_cad = frame.axes.T @ (a / np.linalg.norm(a))
    return Frame.from_x(frame.origin, a_cad, y_hint=frame.axes[1] if abs(a_cad @ frame.axes[1]) < 0.9
                        else frame.axes[2])


def beam_model(body, frame: Frame, x_base: float, x_tip: float, n: int, material: Material,
               axis=None) -> BeamModel:
    """N-beam model of a solid between ``x_base`` and ``x_tip`` along the beam axis.

    Parameters
    ----------
    body : cadquery.Shape
    frame : Frame
        The link frame (CAD coordinates); the result is expressed there.
    x_base, x_tip : float
        Ends of the beam along the beam axis, mm from the frame origin (``x_base < x_tip``).
    n : int
        Number of segments (> 0).
    material : Material
    axis : 3-vector, optional
        Beam axis in link-frame components (default x).

    Raises
    ------
    LinkFeaError
        ``n <= 0``, ends in the wrong order, a station that cuts no material or a
        section sectionproperties cannot analyse.
    """
    if isinstance(n, bool) or not isinstance(n, (int, np.integer)) or n <= 0:
        raise LinkFeaError(f"number of beams must be a positive integer, got {n!r}")
    if not (np.isfinite(x_base) and np.isfinite(x_tip) and x_base < x_tip):
        raise LinkFeaError(f"beam ends must satisfy x_base < x_tip along the axis, got {x_base:g}, {x_tip:g} mm")
    bf = beam_frame(frame, axis)
    edges = np.linspace(x_base, x_tip, n + 1)
    stations = 0.5 * (edges[:-1] + edges[1:])
    secs = []
    for x in stations:
        try:
            secs.append(section_constants(cut_section(body, bf, float(x))))
        except LinkFeaError as exc:
            raise LinkFeaError(f"beam model with {n} segments, station x = {x:g} mm: {exc}") from None
    segs = tuple(BeamSegment(float(a), float(b), s.principal_section(), s.centroid, s.angle)
                 for a, b, s in zip(edges[:-1], edges[1:], secs))
    C_t = series_compliance(segs, material.E, material.nu, shear=True)
    C_e = series_compliance(segs, material.E, material.nu, shear=False)
    if bf is not frame:
        C_t, C_e = bf.compliance_to(C_t, frame), bf.compliance_to(C_e, frame)
    return BeamModel(n, stations, segs, tuple(secs), C_t, C_e)


def link_extent(link, axis=None) -> tuple[float, float]:
    """Base and tip interface centroids projected on the beam axis, mm from the frame origin."""
    from .cad import faces_area_centroid

    bf = beam_frame(link.frame, axis)
    out = []
    for name, faces in (("base", link.base_faces), ("tip", link.tip_faces)):
        if not faces:
            raise LinkFeaError(f"{link.name}: the {name} selector finds no face")
        _, c = faces_area_centroid(faces)
        out.append(float((c - bf.origin) @ bf.axes[0]))
    return out[0], out[1]


def link_beam_model(link, n: int, axis=None) -> BeamModel:
    """N-beam equivalent of a :class:`linkfea.cad.Link` (see the module docstring)."""
    x_base, x_tip = link_extent(link, axis)
    if not x_base < x_tip:
        raise LinkFeaError(f"{link.name}: along the beam axis the base ({x_base:g} mm) is not behind the tip "
                           f"({x_tip:g} mm); choose another axis")
    return beam_model(link.body, link.frame, x_base, x_tip, n, get_material(link.material), axis)


# --------------------------------------------------------------------------- error measures
def entry_errors(C_fea, C_beam) -> np.ndarray:
    """Signed ``(C_beam - C_fea) / sqrt(C_fea_ii C_fea_jj)``, 6x6."""
    C_fea, C_beam = np.asarray(C_fea, float), np.asarray(C_beam, float)
    d = np.diag(C_fea)
    if np.any(d <= 0):
        raise LinkFeaError("FEA compliance must have a positive diagonal")
    return (C_beam - C_fea) / np.sqrt(np.outer(d, d))


def principal_errors(A_fea, A_beam, tol: float = CLUSTER_TOL) -> dict:
    """Eigenvalue and direction errors of two symmetric 3x3 blocks (see module docstring)."""
    from scipy.linalg import subspace_angles

    lf, Vf = np.linalg.eigh(np.asarray(A_fea, float))
    lb, Vb = np.linalg.eigh(np.asarray(A_beam, float))
    overlap = np.abs(Vf.T @ Vb) ** 2
    perm = max(itertools.permutations(range(3)), key=lambda p: sum(overlap[i, p[i]] for i in range(3)))
    lb, Vb = lb[list(perm)], Vb[:, list(perm)]
    # Clusters of (nearly) equal eigenvalues in either model: union-find on 3 items.
    group = list(range(3))
    for i, j in itertools.combinations(range(3), 2):
        close = lambda l, i=i, j=j: abs(l[i] - l[j]) <= tol * max(abs(l[i]), abs(l[j]))  # noqa: E731
        if close(lf) or close(lb):
            gi, gj = group[i], group[j]
            group = [gi if g == gj else g for g in group]
    rel = np.empty(3)
    ang = np.empty(3)
    for g in set(group):
        idx = [k for k in range(3) if group[k] == g]
        rel[idx] = np.abs(np.sort(lb[idx]) - np.sort(lf[idx])) / np.sort(lf[idx])
        ang[idx] = np.rad2deg(np.max(subspace_angles(Vf[:, idx], Vb[:, idx])))
    return {"fea_eigenvalues": lf.tolist(), "beam_eigenvalues": lb.tolist(),
            "fea_directions": Vf.T.tolist(), "beam_directions": Vb.T.tolist(),
            "relative_error": rel.tolist(), "angle_deg": ang.tolist(),
            "max_relative_error": float(rel.max()), "max_angle_deg": float(ang.max())}


def compare_compliance(C_fea, C_beam) -> dict:
    """All error measures of a beam compliance against the FEA one (same frame)."""
    E = entry_errors(C_fea, C_beam)
    off = E[np.triu_indices(6, 1)]
    tr = principal_errors(np.asarray(C_fea)[:3, :3], np.asarray(C_beam)[:3, :3])
    ro = principal_errors(np.asarray(C_fea)[3:, 3:], np.asarray(C_beam)[3:, 3:])
    return {
        "entry_error": E.tolist(),
        "diagonal_error": np.diag(E).tolist(),
        "coupling_error": {"C26 (dy-Mz)": float(E[1, 5]), "C35 (dz-My)": float(E[2, 4])},
        "principal": {"translation": tr, "rotation": ro},
        "summary": {
            "max_principal_error": max(tr["max_relative_error"], ro["max_relative_error"]),
            "max_principal_error_translation": tr["max_relative_error"],
            "max_principal_error_rotation": ro["max_relative_error"],
            "max_angle_deg": max(tr["max_angle_deg"], ro["max_angle_deg"]),
            "max_abs_diagonal_error": float(np.max(np.abs(np.diag(E)))),
            "max_abs_coupling_error": float(np.max(np.abs(off))),
        },
    }


# --------------------------------------------------------------------------- the comparison
def parse_beams(text) -> tuple:
    """``"1,2,4,8"`` (or a sequence) -> (1, 2, 4, 8); every N a positive integer."""
    items = [t.strip() for t in text.split(",")] if isinstance(text, str) else list(text)
    out = []
    for t in items:
        try:
            v = int(t)
            if isinstance(t, float) and v != t:
                raise ValueError
        except (TypeError, ValueError):
            raise LinkFeaError(f"--beams: {t!r} is not an integer") from None
        if v <= 0:
            raise LinkFeaError(f"--beams: the number of beams must be > 0, got {v}")
        out.append(v)
    if not out:
        raise LinkFeaError("--beams: give at least one number of beams, e.g. 1,2,4,8")
    return tuple(sorted(set(out)))


def compare_link(link, C_fea, beams=DEFAULT_BEAMS, axis=None, fea_info: dict | None = None) -> dict:
    """The comparison record (JSON-ready) of a link's N-beam models against its FEA compliance.

    ``C_fea`` is the FEA compliance in ``link.frame``.
    """
    beams = parse_beams(beams)
    C_fea = np.asarray(C_fea, dtype=float)
    if C_fea.shape != (6, 6) or not np.all(np.isfinite(C_fea)):
        raise LinkFeaError(f"FEA compliance must be a finite 6x6 matrix, got shape {C_fea.shape}")
    mat = get_material(link.material)
    x_base, x_tip = link_extent(link, axis)
    models = []
    for n in beams:
        m = link_beam_model(link, n, axis)
        models.append({
            "n": n,
            "stations": m.stations.tolist(),
            "sections": [s.to_dict() for s in m.sections],
            "compliance_timoshenko": m.compliance.tolist(),
            "compliance_euler_bernoulli": m.compliance_eb.tolist(),
            "timoshenko": compare_compliance(C_fea, m.compliance),
            "euler_bernoulli": compare_compliance(C_fea, m.compliance_eb),
        })
    return {
        "link": link.name,
        "source": str(link.source),
        "params": {k: v for k, v in link.params.items()},
        "material": {"name": mat.name, "E": mat.E, "nu": mat.nu, "units": "MPa"},
        "frame": link.frame.to_dict(),
        "beam_axis": list(beam_frame(link.frame, axis).axes[0]),
        "beam_length": x_tip - x_base,
        "base_station": x_base,
        "tip_station": x_tip,
        "units": UNITS,
        "order": "wrench Fx Fy Fz Mx My Mz; twist dx dy dz rx ry rz; compliances at the link frame origin, "
                 "components in the link frame",
        "fea": {"compliance": C_fea.tolist(), **(fea_info or {})},
        "beams": models,
        "definitions": {
            "entry_error": "(C_beam_ij - C_fea_ij) / sqrt(C_fea_ii * C_fea_jj), signed",
            "principal": "eigen-decomposition of the 3x3 translational and rotational blocks separately; "
                         "relative_error = |l_beam - l_fea| / l_fea of direction-matched eigenvalues; "
                         f"angle between matched principal directions (subspace angle for eigenvalues within "
                         f"{CLUSTER_TOL:.0%})",
            "sections": "sectionproperties; shear areas geometric (nu = 0 shear function); J from warping",
        },
    }


def fea_compliance(spec, params=None, mesh_size=None, mode="rigid", material=None, base=None, tip=None,
                   progress=None):
    """FEA compliance of a link spec in its frame, and the link: ``(C, link, info)``.

    Runs :func:`linkfea.pipeline.compute` (the one home of CAD -> mesh -> P2
    solve -> rigid fit) and keeps what the comparison record needs.
    """
    from .pipeline import compute as run

    res = run(spec, params=params, mesh_size=mesh_size, mode=mode, material=material, base=base, tip=tip,
              progress=progress)
    return fea_info(res)


def fea_info(res) -> tuple:
    """``(C, link, info)`` of a :class:`linkfea.pipeline.LinkResult`: C in ``res.link.frame``."""
    link, mesh, comp = res.link, res.mesh, res.compliance
    # The pipeline fits at the mesh frame, which is the link frame; the adjoint map makes that explicit.
    C = comp.to_frame(link.frame).matrix
    d = res.diagnostics
    info = {"mode": res.mode, "block_ratio": res.block_ratio,
            "mesh": {"n_nodes": int(mesh.n_nodes), "n_tets": int(mesh.n_tets), "n_dofs": int(res.solution.n_dofs),
                     "edge_length": float(mesh.edge_length), "element": "P2 tetrahedron (10 nodes)"},
            "diagnostics": {k: d.get(k) for k in ("symmetry_error", "fit_residual", "min_eigenvalue",
                                                  "error_estimate")},
            "timing_s": {k: float(v) for k, v in res.timing.items()}}
    return np.asarray(C, dtype=float), link, info


# --------------------------------------------------------------------------- outputs
def markdown_table(record: dict) -> str:
    """The comparison as Markdown: one row per model, errors in percent."""
    lines = [f"### {record['link']}: beam models vs FEA", "",
             f"Beam length {record['beam_length']:.1f} mm along the link x axis; material "
             f"{record['material']['name']} (E = {record['material']['E']:g} MPa, nu = {record['material']['nu']:g}). "
             "Errors in % (signed entry errors relative to sqrt(Cii Cjj) of the FEA; principal errors on the "
             "translational / rotational 3x3 blocks).", "",
             "| model | N | max principal err | transl. | rot. | max angle (deg) | "
             + " | ".join(f"C{i}{i}" for i in range(1, 7)) + " | C26 | C35 | max coupling |",
             "|---|---:|---:|---:|---:|---:|" + "---:|" * 9]
    for m in record["beams"]:
        for key, name in (("euler_bernoulli", "Euler-Bernoulli"), ("timoshenko", "Timoshenko")):
            r = m[key]
            s = r["summary"]
            d = r["diagonal_error"]
            c = r["coupling_error"]
            lines.append(
                f"| {name} | {m['n']} | {100 * s['max_principal_error']:.1f} | "
                f"{100 * s['max_principal_error_translation']:.1f} | {100 * s['max_principal_error_rotation']:.1f} | "
                f"{s['max_angle_deg']:.1f} | " + " | ".join(f"{100 * v:+.1f}" for v in d)
                + f" | {100 * c['C26 (dy-Mz)']:+.1f} | {100 * c['C35 (dz-My)']:+.1f} | "
                f"{100 * s['max_abs_coupling_error']:.1f} |")
    return "\n".join(lines) + "\n"


def figure_png(record: dict) -> bytes:
    """PNG: heatmaps of the signed Timoshenko entry errors for each N, and error versus N."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    models = record["beams"]
    k = len(models)
    fig, axs = plt.subplots(1, k + 1, figsize=(3.2 * k + 4.2, 3.6), gridspec_kw={"width_ratios": [1] * k + [1.3]})
    im = None
    # One colour scale for all N, from 5 % to 100 %, so that small errors stay visible.
    vmax = float(np.clip(max(100.0 * np.max(np.abs(m["timoshenko"]["entry_error"])) for m in models), 5.0, 100.0))
    fmt = "{:.1f}" if vmax < 20 else "{:.0f}"
    for ax, m in zip(axs[:k], models):
        E = 100.0 * np.array(m["timoshenko"]["entry_error"])
        im = ax.imshow(np.clip(E, -vmax, vmax), cmap="RdBu_r", vmin=-vmax, vmax=vmax)
        for i, j in itertools.product(range(6), range(6)):
            ax.text(j, i, fmt.format(E[i, j] + 0.0), ha="center", va="center", fontsize=6)
        ax.set_xticks(range(6), LABELS, fontsize=7)
        ax.set_yticks(range(6), LABELS, fontsize=7)
        ax.set_title(f"N = {m['n']} (Timoshenko)", fontsize=9)
    fig.colorbar(im, ax=list(axs[:k]), shrink=0.8, label="entry error, % of sqrt(Cii Cjj)")
    ns = [m["n"] for m in models]
    ax = axs[k]
    # Log scale: errors of a few % and of several hundred % occur on the same link.  Floor at 0.01 %
    # so that an exact model (error 0) still plots.
    for key, style, nm in (("timoshenko", "-o", "Timoshenko"), ("euler_bernoulli", "--s", "Euler-Bernoulli")):
        for blk in ("translation", "rotation"):
            ax.plot(ns, [max(100 * m[key]["summary"][f"max_principal_error_{blk}"], 1e-2) for m in models], style,
                    label=f"{blk}, {nm}")
    ax.set_xscale("log", base=2)
    ax.set_yscale("log")
    ax.set_xticks(ns, [str(n) for n in ns])
    ax.set_xlabel("N beams")
    ax.set_ylabel("max principal compliance error, %")
    ax.grid(True, alpha=0.3)
    ax.legend(fontsize=6)
    ax.set_title(record["link"], fontsize=9)
    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=110, bbox_inches="tight")
    plt.close(fig)
    return buf.getvalue()


def write_outputs(record: dict, out_dir) -> dict:
    """Write compare.json, compare.md and compare.png into ``out_dir``, each atomically.

    Everything is rendered in memory first; if a write still fails, the files this
    call created (and the folder, if it created it) are removed, so a failure
    leaves no partial set behind.
    """
    from .atomic import write_bytes

    out_dir = Path(out_dir)
    if out_dir.exists() and not out_dir.is_dir():
        raise LinkFeaError(f"--out {str(out_dir)!r} exists and is not a directory")
    blobs = {
        "compare.json": json.dumps(record, indent=1, allow_nan=False).encode(),
        "compare.md": markdown_table(record).encode(),
        "compare.png": figure_png(record),
    }
    made_dir = not out_dir.exists()
    created = []
    try:
        for name, data in blobs.items():
            path = out_dir / name
            new = not path.exists()
            write_bytes(path, data)
            if new:
                created.append(path)
    except BaseException:
        for path in created:
            path.unlink(missing_ok=True)
        if made_dir and out_dir.is_dir() and not any(out_dir.iterdir()):
            out_dir.rmdir()
        raise
    return {name: str(out_dir / name) for name in blobs}


def compare(spec, beams=DEFAULT_BEAMS, params=None, mesh_size=None, mode="rigid", out=None, axis=None,
            material=None, base=None, tip=None, progress=None) -> dict:
    """FEA versus N-beam models of a link; optionally write ``out``/compare.{json,md,png}.

    Parameters
    ----------
    spec : str or Path
        A cad/ script (name or path) or a STEP file.
    beams : sequence of int or str
        Numbers of beams N, e.g. ``"1,2,4,8"``.
    params : dict, optional
        Script parameters.
    mesh_size : float, optional
        FEA target edge length, mm.
    mode : {"rigid", "block"}
    out : path, optional
        Output folder.
    axis : 3-vector, optional
        Beam axis in link-frame components (default x).
    material, base, tip : str, optional
        Material override and interface selectors (required for a STEP file),
        as in :func:`linkfea.pipeline.compute`.
    progress : callable, optional
        Called with a short message at each FEA stage.

    Returns
    -------
    dict
        The comparison record (as written to compare.json).
    """
    beams = parse_beams(beams)  # fail before the (slow) FEA
    if out is not None and Path(out).exists() and not Path(out).is_dir():
        raise LinkFeaError(f"--out {str(out)!r} exists and is not a directory")
    C, link, info = fea_compliance(spec, params, mesh_size, mode, material, base, tip, progress)
    record = compare_link(link, C, beams, axis, info)
    if out is not None:
        write_outputs(record, out)
    return record


# --------------------------------------------------------------------------- library report
def library_report(names=None, beams=DEFAULT_BEAMS, img_dir="docs/img", mesh_size=None) -> str:
    """Compare every bundled cad/ link at its default parameters; Markdown of the results.

    PNGs go to ``img_dir/beam_vs_fea_<name>.png``.  A link whose comparison fails is
    reported with its error message instead of numbers.
    """
    from .atomic import write_bytes
    from .cad import CAD_DIR

    names = names or sorted(p.stem for p in CAD_DIR.glob("*.py") if not p.stem.startswith("_"))
    img_dir = Path(img_dir)
    rows, details = [], []
    for name in names:
        try:
            rec = compare(name, beams, mesh_size=mesh_size)
            write_bytes(img_dir / f"beam_vs_fea_{name}.png", figure_png(rec))
        except LinkFeaError as exc:
            rows.append(f"| {name} | – | failed: {exc} | | | | |")
            continue
        for m in rec["beams"]:
            t, e = m["timoshenko"]["summary"], m["euler_bernoulli"]["summary"]
            rows.append(f"| {name} | {m['n']} | {100 * e['max_principal_error_translation']:.0f} / "
                        f"{100 * e['max_principal_error_rotation']:.0f} | "
                        f"{100 * t['max_principal_error_translation']:.0f} / {100 * t['max_principal_error_rotation']:.0f}"
                        f" | {t['max_angle_deg']:.1f} | {100 * t['max_abs_diagonal_error']:.0f} | "
                        f"{100 * t['max_abs_coupling_error']:.0f} |")
        mesh = rec["fea"].get("mesh", {})
        details.append(markdown_table(rec) + f"\nFEA: {mode_text(rec)}; mesh {mesh}.\n\n"
                       f"![{name}](img/beam_vs_fea_{name}.png)\n")
    head = ("| link | N | EB max principal error, transl. / rot. (%) | Timoshenko, transl. / rot. (%) | "
            "Timoshenko max angle (deg) | Timoshenko max abs diagonal (%) | Timoshenko max abs coupling (%) |\n"
            "|---|---:|---:|---:|---:|---:|---:|\n")
    return head + "\n".join(rows) + "\n\n" + "\n".join(details)


def mode_text(rec: dict) -> str:
    return str(rec["fea"].get("mode", "rigid")) + " tip coupling"


if __name__ == "__main__":  # python -m linkfea.compare [names...]: the library results as Markdown
    import sys

    print(library_report(sys.argv[1:] or None))

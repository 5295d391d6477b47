"""``linkfea faces PART``: the faces a selector can pick, each with a ready selector, and a preview.

Registered on :data:`linkfea.cli.app` (one module per command); the listing is
:func:`linkfea.cad.faces.face_groups`, the picture :func:`linkfea.cad.faces.write_preview`.
"""
from __future__ import annotations

from pathlib import Path
from typing import Optional

import typer

from .runtime.errors import LinkFeaError


def faces(
    spec: str = typer.Argument(..., help="a STEP file or an STL/OBJ/PLY surface"),
    base: Optional[str] = typer.Option(None, "--base", help="base selector to preview, e.g. plane:x=0"),
    tip: Optional[str] = typer.Option(None, "--tip", help="tip selector to preview, e.g. plane:z=105"),
    preview: Optional[Path] = typer.Option(None, "--preview", help="write a PNG of the part with the base "
                                           "(magenta) and tip (orange) faces and the link's frame; needs "
                                           "--base and --tip"),
):
    """List the planar and cylindrical faces of a part with a selector for each (for --base and --tip)."""
    from .cad import build_link, is_step
    from .cad.faces import check_preview, face_groups, write_preview
    from .cad.surface import is_surface
    from .runtime.clirun import fail

    try:
        if not (is_step(spec) or is_surface(spec)):
            raise LinkFeaError(f"{spec}: linkfea faces reads a STEP file or an STL/OBJ/PLY surface "
                               "(a cad/ script names its own faces)")
        if preview is not None and (base is None or tip is None):
            raise LinkFeaError("--preview draws the base and the tip: give --base and --tip too")
        if preview is not None:  # before any work: never over a file linkfea did not write
            check_preview(preview)
        if base is not None and tip is not None:
            link = build_link(spec, base=base, tip=tip, with_block=False)
            body = link.body
        else:
            link = None
            body = _body(spec)
        groups = face_groups(body)
        written = write_preview(link, preview) if preview is not None and link is not None else None
    except LinkFeaError as exc:
        fail(exc)
    print(f"{len(groups)} selectable face groups of {spec} (largest first); use a selector as --base or --tip:")
    for g in groups:
        print("  " + g.line())
    if written is not None:
        print(f"wrote {written}")


def _body(spec):
    """The checked solid of a STEP or surface file, without selectors."""
    from .cad.step import read_step_solid
    from .cad.surface import is_surface, read_surface, solid_from_triangles

    if is_surface(spec):
        V, F = read_surface(spec)
        return solid_from_triangles(V, F, Path(spec).name)
    return read_step_solid(spec)

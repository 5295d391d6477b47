"""The CAD stage: a link's geometry as a :class:`~linkfea.cad.link.Link`, from a CadQuery script,
a STEP file or a triangle surface (:func:`build_link`, the one place that dispatches on the input).

Its parts: :mod:`linkfea.cad.link` (the link value and its checks), :mod:`linkfea.cad.selectors`
(selector syntax and face picking), :mod:`linkfea.cad.step` (STEP loading and validation, frame and
block from the tip faces), :mod:`linkfea.cad.surface` (STL, OBJ, PLY) and :mod:`linkfea.cad.params`
(script parameters).  A link script imports what it needs from here: ``Link``, the selectors ``Plane``
and ``Box`` and ``resolve_params``.
"""
from __future__ import annotations

import importlib.util
import sys
from dataclasses import replace
from pathlib import Path

from ..mechanics.materials import DEFAULT_MATERIAL, get_material
from ..runtime.errors import LinkFeaError, ScriptError
from ..runtime.resources import cad_dir, find_script
from .link import Link, check_link
from .params import resolve_params  # noqa: F401  (for link scripts)
from .selectors import Box, Plane, parse_selector  # noqa: F401  (Box, Plane: for link scripts)
from .step import interface_frame_and_block, load_step
from .surface import is_surface, load_surface

CAD_DIR = cad_dir()
"""Folder of the bundled link scripts (``bar``, ``orthoglide_foot``, ...)."""


def resolve_script(spec: str | Path) -> Path:
    """A cad/ script path, or a bare name like ``bar`` (a local ``./bar.py`` or ``./cad/bar.py`` wins
    over the bundled one): see :func:`linkfea.runtime.resources.find_script`."""
    return find_script(spec)


def script_error(path: Path, exc: BaseException, what: str) -> ScriptError:
    """``exc`` raised by the user's script ``path`` (while ``what``) as one line: the script, its deepest
    line in the traceback and the exception; the traceback from the script's first frame on as details."""
    import traceback

    tb = traceback.TracebackException.from_exception(exc)
    mine = [i for i, fr in enumerate(tb.stack) if Path(fr.filename) == path]
    line = tb.stack[mine[-1]].lineno if mine else None
    if isinstance(exc, SyntaxError) and exc.filename and Path(exc.filename) == path:
        line = exc.lineno
    if mine or isinstance(exc, SyntaxError):  # a syntax error: the importer's frames say nothing
        tb.stack = traceback.StackSummary.from_list(tb.stack[mine[0]:] if mine else [])
    where = f"{path}, line {line}" if line is not None else str(path)
    text = exc.msg if isinstance(exc, SyntaxError) else str(exc)
    if isinstance(exc, SystemExit):
        text = f"the script called sys.exit({exc.code!r}) while {what}; a link script must return a Link, not exit"
        return ScriptError(f"{where}: {text}", "".join(tb.format()))
    return ScriptError(f"{where}: {type(exc).__name__}: {text} (while {what}; --traceback shows the script's "
                       "traceback)", "".join(tb.format()))


def _run_script(path: Path, what: str, fn, *args, **kwargs):
    """``fn(*args, **kwargs)``, the user's code: its own checks (LinkFeaError) pass as they are, any other
    exception, a ``sys.exit`` included, becomes a :class:`ScriptError`; Ctrl-C stays Ctrl-C."""
    try:
        return fn(*args, **kwargs)
    except LinkFeaError:
        raise
    except (Exception, SystemExit) as exc:
        raise script_error(path, exc, what) from exc


def load_script(path: str | Path):
    """Import a cad/ script as a module (it must define ``PARAMS`` and ``build``)."""
    path = resolve_script(path)
    modname = f"linkfea_cad_{path.stem}"
    spec = importlib.util.spec_from_file_location(modname, path)
    mod = importlib.util.module_from_spec(spec)
    writes, sys.dont_write_bytecode = sys.dont_write_bytecode, True  # no __pycache__ in the user's folder
    try:
        _run_script(path, "loading the script", spec.loader.exec_module, mod)
    finally:
        sys.dont_write_bytecode = writes
    if not (hasattr(mod, "PARAMS") and callable(getattr(mod, "build", None))):
        raise LinkFeaError(f"{path}: a link script must define PARAMS and build(**params)")
    return mod


def is_step(spec) -> bool:
    return Path(str(spec)).suffix.lower() in (".step", ".stp")


def build_link(spec, params: dict | None = None, material: str | None = None,
               base=None, tip=None, with_block: bool = True, block_length: float | None = None) -> Link:
    """Build a :class:`Link` from a cad/ script (name or path), a STEP file or a triangle surface
    (STL, OBJ, PLY: :mod:`linkfea.cad.surface`).

    For scripts, ``base``/``tip`` override the script's selectors and
    ``material`` the script's material; a new ``tip`` also rebuilds the frame
    and the block from the selected faces, as for STEP files.  For STEP files ``base`` and ``tip``
    are required and ``params`` must be empty.
    """
    if material is not None:
        get_material(material)
    if is_surface(spec):
        if params:
            raise LinkFeaError("--param applies to cad/ scripts, not to surface files")
        if base is None or tip is None:
            raise LinkFeaError("a surface file (STL, OBJ, PLY) needs --base and --tip selectors")
        return load_surface(spec, parse_selector(base), parse_selector(tip), material or DEFAULT_MATERIAL,
                            with_block=with_block, block_length=block_length)
    if is_step(spec):
        if params:
            raise LinkFeaError("--param applies to cad/ scripts, not to STEP files")
        if base is None or tip is None:
            raise LinkFeaError("a STEP file needs --base and --tip selectors")
        return load_step(spec, parse_selector(base), parse_selector(tip), material or DEFAULT_MATERIAL,
                         with_block=with_block, block_length=block_length)
    mod = load_script(spec)
    p = dict(params or {})
    if material is not None:
        if "material" not in mod.PARAMS:
            raise LinkFeaError(f"{spec}: this script has no material parameter")
        p["material"] = material
    link = _run_script(Path(mod.__file__), "running build()", mod.build, **p)
    if not isinstance(link, Link):
        raise LinkFeaError(f"{spec}: build() must return a linkfea.cad.Link")
    changes: dict = {}
    if base is not None:
        changes["base"] = parse_selector(base)
    if tip is not None:
        changes["tip"] = parse_selector(tip)
    if changes:
        link = replace(link, **changes)
    check_link(link)
    if tip is not None:
        # A new tip interface: the script's frame and block belong to the old one, so both are
        # rebuilt from the selected faces by the STEP rule.
        frame, block, _ = interface_frame_and_block(link.body, link.base_faces, link.tip_faces, with_block,
                                                    block_length, link.name)
        link = replace(link, frame=frame, block=block)
    return link

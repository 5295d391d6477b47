"""Files shipped with the packages: the bundled link scripts (``cad/``) and vjm's data (``data/``).

Their one home is the top of the source tree (``cad/``, ``data/``); the wheel copies them inside
the packages, as ``linkfea/_cad`` and ``vjm/_data`` (``setup.py`` maps the folders).  Where a
package runs from decides, once, which of the two it reads (:func:`shipped_dir`): the source
tree's folders for a tree on ``PYTHONPATH`` or an editable install, the package's own for a wheel,
so both ways run the same commands.
"""
from __future__ import annotations

from importlib import resources
from pathlib import Path

CHECKOUT = Path(__file__).resolve().parents[3]
"""Top of the source tree when the packages run from ``src/`` (unused in an installed wheel)."""


def shipped_dir(package: str, inside: str, checkout: str) -> Path:
    """The folder of files shipped with ``package``: one place, decided by where the package runs from.

    A package imported from the ``src/`` of this source tree (``PYTHONPATH=src`` or an editable install)
    uses the tree's top-level folder ``checkout`` (``cad/``, ``data/``: their one home, which the wheel
    copies); an installed package uses its folder ``inside`` (``linkfea/_cad``, ``vjm/_data``), even if that
    is missing, so that a missing file is reported against the place it looks in and an installed package
    never picks up the files of a checkout that happens to lie around it.
    """
    here = Path(str(resources.files(package))).resolve()
    if here.parent == CHECKOUT / "src":
        return CHECKOUT / checkout
    return here / inside


def cad_dir() -> Path:
    """Folder of the bundled link scripts (``bar``, ``orthoglide_foot``, ``parallelogram_bar``)."""
    return shipped_dir("linkfea", "_cad", "cad")


def _same(a: Path, b: Path) -> bool:
    try:
        return a.samefile(b)
    except OSError:
        return False


def find_script(spec) -> Path:
    """The link script ``spec`` names, absolute.

    The rule, from first to last:

    1. an existing file: that file (``cad/bar.py``, ``/home/me/arm.py``);
    2. a bare name (``bar`` or ``bar.py``, no folder): a **local file wins**: ``./bar.py`` or
       ``./cad/bar.py`` in the current folder (both, with different content: an error naming
       them), else the bundled ``bar.py`` (:func:`cad_dir`).  A local file that takes precedence
       over a different bundled script of the same name gets a :class:`~linkfea.runtime.errors.LinkFeaWarning`
       naming both, since the same command gives another link elsewhere;
    3. ``cad/NAME.py`` that does not exist here: the bundled script (the README's paths work
       from any folder);
    4. anything else: a LinkFeaError listing the bundled scripts.
    """
    import warnings

    from .errors import LinkFeaError, LinkFeaWarning

    p = Path(str(spec))
    if p.is_file():
        return p.resolve()
    bundled_dir = cad_dir()
    if len(p.parts) == 2 and p.parts[0] == "cad" and (bundled_dir / p.name).is_file():
        return (bundled_dir / p.name).resolve()  # the README's cad/bar.py, run from another folder
    if len(p.parts) == 1 and p.suffix in ("", ".py"):
        name = p.stem if p.suffix else p.name
        local = [q for q in (Path.cwd() / f"{name}.py", Path.cwd() / "cad" / f"{name}.py") if q.is_file()]
        if len(local) == 2 and not local[0].read_bytes() == local[1].read_bytes():
            raise LinkFeaError(f"{spec}: two different local scripts ./{name}.py and ./cad/{name}.py; "
                               "give the path of the one to use")
        bundled = bundled_dir / f"{name}.py"
        if local:
            if bundled.is_file() and not _same(local[0], bundled) and local[0].read_bytes() != bundled.read_bytes():
                warnings.warn(f"{spec}: using {local[0]} from this folder, not the bundled script {bundled} "
                              "(a local file takes precedence over a bundled name)", LinkFeaWarning, stacklevel=2)
            return local[0].resolve()
        if bundled.is_file():
            return bundled.resolve()
    known = ", ".join(sorted(q.stem for q in bundled_dir.glob("*.py"))) if bundled_dir.is_dir() else "none"
    raise LinkFeaError(f"no link script or STEP file {str(spec)!r}; bundled scripts: {known}")

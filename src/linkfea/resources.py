"""Files shipped with the packages: the bundled link scripts (``cad/``) and vjm's data (``data/``).

The source tree keeps them at its top (``cad/``, ``data/``); the wheel installs them inside
the packages, as ``linkfea/_cad`` and ``vjm/_data`` (``setup.py`` maps the folders).  They are
found with :mod:`importlib.resources` in an installed package, and in the checkout otherwise
(a source tree on ``PYTHONPATH`` or an editable install), so both ways run the same commands.
"""
from __future__ import annotations

from importlib import resources
from pathlib import Path

CHECKOUT = Path(__file__).resolve().parents[2]
"""Top of the source tree when the packages run from ``src/`` (unused in an installed wheel)."""


def shipped_dir(package: str, inside: str, checkout: str) -> Path:
    """The folder ``inside`` of an installed ``package``, else ``checkout`` at the top of the source tree.

    Returns the installed folder even if neither exists, so that a missing file is reported
    against the place an installed package looks in.
    """
    installed = Path(str(resources.files(package) / inside))
    if installed.is_dir():
        return installed
    source = CHECKOUT / checkout
    return source if source.is_dir() else installed


def cad_dir() -> Path:
    """Folder of the bundled link scripts (``bar``, ``orthoglide_foot``, ``parallelogram_bar``)."""
    return shipped_dir("linkfea", "_cad", "cad")

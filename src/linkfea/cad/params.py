"""Parameters of link scripts: command-line ``NAME=VALUE`` parsing and checked merging into ``PARAMS``."""
from __future__ import annotations

import math

from ..mechanics.materials import get_material
from ..runtime.errors import LinkFeaError

MAX_LENGTH = 1e8
"""Largest length a script parameter may give, mm (100 km).  OpenCASCADE compares points to an
absolute tolerance of 1e-7 mm; the spacing of float64 numbers near ``x`` is ``2.2e-16 x``, which
passes 1e-7 mm from 4.5e8 mm on, where the kernel's constructions fail (``-p length=1e20``:
"gp_Vec::Normalize() - vector has zero norm")."""


def resolve_params(defaults: dict, given: dict | None = None, positive=(), nonnegative=()) -> dict:
    """Merge ``given`` into a script's ``PARAMS`` with checks.

    Values are converted to the type of the default (so ``"200"`` from the
    command line becomes ``200.0``).  Unknown names, non-finite numbers,
    non-positive entries of ``positive`` and negative entries of
    ``nonnegative`` raise :class:`LinkFeaError`; so does an unknown material.
    """
    out = dict(defaults)
    for k, v in (given or {}).items():
        if k not in defaults:
            raise LinkFeaError(f"unknown parameter {k!r}; known parameters: {', '.join(sorted(defaults))}")
        d = defaults[k]
        try:
            if isinstance(d, bool):
                v = v if isinstance(v, bool) else str(v).strip().lower() in ("1", "true", "yes", "on")
            elif isinstance(d, (int, float)) and not isinstance(d, bool):
                v = float(v)
            else:
                v = str(v)
        except (TypeError, ValueError):
            raise LinkFeaError(f"parameter {k!r}: expected a number, got {v!r}") from None
        out[k] = v
    for k, v in out.items():
        if isinstance(v, float) and not math.isfinite(v):
            raise LinkFeaError(f"parameter {k!r} must be a finite number, got {v}")
    for k in positive:
        if not out[k] > 0:
            raise LinkFeaError(f"parameter {k!r} must be > 0 mm, got {out[k]}")
    for k in nonnegative:
        if not out[k] >= 0:
            raise LinkFeaError(f"parameter {k!r} must be >= 0, got {out[k]}")
    for k in (*positive, *nonnegative):
        if out[k] > MAX_LENGTH:
            raise LinkFeaError(f"parameter {k!r} must be <= {MAX_LENGTH:g} mm (beyond, coordinates cannot resolve "
                               f"the CAD kernel's 1e-7 mm tolerance), got {out[k]:g}")
    if "material" in out:
        get_material(out["material"])
    return out


def parse_param_args(items) -> dict:
    """``["length=200", "section=rect"]`` -> ``{"length": "200", "section": "rect"}``."""
    out = {}
    for it in items or ():
        k, eq, v = str(it).partition("=")
        if not eq or not k.strip():
            raise LinkFeaError(f"parameter {it!r}: expected NAME=VALUE")
        if k.strip() in out:  # not the last one silently winning
            raise LinkFeaError(f"--param {k.strip()} given twice ({out[k.strip()]} and {v.strip()}); give it once")
        out[k.strip()] = v.strip()
    return out

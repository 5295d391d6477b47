"""A sweep's designs and their keys: the source's content, the parameters and the compute options."""
from __future__ import annotations

import hashlib
import itertools
import json
import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import Sequence

from ..options import SWEEP_OPTIONS, ComputeOptions
from ..runtime import checks
from ..runtime.errors import LinkFeaError
from .budget import sweep_size
from .grammar import parse_param_spec

KEY_VERSION = "linkfea.sweep/1"
#: the compute options of ``linkfea sweep`` (any field of ComputeOptions is accepted from Python)
OPTION_NAMES = SWEEP_OPTIONS


@dataclass(frozen=True)
class Design:
    """One parameter set of a sweep: ``index`` in the enumeration, swept ``params``, content ``key``."""

    index: int
    params: dict
    key: str


@dataclass(frozen=True)
class Sweep:
    """A sweep definition: the CAD source, the compute options and the designs.

    ``spec`` is the absolute path of the script or STEP file, ``source_sha`` the
    SHA-256 of its bytes; ``options`` the design key's spelling of the
    :class:`linkfea.options.ComputeOptions` (:meth:`~linkfea.options.ComputeOptions.key_options`).
    """

    spec: str
    source_sha: str
    options: dict
    names: tuple
    designs: tuple
    sampling: dict = field(default_factory=dict)


def design_key(source_sha: str, params: dict, options: dict) -> str:
    """16 hex digits of SHA-256 over the source content, the parameters and the options."""
    doc = {"v": KEY_VERSION, "source": source_sha, "params": params,
           "options": {k: options.get(k) for k in sorted(options)}}
    return hashlib.sha256(json.dumps(doc, sort_keys=True).encode()).hexdigest()[:16]


def resolve_source(spec) -> Path:
    """The script or STEP file of ``spec`` (a path, or a bare cad/ name), absolute."""
    from ..cad import is_step, resolve_script

    if is_step(spec):
        p = Path(spec)
        if not p.is_file():
            raise LinkFeaError(f"STEP file {str(spec)!r} not found")
        return p.resolve()
    return resolve_script(spec)


def make_sweep(spec, params: Sequence[str], options: dict | ComputeOptions | None = None, sample: int | None = None,
               seed: int | None = None) -> Sweep:
    """Build the designs of a sweep.

    Parameters
    ----------
    spec : cad/ script (path or name) or STEP file
    params : ``NAME=SPEC`` strings; several give the full grid (first name varies slowest)
    options : a :class:`linkfea.options.ComputeOptions`, or a dict of its fields (None entries: the defaults)
    sample, seed : a Latin hypercube of ``sample`` designs (scipy.stats.qmc) instead of the grid
    """
    # checked here, not on the workers after the cluster started
    opts = options if isinstance(options, ComputeOptions) else ComputeOptions.from_mapping(options)
    src = resolve_source(spec)
    src_bytes = src.read_bytes()
    sha = hashlib.sha256(src_bytes).hexdigest()
    seed = checks.optional_integer(seed, "seed", checks.NON_NEGATIVE)
    options = opts.key_options()
    specs = [parse_param_spec(p) for p in params or ()]
    names = tuple(s.name for s in specs)
    if len(set(names)) != len(names):
        raise LinkFeaError(f"--param given twice for {sorted({n for n in names if names.count(n) > 1})}")
    _check_names(src, names)
    if sample is not None:
        sample = checks.integer(sample, "sample", checks.Bounds(1))
        if not specs:
            raise LinkFeaError("--sample needs at least one --param to sample")
        sweep_size(sample, len(src_bytes)).check()
        from scipy.stats import qmc

        u = qmc.LatinHypercube(d=len(specs), rng=seed).random(sample)
        cols = [s.sample(u[:, j]) for j, s in enumerate(specs)]
        rows = [tuple(c[i] for c in cols) for i in range(sample)]
        sampling = {"method": "latin-hypercube", "n": sample, "seed": seed}
    else:
        sweep_size(math.prod(s.grid_count() for s in specs), len(src_bytes)).check()  # before listing them
        rows = list(itertools.product(*(s.grid_values() for s in specs)))
        sampling = {"method": "grid"}
    designs, seen = [], set()
    for row in rows:
        p = dict(zip(names, row))
        key = design_key(sha, p, options)
        if key in seen:  # a snapped sample may repeat a design: compute it once
            continue
        seen.add(key)
        designs.append(Design(len(designs), p, key))
    return Sweep(str(src), sha, options, names, tuple(designs), sampling)


def _check_names(src: Path, names) -> None:
    """A misspelt parameter is bad input of the whole sweep, not a failure of every design."""
    from ..cad import is_step, load_script

    if not names:
        return
    if is_step(src):
        raise LinkFeaError("--param applies to cad/ scripts, not to STEP files")
    known = script_param_names(src)
    if known is None:  # PARAMS is not a plain literal: run the script to know it
        known = set(load_script(src).PARAMS)
    unknown = [n for n in names if n not in known]
    if unknown:
        raise LinkFeaError(f"unknown parameter {unknown[0]!r}; known parameters: {', '.join(sorted(known))}")


def script_param_names(src: Path) -> set[str] | None:
    """The names of a cad/ script's ``PARAMS``, read from its source without running it (no CAD
    kernel to import), or None unless ``PARAMS`` is one literal dict that no other top-level
    statement changes and the script defines ``build``."""
    import ast

    try:
        tree = ast.parse(src.read_bytes(), filename=str(src))
    except (OSError, SyntaxError, ValueError):
        return None
    literal, has_build, other_use = None, False, False
    for node in tree.body:
        if isinstance(node, ast.FunctionDef) and node.name == "build":
            has_build = True
        elif isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef, ast.ClassDef)):
            continue
        elif isinstance(node, ast.Assign) and [getattr(t, "id", None) for t in node.targets] == ["PARAMS"] \
                and literal is None:
            try:
                literal = ast.literal_eval(node.value)
            except ValueError:
                return None
        elif any(isinstance(n, ast.Name) and n.id == "PARAMS" for n in ast.walk(node)):
            other_use = True
    if not (isinstance(literal, dict) and has_build) or other_use:
        return None
    return {str(k) for k in literal}

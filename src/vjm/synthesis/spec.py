"""A design problem as a user writes it: the spec file of ``vjm design``, read and checked.

The spec (YAML, paths relative to it) names the machine, the free links, the objective, the
constraints and the budget::

    machine: ../orthoglide/puu.yaml          # a parallel machine or a robot model file
    links:
      foot:                                  # a link of the machine (parallel: foot, leg ...; robot: links:)
        cad: orthoglide_foot                 # a cad/ script (name or path), computed by FEA ...
        free: {arm_width: [24, 56], wall: [3, 9]}    # mm; {int: [lo, hi]} or {choice: [a, b]} too
        fixed: {fillet: 0}                   # the script's other parameters (default: its own)
        compute: {mesh_size: 3}              # linkfea compute options (default: its defaults)
      leg:
        beam: {section: rect, length: 310, material: aluminium}   # ... or a closed-form beam
        free: {width: [8, 24], height: [8, 20]}
    objective: moving_mass                   # the only one: the free links' mass as vjm sweep counts it
    constraints:
      k_tran_max: 0.015                      # mm/N, worst case over the workspace grid
      # k_rot_max: 1e-6                      # rad/(N mm)
      # - {quantity: k_tran_max, limit: 0.01, poses: [[0, 0, 0]]}   # at named poses instead
    grid: 11                                 # points per axis of the workspace grid (as vjm sweep)
    budget: 33                               # FEA runs; or {fea_runs: 33, workers: 2, scheduler: tcp://...}
    seed: 0

A robot's constraints are taken over a joint grid (``joints: {name: [lo, hi]}``, ``joint_grid: n``
values per named joint, the others at the file's ``home``) or at named configurations (``poses:``
lists of joint values); ``sag_max`` (mm, the self-weight sag at the tool) is a robot's only.
Everything is checked here, before any FEA: :class:`~vjm.errors.VjmError`, one line.
"""
from __future__ import annotations

import math
import os
from dataclasses import dataclass, field

import numpy as np

from ..errors import VjmError

#: what a constraint may bound, and on which kind of model
QUANTITIES = {"k_tran_max": ("parallel", "serial"), "k_rot_max": ("parallel", "serial"), "sag_max": ("serial",)}
UNITS = {"k_tran_max": "mm/N", "k_rot_max": "rad/(N mm)", "sag_max": "mm"}
OBJECTIVES = ("moving_mass",)
TOP_KEYS = ("machine", "links", "objective", "constraints", "grid", "joints", "joint_grid", "budget", "seed",
            "targets", "conservative")
LINK_KEYS = ("cad", "beam", "free", "fixed", "compute")
#: the dimensions (mm) a beam of each section may free; not its length, which the machine's geometry fixes
BEAM_FREE = {"rect": ("width", "height"), "circle": ("diameter",), "tube": ("diameter", "inner_diameter")}


@dataclass(frozen=True)
class Param:
    """A free parameter: ``kind`` real (``lo``..``hi``), int (``lo``..``hi``) or choice (``choices``)."""

    name: str
    kind: str
    lo: float = 0.0
    hi: float = 0.0
    choices: tuple = ()

    @property
    def log(self) -> bool:
        """Searched in log space: a positive range (compliances follow powers of the dimensions)."""
        return self.kind != "choice" and self.lo > 0

    def to_unit(self, v) -> float:
        """A value as a coordinate in [0, 1] (a choice: its index over the count - 1)."""
        if self.kind == "choice":
            return self.choices.index(v) / max(len(self.choices) - 1, 1)
        if self.hi == self.lo:
            return 0.0
        if self.log:
            return (math.log(v) - math.log(self.lo)) / (math.log(self.hi) - math.log(self.lo))
        return (float(v) - self.lo) / (self.hi - self.lo)

    def from_unit(self, u: float):
        """The value at coordinate ``u`` in [0, 1], snapped: 4 significant digits, an integer, a choice."""
        u = min(max(float(u), 0.0), 1.0)
        if self.kind == "choice":
            return self.choices[int(round(u * (len(self.choices) - 1)))]
        v = math.exp(math.log(self.lo) + u * (math.log(self.hi) - math.log(self.lo))) if self.log \
            else self.lo + u * (self.hi - self.lo)
        if self.kind == "int":
            return int(round(v))
        v = float(f"{v:.4g}")  # a dimension a drawing can carry; equal designs get equal cache keys
        return min(max(v, self.lo), self.hi)

    def corners(self) -> tuple:
        return self.choices if self.kind == "choice" else (self.from_unit(0.0), self.from_unit(1.0))


@dataclass(frozen=True)
class FreeLink:
    """A link of the machine whose dimensions are searched: by FEA of a cad/ script or as a closed-form beam."""

    name: str
    kind: str                      # "cad" or "beam"
    source: object                 # the script's absolute path (cad) or the beam mapping (beam)
    free: tuple                    # Param
    fixed: dict = field(default_factory=dict)
    compute: dict = field(default_factory=dict)

    def params(self, u) -> dict:
        """The link's full parameters at unit coordinates ``u`` (the free ones snapped)."""
        return {**self.fixed, **{p.name: p.from_unit(x) for p, x in zip(self.free, u)}}

    def unit(self, params: dict) -> np.ndarray:
        return np.array([p.to_unit(params[p.name]) for p in self.free])


@dataclass(frozen=True)
class Constraint:
    """``quantity`` <= ``limit``: over the workspace (joint) grid, or at ``poses`` if given."""

    quantity: str
    limit: float
    poses: tuple | None = None

    @property
    def label(self) -> str:
        return self.quantity + ("" if self.poses is None else f" at {len(self.poses)} poses")


@dataclass(frozen=True)
class DesignSpec:
    """A checked spec: the machine file, the free links, the constraints, the grids and the budget."""

    path: str
    machine: str
    links: tuple                   # FreeLink
    constraints: tuple             # Constraint
    objective: str = "moving_mass"
    grid: int = 11
    joints: dict = field(default_factory=dict)
    joint_grid: int = 5
    fea_runs: int = 33
    workers: int | None = None
    scheduler: str | None = None
    seed: int = 0
    targets: tuple = ()
    conservative: bool = False

    @property
    def dims(self) -> int:
        return sum(len(link.free) for link in self.links)


def _number(v, where: str) -> float:
    if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v):
        raise VjmError(f"{where} must be a finite number, got {v!r}")
    return float(v)


def _param(name: str, v, where: str) -> Param:
    """``[lo, hi]``, ``{int: [lo, hi]}`` or ``{choice: [a, b ...]}``."""
    if isinstance(v, dict) and set(v) == {"choice"}:
        ch = v["choice"]
        if not isinstance(ch, list) or len(ch) < 2 or len(set(map(str, ch))) != len(ch):
            raise VjmError(f"{where}.choice must list at least two different values, got {ch!r}")
        return Param(name, "choice", choices=tuple(ch))
    kind = "real"
    if isinstance(v, dict) and set(v) == {"int"}:
        kind, v = "int", v["int"]
    if not (isinstance(v, list) and len(v) == 2):
        raise VjmError(f"{where} must be [lo, hi], {{int: [lo, hi]}} or {{choice: [a, b]}}, got {v!r}")
    lo, hi = _number(v[0], f"{where}[0]"), _number(v[1], f"{where}[1]")
    if not lo < hi:
        raise VjmError(f"{where}: the bounds [{lo:g}, {hi:g}] are reversed or equal (give [lo, hi] with lo < hi)")
    if kind == "int" and (lo != int(lo) or hi != int(hi)):
        raise VjmError(f"{where}: integer bounds must be integers, got [{lo:g}, {hi:g}]")
    return Param(name, kind, lo, hi)


def _link(name: str, d, base: str) -> FreeLink:
    where = f"links.{name}"
    if not isinstance(d, dict):
        raise VjmError(f"{where} must be a mapping with cad: or beam:, free:, fixed:")
    extra = sorted(set(d) - set(LINK_KEYS))
    if extra:
        raise VjmError(f"{where}: unknown key {extra[0]!r}; known: {', '.join(LINK_KEYS)}")
    if ("cad" in d) == ("beam" in d):
        raise VjmError(f"{where}: give exactly one of cad: (a cad/ script) or beam: (a closed-form beam)")
    free = d.get("free")
    if not isinstance(free, dict) or not free:
        raise VjmError(f"{where}.free must name at least one parameter with its bounds, e.g. {{width: [8, 24]}}")
    fixed = d.get("fixed") or {}
    compute = d.get("compute") or {}
    if not isinstance(fixed, dict) or not isinstance(compute, dict):
        raise VjmError(f"{where}: fixed: and compute: are mappings")
    params = tuple(_param(str(k), v, f"{where}.free.{k}") for k, v in free.items())
    both = sorted(set(free) & set(fixed))
    if both:
        raise VjmError(f"{where}: {both[0]!r} is both free and fixed")
    if "cad" in d:
        return FreeLink(name, "cad", _script(d["cad"], base, where), params, dict(fixed), dict(compute))
    beam = d["beam"]
    if not isinstance(beam, dict):
        raise VjmError(f"{where}.beam must be a mapping (section, length, material ...)")
    if compute:
        raise VjmError(f"{where}: compute: options are for cad: links (a beam is computed in closed form)")
    dims = BEAM_FREE.get(beam.get("section"), ())
    if not dims:
        raise VjmError(f"{where}.beam.section must be rect, circle or tube, got {beam.get('section')!r}")
    bad = [p.name for p in params if p.name not in dims or p.kind != "real"]
    if bad:
        raise VjmError(f"{where}.free: a {beam['section']} beam frees its section's dimensions ({', '.join(dims)}) "
                       f"as [lo, hi]; {bad[0]!r} is not one (its length is the machine's)")
    return FreeLink(name, "beam", {**beam, **fixed}, params, {}, {})


def _script(spec, base: str, where: str) -> str:
    from linkfea.cad import is_step, resolve_script
    from linkfea.runtime.errors import LinkFeaError

    if not isinstance(spec, str):
        raise VjmError(f"{where}.cad must be a cad/ script name or path, got {spec!r}")
    local = os.path.join(base, spec)
    try:
        if is_step(spec):
            raise VjmError(f"{where}.cad: {spec} is a STEP file, which has no parameters to free; give the script "
                           "that builds it")
        return str(resolve_script(local if os.path.isfile(local) else spec))
    except LinkFeaError as exc:
        raise VjmError(f"{where}.cad: {exc}") from None


def _constraints(c) -> tuple:
    """A mapping ``{quantity: limit}`` or a list of ``{quantity, limit[, poses]}``."""
    items = [{"quantity": k, "limit": v} for k, v in c.items()] if isinstance(c, dict) else c
    if not isinstance(items, list) or not items:
        raise VjmError("constraints must give at least one limit, e.g. {k_tran_max: 0.015} (mm/N)")
    out = []
    for i, it in enumerate(items):
        where = f"constraints[{i}]"
        if not isinstance(it, dict) or not {"quantity", "limit"} <= set(it) or set(it) - {"quantity", "limit", "poses"}:
            raise VjmError(f"{where} must be {{quantity: k_tran_max, limit: 0.015[, poses: [...]]}}, got {it!r}")
        q = it["quantity"]
        if q not in QUANTITIES:
            raise VjmError(f"{where}: unknown quantity {q!r}; known: {', '.join(QUANTITIES)}")
        limit = _number(it["limit"], f"{where}.limit")
        if not limit > 0:
            raise VjmError(f"{where}.limit must be > 0 ({UNITS[q]}), got {limit:g}")
        poses = it.get("poses")
        if poses is not None:
            try:
                arr = np.array(poses, dtype=float)
            except (TypeError, ValueError):
                arr = np.array([])
            if arr.ndim != 2 or len(arr) == 0 or not np.all(np.isfinite(arr)):
                raise VjmError(f"{where}.poses must be a list of poses (points x, y, z in mm, or a robot's joint "
                               "values), finite numbers")
            poses = tuple(map(tuple, arr.tolist()))
        out.append(Constraint(q, limit, poses))
    return tuple(out)


def _budget(b) -> tuple:
    if isinstance(b, dict):
        extra = sorted(set(b) - {"fea_runs", "workers", "scheduler"})
        if extra:
            raise VjmError(f"budget: unknown key {extra[0]!r}; known: fea_runs, workers, scheduler")
        runs, workers, scheduler = b.get("fea_runs", 33), b.get("workers"), b.get("scheduler")
    else:
        runs, workers, scheduler = b, None, None
    if isinstance(runs, bool) or not isinstance(runs, int) or runs < 1:
        raise VjmError(f"budget: fea_runs must be a positive integer, got {runs!r}")
    if workers is not None and (isinstance(workers, bool) or not isinstance(workers, int) or workers < 1):
        raise VjmError(f"budget: workers must be a positive integer, got {workers!r}")
    if scheduler is not None and not isinstance(scheduler, str):
        raise VjmError(f"budget: scheduler must be an address such as tcp://host:8786, got {scheduler!r}")
    return runs, workers, scheduler


def _integer(v, where: str, lo: int, hi: int) -> int:
    if isinstance(v, bool) or not isinstance(v, int) or not lo <= v <= hi:
        raise VjmError(f"{where} must be an integer in [{lo}, {hi}], got {v!r}")
    return v


def parse_spec(d, path: str = "<spec>") -> DesignSpec:
    """A spec mapping (paths relative to ``path``'s folder) as a :class:`DesignSpec`."""
    if not isinstance(d, dict):
        raise VjmError(f"{path}: a design spec is a mapping (machine:, links:, constraints: ...)")
    extra = sorted(set(d) - set(TOP_KEYS))
    if extra:
        raise VjmError(f"{path}: unknown key {extra[0]!r}; known: {', '.join(TOP_KEYS)}")
    base = os.path.dirname(os.path.abspath(path)) if path != "<spec>" else os.getcwd()
    if not isinstance(d.get("machine"), str):
        raise VjmError(f"{path}: machine: names the model file (a parallel machine or a robot)")
    machine = os.path.join(base, d["machine"])
    if not os.path.isfile(machine):
        raise VjmError(f"{path}: machine file {machine} {'is a folder' if os.path.isdir(machine) else 'not found'}")
    links = d.get("links")
    if not isinstance(links, dict) or not links:
        raise VjmError(f"{path}: links: must name at least one free link")
    objective = d.get("objective", "moving_mass")
    if objective not in OBJECTIVES:
        raise VjmError(f"objective must be one of {', '.join(OBJECTIVES)}, got {objective!r}")
    joints = d.get("joints") or {}
    if not isinstance(joints, dict):
        raise VjmError("joints: maps a robot's joint names to [lo, hi] (rad, or mm for a prismatic joint)")
    jp = {str(k): _param(str(k), v, f"joints.{k}") for k, v in joints.items()}
    runs, workers, scheduler = _budget(d.get("budget", 33))
    seed = _integer(d.get("seed", 0), "seed", 0, 2 ** 32 - 1)
    targets = d.get("targets", [])
    if not isinstance(targets, list):
        raise VjmError("targets: a list of k_tran_max limits (mm/N) for the mass-stiffness front")
    targets = tuple(_number(t, "targets[]") for t in targets)
    if any(t <= 0 for t in targets):
        raise VjmError("targets must be > 0 (mm/N)")
    conservative = d.get("conservative", False)
    if not isinstance(conservative, bool):
        raise VjmError(f"conservative must be true or false, got {conservative!r}")
    return DesignSpec(os.path.abspath(path), machine, tuple(_link(str(k), v, base) for k, v in links.items()),
                      _constraints(d.get("constraints")), objective,
                      _integer(d.get("grid", 11), "grid", 2, 101), {k: (p.lo, p.hi) for k, p in jp.items()},
                      _integer(d.get("joint_grid", 5), "joint_grid", 1, 51), runs, workers, scheduler, seed,
                      targets, conservative)


def read_spec(path) -> DesignSpec:
    """The spec file at ``path`` (YAML), checked."""
    from ..modelio.yamldata import read_yaml

    p = os.fspath(path)
    if os.path.isdir(p):
        raise VjmError(f"design spec {p} is a folder; give the spec file (YAML)")
    if not os.path.isfile(p):
        raise VjmError(f"design spec {p} not found")
    return parse_spec(read_yaml(p, "design spec"), p)

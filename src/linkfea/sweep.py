"""Design sweeps: many parameter sets of one link, each through the whole pipeline, on Dask.

A sweep is a list of :class:`Design` (a full grid over several ``--param`` or a
Latin hypercube sample), each identified by a key: a hash of the CAD source's
content, the design's parameters and the compute options.  Each design is one
Dask task running :func:`linkfea.pipeline.compute`; the client writes its
result to ``DIR/results/<key>.json`` (atomically) as soon as it completes, so:

* a rerun skips every design whose result is already there (resumable);
* a design that fails is recorded with its one-line error and the others go on;
* a worker that dies loses only the design it was running (Dask reruns it
  elsewhere, or a rerun of the sweep does);
* the table (``sweep.parquet``, ``sweep.csv``) and the plot (``sweep.png``)
  are rebuilt from ``results/`` at the end of every run, also after Ctrl-C,
  in the designs' enumeration order: the same whatever the number of workers.

Units: compliance t = C w (mm/N, rad/(N mm), 1/N, rad/N by block) in each
link's reference frame (origin and axes in the design's JSON); stiffness N/mm
and N mm/rad; volume mm^3; mass kg; times s.
"""
from __future__ import annotations

import hashlib
import itertools
import json
import math
import os
import socket
import sys
import tempfile
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Callable, Sequence

import numpy as np

from . import checks
from .atomic import plain, write_text
from .errors import LinkFeaError
from .io import TWIST, WRENCH
from .options import SWEEP_OPTIONS, ComputeOptions
from .outputs import OutputSet, check_folder, claim, fault
from .sweep_budget import DesignProgress, announcement, check_memory_limit, median_seconds, range_count, sweep_size

KEY_VERSION = "linkfea.sweep/1"
#: what a sweep writes in its folder: the table set and the results/ sub-folder
SWEEP_FILES = ("sweep.parquet", "sweep.csv", "sweep.json", "sweep.png", "results/")
RESULT_SCHEMA_FAILED = "linkfea.sweep-failure/1"
#: the compute options of ``linkfea sweep`` (any field of ComputeOptions is accepted from Python)
OPTION_NAMES = SWEEP_OPTIONS
#: compliance columns of the table: C_<twist>_<wrench>, t = C w
C_COLUMNS = [f"C_{t}_{w}" for t in TWIST for w in WRENCH]
K_COLUMNS = [f"K_{t}" for t in TWIST]
DIAGONAL = [f"{t}_{w}" for t, w in zip(TWIST, WRENCH)]
UNITS = {
    "C_d*_F*": "mm/N", "C_r*_M*": "rad/(N*mm)", "C_d*_M*": "1/N", "C_r*_F*": "rad/N",
    "K_dx..K_dz": "N/mm", "K_rx..K_rz": "N*mm/rad",
    "volume_mm3": "mm^3", "mass_kg": "kg", "edge_length": "mm", "t_*": "s",
    "frame": "each design's link reference frame (results/<key>.json 'frame')",
}


# --------------------------------------------------------------------------- parameter specs
@dataclass(frozen=True)
class ParamSpec:
    """One ``--param NAME=SPEC``: a list ``10,15,20`` (numbers or words) or a range ``lo:hi[:step]``.

    A range with a step gives ``lo, lo+step, ...`` up to ``hi`` inclusive.  In
    a Latin hypercube, a range is sampled uniformly in ``[lo, hi]`` (snapped to
    the step if one is given) and a list by its items.
    """

    name: str
    values: tuple = ()
    lo: float | None = None
    hi: float | None = None
    step: float | None = None

    @property
    def is_range(self) -> bool:
        return self.lo is not None

    def grid_values(self) -> tuple:
        if not self.is_range:
            return self.values
        return tuple(_tidy(self.lo + k * self.step) for k in range(self.grid_count()))

    def grid_count(self) -> int:
        """Number of grid values, counted without listing them."""
        if not self.is_range:
            return len(self.values)
        if self.step is None:
            raise LinkFeaError(f"--param {self.name}: a grid needs a step, lo:hi:step (or use --sample)")
        return range_count(self.lo, self.hi, self.step)

    def sample(self, u: np.ndarray) -> list:
        """Values at the unit-interval coordinates ``u`` of a Latin hypercube."""
        if not self.is_range:
            idx = np.minimum((u * len(self.values)).astype(int), len(self.values) - 1)
            return [self.values[i] for i in idx]
        x = self.lo + u * (self.hi - self.lo)
        if self.step is not None:
            x = np.minimum(self.lo + np.round((x - self.lo) / self.step) * self.step, self.hi)
        return [_tidy(v, 6) for v in x]


def _tidy(v: float, digits: int = 12) -> float:
    """Round to ``digits`` significant digits: 10 + 3*0.1 is 10.3, and keys do not depend on round-off."""
    return 0.0 if v == 0 else float(f"{v:.{digits}g}")


def _number(text: str):
    try:
        v = float(text)
    except ValueError:
        return None
    return v if math.isfinite(v) else None


def parse_param_spec(item: str) -> ParamSpec:
    """``"width=10,15,20"`` or ``"length=100:300:50"`` -> :class:`ParamSpec`.

    >>> parse_param_spec("length=10:20:5").grid_values()
    (10.0, 15.0, 20.0)
    >>> parse_param_spec("section=rect,tube").grid_values()
    ('rect', 'tube')
    """
    name, eq, spec = str(item).partition("=")
    name, spec = name.strip(), spec.strip()
    if not eq or not name or not spec:
        raise LinkFeaError(f"--param {item!r}: expected NAME=SPEC, SPEC a list 10,15,20 or a range lo:hi:step")
    if ":" in spec:
        parts = spec.split(":")
        nums = [_number(p) for p in parts]
        if len(parts) not in (2, 3) or any(v is None for v in nums):
            raise LinkFeaError(f"--param {name}: range {spec!r} must be lo:hi or lo:hi:step with finite numbers")
        lo, hi = nums[0], nums[1]
        step = nums[2] if len(parts) == 3 else None
        if not hi >= lo:
            raise LinkFeaError(f"--param {name}: range {spec!r} needs hi >= lo")
        if step is not None and not step > 0:
            raise LinkFeaError(f"--param {name}: range {spec!r} needs a step > 0")
        return ParamSpec(name, lo=lo, hi=hi, step=step)
    items = [s.strip() for s in spec.split(",")]
    if any(not s for s in items):
        raise LinkFeaError(f"--param {name}: empty item in list {spec!r}")
    vals = tuple(_number(s) if _number(s) is not None else s for s in items)
    return ParamSpec(name, values=vals)


# --------------------------------------------------------------------------- designs
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
    from .cad import is_step, resolve_script

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
    from .cad import is_step, load_script

    if not names:
        return
    if is_step(src):
        raise LinkFeaError("--param applies to cad/ scripts, not to STEP files")
    known = load_script(src).PARAMS
    unknown = [n for n in names if n not in known]
    if unknown:
        raise LinkFeaError(f"unknown parameter {unknown[0]!r}; known parameters: {', '.join(sorted(known))}")


# --------------------------------------------------------------------------- the task (runs on a worker)
def _one_line(exc: BaseException) -> str:
    msg = " ".join(str(exc).split())
    return msg if isinstance(exc, LinkFeaError) else f"{type(exc).__name__}: {msg}"


def _source_here(task: dict) -> str:
    """A path to the design's source on this worker: the client's file if it is here with the
    same content (a shared file system), else the shipped bytes written to a temporary folder."""
    p = Path(task["spec"])
    try:
        if p.is_file() and hashlib.sha256(p.read_bytes()).hexdigest() == task["source_sha"]:
            return str(p)
    except OSError:
        pass
    d = Path(tempfile.gettempdir()) / "linkfea-sweep" / task["source_sha"][:16]
    q = d / p.name  # keep the name: scripts are imported by it and STEP by its suffix
    if not q.is_file():
        from .atomic import write_bytes

        write_bytes(q, task["source_bytes"])
    return str(q)


def run_design(task: dict) -> dict:
    """Run the whole pipeline for one design; the JSON document of its result.

    A success is :func:`linkfea.io.result_dict` (the ``linkfea compute``
    schema) plus a ``sweep`` block; a failure is a small document with the
    one-line error.  Exceptions of the design never escape (Dask would retry
    them); only a dying worker ends a task without a document.
    """
    t0 = time.perf_counter()
    info = {"key": task["key"], "index": task["index"], "params": task["params"],
            "worker": f"{socket.gethostname()}:{os.getpid()}"}
    try:
        from .io import result_dict
        from .pipeline import compute

        res = compute(_source_here(task), params=dict(task["params"]), cache_dir=task.get("cache_dir"),
                      options=ComputeOptions.from_mapping(task["options"]))
        doc = result_dict(res)
        doc["source"] = task["spec"]
        doc["sweep"] = {**info, "status": "ok", "error": None, "seconds": time.perf_counter() - t0}
        return doc
    except Exception as exc:  # any failure of one design is recorded, the sweep goes on
        return {"schema": RESULT_SCHEMA_FAILED, "source": task["spec"],
                "sweep": {**info, "status": "failed", "error": _one_line(exc), "seconds": time.perf_counter() - t0}}


# --------------------------------------------------------------------------- where it runs
def worker_env() -> dict:
    """Environment of local worker processes: this package first on the path, one thread each."""
    here = str(Path(__file__).resolve().parents[1])
    path = os.pathsep.join(p for p in (here, os.environ.get("PYTHONPATH", "")) if p)
    return {"PYTHONPATH": path, "OMP_NUM_THREADS": "1", "MKL_NUM_THREADS": "1", "OPENBLAS_NUM_THREADS": "1"}


#: Dask settings of a local cluster (read by the scheduler at start and handed to each worker).
LEAN_CLUSTER_CONFIG = {
    "distributed.worker.profile.enabled": False,
    "distributed.admin.tick.interval": "500ms",
    "distributed.worker.memory.monitor-interval": "200ms",
    "distributed.admin.system-monitor.interval": "2s",
}


def local_cluster(n_workers: int | None = None, memory_limit="auto"):
    """A LocalCluster of single-threaded worker processes (default one per core).

    ``memory_limit`` is per worker ("auto" = the machine's memory divided among the workers,
    or e.g. "4GB"): a worker above it is restarted by its nanny and its design is rerun.
    """
    import logging

    import dask
    from distributed import LocalCluster

    os.environ["PYTHONPATH"] = worker_env()["PYTHONPATH"]  # spawned workers inherit it
    n = checks.integer(n_workers or os.cpu_count() or 1, "workers", checks.Bounds(1))
    # the workers and the scheduler share the machine's cores: with one worker per core, every CPU
    # second the cluster spends on its own bookkeeping is taken from a design.  A design is seconds
    # of work, so the 10 ms stack sampler of each worker and the 20-100 ms ticks and monitors are
    # slowed down; they only feed the dashboard and the memory limit (checked every 200 ms).
    with dask.config.set(LEAN_CLUSTER_CONFIG):
        return LocalCluster(n_workers=n, threads_per_worker=1, processes=True, memory_limit=memory_limit,
                            dashboard_address=":0", silence_logs=logging.ERROR, env=worker_env())


# --------------------------------------------------------------------------- running
@dataclass
class SweepReport:
    """What one run did: counts and the table's rows."""

    n_designs: int = 0
    skipped: list = field(default_factory=list)
    computed: list = field(default_factory=list)
    failed: list = field(default_factory=list)
    unfinished: list = field(default_factory=list)
    rows: list = field(default_factory=list)
    interrupted: bool = False
    seconds: float = 0.0


def result_path(out, key: str) -> Path:
    return Path(out) / "results" / f"{key}.json"


def read_design_result(out, key: str) -> dict | None:
    """The stored document of a design, or None if absent or unreadable (then it is recomputed)."""
    try:
        doc = json.loads(result_path(out, key).read_text())
    except (OSError, ValueError):
        return None
    return doc if isinstance(doc, dict) and isinstance(doc.get("sweep"), dict) else None


def pending(sweep: Sweep, out, retry_failed: bool = False) -> list[Design]:
    """Designs without a stored result (or with a stored failure, if ``retry_failed``)."""
    todo = []
    for d in sweep.designs:
        doc = read_design_result(out, d.key)
        if doc is None or (retry_failed and doc["sweep"].get("status") != "ok"):
            todo.append(d)
    return todo


def run_sweep(sweep: Sweep, out, client=None, scheduler: str | None = None, workers: int | None = None,
              memory_limit="auto", retry_failed: bool = False, cache_dir=None, plot: Sequence[str] | None = None,
              progress: bool = False, on_result: Callable[[dict], None] | None = None,
              force: bool = False) -> SweepReport:
    """Run the designs of ``sweep`` not yet in ``out/results/`` and rebuild the table.

    Parameters
    ----------
    client : distributed.Client, optional
        Use this client (its cluster is left running).
    scheduler : str, optional
        Address of an existing scheduler (``tcp://host:8786``); else a :func:`local_cluster`
        of ``workers`` processes is started for the run and closed after it.
    cache_dir : path, optional
        Mesh cache.  Default: for a local cluster the client's (``$LINKFEA_CACHE_DIR`` or
        ``.cache/meshes``, made absolute); with ``scheduler`` each worker's own.
    plot : entries ``dy_Fy`` ... for ``sweep.png`` (default the diagonal)
    on_result : called with each design's document right after it is written
    force : write into a folder that also holds files of other origin (never touching them)
    """
    from .mesh import cache_dir_default

    workers = checks.optional_integer(workers, "workers", checks.Bounds(1))
    check_memory_limit(memory_limit)
    t_start = time.perf_counter()
    out = check_folder(out, SWEEP_FILES, force=force)
    rep = SweepReport(n_designs=len(sweep.designs))
    todo = pending(sweep, out, retry_failed)
    todo_keys = {d.key for d in todo}
    rep.skipped = [d.key for d in sweep.designs if d.key not in todo_keys]
    if plot:
        _check_entries(plot)
    try:
        claim(out, ["results/"], "linkfea sweep results")  # owned before a kill can leave it half made
    except OSError as exc:
        raise LinkFeaError(f"cannot write {out}: {exc.strerror or exc}") from None
    if cache_dir is None and scheduler is None:
        cache_dir = cache_dir_default()
    cache = None if cache_dir is None else str(Path(cache_dir).absolute())
    own_cluster = own_client = None
    try:
        if todo:
            src_bytes = Path(sweep.spec).read_bytes()
            if client is None:
                from distributed import Client

                if scheduler is None:
                    own_cluster = local_cluster(workers, memory_limit)
                    own_client = client = Client(own_cluster)
                else:
                    try:
                        own_client = client = Client(scheduler, timeout="20s")
                    except (OSError, TimeoutError) as exc:
                        raise LinkFeaError(f"cannot reach the Dask scheduler at {scheduler}: {exc}") from None
            _compute(client, sweep, todo, out, src_bytes, cache, rep, progress, on_result,
                     median_seconds(read_design_result(out, k) for k in rep.skipped + [d.key for d in todo]))
    except KeyboardInterrupt:
        rep.interrupted = True
    finally:
        if own_client is not None:
            own_client.close()
        if own_cluster is not None:
            own_cluster.close()
        done = {k for k in rep.computed} | {k for k in rep.failed}
        rep.unfinished = sorted({d.key for d in todo} - done)
        rep.rows = write_table(sweep, out, plot)
        rep.seconds = time.perf_counter() - t_start
    return rep


def _compute(client, sweep, todo, out, src_bytes, cache, rep, progress, on_result, per_design=None):
    from distributed import as_completed

    futures = []
    for d in todo:
        task = {"key": d.key, "index": d.index, "params": d.params, "spec": sweep.spec,
                "source_sha": sweep.source_sha, "source_bytes": src_bytes, "options": sweep.options,
                "cache_dir": cache}
        # pure=False: a rerun must run; the name makes the dashboard readable
        futures.append(client.submit(run_design, task, key=f"design-{d.key}", pure=False))
    if progress:
        say = announcement(len(todo), len(client.scheduler_info().get("workers", {})) or 1, per_design)
        if say:
            print(say, file=sys.stderr)
    bar = DesignProgress(len(futures)) if progress else None
    try:
        for fut in as_completed(futures):
            if fut.status != "finished":  # cancelled (restart) or lost worker: not the design's fault
                if bar:
                    bar.advance()
                continue
            try:
                doc = fut.result()
            except Exception:  # e.g. KilledWorker after repeated worker deaths: not the design's fault
                if bar:
                    bar.advance()
                continue
            key = doc["sweep"]["key"]
            write_text(result_path(out, key), json.dumps(plain(doc), indent=1) + "\n")
            fault("design-written")
            (rep.computed if doc["sweep"]["status"] == "ok" else rep.failed).append(key)
            if bar:
                bar.advance(ok=doc["sweep"]["status"] == "ok")
            if on_result is not None:
                on_result(doc)
    finally:
        if bar:
            bar.stop()
        client.cancel([f for f in futures if not f.done()])


# --------------------------------------------------------------------------- table and plot
def design_row(design: Design, doc: dict | None) -> dict:
    """One table row: the design's parameters, status, compliance, stiffness diagonal, mass, mesh, timing."""
    row = {"index": design.index, "key": design.key}
    row.update({f"param_{k}": v for k, v in design.params.items()})
    sw = (doc or {}).get("sweep", {})
    row["status"] = sw.get("status", "not_run")
    row["error"] = sw.get("error")
    ok = row["status"] == "ok"
    C = np.asarray(doc["compliance"], dtype=float) if ok else np.full((6, 6), np.nan)
    K = np.asarray(doc["stiffness"], dtype=float) if ok else np.full((6, 6), np.nan)
    row.update(dict(zip(C_COLUMNS, C.ravel().tolist())))
    row.update(dict(zip(K_COLUMNS, np.diag(K).tolist())))
    g = (lambda *ks: _get(doc, ks)) if ok else (lambda *ks: None)
    row.update(volume_mm3=g("volume_mm3"), mass_kg=g("mass_kg"), material=g("material", "name"),
               n_nodes=g("mesh", "n_nodes"), n_tets=g("mesh", "n_tets"), n_dofs=g("mesh", "n_dofs"),
               edge_length=g("mesh", "edge_length"), radius_ratio_min=g("mesh", "quality", "radius_ratio_min"),
               volume_error=g("mesh", "quality", "volume_error"),
               symmetry_error=g("diagnostics", "symmetry_error"), fit_residual=g("diagnostics", "fit_residual"))
    for k in ("cad", "mesh", "assemble", "factor", "solve", "fit", "total"):
        row[f"t_{k}"] = g("timing", k)
    row["worker"] = sw.get("worker")
    return row


def _get(doc, keys):
    for k in keys:
        if not isinstance(doc, dict):
            return None
        doc = doc.get(k)
    return doc


def _column(values: list):
    """A pyarrow array: float64 if every non-null value is a number, else string."""
    import pyarrow as pa

    nonnull = [v for v in values if v is not None]
    if all(isinstance(v, (int, float)) and not isinstance(v, bool) for v in nonnull):
        if all(isinstance(v, int) for v in nonnull) and nonnull:
            return pa.array(values, type=pa.int64())
        return pa.array([None if v is None else float(v) for v in values], type=pa.float64())
    return pa.array([None if v is None else str(v) for v in values], type=pa.string())


def write_table(sweep: Sweep, out, plot: Sequence[str] | None = None) -> list[dict]:
    """Rebuild ``sweep.parquet``, ``sweep.csv``, ``sweep.json`` and ``sweep.png`` from ``results/``.

    One row per design of the sweep, in enumeration order (grid or sample
    order), with status ``ok``, ``failed`` (and its error) or ``not_run``.
    """
    import pyarrow as pa
    import pyarrow.csv as pacsv
    import pyarrow.parquet as pq

    out = Path(out)
    rows = [design_row(d, read_design_result(out, d.key)) for d in sweep.designs]
    cols = list(rows[0]) if rows else ["index", "key", "status", "error"]
    meta = {"schema": "linkfea.sweep-table/1", "spec": sweep.spec, "source_sha256": sweep.source_sha,
            "options": sweep.options, "params": list(sweep.names), "sampling": sweep.sampling, "units": UNITS,
            "order": {"wrench": WRENCH, "twist": TWIST, "compliance": "t = C w, C_<twist>_<wrench>"}}
    table = pa.table({c: _column([r.get(c) for r in rows]) for c in cols})
    table = table.replace_schema_metadata({"linkfea.sweep": json.dumps(plain(meta))})
    counts = {s: sum(r["status"] == s for r in rows) for s in ("ok", "failed", "not_run")}
    doc = json.dumps(plain({**meta, "counts": counts, "designs": [{"index": d.index, "key": d.key, "params": d.params}
                                                                for d in sweep.designs]}), indent=1) + "\n"
    with OutputSet(out, "linkfea sweep") as s:  # the four files are one set: all from this run, or the old ones
        pq.write_table(table, s.path("sweep.parquet"))
        pacsv.write_csv(table, s.path("sweep.csv"))
        Path(s.path("sweep.json")).write_text(doc, encoding="utf-8")
        plot_sweep(rows, sweep.names, plot or DIAGONAL, s.path("sweep.png"))
    return rows


def _check_entries(entries) -> None:
    bad = [e for e in entries if f"C_{e}" not in C_COLUMNS]
    if bad:
        raise LinkFeaError(f"--plot: unknown compliance entries {bad}; use twist_wrench such as dy_Fy or rz_Fy")


def plot_sweep(rows: list[dict], names: Sequence[str], entries: Sequence[str], path) -> None:
    """Compliance entries (rows of panels) against each swept parameter (columns).

    Points that share the other parameters' values are joined, so a grid shows one curve per
    combination of the other parameters; word-valued parameters are categorical axes.
    """
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    _check_entries(entries)
    ok = [r for r in rows if r["status"] == "ok"]
    names = list(names) or ["index"]
    fig, axes = plt.subplots(len(entries), len(names), figsize=(3.6 * len(names) + 0.8, 2.4 * len(entries) + 0.6),
                             squeeze=False)
    for j, nm in enumerate(names):
        col = "index" if nm == "index" else f"param_{nm}"
        vals = [r[col] for r in ok]
        cats = sorted({v for v in vals if isinstance(v, str)})
        x_of = cats.index if cats else float
        others = [f"param_{n}" for n in names if n != nm and nm != "index"]
        groups: dict = {}
        for r in ok:
            groups.setdefault(tuple(r[o] for o in others), []).append(r)
        for i, e in enumerate(entries):
            ax = axes[i, j]
            for label, g in groups.items():
                g = sorted(g, key=lambda r: x_of(r[col]))
                ax.plot([x_of(r[col]) for r in g], [r[f"C_{e}"] for r in g], "o-", ms=3, lw=0.8,
                        label=", ".join(f"{o[6:]}={v}" for o, v in zip(others, label)))
            if i == 0 and others and 1 < len(groups) <= 8:
                ax.legend(fontsize=6)
            ys = [r[f"C_{e}"] for r in ok if r[f"C_{e}"] is not None and r[f"C_{e}"] > 0]
            if ys and max(ys) > 10 * min(ys):
                ax.set_yscale("log")
            if cats:
                ax.set_xticks(range(len(cats)), cats)
            unit = _unit(e)
            ax.set_ylabel(f"C {e} ({unit})", fontsize=8)
            ax.tick_params(labelsize=7)
            if i == len(entries) - 1:
                ax.set_xlabel(nm, fontsize=8)
    if not ok:
        fig.text(0.5, 0.5, "no successful design", ha="center")
    fig.suptitle(f"compliance in the link frame, {len(ok)} of {len(rows)} designs", fontsize=9)
    fig.tight_layout()
    fig.savefig(path, dpi=110, format="png")
    plt.close(fig)


def _unit(entry: str) -> str:
    t, w = entry.split("_")
    return {("d", "F"): "mm/N", ("r", "M"): "rad/(N mm)", ("d", "M"): "1/N", ("r", "F"): "rad/N"}[(t[0], w[0])]

"""Running a sweep: the pending designs on Dask, each result written as it completes, then the table."""
from __future__ import annotations

import json
import sys
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Callable, Sequence

from ..files.atomic import plain, write_text
from ..files.outputs import check_folder, claim, fault
from ..runtime import checks
from ..runtime.errors import LinkFeaError
from ..runtime.progress import Progress
from . import cluster
from .budget import DesignProgress, LineProgress, announcement, check_memory_limit, median_seconds
from .designs import Sweep
from .plot import check_entries
from .store import pending, read_design_result, result_path
from .table import table_is_current, table_rows, write_table
from .task import run_design

#: what a sweep writes in its folder: the table set and the results/ sub-folder
SWEEP_FILES = ("sweep.parquet", "sweep.csv", "sweep.json", "sweep.png", "results/")


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


def run_sweep(sweep: Sweep, out, client=None, scheduler: str | None = None, workers: int | None = None,
              memory_limit="auto", retry_failed: bool = False, cache_dir=None, plot: Sequence[str] | None = None,
              progress: bool | Progress = False, on_result: Callable[[dict], None] | None = None,
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
        the platform's cache folder, made absolute); with ``scheduler`` each worker's own.
    plot : entries ``dy_Fy`` ... for ``sweep.png`` (default the diagonal)
    progress : True for a progress bar on stderr, or a callable called with a line per finished design
        (and, first, the expected time of a long run)
    on_result : called with each design's document right after it is written
    force : write into a folder that also holds files of other origin (never touching them)
    """
    from ..mesh.pytetwild import cache_dir_default

    workers = checks.optional_integer(workers, "workers", checks.Bounds(1))
    check_memory_limit(memory_limit)
    t_start = time.perf_counter()
    out = check_folder(out, SWEEP_FILES, force=force)
    rep = SweepReport(n_designs=len(sweep.designs))
    todo = pending(sweep, out, retry_failed)
    todo_keys = {d.key for d in todo}
    rep.skipped = [d.key for d in sweep.designs if d.key not in todo_keys]
    if plot:
        check_entries(plot)
    own_cluster = own_client = None
    if todo and client is None and scheduler is not None:
        own_client = client = cluster.connect(scheduler)  # a scheduler that is not there: before anything is written
    try:
        claim(out, ["results/"], "linkfea sweep results")  # owned before a kill can leave it half made
    except OSError as exc:
        if own_client is not None:
            own_client.close()
        raise LinkFeaError(f"cannot write {out}: {exc.strerror or exc}") from None
    if cache_dir is None and scheduler is None:
        cache_dir = cache_dir_default()
    cache = None if cache_dir is None else str(Path(cache_dir).absolute())
    try:
        if todo:
            src_bytes = Path(sweep.spec).read_bytes()
            if client is None:
                from distributed import Client

                own_cluster = cluster.local_cluster(workers, memory_limit)
                own_client = client = Client(own_cluster)
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
        rows = table_rows(sweep, out)
        if rep.computed or rep.failed or not table_is_current(sweep, out, rows, plot):
            write_table(sweep, out, plot, rows)
        rep.rows = rows
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
    note = announcement(len(todo), len(client.scheduler_info().get("workers", {})) or 1, per_design) \
        if progress else None
    bar: DesignProgress | LineProgress | None = None
    if callable(progress):
        if note:
            progress(note)
        bar = LineProgress(len(futures), progress)
    elif progress:
        if note:
            print(note, file=sys.stderr)
        bar = DesignProgress(len(futures))
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



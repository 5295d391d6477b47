"""One design on a worker: the whole pipeline, its result as a JSON document, never an exception."""
from __future__ import annotations

import hashlib
import os
import socket
import tempfile
import time
from pathlib import Path

from ..options import ComputeOptions
from ..runtime.errors import LinkFeaError

RESULT_SCHEMA_FAILED = "linkfea.sweep-failure/1"


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
        from ..files.atomic import write_bytes

        write_bytes(q, task["source_bytes"])
    return str(q)


def run_design(task: dict) -> dict:
    """Run the whole pipeline for one design; the JSON document of its result.

    A success is :meth:`linkfea.result.linkresult.LinkResult.to_dict` (the ``linkfea compute``
    schema) plus a ``sweep`` block; a failure is a small document with the
    one-line error.  Exceptions of the design never escape (Dask would retry
    them); only a dying worker ends a task without a document.
    """
    t0 = time.perf_counter()
    info = {"key": task["key"], "index": task["index"], "params": task["params"],
            "worker": f"{socket.gethostname()}:{os.getpid()}"}
    try:
        from ..pipeline import compute

        res = compute(_source_here(task), params=dict(task["params"]), cache_dir=task.get("cache_dir"), progress=False,
                      options=ComputeOptions.from_mapping(task["options"]))
        doc = res.to_dict()
        doc["source"] = task["spec"]
        doc["sweep"] = {**info, "status": "ok", "error": None, "seconds": time.perf_counter() - t0}
        return doc
    except Exception as exc:  # any failure of one design is recorded, the sweep goes on
        return {"schema": RESULT_SCHEMA_FAILED, "source": task["spec"],
                "sweep": {**info, "status": "failed", "error": _one_line(exc), "seconds": time.perf_counter() - t0}}



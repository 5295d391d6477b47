"""Where a sweep runs: a lean local Dask cluster of single-threaded worker processes."""
from __future__ import annotations

import os

from ..runtime import checks
from ..runtime.errors import LinkFeaError


def worker_env() -> dict:
    """Environment of local worker processes: one thread each for the numerical libraries.

    No path is set here: the workers are processes started by multiprocessing from this one (spawn,
    the Dask default, and forkserver hand the child this process's ``sys.path``; fork copies it), so
    they import the very ``linkfea`` the caller imported, and the caller's ``PYTHONPATH`` is left alone.
    """
    return {"OMP_NUM_THREADS": "1", "MKL_NUM_THREADS": "1", "OPENBLAS_NUM_THREADS": "1"}


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

    n = checks.integer(n_workers or os.cpu_count() or 1, "workers", checks.Bounds(1))
    # the workers and the scheduler share the machine's cores: with one worker per core, every CPU
    # second the cluster spends on its own bookkeeping is taken from a design.  A design is seconds
    # of work, so the 10 ms stack sampler of each worker and the 20-100 ms ticks and monitors are
    # slowed down; they only feed the dashboard and the memory limit (checked every 200 ms).
    with dask.config.set(LEAN_CLUSTER_CONFIG):
        return LocalCluster(n_workers=n, threads_per_worker=1, processes=True, memory_limit=memory_limit,
                            dashboard_address=":0", silence_logs=logging.ERROR, env=worker_env())




def check_scheduler(address: str, timeout: float = 5.0) -> None:
    """Refuse a ``tcp://`` (or ``tls://``) scheduler address where nothing answers, in seconds at most:
    a quick connect before anything is written (Dask's own client waits 20 s before it gives up)."""
    import socket
    from urllib.parse import urlsplit

    u = urlsplit(address if "://" in address else f"tcp://{address}")
    if u.scheme not in ("tcp", "tls"):
        return  # other transports: the client's own connect tells
    try:
        host, port = u.hostname, u.port or 8786
    except ValueError:
        host, port = None, 0
    if not host:
        raise LinkFeaError(f"--scheduler {address}: not an address such as tcp://host:8786")
    try:
        socket.create_connection((host, port), timeout=timeout).close()
    except OSError as exc:
        raise LinkFeaError(f"cannot reach the Dask scheduler at {address}: {exc.strerror or exc}; nothing was "
                           f"written") from None


def connect(address: str):
    """A client of the Dask scheduler at ``address`` (checked first: :func:`check_scheduler`)."""
    from distributed import Client

    check_scheduler(address)
    try:
        return Client(address, timeout="20s")
    except (OSError, TimeoutError) as exc:
        raise LinkFeaError(f"cannot reach the Dask scheduler at {address}: {exc}; nothing was written") from None

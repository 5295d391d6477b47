"""Running a long C computation (the mesher) so that Ctrl-C stops it at once.

gmsh holds the process inside C for as long as it meshes: Python's SIGINT handler only sets a
flag, so Ctrl-C waited for the mesh (more than 2 min at ``--mesh-size 0.3`` on the bar), and
gmsh's own hook (``interruptible=True``) restores the default action, which kills the process
without a word.  :func:`run_in_child` forks: the child computes and sends the pickled result
through a pipe; the parent waits in a ``read``, which Python interrupts for Ctrl-C, and then
kills the child (SIGKILL: gmsh does not stop for SIGTERM either) and raises
``KeyboardInterrupt`` itself.  The fork is copy-on-write, so the CAD objects and a size callback
reach the child without pickling; only the result (arrays) is copied back.

Where Ctrl-C cannot reach the caller anyway (a worker thread, a Dask worker, a handler other
or SIGINT ignored, as in a background job), the function runs in-process.
"""
from __future__ import annotations

import os
import pickle
import signal
import threading
from typing import Callable, TypeVar

from .errors import SolverError

T = TypeVar("T")


def interruptible_here() -> bool:
    """Can Ctrl-C reach this call (main thread, a Python handler for SIGINT: not ignored, not the default)?"""
    return (hasattr(os, "fork") and threading.current_thread() is threading.main_thread()
            and callable(signal.getsignal(signal.SIGINT)))


def _child(fn: Callable, args, kwargs, w: int) -> None:  # pragma: no cover (runs in the forked child)
    signal.signal(signal.SIGINT, signal.SIG_DFL)  # Ctrl-C at a terminal reaches the whole group: die at once
    try:
        payload = (True, fn(*args, **kwargs))
    except BaseException as exc:  # everything goes back to the parent, Ctrl-C included
        payload = (False, exc)
    try:
        data = pickle.dumps(payload, protocol=pickle.HIGHEST_PROTOCOL)
    except Exception as exc:  # an exception that does not pickle: its text
        data = pickle.dumps((False, SolverError(f"{type(payload[1]).__name__}: {payload[1]} ({exc})")))
    with os.fdopen(w, "wb") as fh:
        fh.write(data)


def run_in_child(fn: Callable[..., T], *args, **kwargs) -> T:
    """``fn(*args, **kwargs)`` in a forked child process that Ctrl-C kills at once (see the module docstring);
    its exceptions are raised here.  In-process where Ctrl-C could not reach the caller."""
    if not interruptible_here():
        return fn(*args, **kwargs)
    r, w = os.pipe()
    try:
        pid = os.fork()
    except OSError:  # no memory for the fork's page tables (strict overcommit): run here, as before
        os.close(r)
        os.close(w)
        return fn(*args, **kwargs)
    if pid == 0:  # pragma: no cover (the child)
        try:
            os.close(r)
            _child(fn, args, kwargs, w)
        finally:
            os._exit(0)
    os.close(w)
    try:
        with os.fdopen(r, "rb") as fh:
            data = fh.read()
    except BaseException:  # Ctrl-C (or any failure of the wait): the child must not go on meshing
        os.kill(pid, signal.SIGKILL)
        os.waitpid(pid, 0)
        raise
    _, status = os.waitpid(pid, 0)
    if not data:
        raise SolverError(f"the mesher process ended without a result ({_how(status)}; out of memory?)")
    ok, value = pickle.loads(data)
    if ok:
        return value
    raise value


def _how(status: int) -> str:
    if os.WIFSIGNALED(status):
        return f"killed by signal {os.WTERMSIG(status)}"
    return f"exit status {os.WEXITSTATUS(status)}" if os.WIFEXITED(status) else f"status {status}"

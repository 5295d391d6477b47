"""Fresh processes without a fresh interpreter's imports: a script or a command run in a process of its own,
forked from a server that has imported the heavy packages once (numpy, scipy, matplotlib, cadquery, pyvista,
linkfea, vjm: about 5 s of CPU per interpreter).

Each run is a new process, as ``python script.py`` or the console script would be: its own module state (an
effect registered, a backend set, a fault counter, a SIGKILL end nothing but it), its own working folder,
environment, ``sys.path`` (that of a fresh interpreter with the run's environment) and its own output files.
Only what the server imported is shared, imported as a fresh interpreter would, with ``MPLBACKEND=Agg``.

The server is :mod:`multiprocessing`'s forkserver: a single-threaded process started once per test process, so a
fork from it is safe (a fork of a test process with threads is not).
"""
from __future__ import annotations

import json
import multiprocessing
import os
import shutil
import signal
import subprocess
import sys
import tempfile
from dataclasses import dataclass
from pathlib import Path

#: what the server imports (each one: seconds of a fresh interpreter's start)
PRELOAD = ["numpy", "scipy.optimize", "scipy.stats", "scipy.sparse", "matplotlib", "matplotlib.pyplot", "pyvista",
           "cadquery", "linkfea", "linkfea.cli", "vjm", "vjm.cli"]

_ctx = None
_paths: dict = {}


@dataclass(frozen=True)
class Result:
    returncode: int  # negative: killed by that signal, as subprocess reports it
    stdout: str
    stderr: str


def _context():
    global _ctx
    if _ctx is None:
        ctx = multiprocessing.get_context("forkserver")
        ctx.set_forkserver_preload(PRELOAD)
        old = os.environ.get("MPLBACKEND")
        os.environ["MPLBACKEND"] = "Agg"  # read when matplotlib is imported, in the server
        try:
            from multiprocessing import forkserver

            forkserver.ensure_running()
        finally:
            if old is None:
                os.environ.pop("MPLBACKEND")
            else:
                os.environ["MPLBACKEND"] = old
        _ctx = ctx
    return _ctx


def _fresh_path(env: dict) -> list:
    """``sys.path`` of a fresh interpreter with ``env`` (its first entry, the script's folder, left out)."""
    key = env.get("PYTHONPATH", "")
    if key not in _paths:
        out = subprocess.run([sys.executable, "-c", "import json, sys; print(json.dumps(sys.path[1:]))"], env=env,
                             capture_output=True, text=True, check=True).stdout
        _paths[key] = json.loads(out)
    return _paths[key]


def _child(kind: str, what, cwd: str, env: dict, path: list, log: str) -> None:
    os.setsid()  # a process group of its own: what it starts (Dask workers) can be killed with it
    os.chdir(cwd)
    os.environ.clear()
    os.environ.update(env)
    sys.stdout.flush()
    sys.stderr.flush()
    os.dup2(os.open(log + ".out", os.O_WRONLY | os.O_TRUNC), 1)
    os.dup2(os.open(log + ".err", os.O_WRONLY | os.O_TRUNC), 2)
    if kind == "script":
        import runpy

        sys.path[:] = [str(Path(what).parent), *path]
        sys.argv = [str(what)]
        runpy.run_path(str(what), run_name="__main__")
    else:  # a console script: linkfea or vjm, and its arguments
        sys.path[:] = [str(Path(sys.executable).parent), *path]
        sys.argv = list(what)
        from linkfea.cli import main as linkfea_main
        from vjm.cli import main as vjm_main

        sys.exit({"linkfea": linkfea_main, "vjm": vjm_main}[what[0]](list(what[1:])))


def _run(kind: str, what, cwd, env: dict, timeout: float) -> Result:
    ctx = _context()
    cwd = Path(cwd)
    log = tempfile.mkdtemp(prefix="freshrun-") + "/log"
    for name in (log + ".out", log + ".err"):
        Path(name).touch()
    p = ctx.Process(target=_child, args=(kind, what, str(cwd), dict(env), _fresh_path(env), log))
    p.start()
    p.join(timeout)
    hung = p.is_alive()
    try:
        os.killpg(p.pid, signal.SIGKILL)  # what is left of its group: the workers of a killed sweep
    except (ProcessLookupError, PermissionError):
        pass
    p.join()
    outs = [Path(log + ext).read_text(errors="replace") for ext in (".out", ".err")]
    shutil.rmtree(Path(log).parent, ignore_errors=True)
    if hung:  # not the SIGKILL a test waits for: the run did not end by itself
        raise subprocess.TimeoutExpired(what, timeout, outs[0], outs[1])
    return Result(p.exitcode, *outs)


def script(path, cwd, env: dict, timeout: float = 600) -> Result:
    """``python path`` in ``cwd`` with the environment ``env``."""
    return _run("script", str(path), cwd, env, timeout)


def command(argv: list, cwd, env: dict, timeout: float = 600) -> Result:
    """The console script ``argv[0]`` (``linkfea`` or ``vjm``) with ``argv[1:]`` in ``cwd`` with ``env``."""
    return _run("command", [str(a) for a in argv], cwd, env, timeout)

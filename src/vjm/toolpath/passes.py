"""The nonlinear deflection and compensation of a toolpath in passes of :data:`CHUNK` points.

Each pass solves its points' deflection (warm-started runs, :mod:`vjm.toolpath.equilibrium`), then their
compensation, whose check equilibria start from the deflection's states at the same points; nothing
is carried from one pass to the next, so the passes are independent (each run starts cold at its
first point, and the cold starts are counted).  With ``workers > 1`` on a long path the passes go to
that many worker processes (forked: they share the toolpath and the model with this one and return
only their pass's results), which run truly side by side where threads would wait on each other's
numpy set-up; the results are the same numbers as in one process.  Progress lines carry the rate and
an estimate of the time left.
"""
from __future__ import annotations

import multiprocessing
import signal
import time

import numpy as np

from .compensate import compensate as _compensate
from .deflect import nonlinear_tcp_solved

#: points per pass of deflection then compensation (their equilibrium states are kept for one pass only)
CHUNK = 8192

#: the job the forked workers compute passes of: (model, toolpath, wrenches, tool, compensate)
_JOB: tuple | None = None


def _eta(progress, done: int, n: int, t0: float) -> None:
    """A progress line with the rate and the time left (programs of more than one pass)."""
    if n <= CHUNK or done >= n:
        return
    rate = done / max(time.perf_counter() - t0, 1e-9)
    progress(f"  {done:,} of {n:,} points, {rate:,.0f} points/s, about {(n - done) / rate:,.0f} s left")


def one_pass(m, tp, W, t, a: int, b: int, workers: int, compensate: bool) -> tuple:
    """(twist, deflection cold starts, commands, residuals, residual vectors, equilibria, check cold starts)
    of points a:b; the twist's NaN rows are named by the caller."""
    sl = slice(a, b)
    s = nonlinear_tcp_solved(m, tp.poses[sl], W[sl], t, workers)
    _named_nan(tp, s.twist, a)
    if not compensate:
        return s.twist, s.cold, None, None, None, 0, 0
    c = _compensate(m, tp.poses[sl], W[sl], t, s.twist, workers, lambda i: tp.where(i + a), s.state)
    return s.twist, s.cold, c.commanded, c.residual, c.residual_vector, c.equilibria, c.cold


def _worker_pass(ab: tuple) -> tuple:
    assert _JOB is not None  # set before the fork
    m, tp, W, t, compensate = _JOB
    return one_pass(m, tp, W, t, ab[0], ab[1], 1, compensate)


def _ignore_sigint() -> None:
    """Workers leave Ctrl-C to the parent, which terminates them (no traceback from each)."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)


def _forkable() -> bool:
    return "fork" in multiprocessing.get_all_start_methods()


def run_passes(m, tp, W, t, workers: int, compensate: bool, progress):
    """Yields (a, b, one_pass result) for consecutive passes, in order.  The first pass runs here (it
    loads the compiled kernels before any fork); with ``workers > 1`` and more passes, the rest go to
    ``workers`` forked processes."""
    global _JOB
    n = len(tp.poses)
    ranges = [(a, min(n, a + CHUNK)) for a in range(0, n, CHUNK)]
    t0 = time.perf_counter()
    procs = workers > 1 and len(ranges) > 2 and _forkable()
    for a, b in ranges[:1] if procs else ranges:
        yield a, b, one_pass(m, tp, W, t, a, b, workers, compensate)
        _eta(progress, b, n, t0)
    if not procs:
        return
    _JOB = (m, tp, W, t, compensate)
    pool = multiprocessing.get_context("fork").Pool(workers, initializer=_ignore_sigint)
    try:
        for (a, b), out in zip(ranges[1:], pool.imap(_worker_pass, ranges[1:])):
            yield a, b, out
            _eta(progress, b, n, t0)
        pool.close()
    finally:
        pool.terminate()  # on an error or Ctrl-C: the workers stop at once
        pool.join()
        _JOB = None


def deflect_and_compensate(m, tp, W, t, workers: int, compensate: bool, progress):
    """(nonlinear deflection (n, 6), (commands, residuals, residual vectors, equilibria, check cold starts)
    or None, deflection cold starts) of the whole toolpath, pass by pass."""
    n = len(tp.poses)
    d_nl = np.empty((n, 6))
    cmd, res, resvec = np.empty_like(tp.poses), np.empty(n), np.empty((n, 3))
    iters = cold = cold_c = 0
    for a, b, (tw, c0, c_cmd, c_res, c_vec, c_it, c_cold) in run_passes(m, tp, W, t, workers, compensate,
                                                                       progress):
        d_nl[a:b] = tw
        cold += c0
        if compensate:
            cmd[a:b], res[a:b], resvec[a:b] = c_cmd, c_res, c_vec
            iters, cold_c = max(iters, c_it), cold_c + c_cold
    return d_nl, ((cmd, res, resvec, iters, cold_c) if compensate else None), cold


def _named_nan(tp, d, offset: int = 0) -> None:
    from ..errors import EquilibriumError

    bad = ~np.all(np.isfinite(d), axis=1)
    if bad.any():
        i = int(np.argmax(bad)) + offset
        raise EquilibriumError(f"{tp.where(i)}: no equilibrium of the loaded machine (load too large for the "
                               f"model, or past a buckling load?)")

"""Synthetic measurements from a model with hidden effects (``vjm simulate``).

Design of the experiment
------------------------
``poses``:
  * ``grid:N``   -- N x N x N grid over the model's workspace box, unreachable points dropped;
  * ``random:N`` -- N uniform random points in the box (reachable ones kept, drawn until N);
  * ``PATH.csv`` -- a CSV with columns x,y,z (mm).
``loads`` (applied at every posture):
  * ``axes:F[:M]``   -- +-F N along x, y, z (and +-M N mm about x, y, z if M is given);
  * ``random:N:F``   -- N random force directions of magnitude F N (drawn per posture);
  * ``PATH.csv``     -- a CSV with columns Fx,Fy,Fz,Mx,My,Mz.
The same CSV given to both ``--poses`` and ``--loads`` (columns x,y,z,Fx..Mz, e.g.
``next_measurements.csv`` written by ``vjm diagnose --suggest``) is read as
(posture, load) pairs, one measurement per row, instead of every load at every posture.
Noise: independent Gaussian, ``noise_t`` (mm) on dx, dy, dz and ``noise_r``
(rad) on rx, ry, rz; without ``noise_r`` rotations are left blank (translation-only
data, the common case).  The sigmas are written in ``sigma_t``/``sigma_r``.
"""
from __future__ import annotations

import csv
import os

import numpy as np

from linkfea.checks import NON_NEGATIVE, Bounds, integer, number, optional_number

from ..errors import ArgumentError, VjmError
from . import effects as fx
from . import modelops as mo
from .data import Deflections
from .predict import Context, unique_postures


def parse_effect(spec: str):
    """``NAME[:param=value,...]`` -> (name, {param: value})."""
    name, _, rest = spec.partition(":")
    eff = fx.get(name.strip(), f"--effect {spec}")
    vals = {}
    for item in filter(None, (s.strip() for s in rest.split(","))):
        k, eq, v = item.partition("=")
        if not eq:
            raise VjmError(f"--effect {spec}: expected param=value, got '{item}'")
        try:
            vals[k.strip()] = float(v)
        except ValueError:
            raise VjmError(f"--effect {spec}: '{v}' is not a number") from None
    return eff.name, vals


def _effect_theta(model, name, vals):
    eff = fx.get(name)
    specs = eff.param_specs(model)
    vals = fx.check_values(name, vals, model, f"effect {name}")
    missing = [p.name for p in specs if p.name not in vals]
    # a multi-parameter effect may leave some parameters at their null (e.g. a foot that only bends)
    if missing and (len(missing) == len(specs)):
        raise VjmError(f"effect {name}: give a value for {', '.join(missing)} (e.g. {name}:{missing[0]}=...)")
    return np.array([vals.get(p.name, p.null) for p in specs])


def _read_cols(path, cols):
    try:
        with open(path, newline="", encoding="utf-8") as fh:
            rows = [r for r in csv.reader(fh) if r and not r[0].lstrip().startswith("#")]
    except OSError as exc:
        raise VjmError(f"cannot read {path}: {exc.strerror}") from None
    if not rows:
        raise VjmError(f"{path}: empty file")
    hdr = [h.strip() for h in rows[0]]
    miss = [c for c in cols if c not in hdr]
    if miss:
        raise VjmError(f"{os.path.basename(path)}: row 1: missing column(s) {', '.join(miss)}")
    out = np.empty((len(rows) - 1, len(cols)))
    for i, r in enumerate(rows[1:]):
        for j, c in enumerate(cols):
            try:
                out[i, j] = float(r[hdr.index(c)])
            except (ValueError, IndexError):
                raise VjmError(f"{os.path.basename(path)}: row {i + 2}, column '{c}': not a number") from None
    return out


def _reachable(model, P):
    ok = np.ones(len(P), bool)
    try:
        q = mo.actuator_coords(model, P)
        return np.all(np.isfinite(q), axis=1)
    except VjmError:
        for k in range(len(P)):
            try:
                ok[k] = np.all(np.isfinite(mo.actuator_coords(model, P[k:k + 1])))
            except VjmError:
                ok[k] = False
    return ok


def design_poses(model, spec: str, rng) -> np.ndarray:
    lo, hi = mo.workspace_box(model)
    kind, _, arg = spec.partition(":")
    if kind == "grid":
        n = _int(arg, spec, "poses")
        ax = [np.linspace(lo[i], hi[i], n) for i in range(3)]
        P = np.stack(np.meshgrid(*ax, indexing="ij"), -1).reshape(-1, 3)
        P = P[_reachable(model, P)]
    elif kind == "random":
        n = _int(arg, spec, "poses")
        P = np.empty((0, 3))
        for _ in range(20):
            Q = lo + (hi - lo) * rng.random((2 * n, 3))
            P = np.vstack([P, Q[_reachable(model, Q)]])
            if len(P) >= n:
                break
        P = P[:n]
    elif os.path.isfile(spec):
        P = _read_cols(spec, ["x", "y", "z"])
    else:
        raise ArgumentError("poses", f"{spec}: expected grid:N, random:N or a CSV file with columns x,y,z")
    if len(P) == 0:
        raise ArgumentError("poses", f"{spec}: no reachable posture")
    return P


def design_loads(spec: str, n_poses: int, rng) -> np.ndarray:
    """(n_poses, k, 6) wrenches applied at each posture."""
    kind, _, arg = spec.partition(":")
    if kind == "axes":
        parts = arg.split(":")
        F = _num(parts[0], spec, "loads")
        M = _num(parts[1], spec, "loads") if len(parts) > 1 else 0.0
        L = [s * F * np.eye(6)[i] for i in range(3) for s in (1, -1)]
        if M:
            L += [s * M * np.eye(6)[i] for i in range(3, 6) for s in (1, -1)]
        return np.broadcast_to(np.array(L), (n_poses, len(L), 6)).copy()
    if kind == "random":
        parts = arg.split(":")
        if len(parts) != 2:
            raise ArgumentError("loads", f"{spec}: expected random:N:F")
        k, F = _int(parts[0], spec, "loads"), _num(parts[1], spec, "loads")
        d = rng.standard_normal((n_poses, k, 3))
        d /= np.linalg.norm(d, axis=2, keepdims=True)
        out = np.zeros((n_poses, k, 6))
        out[:, :, :3] = F * d
        return out
    if os.path.isfile(spec):
        L = _read_cols(spec, ["Fx", "Fy", "Fz", "Mx", "My", "Mz"])
        return np.broadcast_to(L, (n_poses,) + L.shape).copy()
    raise ArgumentError("loads", f"{spec}: expected axes:F[:M], random:N:F or a CSV file with columns Fx..Mz")


def _int(s, spec, arg):
    try:
        v = int(s)
    except ValueError:
        raise ArgumentError(arg, f"{spec}: {s!r} is not a whole number") from None
    if v < 1:
        raise ArgumentError(arg, f"{spec}: the count must be a whole number >= 1, got {v}")
    return v


def _num(s, spec, arg):
    try:
        v = float(s)
    except ValueError:
        raise ArgumentError(arg, f"{spec}: {s!r} is not a number") from None
    if not np.isfinite(v):
        raise ArgumentError(arg, f"{spec}: {s!r} is not a finite number")
    return v


def _same_file(poses: str, loads: str) -> bool:
    """--poses and --loads name the same CSV: its rows are (posture, load) pairs, not a product."""
    return os.path.isfile(poses) and os.path.isfile(loads) and os.path.samefile(poses, loads)


def true_model(model, effects):
    """Model with the model-kind hidden effects applied, and the additive ones as (effect, theta)."""
    add = []
    for name, vals in effects:
        th = _effect_theta(model, name, vals)
        eff = fx.get(name)
        if eff.kind == "model":
            model = eff.apply(model, th)
        else:
            add.append((eff, th))
    return model, add


#: valid ranges of the noise sigmas (mm, rad) and the random seed
NOISE_T = Bounds(0, unit="mm")
NOISE_R = Bounds(0, unit="rad")


def check_arguments(noise_t, noise_r, seed):
    """The numeric arguments of :func:`simulate`, checked (type, finiteness, range): ArgumentError naming one."""
    return (number(noise_t, "noise_t", NOISE_T, ArgumentError),
            optional_number(noise_r, "noise_r", NOISE_R, ArgumentError),
            integer(seed, "seed", NON_NEGATIVE, ArgumentError))


def simulate(model, effects, P, W, noise_t: float, noise_r: float | None, seed: int) -> Deflections:
    """Noisy deflections of ``model`` with hidden ``effects`` at postures P (n,3) under wrenches W (n,6)."""
    noise_t, noise_r, seed = check_arguments(noise_t, noise_r, seed)
    if not np.all(np.isfinite(W)):
        raise VjmError("loads must be finite numbers")
    if not np.any(W):
        raise VjmError("all loads are zero: a deflection measurement needs a load")
    rng = np.random.default_rng(seed)
    mt, add = true_model(model, effects)
    U, idx = unique_postures(P)
    C = mo.compliance_map(mt, U)[idx]
    t = np.einsum("nij,nj->ni", C, W)
    ctx = Context(mt, U, idx, W)
    for eff, th in add:
        t = t + eff.extra(ctx, th, C)
    n = len(P)
    T = t.copy()
    T[:, :3] += noise_t * rng.standard_normal((n, 3))
    if noise_r is None:
        T[:, 3:] = np.nan
        sr = None
    else:
        T[:, 3:] += noise_r * rng.standard_normal((n, 3))
        sr = np.full(n, noise_r if noise_r > 0 else 1e-12)
    st = np.full(n, noise_t if noise_t > 0 else 1e-12)
    return Deflections(np.asarray(P, float), np.asarray(W, float), T, st, sr, np.arange(2, n + 2), "<simulated>")


def run(model_path, effect_specs, poses: str, loads: str, noise_t: float, noise_r, seed: int, out) -> Deflections:
    """Body of ``vjm simulate``: check ``out``, design, simulate, write the CSV atomically.

    An existing ``out`` is replaced only if vjm simulate wrote it (measured data is never overwritten).
    """
    from linkfea.outputs import SIMULATED_CSV_MARK, check_file, is_simulated_csv

    from .data import write_deflections

    check_arguments(noise_t, noise_r, seed)
    check_file(out, is_simulated_csv, "a CSV written by vjm simulate")
    model = mo.load_model(model_path)
    effects = [parse_effect(s) for s in effect_specs]
    rng = np.random.default_rng([seed, 1])
    if _same_file(poses, loads):
        # one file with x,y,z,Fx..Mz (e.g. next_measurements.csv of vjm diagnose --suggest): paired rows
        P = _read_cols(poses, ["x", "y", "z"])
        W = _read_cols(loads, ["Fx", "Fy", "Fz", "Mx", "My", "Mz"])
        if len(P) == 0:
            raise ArgumentError("poses", f"{poses}: no data rows")
        bad = ~_reachable(model, P)
        if bad.any():
            raise VjmError(f"{os.path.basename(poses)}: row {int(np.argmax(bad)) + 2}, columns 'x,y,z': posture "
                           f"({P[bad][0, 0]:g}, {P[bad][0, 1]:g}, {P[bad][0, 2]:g}) mm is unreachable")
    else:
        P0 = design_poses(model, poses, rng)
        L = design_loads(loads, len(P0), rng)
        k = L.shape[1]
        P = np.repeat(P0, k, axis=0)
        W = L.reshape(-1, 6)
    data = simulate(model, effects, P, W, noise_t, noise_r, seed)
    desc = ", ".join(f"{n}:" + ",".join(f"{a}={b:g}" for a, b in v.items()) for n, v in effects) or "none"
    write_deflections(out, data, f"{SIMULATED_CSV_MARK[2:]} from {os.path.basename(str(model_path))}; "
                                 f"poses {poses}; loads {loads}; noise_t {noise_t} mm; noise_r {noise_r} rad; "
                                 f"seed {seed}; hidden effects: {desc}")
    return data

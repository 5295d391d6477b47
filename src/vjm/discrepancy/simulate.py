"""Synthetic measurements from a model with hidden effects (``vjm simulate``).

Design of the experiment
------------------------
``poses``:
  * ``grid:N``   -- N x N x N grid over the model's workspace box, unreachable points dropped;
  * ``random:N`` -- N uniform random points in the box (reachable ones kept, drawn until N);
  * ``PATH.csv`` -- a CSV with columns x,y,z (mm) and, for a 6-dof platform, optionally ox,oy,oz
    (the platform orientation, a rotation vector in rad, as ``vjm stiffness --at``).
A 6-dof platform's grid and random postures are level (zero orientation) unless ``tilt`` (rad)
is given: then each gets a random orientation, every rotation-vector component uniform in
``[-tilt, tilt]`` (unreachable poses dropped, as for the positions).  The file written for a
6-dof platform always has the orientation columns ``ox,oy,oz``.
``loads`` (applied at every posture):
  * ``axes:F[:M]``   -- +-F N along x, y, z (and +-M N mm about x, y, z if M is given);
  * ``random:N:F``   -- N random force directions of magnitude F N (drawn per posture);
  * several magnitudes (*load levels*), comma-separated: ``axes:50,100`` applies every axis
    load at 50 N and at 100 N; ``axes:50,100:2500,5000`` pairs the moments with the forces,
    ``axes:50,100:5000`` scales the moment with the force (5000 N mm at 100 N);
    ``random:N:50,100`` applies each random direction at every magnitude.  The same posture
    and direction at several magnitudes is what tells a load-dependent stiffness apart from a
    compliance (:mod:`vjm.discrepancy.loads`);
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
import io
import os

import numpy as np

from linkfea.mechanics.compliance import WRENCH
from linkfea.runtime.checks import NON_NEGATIVE, Bounds, integer, number, optional_number

from .. import effects as fx
from ..effects import modelops as mo
from ..effects.context import Context, unique_postures
from ..errors import ArgumentError, VjmError
from ..maps.grid import SIMULATE_BYTES, in_chunks, plan
from ..modelio.read import load_model
from .data import ORIENT, Deflections
from .loads import parse_levels


def parse_effect(spec: str):
    """``NAME[:param=value,...]`` -> (name, {param: value})."""
    name, _, rest = spec.partition(":")
    eff = fx.get(name.strip(), f"--effect {spec}")
    vals = {}
    for item in filter(None, (s.strip() for s in rest.split(","))):
        k, eq, v = item.partition("=")
        if not eq:
            raise VjmError(f"--effect {spec}: expected param=value, got '{item}'")
        if k.strip() in vals:
            raise VjmError(f"--effect {spec}: {k.strip()} is given twice; give it once")
        try:
            vals[k.strip()] = float(v)
        except ValueError:
            raise VjmError(f"--effect {spec}: '{v}' is not a number") from None
    return eff.name, vals


def _effect_theta(model, name, vals):
    eff = fx.get(name)
    specs = eff.param_specs(model)
    vals = fx.check_values(name, vals, model, f"effect {name}", fit_range=False)
    missing = [p.name for p in specs if p.name not in vals]
    # a multi-parameter effect may leave some parameters at their null (e.g. a foot that only bends)
    if missing and (len(missing) == len(specs)):
        raise VjmError(f"effect {name}: give a value for {', '.join(missing)} (e.g. {name}:{missing[0]}=...)")
    return np.array([vals.get(p.name, p.null) for p in specs])


def _read_cols(path, cols, optional=()):
    """Columns ``cols`` (n, k) of a CSV, and ``optional`` after them when the header has them all."""
    from linkfea.files.atomic import read_user_file

    raw = read_user_file(path, "CSV file", error=VjmError)  # a regular file of bounded size only
    try:
        text = raw.decode("utf-8-sig")
    except UnicodeDecodeError:
        raise VjmError(f"{os.path.basename(path)}: not UTF-8 text; save it as UTF-8 (CSV UTF-8 in a spreadsheet)") from None
    rows = [r for r in csv.reader(io.StringIO(text, newline="")) if r and not r[0].lstrip().startswith("#")]
    if not rows:
        raise VjmError(f"{path}: empty file")
    hdr = [h.strip() for h in rows[0]]
    miss = [c for c in cols if c not in hdr]
    if miss:
        raise VjmError(f"{os.path.basename(path)}: row 1: missing column(s) {', '.join(miss)}")
    given = [c for c in optional if c in hdr]
    if given:
        if len(given) < len(optional):
            miss = [c for c in optional if c not in hdr]
            raise VjmError(f"{os.path.basename(path)}: row 1: missing column(s) {', '.join(miss)} "
                           f"(give {','.join(optional)} all three or none)")
        cols = list(cols) + list(optional)
    out = np.empty((len(rows) - 1, len(cols)))
    for i, r in enumerate(rows[1:]):
        for j, c in enumerate(cols):
            try:
                out[i, j] = float(r[hdr.index(c)])
            except (ValueError, IndexError):
                raise VjmError(f"{os.path.basename(path)}: row {i + 2}, column '{c}': not a number") from None
    return out


FEWER = "use fewer postures or loads"


def with_orientation(model, P, tilt: float = 0.0, rng=None) -> np.ndarray:
    """Poses of ``model``: points P (n, 3) of a 3-dof platform as they are; for a 6-dof platform
    (n, 6) with the orientation given, or zero, or (``tilt`` > 0) random, each rotation-vector
    component uniform in ``[-tilt, tilt]`` rad."""
    P = np.asarray(P, float)
    if model.dof != 6 or P.shape[1] == 6:
        return P
    O = np.zeros((len(P), 3))
    if tilt > 0:
        O = tilt * (2.0 * (np.random.default_rng() if rng is None else rng).random((len(P), 3)) - 1.0)
    return np.hstack([P, O])


def grid_poses(model, n: int, tilt: float = 0.0, rng=None) -> np.ndarray:
    """The reachable poses of an n x n x n grid of the model's workspace (:meth:`vjm.Model.grid`), mm:
    points (m, 3), or (m, 6) with the orientations of :func:`with_orientation` for a 6-dof platform."""
    plan(f"a posture grid of {n} per axis", int(n) ** 3, SIMULATE_BYTES, unit="postures", hint=FEWER)
    P = with_orientation(model, model.grid(n).points, tilt, rng)
    return P[model.reachable(P)]


def random_poses(model, n: int, rng, tilt: float = 0.0) -> np.ndarray:
    """n uniform random reachable poses of the model's workspace box (points (n, 3), or (n, 6) for a
    6-dof platform, see :func:`with_orientation`), mm and rad (fewer if the box is mostly out of
    reach: 20 draws of 2n poses at most)."""
    plan(f"{n} random postures", 2 * n, SIMULATE_BYTES, unit="draws", hint=FEWER)
    ws = model.workspace
    P = np.empty((0, 6 if model.dof == 6 else 3))
    for _ in range(20):
        Q = with_orientation(model, ws.random(2 * n, rng), tilt, rng)
        P = np.vstack([P, Q[model.reachable(Q)]])
        if len(P) >= n:
            break
    return P[:n]


def _pose_text(p) -> str:
    text = f"({p[0]:g}, {p[1]:g}, {p[2]:g}) mm"
    return text + (f" at orientation ({p[3]:g}, {p[4]:g}, {p[5]:g}) rad" if len(p) == 6 else "")


def file_poses(model, path) -> np.ndarray:
    """Poses of a CSV: columns x,y,z, and ox,oy,oz where given (a 6-dof platform only: one line
    naming the file and the column for a 3-dof one); a 6-dof platform's poses are (n, 6)."""
    P = _read_cols(path, ["x", "y", "z"], ORIENT)
    if P.shape[1] == 6 and model.dof != 6:
        raise VjmError(f"{os.path.basename(path)}: column 'ox': the file gives platform orientations (ox,oy,oz) "
                       f"but the machine's platform only translates (3 dof); drop the columns ox,oy,oz")
    return with_orientation(model, P)


def design_poses(model, spec, rng=None, tilt: float = 0.0) -> np.ndarray:
    """Poses, mm and rad: ``spec`` is ``grid:N``, ``random:N``, a CSV path with columns x,y,z[,ox,oy,oz],
    or an array of points (n, 3) or poses (n, 6) (checked reachable).  ``rng`` draws the random ones;
    ``tilt`` (rad) the random orientations of a 6-dof platform's grid and random poses.
    Points (n, 3) for a 3-dof platform, poses (n, 6) x, y, z, ox, oy, oz for a 6-dof one."""
    rng = np.random.default_rng() if rng is None else rng
    if not isinstance(spec, (str, os.PathLike)):
        P = np.asarray(spec, dtype=float)
        if P.ndim != 2 or P.shape[1] not in (3, 6) or not np.all(np.isfinite(P)):
            raise VjmError(f"postures must be a finite array (n, 3) of points in mm or (n, 6) of poses "
                           f"x, y, z, ox, oy, oz (mm, rad), got shape {P.shape}")
        if P.shape[1] == 6 and model.dof != 6:
            raise VjmError("postures: orientations (n, 6) given, but the machine's platform only translates (3 dof)")
        P = with_orientation(model, P)
        bad = ~model.reachable(P)
        if bad.any():
            i = int(np.argmax(bad))
            raise VjmError(f"posture {i} {_pose_text(P[i])} is unreachable")
        return P
    spec = os.fspath(spec)
    kind, _, arg = spec.partition(":")
    if kind == "grid":
        P = grid_poses(model, _int(arg, spec, "poses"), tilt, rng)
    elif kind == "random":
        P = random_poses(model, _int(arg, spec, "poses"), rng, tilt)
    elif os.path.exists(spec):  # a file that is not a regular one is refused by the reader, by name
        P = file_poses(model, spec)
    else:
        raise ArgumentError("poses", f"{spec}: expected grid:N, random:N or a CSV file with columns x,y,z")
    if len(P) == 0:
        raise ArgumentError("poses", f"{spec}: no reachable posture")
    return P


def axes_loads(force: float, moment: float = 0.0) -> np.ndarray:
    """(k, 6) loads: +-force N along x, y, z, then +-moment N mm about x, y, z if moment is not 0."""
    L = [s * force * np.eye(6)[i] for i in range(3) for s in (1, -1)]
    if moment:
        L += [s * moment * np.eye(6)[i] for i in range(3, 6) for s in (1, -1)]
    return np.array(L)


def random_loads(n_poses: int, k: int, force: float, rng) -> np.ndarray:
    """(n_poses, k, 6) forces of magnitude ``force`` N in random directions, drawn per posture."""
    plan(f"{k} random loads at each of {n_poses} postures", n_poses * k, SIMULATE_BYTES, unit="measurements",
         hint=FEWER)
    d = rng.standard_normal((n_poses, k, 3))
    d /= np.linalg.norm(d, axis=2, keepdims=True)
    out = np.zeros((n_poses, k, 6))
    out[:, :, :3] = force * d
    return out


def design_loads(spec, n_poses: int, rng=None) -> np.ndarray:
    """(n_poses, k, 6) wrenches applied at each posture (N, N mm): ``spec`` is ``axes:F[:M]``,
    ``random:N:F``, a CSV path with columns Fx..Mz, or an array (k, 6) applied at every posture."""
    if not isinstance(spec, (str, os.PathLike)):
        L = np.asarray(spec, dtype=float)
        if L.ndim != 2 or L.shape[1] != 6 or not np.all(np.isfinite(L)):
            raise VjmError(f"loads must be a finite array (k, 6) of wrenches Fx..Mz (N, N mm), got shape {L.shape}")
        return _every_posture(L, n_poses)
    spec = os.fspath(spec)
    kind, _, arg = spec.partition(":")
    if kind == "axes":
        parts = arg.split(":")
        if len(parts) > 2:
            raise ArgumentError("loads", f"{spec}: expected axes:F[:M] (F, M: one magnitude or several, "
                                         "comma-separated)")
        Fs = _magnitudes(parts[0], spec)
        Ms = _magnitudes(parts[1], spec) if len(parts) > 1 else [0.0]
        if len(Fs) == 1 and len(Ms) == 1:
            return _every_posture(axes_loads(Fs[0], Ms[0]), n_poses)
        if len(Ms) == 1:  # one moment: scaled with the force, the largest force taking it whole
            Ms = [Ms[0] * F / max(Fs) for F in Fs]
        if len(Ms) != len(Fs):
            raise ArgumentError("loads", f"{spec}: give one moment or as many moments as forces "
                                         f"({len(Fs)}), got {len(Ms)}")
        return _every_posture(np.concatenate([axes_loads(F, M) for F, M in zip(Fs, Ms)]), n_poses)
    if kind == "random":
        parts = arg.split(":")
        if len(parts) != 2:
            raise ArgumentError("loads", f"{spec}: expected random:N:F")
        Fs = _magnitudes(parts[1], spec)
        L = random_loads(n_poses, _int(parts[0], spec, "loads"), 1.0,
                         np.random.default_rng() if rng is None else rng)
        return np.concatenate([F * L for F in Fs], axis=1)
    if os.path.exists(spec):
        return _every_posture(_read_cols(spec, list(WRENCH)), n_poses)
    raise ArgumentError("loads", f"{spec}: expected axes:F[:M], random:N:F or a CSV file with columns Fx..Mz")


def _magnitudes(s, spec) -> list[float]:
    """One magnitude, or several comma-separated ones (load levels: each finite and > 0, distinct)."""
    if "," not in s:
        return [_num(s, spec, "loads")]
    try:
        return parse_levels(s, spec)
    except ValueError as exc:
        raise ArgumentError("loads", str(exc)) from None


def _every_posture(L: np.ndarray, n_poses: int) -> np.ndarray:
    plan(f"{len(L)} loads at each of {n_poses} postures", n_poses * len(L), SIMULATE_BYTES, unit="measurements",
         hint=FEWER)
    return np.broadcast_to(L, (n_poses,) + L.shape).copy()


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
#: random orientations of a 6-dof platform's poses: each rotation-vector component within +-tilt
TILT = Bounds(0, 3.14159, unit="rad")


def check_arguments(noise_t, noise_r, seed):
    """The numeric arguments of :func:`simulate`, checked (type, finiteness, range): ArgumentError naming one."""
    return (number(noise_t, "noise_t", NOISE_T, ArgumentError),
            optional_number(noise_r, "noise_r", NOISE_R, ArgumentError),
            integer(seed, "seed", NON_NEGATIVE, ArgumentError))


def simulate(model, effects, P, W, noise_t: float, noise_r: float | None, seed: int,
             progress=None) -> Deflections:
    """Noisy deflections of ``model`` with hidden ``effects`` at postures P (n, 3) (or poses (n, 6) x, y, z,
    ox, oy, oz of a 6-dof platform; its points get zero orientation) under wrenches W (n, 6).

    The arguments and the memory of the rows are checked first; a run longer than about a minute
    reports through ``progress`` (a callable taking one line of text).
    """
    noise_t, noise_r, seed = check_arguments(noise_t, noise_r, seed)
    plan("the simulated measurements", len(P), SIMULATE_BYTES, unit="measurements", hint=FEWER)
    if not np.all(np.isfinite(W)):
        raise VjmError("loads must be finite numbers")
    if not np.any(W):
        raise VjmError("all loads are zero: a deflection measurement needs a load")
    rng = np.random.default_rng(seed)
    P = with_orientation(model, P)
    mt, add = true_model(model, effects)
    U, idx = unique_postures(P)
    CU = np.empty((len(U), 6, 6))

    def step(s: slice) -> None:
        CU[s] = mo.compliance_map(mt, U[s])

    in_chunks(len(U), step, progress, "postures")
    C = CU[idx]
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


def run(model_path, effect_specs, poses: str, loads: str, noise_t: float, noise_r, seed: int, out,
        progress=None, tilt: float = 0.0) -> Deflections:
    """Body of ``vjm simulate``: check ``out``, design, simulate, write the CSV atomically.

    ``tilt`` (rad): random orientations of a 6-dof platform's grid and random poses (see
    :func:`design_poses`); a 3-dof platform refuses a non-zero tilt.

    An existing ``out`` is replaced only if vjm simulate wrote it (measured data is never overwritten).
    """
    from linkfea.files.outputs import SIMULATED_CSV_MARK, check_file, is_simulated_csv

    from .data import write_deflections

    check_arguments(noise_t, noise_r, seed)
    tilt = number(tilt, "tilt", TILT, ArgumentError)
    check_file(out, is_simulated_csv, "a CSV written by vjm simulate")
    model = load_model(model_path)
    if tilt and model.dof != 6:
        raise ArgumentError("tilt", f"{tilt:g} rad: the machine's platform only translates (3 dof)")
    effects = [parse_effect(s) for s in effect_specs]
    rng = np.random.default_rng([seed, 1])
    if _same_file(poses, loads):
        # one file with x,y,z,Fx..Mz (e.g. next_measurements.csv of vjm diagnose --suggest): paired rows
        P = file_poses(model, poses)
        W = _read_cols(loads, list(WRENCH))
        if len(P) == 0:
            raise ArgumentError("poses", f"{poses}: no data rows")
        bad = ~model.reachable(P)
        if bad.any():
            cols = "x,y,z,ox,oy,oz" if P.shape[1] == 6 else "x,y,z"
            raise VjmError(f"{os.path.basename(poses)}: row {int(np.argmax(bad)) + 2}, columns '{cols}': posture "
                           f"{_pose_text(P[bad][0])} is unreachable")
    else:
        P0 = design_poses(model, poses, rng, tilt)
        L = design_loads(loads, len(P0), rng)
        k = L.shape[1]
        P = np.repeat(P0, k, axis=0)
        W = L.reshape(-1, 6)
    data = simulate(model, effects, P, W, noise_t, noise_r, seed, progress)
    desc = ", ".join(f"{n}:" + ",".join(f"{a}={b:g}" for a, b in v.items()) for n, v in effects) or "none"
    write_deflections(out, data, f"{SIMULATED_CSV_MARK[2:]} from {os.path.basename(str(model_path))}; "
                                 f"poses {poses}; loads {loads}; noise_t {noise_t} mm; noise_r {noise_r} rad; "
                                 f"seed {seed}{f'; tilt {tilt} rad' if tilt else ''}; hidden effects: {desc}")
    return data

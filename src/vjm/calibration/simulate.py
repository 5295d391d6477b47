"""``vjm simulate`` on a serial or tree robot: absolute-pose rows that ``vjm calibrate`` reads.

Each row holds the joint values a controller would report and the point a tracker would measure: a
frame's origin (default the first tool) where the robot really is -- its joints turned by hidden
offsets, its joints' compliances scaled by hidden factors, sagging under its own weight and payload on its
joint and link springs (the nonlinear equilibrium of :meth:`vjm.robot.model.RobotModel.self_weight`, not the
calibration's first-order measurement model) -- plus Gaussian noise, in the
robot's base frame (vjm calibrate registers the instrument frame anyway).  So ``vjm calibrate``
can be tried, and its recovery of known effects checked, without a tracker.

Hidden effects (``--effect``, repeatable), ``NAME:param=value,...`` as a parallel machine's, ``NAME`` a robot's
effect of :mod:`vjm.effects.absolute` that can be hidden (:meth:`~vjm.effects.absolute.PoseEffect.hidden_params`):

- ``geometry:<joint>.offset=<value>,...`` (or ``offset:<joint>=<value>,...``): the joint's true value is the
  reported one plus ``value`` (rad, mm);
- ``compliance:<joint>=<factor>,...``: the joint's compliance is ``factor`` times the model file's;
- an effect giving the joints' motion (``joint_motion``): ``NAME:<parameter>=<value>,...`` with its
  parameters' names, the joints turned by that motion.

Poses (``--poses``): ``random:N`` (N configurations uniform within the joint limits, a continuous
joint over one turn) or a CSV whose header names the model's joints (rad, mm).
"""
from __future__ import annotations

import csv
import os
from dataclasses import dataclass

import numpy as np

from ..effects import absolute
from ..errors import ArgumentError, VjmError
from .serial import site

#: rows at most (a calibration set has tens to thousands)
MAX_ROWS = 100_000


@dataclass(frozen=True)
class Hidden:
    """Hidden truth: ((effect, {parameter: value}), ...) in the order of the effects' registration."""

    effects: tuple = ()

    def describe(self, model) -> str:
        return ", ".join(e.describe(model, v) for e, v in self.effects) or "none"


def _hint(model, at) -> str:
    spell, named = [], []
    for e in absolute.POSES.values():
        keys = e.hidden_params(model, at) if "serial" in e.model_kinds else {}
        if not keys:
            continue
        if e.aliases:   # the short spellings first, the effect's own name after every other
            spell += [f"{a}:<joint>=<value>,..." for a in e.aliases]
            named.append(f"{e.name}:<parameter>=<value>,...")
        elif set(keys) <= set(model.q_names):
            spell.append(f"{e.name}:<joint>={'<factor>' if all(keys.values()) else '<value>'},...")
        else:
            spell.append(f"{e.name}:<parameter>=<value>,...")
    return " or ".join(spell + named)


def parse_hidden(model, specs, frame: str) -> Hidden:
    """``["offset:elbow_joint=0.002", "compliance:elbow_joint=2"]`` -> :class:`Hidden` (on the path to ``frame``)."""
    at = site(model, frame)
    given: dict = {}
    for spec in specs:
        kind, _, body = str(spec).partition(":")
        eff = next((e for e in absolute.POSES.values() if "serial" in e.model_kinds
                    and (e.name == kind or kind in e.aliases)), None)
        keys = eff.hidden_params(model, at) if eff is not None else {}
        if not keys or not body:
            other = f"; {kind} is not simulated" if eff is not None else ""
            raise ArgumentError("effect", f"a robot takes {_hint(model, at)}{other}; got {spec!r}")
        alias = eff.aliases.get(kind)
        joints = alias is not None or set(keys) <= set(model.q_names)
        vals = given.setdefault(eff.name, {})
        for item in body.split(","):
            name, _, val = item.partition("=")
            name = name.strip()
            key = alias.format(joint=name) if alias is not None else name
            if key not in keys or (alias is not None and name not in model.q_names):
                listing = model.q_names if joints else list(keys)
                raise ArgumentError("effect", f"{kind}: no {'joint' if joints else 'parameter'} {name!r}; "
                                              f"{'joints' if joints else 'parameters'}: {', '.join(listing)}")
            try:
                v = float(val)
            except ValueError:
                v = float("nan")
            if not np.isfinite(v) or (keys[key] and not v > 0):
                raise ArgumentError("effect", f"{kind}:{name} needs a finite number{' > 0' if keys[key] else ''}"
                                              f", got {val!r}")
            try:
                eff.check_hidden(model, key, v)
            except VjmError as exc:
                raise ArgumentError("effect", str(exc)) from None
            if key in vals:
                raise ArgumentError("effect", f"{kind}:{name} is given twice ({vals[key]:g} and {v:g}); give it once")
            vals[key] = v
    return Hidden(tuple((e, given[n]) for n, e in absolute.POSES.items() if n in given))


def design(model, poses: str, rng) -> np.ndarray:
    """Configurations (n, nq) of ``--poses``: ``random:N`` or a CSV naming the joints."""
    if poses.startswith("random:"):
        try:
            n = int(poses.split(":", 1)[1])
        except ValueError:
            n = 0
        if not 1 <= n <= MAX_ROWS:
            raise ArgumentError("poses", f"random:N needs a whole number N in 1..{MAX_ROWS:,}, got {poses!r}")
        lo, hi = model.tree.limits
        lo = np.where(np.isfinite(lo), lo, -np.pi)
        hi = np.where(np.isfinite(hi), hi, np.pi)
        return lo + (hi - lo) * rng.random((n, model.nq))
    if not os.path.isfile(poses):
        raise ArgumentError("poses", f"a robot takes random:N or a CSV of joint values ({', '.join(model.q_names)}); "
                                     f"got {poses!r}")
    return _read_q(model, poses)


def _read_q(model, path: str) -> np.ndarray:
    try:
        with open(path, newline="", encoding="utf-8-sig") as fh:
            rows = [r for r in csv.reader(fh) if r and not r[0].startswith("#")]
    except (OSError, UnicodeDecodeError) as e:
        raise VjmError(f"{path}: cannot read ({getattr(e, 'strerror', None) or 'not UTF-8 text'})") from None
    head = [h.strip() for h in rows[0]] if rows else []
    missing = [n for n in model.q_names if n not in head]
    if missing:
        raise VjmError(f"{path}: no column for joint(s) {', '.join(missing)}")
    cols = [head.index(n) for n in model.q_names]
    try:
        Q = np.array([[float(r[c]) for c in cols] for r in rows[1:]]).reshape(-1, model.nq)
    except (ValueError, IndexError):
        raise VjmError(f"{path}: joint values must be numbers in every row") from None
    if len(Q) == 0 or not np.all(np.isfinite(Q)):
        raise VjmError(f"{path}: no rows, or a joint value that is not finite")
    return Q


def measure(model, Q: np.ndarray, hidden: Hidden, frame: str, noise_t: float, rng) -> np.ndarray:
    """Points (n, 3) mm of ``frame`` where the robot really is at reported joint values ``Q``: the robot each
    hidden effect makes (:meth:`~vjm.effects.absolute.PoseEffect.true_model`), at the joint values they turn
    it to (:meth:`~vjm.effects.absolute.PoseEffect.true_joints`), sagging under its own weight."""
    truth = model
    for e, v in hidden.effects:
        truth = e.true_model(truth, v)
    Qt = Q
    for e, v in hidden.effects:
        Qt = e.true_joints(model, Qt, v)
    P = truth.forward(Qt, frame)[:, :3, 3] + truth.self_weight(Qt, frame)[:, :3]
    return P + noise_t * rng.standard_normal(P.shape)


def run(model, model_path, effects, poses: str, noise_t: float, seed: int, out, frame: str | None = None) -> int:
    """Body of ``vjm simulate robot.yaml``: check, design, measure, write the CSV atomically; the rows."""
    from linkfea.files.atomic import write_text
    from linkfea.files.outputs import SIMULATED_CSV_MARK, check_file, is_simulated_csv

    from ..modelio.csvtext import header

    if not (np.isfinite(noise_t) and noise_t >= 0):
        raise ArgumentError("noise-t", f"must be a number >= 0 (mm), got {noise_t!r}")
    check_file(out, is_simulated_csv, "a CSV written by vjm simulate")
    frame = model._tool(frame)
    hidden = parse_hidden(model, effects, frame)
    Q = design(model, poses, np.random.default_rng([seed, 2]))
    P = measure(model, Q, hidden, frame, noise_t, np.random.default_rng([seed, 3]))
    head = list(model.q_names) + [f"{frame}.{c}" for c in "xyz"] + ([f"{frame}.sigma"] if noise_t > 0 else [])
    lines = [f"{SIMULATED_CSV_MARK} from {os.path.basename(str(model_path))}; poses {poses}; noise_t {noise_t} mm; "
             f"seed {seed}; the robot's base frame; hidden effects: {hidden.describe(model)}",
             header(head)]
    for q, p in zip(Q, P):
        lines.append(",".join([repr(float(v)) for v in (*q, *p)] + ([repr(float(noise_t))] if noise_t > 0 else [])))
    write_text(out, "\n".join(lines) + "\n")
    return len(Q)


def simulate_robot(model_path, effects, poses, loads: str, noise_t: float, noise_r, seed: int, out,
                   tilt: float = 0.0) -> int | None:
    """``vjm simulate``'s dispatch: the rows written if ``model_path`` is a robot, None for a parallel machine.

    A robot's rows have no load (its own weight is the load), no measured rotation and no platform
    tilt: those options, given, are refused rather than ignored."""
    from linkfea.files.outputs import check_file, is_simulated_csv

    from ..modelio.read import load_model
    from ..robot.model import RobotModel

    check_file(out, is_simulated_csv, "a CSV written by vjm simulate")  # before any work, robot or not
    model = load_model(model_path)
    if not isinstance(model, RobotModel):
        return None
    for option, given in (("loads", loads != "axes:100"), ("noise-r", noise_r is not None), ("tilt", tilt != 0.0)):
        if given:
            raise ArgumentError(option, f"is for parallel machines; a robot's simulated rows are absolute poses "
                                        f"under its own weight ({model_path})")
    return run(model, model_path, effects, poses or "random:100", noise_t, seed, out)

"""``vjm simulate`` on a serial or tree robot: absolute-pose rows that ``vjm calibrate`` reads.

Each row holds the joint values a controller would report and the point a tracker would measure: a
frame's origin (default the first tool) where the robot really is -- its joints turned by hidden
offsets, its joints' compliances scaled by hidden factors, sagging under its own weight (the
equilibrium of :meth:`vjm.robot.model.RobotModel.self_weight`) -- plus Gaussian noise, in the
robot's base frame (vjm calibrate registers the instrument frame anyway).  So ``vjm calibrate``
can be tried, and its recovery of known effects checked, without a tracker.

Hidden effects (``--effect``, repeatable):

- ``offset:<joint>=<value>,...``: the joint's true value is the reported one plus ``value`` (rad, mm);
- ``compliance:<joint>=<factor>,...``: the joint's compliance is ``factor`` times the model file's.

Poses (``--poses``): ``random:N`` (N configurations uniform within the joint limits, a continuous
joint over one turn) or a CSV whose header names the model's joints (rad, mm).
"""
from __future__ import annotations

import csv
import dataclasses
import os
from dataclasses import dataclass, field

import numpy as np

from ..errors import ArgumentError, VjmError

#: the kinds of hidden effect a robot's simulation takes
KINDS = ("offset", "compliance")
#: rows at most (a calibration set has tens to thousands)
MAX_ROWS = 100_000


@dataclass(frozen=True)
class Hidden:
    """Hidden truth: joint ``offsets`` (nq,) and compliance ``factors`` {joint: factor}."""

    offsets: np.ndarray
    factors: dict = field(default_factory=dict)

    def describe(self, names) -> str:
        parts = [f"offset {n}={v:g}" for n, v in zip(names, self.offsets) if v != 0.0]
        parts += [f"compliance {n}x{f:g}" for n, f in self.factors.items()]
        return ", ".join(parts) or "none"


def parse_hidden(model, specs) -> Hidden:
    """``["offset:elbow_joint=0.002", "compliance:elbow_joint=2"]`` -> :class:`Hidden`."""
    off = np.zeros(model.nq)
    factors: dict = {}
    for spec in specs:
        kind, _, body = str(spec).partition(":")
        if kind not in KINDS or not body:
            raise ArgumentError("effect", f"a robot takes offset:<joint>=<value>,... or compliance:<joint>=<factor>,"
                                          f"...; got {spec!r}")
        for item in body.split(","):
            name, _, val = item.partition("=")
            name = name.strip()
            if name not in model.q_names:
                raise ArgumentError("effect", f"{kind}: no joint {name!r}; joints: {', '.join(model.q_names)}")
            try:
                v = float(val)
            except ValueError:
                v = float("nan")
            if not np.isfinite(v) or (kind == "compliance" and not v > 0):
                raise ArgumentError("effect", f"{kind}:{name} needs a finite number{' > 0' if kind == 'compliance' else ''}"
                                              f", got {val!r}")
            if kind == "offset":
                off[model.q_names.index(name)] = v
            else:
                if name not in model.joint_springs:
                    raise ArgumentError("effect", f"compliance:{name}: the joint is rigid in the model file (no "
                                                  f"stiffness to scale)")
                factors[name] = v
    return Hidden(off, factors)


def hidden_model(model, hidden: Hidden):
    """``model`` with each named joint's compliance times its factor (a constant, table or expression)."""
    springs = dict(model.joint_springs)
    for name, f in hidden.factors.items():
        s = springs[name]
        if s.stiffness is not None:
            springs[name] = dataclasses.replace(s, stiffness=float(s.stiffness) / f)
        elif s.table is not None:
            springs[name] = dataclasses.replace(s, table=(s.table[0], tuple(np.asarray(s.table[1]) / f)))
        else:
            springs[name] = dataclasses.replace(s, expression=f"({s.expression}) / {f!r}")
    return dataclasses.replace(model, joint_springs=springs)


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
    """Points (n, 3) mm of ``frame`` where the robot really is at reported joint values ``Q``."""
    truth = hidden_model(model, hidden)
    Qt = Q + hidden.offsets
    P = truth.forward(Qt, frame)[:, :3, 3] + truth.self_weight(Qt, frame)[:, :3]
    return P + noise_t * rng.standard_normal(P.shape)


def run(model, model_path, effects, poses: str, noise_t: float, seed: int, out, frame: str | None = None) -> int:
    """Body of ``vjm simulate robot.yaml``: check, design, measure, write the CSV atomically; the rows."""
    from linkfea.files.atomic import write_text
    from linkfea.files.outputs import SIMULATED_CSV_MARK, check_file, is_simulated_csv

    if not (np.isfinite(noise_t) and noise_t >= 0):
        raise ArgumentError("noise-t", f"must be a number >= 0 (mm), got {noise_t!r}")
    check_file(out, is_simulated_csv, "a CSV written by vjm simulate")
    hidden = parse_hidden(model, effects)
    frame = model._tool(frame)
    Q = design(model, poses, np.random.default_rng([seed, 2]))
    P = measure(model, Q, hidden, frame, noise_t, np.random.default_rng([seed, 3]))
    head = list(model.q_names) + [f"{frame}.{c}" for c in "xyz"] + ([f"{frame}.sigma"] if noise_t > 0 else [])
    lines = [f"{SIMULATED_CSV_MARK} from {os.path.basename(str(model_path))}; poses {poses}; noise_t {noise_t} mm; "
             f"seed {seed}; the robot's base frame; hidden effects: {hidden.describe(model.q_names)}",
             ",".join(head)]
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

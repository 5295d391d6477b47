"""The machine side of a design: its constraints' values for given link compliances, for both kinds.

A parallel machine is evaluated as ``vjm sweep`` does: its links replaced, one batched stiffness map
over the reachable points of the ``grid``-point workspace grid (the kinematics solved once and
shared by every design), worst case = largest k_tran (mm/N) or k_rot (rad/(N mm)); a constraint
with ``poses`` takes the largest over those points instead.  A robot is evaluated over a joint grid
(``joints: {name: [lo, hi]}`` with ``joint_grid`` values each, the other joints at ``home``) or at
named configurations: k_tran and k_rot of :meth:`~vjm.robot.RobotModel.stiffness` and the
translational self-weight sag at the tool (mm) of :meth:`~vjm.robot.RobotModel.self_weight`.

The moving mass counts the free links as ``vjm sweep`` does on a parallel machine (every chain's
foot and leg, two bars for a parallelogram leg; a described machine's other links once); on a robot
each free link once.  A robot's gravity load is its model file's inertials: a lighter link spring
does not lighten them.
"""
from __future__ import annotations

import itertools
from dataclasses import dataclass

import numpy as np

from ..errors import VjmError
from .spec import QUANTITIES, DesignSpec


@dataclass(frozen=True, eq=False)
class Machine:
    """A loaded model with its evaluation points: ``points`` (workspace grid, or joint grid for a robot)."""

    model: object
    spec: DesignSpec
    points: np.ndarray
    kin: object = None

    @property
    def kind(self) -> str:
        return self.model.kind  # type: ignore[attr-defined]

    def count(self, link: str) -> int:
        """How many pieces of ``link`` move (a parallel machine's chains share one design)."""
        m = self.model
        if self.kind != "parallel":
            return 1
        chains = len(m.chains)  # type: ignore[attr-defined]
        if link == "leg":
            return chains * m.arch.leg_bars  # type: ignore[attr-defined]
        return chains if link == "foot" else 1

    def with_links(self, comps: dict, errors: dict | None = None, t: float = 0.0):
        """The model with ``comps`` ({link: 6x6}) in place, each moved ``t`` along its error bar."""
        from ..model.links import LinkSpring

        springs = {}
        for name, C in comps.items():
            e = None if errors is None else errors.get(name)
            s = LinkSpring(C, {"vjm design": name}, e)
            springs[name] = s.scaled(t) if (t and e is not None) else s
        if self.kind == "parallel":
            return self.model.replace(links=springs)  # type: ignore[attr-defined]
        from ..robot.model import PlacedSpring

        old = self.model.links  # type: ignore[attr-defined]
        placed = {**old, **{k: PlacedSpring(s.checked(f"links.{k}"), old[k].at, old[k].offset)
                            for k, s in springs.items()}}
        return self.model.replace(links=placed)  # type: ignore[attr-defined]

    def values(self, comps: dict, errors: dict | None = None, t: float = 0.0) -> dict:
        """``{constraint label: value}`` plus ``k_tran_max`` and ``k_rot_max`` over the grid (inf if singular)."""
        m = self.with_links(comps, errors, t)
        out = {}
        grid = self._map(m, self.kin if self.kin is not None else self.points)
        out["k_tran_max"], out["k_rot_max"] = grid
        for c in self.spec.constraints:
            if c.poses is None and c.quantity != "sag_max":
                continue
            pts = self.points if c.poses is None else np.array(c.poses, dtype=float)
            if c.quantity == "sag_max":
                sag = np.asarray(m.self_weight(pts))
                out[c.label] = float(np.max(np.linalg.norm(sag[:, :3], axis=1)))
            else:
                out[c.label] = self._map(m, pts)[0 if c.quantity == "k_tran_max" else 1]
        return out

    def reduced(self, comps: dict, n: int = 48) -> "Machine":
        """This machine on fewer points: per quantity of the grid, the ``n`` nearest to their limits with the
        links ``comps``.  A search near those links screens its candidates on them (the worst case sits
        there); its answer is always checked on the whole grid."""
        if len(self.points) <= 2 * n:
            return self
        m = self.with_links(comps)
        kt, kr = self._arrays(m, self.kin if self.kin is not None else self.points)
        idx = np.union1d(np.argsort(kt)[-n:], np.argsort(kr)[-n:])
        if any(c.quantity == "sag_max" and c.poses is None for c in self.spec.constraints):
            sag = np.linalg.norm(np.asarray(m.self_weight(self.points))[:, :3], axis=1)
            idx = np.union1d(idx, np.argsort(sag)[-n:])
        P = self.points[idx]
        return Machine(self.model, self.spec, P, self.model.kinematics(P) if self.kind == "parallel" else None)  # type: ignore[attr-defined]

    def _map(self, m, pts) -> tuple:
        kt, kr = self._arrays(m, pts)
        worst = lambda k: float(np.max(k)) if np.all(np.isfinite(k)) else float("inf")  # noqa: E731
        return worst(kt), worst(kr)

    def _arrays(self, m, pts) -> tuple:
        r = m.stiffness_map(pts) if self.kind == "parallel" else m.stiffness(pts)
        return np.atleast_1d(np.asarray(r.k_tran, dtype=float)), np.atleast_1d(np.asarray(r.k_rot, dtype=float))

    def pointwise(self, comps: dict, cons: tuple) -> np.ndarray:
        """``log(value / limit)`` of every constraint at every point of its grid or poses, concatenated (a
        smooth vector for a gradient-based search, where the worst case over the points is not smooth)."""
        m = self.with_links(comps)
        grid = self._arrays(m, self.kin if self.kin is not None else self.points)
        out = []
        for c in cons:
            if c.quantity == "sag_max":
                pts = self.points if c.poses is None else np.array(c.poses, dtype=float)
                v = np.linalg.norm(np.asarray(m.self_weight(pts))[:, :3], axis=1)
            else:
                arrs = grid if c.poses is None else self._arrays(m, np.array(c.poses, dtype=float))
                v = arrs[0 if c.quantity == "k_tran_max" else 1]
            with np.errstate(divide="ignore", invalid="ignore"):
                out.append(np.where(np.isfinite(v) & (v > 0), np.log(v / c.limit), 50.0))
        return np.concatenate(out)


def load_machine(spec: DesignSpec) -> Machine:
    """The spec's model and points, with every link and constraint checked against the model's kind."""
    from ..modelio.read import load_model

    try:
        model = load_model(spec.machine)
    except VjmError as exc:
        raise VjmError(f"machine {spec.machine}: {exc}") from None
    kind = model.kind
    for link in spec.links:
        if link.name not in model.links:
            raise VjmError(f"links.{link.name}: the machine {spec.machine} has no link {link.name!r}; its links: "
                           f"{', '.join(model.links) or 'none'}")
        _check_length(model, link)
    for c in spec.constraints:
        if kind not in QUANTITIES[c.quantity]:
            raise VjmError(f"constraint {c.quantity}: a {kind} model cannot give it (a robot's only: the self-weight "
                           f"sag at its tool); {kind} models give {', '.join(q for q, k in QUANTITIES.items() if kind in k)}")
    if kind == "parallel":
        from ..sweep.combine import workspace_points

        if spec.joints:
            raise VjmError("joints: is a robot's joint grid; a parallel machine uses grid: (its workspace grid)")
        P = workspace_points(model, spec.grid)  # type: ignore[arg-type]
        for c in spec.constraints:
            if c.poses is not None:
                _check_points(model, c)
        return Machine(model, spec, P, model.kinematics(P))
    Q = joint_grid(model, spec)
    for c in spec.constraints:
        if c.poses is not None:
            q = np.array(c.poses, dtype=float)
            if q.shape[1] != model.nq:
                raise VjmError(f"constraint {c.quantity}: poses of a robot are {model.nq} joint values each "
                               f"({', '.join(model.q_names)})")
            model.replace(strict_limits=True).check_q(q)
    return Machine(model, spec, Q)


def _check_length(model, link) -> None:
    """A beam's length is the machine's: the model file's own beam for that link, when it states one."""
    if link.kind != "beam":
        return
    own = model.links[link.name]
    src = (getattr(own, "spring", own).source or {}).get("beam")
    length = link.source.get("length")
    if isinstance(src, dict) and "length" in src and length != src["length"]:
        raise VjmError(f"links.{link.name}.beam.length is {length!r} mm, the machine's {link.name} is {src['length']!r} "
                       "mm long (its geometry does not follow the beam): give its length")


def _check_points(model, c) -> None:
    P = np.array(c.poses, dtype=float)
    if P.shape[1] not in (3, 6):
        raise VjmError(f"constraint {c.quantity}: poses of a parallel machine are points x, y, z (mm) or x, y, z, "
                       "rx, ry, rz (mm, rad)")
    ok = model.reachable(P[:, :3]) if P.shape[1] == 3 else np.ones(len(P), bool)
    if not np.all(ok):
        raise VjmError(f"constraint {c.quantity}: the pose {P[int(np.flatnonzero(~ok)[0])].tolist()} is not "
                       f"reachable by {model.architecture}")
    try:
        model.kinematics(P)   # a 6-value pose's reach, and every pose's inverse kinematics
    except VjmError as exc:
        raise VjmError(f"constraint {c.quantity}: {exc}") from None


def joint_grid(model, spec: DesignSpec) -> np.ndarray:
    """(n, nq) configurations: ``joint_grid`` values of each named joint, the others at ``home`` (or 0)."""
    if not spec.joints and not any(c.poses is not None for c in spec.constraints):
        raise VjmError("a robot's constraints are taken over a joint grid: name its joints with their ranges, "
                       "e.g. joints: {shoulder_lift_joint: [-2.0, -0.5]} (rad)")
    names = list(model.q_names)
    for j in spec.joints:
        if j not in names:
            raise VjmError(f"joints.{j}: the robot has no joint {j!r}; its joints: {', '.join(names)}")
    home = np.array(model.home if model.home is not None else np.zeros(model.nq), dtype=float)
    axes = [np.linspace(lo, hi, spec.joint_grid) for lo, hi in spec.joints.values()]
    rows = []
    for combo in itertools.product(*axes):
        q = home.copy()
        for j, v in zip(spec.joints, combo):
            q[names.index(j)] = v
        rows.append(q)
    Q = np.array(rows) if rows else home[None, :]
    model.replace(strict_limits=True).check_q(Q)   # beyond a joint's limits is an error here (radians, not degrees)
    return Q

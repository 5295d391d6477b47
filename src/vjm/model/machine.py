"""The parallel kind of :class:`vjm.Model` and its per-pose computations (pinocchio-style Model / Data).

A :class:`ParallelModel` holds parameters only (architecture, geometry, springs,
effects); every call such as :meth:`ParallelModel.stiffness_map` returns a fresh
:class:`~vjm.stiffness.linear.StiffnessResult`.  :meth:`ParallelModel.replace` gives a modified
model, validated again.
"""
from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field
from functools import cached_property

import numpy as np

from linkfea.mechanics.compliance import check as check_compliance
from linkfea.runtime.errors import LinkFeaError

from ..architectures import ARCHITECTURES
from ..errors import VjmError
from ..kinematics.chain import _frame_product
from ..kinematics.poses import Kinematics, as_poses
from ..kinematics.transforms import rotation_vector
from ..maps.grid import CHUNK, Grid, Workspace
from ..memo import Recent
from ..modelio.description import Description
from ..stiffness.linear import (
    StiffnessResult,
    assemble,
    assemble_soa,
    chain_stiffness,
    chain_stiffness_frames,
    machine_block_compiled,
    use_kernel,
)
from ..sweep.spread import Spread
from .base import Model
from .links import LinkSpring, as_link

#: poses per block in :meth:`ParallelModel.stiffness_map` (working set of a block stays in cache)
MAP_BLOCK = 2048
#: batches of kinematics a model keeps (see :meth:`ParallelModel.kinematics`)
KIN_CACHE = 8


def validate_compliance(C, key: str) -> np.ndarray:
    """A 6x6 symmetric positive-definite compliance, or VjmError naming ``key``.

    The check and its tolerances are linkfea's, the one contract between the two packages
    (:func:`linkfea.mechanics.compliance.check`).
    """
    try:
        return check_compliance(C, f"{key}: compliance")
    except LinkFeaError as exc:
        raise VjmError(str(exc)) from None


@dataclass(frozen=True)
class Actuator:
    """Actuator spring: ``c(q) = 1/stiffness + compliance_slope * (q - q_ref)``.

    ``stiffness`` in N/mm (prismatic) or N mm/rad (rotary); ``compliance_slope``
    in (mm/N)/mm, e.g. a ball screw whose compliance grows with the nut's
    distance from the fixed bearing; ``q_ref`` in mm (rad).
    """

    stiffness: float
    compliance_slope: float = 0.0
    q_ref: float = 0.0

    def __post_init__(self):
        for k in ("stiffness", "compliance_slope", "q_ref"):
            v = getattr(self, k)
            if isinstance(v, bool) or not isinstance(v, (int, float, np.floating, np.integer)) or not np.isfinite(v):
                raise VjmError(f"actuator.{k} must be a finite number, got {v!r}")
        if not self.stiffness > 0:
            raise VjmError(f"actuator.stiffness must be > 0, got {self.stiffness}")


@dataclass(frozen=True)
class Joints:
    """Passive-joint elasticity: ``passive_stiffness`` N mm/rad about each joint's
    constrained rotation directions, or None for ideal joints."""

    passive_stiffness: float | None = None

    def __post_init__(self):
        k = self.passive_stiffness
        if k is not None and not (isinstance(k, (int, float, np.floating)) and np.isfinite(k) and k > 0):
            raise VjmError(f"joints.passive_stiffness must be a number > 0 (N mm/rad), got {k!r}")


@dataclass(frozen=True, eq=False, kw_only=True)
class ParallelModel(Model):
    """Immutable VJM model of a parallel machine: the ``"parallel"`` kind of :class:`vjm.Model`.

    Attributes
    ----------
    architecture : one of ``vjm.architectures.ARCHITECTURES``
    geometry : dict of lengths in mm (``L``, ``r``, ``d`` ...; see the architecture); an optional
        ``workspace: [lo, hi]`` (mm) replaces the architecture's workspace box
    actuator : Actuator
    links : the named links, name -> :class:`~vjm.model.links.LinkSpring`: ``foot`` and ``leg`` of the
        built-in architectures (spring frames: see the architecture's module), any names of a
        described machine.  ``model.foot`` and ``model.leg`` read ``links["foot"]``, ``links["leg"]``.
    joints : Joints
    effects : dict, kept verbatim for the discrepancy workflow
    name : free text
    path : the file this model was read from (resolves relative paths), or None
    description : the machine description (:class:`vjm.modelio.description.Description`) of
        architecture ``"description"``, else None

    Keyword arguments only; a link may be given as anything :func:`vjm.model.links.as_link` takes (a
    LinkResult, a Compliance, a result path ...).
    """

    kind = "parallel"
    architecture: str
    geometry: dict
    actuator: Actuator
    links: dict = field(default_factory=dict)
    joints: Joints = field(default_factory=Joints)
    effects: dict = field(default_factory=dict)
    name: str = ""
    path: str | None = None
    description: Description | None = None
    #: kinematics of recent small pose batches (see :meth:`kinematics`), shared with the copies of the
    #: same kinematic key (the kinematics do not depend on the springs); not a parameter
    _kin_cache: Recent = field(default_factory=lambda: Recent(KIN_CACHE), init=False, repr=False, compare=False)
    #: the load sharing of the last kinematics asked for (see :meth:`joint_forces`); this model's own
    _sharing: dict = field(default_factory=dict, init=False, repr=False, compare=False)

    def __post_init__(self):
        if not isinstance(self.links, dict):
            raise VjmError("links must be a mapping name -> vjm.LinkSpring")
        if self.architecture not in ARCHITECTURES:
            raise VjmError(f"architecture: unknown {self.architecture!r}; known: {', '.join(ARCHITECTURES)}")
        arch = ARCHITECTURES[self.architecture]
        if not isinstance(self.geometry, dict):
            raise VjmError("geometry must be a mapping of lengths in mm")
        for k in arch.geometry_keys:
            v = self.geometry.get(k)
            if isinstance(v, bool) or not isinstance(v, (int, float, np.floating, np.integer)) or not (np.isfinite(v) and v > 0):
                raise VjmError(f"geometry.{k} must be a length > 0 in mm for {self.architecture}, got {v!r}")
        links = {}
        for key, link in self.links.items():
            if not isinstance(link, LinkSpring):
                link = as_link(link, str(key))
            links[str(key)] = link.checked(str(key) if key in ("foot", "leg") else f"links.{key}")
        if self.description is None:
            missing = [k for k in ("foot", "leg") if k not in links]
            extra = [k for k in links if k not in ("foot", "leg")]
            if missing:
                raise VjmError(f"{missing[0]}: missing ({self.architecture} has the links foot and leg)")
            if extra:
                raise VjmError(f"links.{extra[0]}: {self.architecture} has the links foot and leg only")
        object.__setattr__(self, "links", links)
        if not isinstance(self.effects, dict):
            raise VjmError("effects must be a mapping name -> parameters")
        self.arch.validate(self)

    @property
    def foot(self) -> LinkSpring:
        """``links["foot"]`` (rigid if a described machine has none)."""
        return self.links.get("foot") or LinkSpring.rigid()

    @property
    def leg(self) -> LinkSpring:
        """``links["leg"]`` (rigid if a described machine has none)."""
        return self.links.get("leg") or LinkSpring.rigid()

    def link(self, name: str) -> LinkSpring:
        """The link called ``name`` (``foot``, ``leg`` or a described machine's own)."""
        if name in ("foot", "leg"):
            return getattr(self, name)
        if name not in self.links:
            raise VjmError(f"no link {name!r}; links: {', '.join(dict.fromkeys(['foot', 'leg', *self.links]))}")
        return self.links[name]

    # -- derived, computed once per model ---------------------------------
    @cached_property
    def arch(self):
        return ARCHITECTURES[self.architecture].bind(self)

    @cached_property
    def chains(self):
        """The chains (eq. 1) of this model, built once."""
        return self.arch.chains(self)

    @cached_property
    def kinematic_key(self) -> tuple:
        """What the kinematics depend on: architecture, geometry and chain structure (never a compliance)."""
        geo = tuple(sorted((k, repr(v)) for k, v in self.geometry.items()))
        return (self.architecture, geo, self.joints.passive_stiffness is None, self.arch.kinematic_key(self))

    @property
    def dof(self) -> int:
        """Degrees of freedom of the platform: 3 (translations) or 6."""
        return self.arch.platform_dof(self)

    # -- the workspace ----------------------------------------------------
    @cached_property
    def workspace(self) -> Workspace:
        """The box maps, sweeps and simulated experiments cover: ``geometry.workspace`` if given,
        else the architecture's (:class:`vjm.maps.grid.Workspace`, corners ``lo``, ``hi`` in mm)."""
        return Workspace.of(self)

    def grid(self, n: int, slice: str | None = None) -> Grid:
        """An n-point-per-axis grid over :attr:`workspace`; ``slice="z=0"`` fixes one axis."""
        return self.workspace.grid(n, slice)

    def reachable(self, P) -> np.ndarray:
        """Boolean mask (n,) of the poses P (points (n, 3), or (n, 6) for a 6-dof platform) the
        inverse kinematics accepts; the one test every grid and design uses."""
        P = np.asarray(P, dtype=float)
        if P.ndim == 1:
            P = P[None]
        out = np.empty(len(P), dtype=bool)
        for a in range(0, len(P), CHUNK):
            out[a:a + CHUNK] = self.arch.reachable(self, P[a:a + CHUNK])
        return out

    def map(self, grid: int = 41, slice: str | None = None, orientation=None, progress=None, spread: bool = False):
        """The stiffness map over an n-point-per-axis workspace grid (:class:`vjm.maps.compute.StiffnessMap`).

        ``slice="z=0"`` fixes one axis; ``orientation`` (rx, ry, rz, rad) is the fixed platform
        rotation of a 6-dof platform's map (a 3-dof platform takes none: a non-zero one is an
        ArgumentError).  The memory the map needs is checked first
        (VjmError if it cannot fit); a run longer than about a minute reports through
        ``progress`` (a callable taking one line of text).  ``spread=True`` adds the spread of
        k_tran and k_rot from the links' FEA error bars (:mod:`vjm.sweep.spread`).
        """
        from ..maps.compute import grid_map

        return grid_map(self, grid, slice, orientation=orientation, progress=progress, spread=spread)

    def save(self, path) -> None:
        """Write this model as a YAML model file (:func:`vjm.save_model`; atomic), read back by
        :func:`vjm.load_model` to an equal model.

        >>> import tempfile, pathlib, vjm
        >>> m = vjm.load_model("puu")
        >>> p = pathlib.Path(tempfile.mkdtemp()) / "m.yaml"
        >>> m.save(p)
        >>> vjm.load_model(p).geometry == m.geometry
        True
        """
        from ..modelio.write import save_model

        save_model(self, path)

    def __repr__(self) -> str:
        """A few lines: name, architecture, links, actuator, joints, effects (:meth:`_repr_html_`: all of it)."""
        from ..maps.views import model_text

        return model_text(self)

    def _repr_html_(self) -> str:
        """Architecture, geometry, links with their frames, actuator, joints and effects.

        >>> import vjm
        >>> "orthoglide-3PUU" in vjm.load_model("puu")._repr_html_()
        True
        """
        from ..maps.views import model_html

        return model_html(self)

    def replace(self, **changes) -> "ParallelModel":
        """A copy with some fields or links changed (validated), like ``dataclasses.replace``.

        A keyword naming a link (``foot=``, ``leg=``, or a described machine's link) replaces that
        link, and ``links=`` replaces the links it names; a link may be a LinkSpring, a
        :class:`linkfea.LinkResult`, a :class:`linkfea.Compliance`, a 6x6 matrix, the path of a
        result JSON or a bundled link name (see :func:`vjm.model.links.as_link`).

        The copy shares this model's cache of recent kinematics and its chains when its
        kinematic key is unchanged (a change of springs, say), so repeated
        stiffness evaluations at the same poses redo only the spring part.
        """
        links = dict(self.links)
        extra = changes.pop("links", None)
        if extra is not None:
            if not isinstance(extra, dict):
                raise VjmError("links must be a mapping name -> link")
            links.update(extra)
        for key in [k for k in changes if k in ("foot", "leg") or k in self.links]:
            links[key] = changes.pop(key)
        links = {k: v if isinstance(v, LinkSpring) else as_link(v, k) for k, v in links.items()}
        new = dataclasses.replace(self, links=links, **changes)
        if new.kinematic_key == self.kinematic_key:
            object.__setattr__(new, "_kin_cache", self._kin_cache)
            if "chains" in self.__dict__ and "chains" not in new.__dict__:
                # the chains are a function of the kinematic key (never of a compliance): a fit that
                # changes springs only does not rebuild them at every step
                new.__dict__["chains"] = self.chains
        return new

    # -- per-pose computations --------------------------------------------
    def _solve_kinematics(self, frames: np.ndarray) -> Kinematics:
        q, vals = self.arch.solve(self, frames)
        return Kinematics(self.kinematic_key, self.chains, frames, np.asarray(q, dtype=float),
                          tuple(np.asarray(v, dtype=float) for v in vals))

    def kinematics(self, P) -> Kinematics:
        """Inverse kinematics of poses P (see :func:`vjm.kinematics.poses.as_poses`), solved once.

        Raises VjmError for an unreachable pose.  The last few small batches
        (up to ``MAP_BLOCK`` poses) are kept, so that asking again for the same
        poses costs nothing.
        """
        if isinstance(P, Kinematics):
            return self._check_kinematics(P)
        frames = as_poses(P, self.dof)
        if frames.shape[0] > MAP_BLOCK:
            return self._solve_kinematics(frames)
        return self._kin_cache.get(frames.tobytes(), lambda: self._solve_kinematics(frames))

    def _check_kinematics(self, kin: Kinematics) -> Kinematics:
        if kin.key != self.kinematic_key:
            raise VjmError("these kinematics belong to a model with another architecture, geometry or chain "
                           "structure; compute them with this model's kinematics(P)")
        return kin

    def inverse_kinematics(self, P) -> np.ndarray:
        """Actuator coordinates (n, n_chains) (mm, or rad for rotary) of poses P.

        Raises VjmError for an unreachable pose.
        """
        return self.kinematics(P).q

    def compliances(self, kin: Kinematics) -> list[dict]:
        """Per chain, ``{spring name: compliance (k, k) or (n, k, k)}`` at these kinematics (rigid springs omitted)."""
        return self.arch.compliances(self, kin.points, list(kin.values), kin.q)

    def _closed(self, kin: Kinematics, k: int, p_end: np.ndarray, tol: float) -> None:
        self._gap(kin, k, np.max(np.abs(p_end - kin.points), initial=0.0), tol)

    @staticmethod
    def _gap(kin: Kinematics, k: int, err: float, tol: float) -> None:
        if err > tol:
            raise VjmError(f"internal: chain {kin.chains[k].name} does not close on the pose (error {err:.3g} mm)")

    def chain_stiffness(self, P) -> tuple[np.ndarray, np.ndarray]:
        """Each chain's stiffness K_i (n, n_chains, 6, 6) and J_q rank (n, n_chains)."""
        kin = self.kinematics(P)
        Ks, ranks = self._chain_stiffness(kin)
        return np.stack(Ks, axis=1), np.stack(ranks, axis=1)

    def _chain_stiffness(self, kin: Kinematics):
        tol = 1e-6 * (1.0 + np.max(np.abs(kin.points), initial=0.0))
        out = []
        for k, (ch, J, c) in enumerate(zip(kin.chains, kin.jacobians, self.compliances(kin))):
            self._closed(kin, k, frame_points(ch, kin.values[k]), tol)
            out.append(chain_stiffness(ch, J, c))
        return tuple(zip(*out))

    def stiffness_map(self, P, spread: bool = False, spread_method: str = "linear",
                      kernel: str | None = None) -> StiffnessResult:
        """Stiffness at every pose of P (points (n, 3), poses (n, 6) or (n, 4, 4), or a
        :class:`~vjm.kinematics.poses.Kinematics`): batched, no loop over poses.

        ``spread=True`` adds the links' FEA error bars carried to k_tran and k_rot
        (``k_tran_spread``, ``k_rot_spread``; :mod:`vjm.sweep.spread`, ``spread_method`` "linear" or
        "ends"); links without an error estimate contribute none.

        The poses are processed in blocks of ``MAP_BLOCK``; a bad pose raises the same
        VjmError as the whole batch would.  ``kernel`` picks the path of a block: ``"numpy"``
        (batched over poses, the pose axis last: the reference), ``"numba"`` (the compiled
        kernels of :mod:`vjm.maps.map_kernel`, same arithmetic pose by pose, same rank decisions) or
        ``"auto"`` (the kernels for blocks of ``vjm.stiffness.linear.KERNEL_FROM`` poses or more);
        None reads the environment variable ``VJM_MAP_KERNEL`` (default ``auto``).  With
        ``spread`` the numpy path runs.
        """
        if isinstance(P, Kinematics):
            kin = self._check_kinematics(P)
            frames = kin.frames
        else:
            frames = as_poses(P, self.dof)
            kin = self.kinematics(frames) if frames.shape[0] <= MAP_BLOCK else None
        n = frames.shape[0]
        pts = frames[:, :3, 3]
        out = (np.empty((n, 6, 6)), np.empty((n, 6, 6)), np.empty(n), np.empty(n),
               np.empty(n, dtype=int), np.empty(n, dtype=bool), np.empty((n, len(self.chains)), dtype=int))
        tol = 1e-6 * (1.0 + (np.max(np.abs(pts)) if n else 0.0))
        step = MAP_BLOCK if kin is not None else self.arch.ik_block
        sp = Spread(self, n, spread_method) if spread else None
        for a0 in range(0, n, step):
            b0 = min(n, a0 + step)
            if kin is not None:
                kb = kin if (a0, b0) == (0, n) else kin.take(slice(a0, b0))
            else:
                try:
                    kb = self._solve_kinematics(frames[a0:b0])
                    self.compliances(kb)
                except VjmError:
                    # report the error the whole batch gives (first offending pose, first check)
                    self.compliances(self._solve_kinematics(frames))
                    raise
            for a in range(a0, b0, MAP_BLOCK):
                b = min(b0, a + MAP_BLOCK)
                self._map_block(kb if (a, b) == (a0, b0) else kb.take(slice(a - a0, b - a0)), a, out, tol, sp,
                                kernel)
        K, C, kt, kr, rank, inv, chain_rank = out
        rot = rotation_vector(frames[:, :3, :3]) if self.dof == 6 else None
        if sp is None:
            return StiffnessResult(pts, K, C, kt, kr, rank, inv, chain_rank, rot)
        return StiffnessResult(pts, K, C, kt, kr, rank, inv, chain_rank, rot, sp.k_tran, sp.k_rot, sp.by_link)

    def _block_stiffness(self, kin: Kinematics, tol: float):
        """The machine stiffness (6, 6, n) (pose axis last) at ``kin`` and each chain's J_q rank;
        the geometric part is kept with ``kin`` and shared by every model evaluated there."""
        Ksum, ranks = None, []
        for k, (ch, v, c) in enumerate(zip(kin.chains, kin.values, self.compliances(kin))):
            Kc, rank, pe = chain_stiffness_frames(ch, np.ascontiguousarray(v.T), c, kin.stiffness_memo[k])
            self._closed(kin, k, pe.T, tol)
            ranks.append(rank)
            Ksum = Kc if Ksum is None else Ksum + Kc
        return Ksum, ranks

    def _map_block(self, kin: Kinematics, a: int, out, tol: float, spread: Spread | None = None,
                   kernel: str | None = None) -> None:
        """Poses ``a : a + kin.n`` of :meth:`stiffness_map`, written into ``out`` (and into ``spread``)."""
        b = a + kin.n
        K, C, kt, kr, rank, inv, chain_rank = out
        if spread is None and use_kernel(kin.n, kernel):
            machine_block_compiled(kin.chains, kin.values, self.compliances(kin), kin.points,
                                   tuple(o[a:b] for o in out), lambda k, gap: self._gap(kin, k, gap, tol))
            return
        Ksum, ranks = self._block_stiffness(kin, tol)
        for k, r in enumerate(ranks):
            chain_rank[a:b, k] = r
        Cb, rank[a:b], inv[a:b], kt[a:b], kr[a:b] = assemble_soa(Ksum)
        K[a:b] = Ksum.transpose(2, 0, 1)
        C[a:b] = Cb.transpose(2, 0, 1)
        if spread is not None:
            spread.block(kin, a, kt[a:b], kr[a:b], tol)

    def stiffness(self, p, spread: bool = False) -> StiffnessResult:
        """Stiffness at one pose p: a point (3,), (x, y, z, rx, ry, rz) or a 4x4 frame.

        K (6, 6), C, k_tran, k_rot, rank ... (no leading pose axis); ``spread=True`` adds the
        links' FEA error bars carried to k_tran and k_rot (see :meth:`stiffness_map`)."""
        p = np.asarray(p, dtype=float)
        if p.shape not in ((3,), (6,), (4, 4)):
            raise VjmError(f"a pose is a point (x, y, z) in mm, (x, y, z, rx, ry, rz) or a 4x4 frame; "
                           f"got shape {p.shape}")
        return self.stiffness_map(p[None], spread=spread).pose(0)

    def deflection(self, P, wrench) -> np.ndarray:
        """Linear deflection twist ``C w`` (n, 6) (or (6,)) under wrench(es) (Fx..Mz, N and N mm)."""
        single = _single(P)
        res = self.stiffness_map(P)
        W = np.broadcast_to(np.asarray(wrench, dtype=float), (res.K.shape[0], 6))
        t = np.einsum("nij,nj->ni", res.C, W)
        return t[0] if single else t

    def joint_forces(self, P, wrench) -> dict:
        """Load sharing under an external wrench on the platform (eq. 9, 12).

        Returns a dict with

        * ``"chain_wrench"``: (n, n_chains, 6) wrench carried by each chain,
          ``f_i = K_i C w`` (world axes, at the end-effector point);
        * ``"actuator"``: (n, n_chains) generalised force of each actuator
          spring, ``tau_0 = J_theta0^T f_i`` (N, or N mm for rotary).  Positive
          when the load pushes the actuator towards increasing ``q0``.
        * ``"twist"``: (n, 6) the deflection ``C w``.

        For a single pose the leading axis is dropped.
        """
        single = _single(P)
        kin = self.kinematics(P)
        Ks, res = self._load_sharing(kin)
        W = np.broadcast_to(np.asarray(wrench, dtype=float), (kin.n, 6))
        t = np.einsum("nij,nj->ni", res.C, W)
        f = np.stack([np.einsum("nij,nj->ni", K, t) for K in Ks], axis=1)
        tau = np.stack([np.einsum("ni,ni->n", J[:, :, ch.actuated[0]], f[:, k])
                        for k, (ch, J) in enumerate(zip(kin.chains, kin.jacobians))], axis=1)
        out = {"chain_wrench": f, "actuator": tau, "twist": t}
        return {k: v[0] for k, v in out.items()} if single else out


    def _load_sharing(self, kin: Kinematics):
        """Each chain's K_i and the assembled machine at ``kin``, kept for the last kinematics
        asked for: the wrench-by-wrench calls at the same poses (unit loads) solve them once."""
        hit = self._sharing.get("last")
        if hit is not None and hit[0] is kin:
            return hit[1], hit[2]
        Ks, ranks = self._chain_stiffness(kin)
        res = assemble(kin.points, list(Ks), list(ranks))
        self._sharing["last"] = (kin, Ks, res)
        return Ks, res


def _single(P) -> bool:
    """A single pose (3,), (6,) or (4, 4) rather than a batch."""
    return not isinstance(P, Kinematics) and np.shape(P) in ((3,), (6,), (4, 4))


def frame_points(chain, values) -> np.ndarray:
    """End points (n, 3) of a chain at variable values (n, n_vars)."""
    cols, _ = _frame_product(chain, np.ascontiguousarray(np.asarray(values, dtype=float).T))
    return cols[3].T

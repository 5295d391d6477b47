"""Any parallel machine from a description file (:mod:`vjm.modelio.description`): general chains,
numeric inverse kinematics (:mod:`vjm.kinematics.ik`), 3- or 6-dof platforms.

The model's ``description`` holds the chains as written; the chains are built
against the model's geometry, so ``model.replace(geometry=...)`` moves them.
Spring names: ``actuator`` for each chain's actuated coordinate, the link name
for a 6-dof spring, the coordinate name for a 1-dof joint spring.
"""
from __future__ import annotations

import numpy as np

from ..errors import VjmError
from ..kinematics.chain import ChainBuilder, jacobian
from ..kinematics.ik import chain_size, conjugate, solve_chain
from ..kinematics.poses import as_poses
from ..memo import Recent
from ..modelio.description import constant_matrix, seed_frame
from .base import ACTUATOR, Architecture, actuator_compliance, joint_spring_compliance
from .parallelogram import parallelogram_compliance, parallelogram_stiffness

NAME = "description"
#: kinematic keys of the models that passed ``validate`` (oldest first)
_VALID = Recent(64)


def _fmt(frame: np.ndarray, dof: int) -> str:
    from ..kinematics.transforms import rotation_vector
    p = frame[:3, 3].tolist()
    if dof == 6:
        p += rotation_vector(frame[:3, :3]).tolist()
    return "(" + ", ".join(f"{v:.6g}" for v in p) + ")"


class Described(Architecture):
    name = NAME
    geometry_keys = ()
    #: the numeric IK's per-call overhead is amortised over larger batches than the stiffness's
    ik_block = 4096
    springs: tuple[str, ...] = (ACTUATOR,)  # plus the description's link and joint-spring names

    def platform_dof(self, model):
        return model.description.dof

    def kinematic_key(self, model):
        return repr(model.description)

    def bind(self, model):
        if model.description is None or model.description.workspace is None:
            return self
        arch = Described()
        arch.workspace = model.description.workspace
        return arch

    def validate(self, model):
        desc = model.description
        if desc is None:
            raise VjmError("a 'description' model needs a machine description (platform and chains)")
        # what is checked depends on the kinematics only: a copy changed in its springs (as a
        # calibration makes hundreds of) is not checked again
        _VALID.get(model.kinematic_key, lambda: self._validate(model) or True)

    def _validate(self, model):
        desc = model.description
        chains = model.chains
        # every chain must close at the seed posture, from its seed values
        X0 = seed_frame(desc)
        wrenches = []
        scale = max(chain_size(ch) for ch in chains)  # rotations times a length: one unit for all chains
        for k, (spec, ch) in enumerate(zip(desc.chains, chains)):
            F = self._seed_frame(model, k)
            _, ok, err = solve_chain(ch, self._unknowns(ch), self._seed_values(spec, ch), F, F[None])
            if not ok[0]:
                raise VjmError(f"chain {ch.name} does not close at the seed posture {_fmt(F, desc.dof)} "
                               f"(closure error {err[0]:.3g} mm after Newton from its seed values); check its "
                               f"transforms, its seed and platform.seed")
            # the wrenches this chain transmits with its actuator free: reciprocal to its joint twists
            v0, ok0 = self._seed_values_at(model, k, X0, spec, ch)
            if not ok0:
                wrenches = None  # a copy cannot reach the unrotated seed pose: mobility not checked
            if wrenches is not None:
                Jc = jacobian(ch, v0)[1][0][:, list(self._unknowns(ch))]
                Jc[3:] *= scale
                U, sv, _ = np.linalg.svd(Jc)
                r = int(np.sum(sv > 1e-9 * max(sv[0], 1e-300)))
                wrenches.append(U[:, r:])
        if wrenches is None:
            return
        W = np.hstack(wrenches)
        sw = np.linalg.svd(W, compute_uv=False) if W.size else np.zeros(0)
        mobility = 6 - int(np.sum(sw > 1e-9 * max(sw[0] if sw.size else 0.0, 1e-300)))
        if mobility != desc.dof:
            raise VjmError(f"platform.dof is {desc.dof}, but with the actuators free the chains let the platform "
                           f"move in {mobility} independent directions at the seed posture "
                           f"{_fmt(X0, 6)}; " + (f"set platform.dof to {mobility} or check the chains"
                                                 if mobility in (3, 6) else
                                                 "check the chains (a platform has 3 or 6 dof)"))

    # -- chains -----------------------------------------------------------
    def chains(self, model):
        return tuple(self._build(model, spec, spec.power) for spec in model.description.chains)

    def _build(self, model, spec, power):
        """One chain: ``S^power``, the elements, the attachment's inverse, ``S^-power``."""
        g = model.geometry
        js = model.joints.passive_stiffness is not None
        b = ChainBuilder(spec.name)
        Sk = np.linalg.matrix_power(constant_matrix(spec.symmetry, g), power) if power else None
        if power:
            b.const(Sk)
        links = set()
        for e in spec.elements:
            if e.role == "const":
                b.const(constant_matrix((e,), g))
            elif e.role == "actuated":
                b.actuated(e.kind, e.var, spring=ACTUATOR)
            elif e.role == "passive":
                b.passive(e.kind, e.var, e.coef)
            elif e.role == "joint":
                if js:
                    b.spring1(e.kind, e.var)
            else:
                if e.link in links:
                    raise VjmError(f"chain {spec.name}: link {e.link!r} is used twice; give the second "
                                   f"a name of its own under links:")
                links.add(e.link)
                b.spring6(e.link)
        if spec.attach:
            b.const(np.linalg.inv(constant_matrix(dict(model.description.attachments)[spec.attach], g)))
        if power:
            b.const(np.linalg.inv(Sk))
        return b.build()

    def _symmetry(self, model, k):
        spec = model.description.chains[k]
        if not spec.power:
            return None
        return np.linalg.matrix_power(constant_matrix(spec.symmetry, model.geometry), spec.power)

    @staticmethod
    def _unknowns(ch):
        return tuple(sorted(ch.passive + ch.actuated))

    @staticmethod
    def _seed_values(spec, ch):
        v = np.zeros(ch.n_vars)
        for name, val in spec.seed:
            if name in ch.var_names:
                v[ch.index(name)] = val
        return v

    def _seed_frame(self, model, k):
        """Copy ``k`` of a chain reaches the platform frame ``S^k X0 S^-k`` with the seed values
        that close the original on ``X0``."""
        X0 = seed_frame(model.description)
        Sk = self._symmetry(model, k)
        return X0 if Sk is None else Sk @ X0 @ np.linalg.inv(Sk)

    def _seed_values_at(self, model, k, X0, spec, ch):
        """Chain ``k``'s values at the (unrotated) seed frame ``X0``."""
        v, ok, _ = solve_chain(ch, self._unknowns(ch), self._seed_values(spec, ch), self._seed_frame(model, k),
                               X0[None])
        return v, bool(ok[0])

    # -- inverse kinematics -----------------------------------------------
    def solve_all(self, model, frames):
        """Actuator coordinates (n, n_chains), chain values and a reachable mask (n,), first failure.

        Copies of a chain by symmetry are solved together as the original chain: copy ``k``
        reaches frame ``X`` exactly when the original reaches ``S^-k X S^k``.
        """
        n = frames.shape[0]
        desc, chains = model.description, model.chains
        q = np.empty((n, len(chains)))
        vals, ok, first = [None] * len(chains), np.ones(n, dtype=bool), None
        groups: dict = {}
        for k, spec in enumerate(desc.chains):
            groups.setdefault((spec.name if not spec.symmetry else spec.elements, spec.symmetry, spec.seed,
                               spec.attach, spec.limits), []).append(k)
        for ks in groups.values():
            spec0 = desc.chains[ks[0]]
            base = self._build(model, spec0, power=0)
            Fs = np.empty((len(ks) * n, 4, 4))
            for j, k in enumerate(ks):
                Sk = self._symmetry(model, k)
                if Sk is None:
                    Fs[j * n:(j + 1) * n] = frames
                else:
                    conjugate(Sk, frames, Fs[j * n:(j + 1) * n])
            v, okk, err = solve_chain(base, self._unknowns(base), self._seed_values(spec0, base),
                                      seed_frame(desc), Fs)
            for j, k in enumerate(ks):
                ch = chains[k]
                sl = slice(j * n, (j + 1) * n)
                bad = np.flatnonzero(~okk[sl])
                if bad.size and (first is None or bad[0] < first[0]):
                    first = (bad[0], ch.name, (f"Newton on its loop closure, continued from the seed posture, "
                                               f"leaves {err[sl][bad[0]]:.3g} mm"))
                for name, lo, hi in spec0.limits:
                    x = v[sl, ch.index(name)]
                    out = np.flatnonzero(okk[sl] & ((x < lo) | (x > hi)))
                    okk[sl][out] = False
                    if out.size and (first is None or out[0] < first[0]):
                        first = (out[0], ch.name, (f"it needs {name} = {x[out[0]]:.6g}, outside its limits "
                                                   f"[{lo:.6g}, {hi:.6g}]"))
                ok &= okk[sl]
                q[:, k] = v[sl, ch.actuated[0]]
                vals[k] = v[sl]
        return q, vals, ok, first

    def solve(self, model, frames):
        q, vals, _, first = self.solve_all(model, frames)
        if first is not None:
            i, name, why = first
            raise VjmError(f"pose {_fmt(frames[i], model.description.dof)} is unreachable by chain {name} ({why})")
        return q, vals

    def inverse_kinematics(self, model, P):
        return self.solve(model, as_poses(P, model.description.dof))

    def reachable(self, model, P):
        return self.solve_all(model, as_poses(P, model.description.dof))[2]

    # -- springs ----------------------------------------------------------
    def compliances(self, model, P, chain_values, q_act):
        g = model.geometry
        cj = joint_spring_compliance(model)
        out = []
        for k, (spec, ch) in enumerate(zip(model.description.chains, model.chains)):
            d = {ACTUATOR: actuator_compliance(model, q_act[:, k])}
            for e in spec.elements:
                if e.role == "joint" and cj is not None:
                    d[e.var] = cj
                if e.role != "spring":
                    continue
                C = model.link(e.link).compliance
                if e.parallelogram:
                    if C is None:
                        raise VjmError(f"{e.link}: a parallelogram needs compliant bars (rigid: true would leave "
                                       f"its stiffness undefined); give the bar's compliance")
                    var, Le, de = e.parallelogram
                    from ..modelio.description import evaluate
                    qv = chain_values[k][:, ch.index(var)]
                    Kp, _ = parallelogram_stiffness(C, evaluate(Le, g, e.text), evaluate(de, g, e.text), qv)
                    d[e.link] = parallelogram_compliance(Kp, qv)
                elif C is not None:
                    d[e.link] = C
            out.append(d)
        return out

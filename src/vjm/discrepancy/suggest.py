"""What to measure next: an optimal design of N (posture, load) rows.

The candidate rows are reachable, non-singular postures drawn uniformly in
the model's workspace box (a 6-dof platform's data with orientations: each
with an orientation drawn uniformly within the largest tilt of the data,
component by component, so the rows stay where the data say the platform
goes), each with the axis loads ``+-F`` along x, y, z
(and ``+-M`` about them unless the rig applies forces only), ``F`` and ``M``
being the median force and moment magnitudes of the data (``M = F x 100 mm``
when the data hold no moment); when the data apply their loads at a few
levels (:mod:`vjm.discrepancy.loads`), the axis loads at each level's median
magnitudes, so that the suggested rows keep the levels.  Each row's information is the whitened
sensitivity of the measured components to the parameters, the same
quantity the fit uses, so rows add to the information of the data already
taken.  N rows are chosen greedily (one at a time, each the best given the
rows before it):

* **T-optimal** (model discrimination, Atkinson and Fedorov) when the
  diagnosis reports a group of candidates it cannot tell apart: for the
  group's first member A and each other member B, the chi-square distance
  between A's signature (at its fitted size, or one typical step) and its
  best imitation by B plus the calibration, ``T = |(I - P_[cal, B]) s_A|^2``,
  summed over B, is maximised;
* **Bayesian D-optimal** otherwise: ``log det(I + M)`` of the information
  ``M`` of the calibration, the named effects and the most likely other
  candidates (parameters in units of their allowed range, so the prior
  precision I stops an unseen parameter from ruling the determinant); it
  pins down the named parameters and makes a quiet data set informative
  about the effects it could not see.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..effects import modelops as mo
from ..effects.context import Context
from . import observe
from .loads import load_levels
from .predict import CALIBRATION, Predictor

#: candidate postures drawn in the workspace box
POOL = 160
#: chi-square distance between an effect's signature and a rival's best imitation at which a chi-square(1)
#: test at level 0.01 separates them with probability 0.8 (non-centrality of chi2(1, lambda) > 6.63)
T_SEPARATE = 11.68
#: moment arm used for the moment magnitude when the data apply no moment, mm
ARM = 100.0


@dataclass(frozen=True)
class Suggestion:
    rows: np.ndarray  # (N, 9): x, y, z, Fx, Fy, Fz, Mx, My, Mz; (N, 12) x, y, z, ox, oy, oz, Fx..Mz (6-dof)
    criterion: str
    targets: list
    gain: float  # criterion after / before (T: chi-square distance; D: log det)
    before: float
    after: float
    #: T-optimal designs: how many of the rows, taken in their order, bring every rival's chi-square
    #: distance to T_SEPARATE (None: the N rows do not, or no group to separate)
    rows_to_separate: int | None = None


def _pool(model, W, forces_only, rng, tilt=None):
    """Candidate rows (P, W, F, M); ``tilt`` (3,) the largest |orientation| per component of the data
    (None: points only)."""
    lo, hi = mo.workspace_box(model)
    P = lo + (hi - lo) * rng.random((4 * POOL, 3))
    if tilt is not None:
        P = np.hstack([P, tilt * (2.0 * rng.random((len(P), 3)) - 1.0)])
    P = P[model.arch.reachable(model, P)]
    if len(P):
        r = model.stiffness_map(P)
        P = P[r.invertible & np.isfinite(r.k_tran)]
    P = P[:POOL]
    lv = load_levels(W)
    groups = [W] if lv is None else [W[lv.index == j] for j in range(lv.count)]
    loads = []
    for Wj in groups:  # the axis loads at the data's magnitude, or at each of its load levels
        f = np.linalg.norm(Wj[:, :3], axis=1)
        m = np.linalg.norm(Wj[:, 3:], axis=1)
        F = float(np.median(f[f > 0])) if np.any(f > 0) else 100.0
        M = float(np.median(m[m > 0])) if np.any(m > 0) else F * ARM
        loads += [s * F * np.eye(6)[i] for i in range(3) for s in (1, -1)]
        if not forces_only:
            loads += [s * M * np.eye(6)[i] for i in range(3, 6) for s in (1, -1)]
    L = np.array(loads)
    return np.repeat(P, len(L), axis=0), np.tile(L, (len(P), 1)), F, M


def _columns(pred, names, theta, comp, sig):
    """(n, c, k) whitened sensitivity of the measured components of every row to every parameter of
    ``names`` (parameters scaled by their typical size for the calibration, their range otherwise)."""
    t0 = pred.twists(names, theta)
    cols, i = [], 0
    for nm in names:
        for p in pred.terms[nm].params:
            s = p.scale if nm == CALIBRATION else observe.span(p)
            h = 1e-2 * p.scale
            th = np.array(theta, float)
            th[i] += h if th[i] + h <= p.upper else -h
            d = (pred.twists(names, th) - t0) / (th[i] - theta[i])
            cols.append(d[:, comp] / sig * s)
            i += 1
    return np.stack(cols, axis=-1)


def _theta(prob_terms, names, values):
    """Parameter vector: fitted values where known, else the reference point (one step off the null)."""
    out = []
    for nm in names:
        ps = prob_terms[nm].params
        if nm in values:
            out.extend(values[nm])
        else:
            out.extend(observe.reference_point(ps))
    return np.array(out, float)


def _greedy_d(Xd, Xp, n):
    """Greedy Bayesian D-optimal rows of the pool (Xp (m, c, k)) added to the data (Xd (N, c, k))."""
    k = Xd.shape[-1]
    M = np.eye(k) + np.einsum("nci,ncj->ij", Xd, Xd)
    G = np.einsum("mci,mcj->mij", Xp, Xp)
    before = float(np.linalg.slogdet(M)[1])
    chosen = []
    for _ in range(n):
        ld = np.linalg.slogdet(M[None] + G)[1]
        ld[chosen] = -np.inf
        j = int(np.argmax(ld))
        chosen.append(j)
        M = M + G[j]
    return chosen, before, float(np.linalg.slogdet(M)[1])


def _t_value(G, h, a):
    return float(a - h @ np.linalg.lstsq(G, h, rcond=1e-12)[0])


def _greedy_t(pairs_d, pairs_p, n):
    """Greedy T-optimal rows: pairs_* lists of (X (., c, kx), s (., c)) for each (A, B) pair."""
    state = []
    for (Xd, sd) in pairs_d:
        state.append([np.einsum("nci,ncj->ij", Xd, Xd), np.einsum("nci,nc->i", Xd, sd), float(np.sum(sd * sd))])

    def total(st):
        return sum(_t_value(G, h, a) for G, h, a in st)

    before = total(state)
    m = pairs_p[0][0].shape[0]
    chosen: list = []
    enough = 0 if min(_t_value(G, h, a) for G, h, a in state) >= T_SEPARATE else None
    for _ in range(n):
        score = np.zeros(m)
        for (G, h, a), (Xp, sp) in zip(state, pairs_p):
            Gj = G[None] + np.einsum("mci,mcj->mij", Xp, Xp)
            hj = h[None] + np.einsum("mci,mc->mi", Xp, sp)
            aj = a + np.einsum("mc,mc->m", sp, sp)
            # ridge of round-off size keeps G_j invertible when X has a column the data cannot see
            ridge = 1e-12 * np.trace(Gj, axis1=1, axis2=2)[:, None, None] * np.eye(Gj.shape[-1])
            sol = np.linalg.solve(Gj + ridge, hj[..., None])[..., 0]
            score += aj - np.einsum("mi,mi->m", hj, sol)
        score[chosen] = -np.inf
        j = int(np.argmax(score))
        chosen.append(j)
        for st, (Xp, sp) in zip(state, pairs_p):
            st[0] = st[0] + Xp[j].T @ Xp[j]
            st[1] = st[1] + Xp[j].T @ sp[j]
            st[2] = st[2] + float(sp[j] @ sp[j])
        if enough is None and min(_t_value(G, h, a) for G, h, a in state) >= T_SEPARATE:
            enough = len(chosen)
    return chosen, float(before), float(total(state)), enough


@dataclass(frozen=True)
class Findings:
    """What the diagnosis found, as far as the next measurements depend on it."""

    named: tuple  # the named effects
    confounded: tuple  # groups of candidates (or a candidate and "calibration") the data cannot tell apart
    p_values: dict  # candidate -> its round-1 p-value (None: not tested), in the candidates' table order
    unobservable: tuple  # candidates the data cannot see


def suggest(model, pred, data_ctx_rows, final_values, found: Findings, n, forces_only=False,
            seed=0) -> Suggestion:
    """N rows (x, y, z, Fx..Mz) to measure next, from the diagnosis' state.

    Parameters
    ----------
    model : the nominal model (the fit's predictions are built on it).
    pred : the data's :class:`Predictor` (terms, fixed parameters, context).
    data_ctx_rows : (comp, sig_data, sig_pool): measured component indices,
        (n_data, c) whitening sigmas of the data rows and (c,) of a new row.
    final_values : name -> fitted parameter vector (calibration, named effects, round-1 fits).
    found : what the diagnosis found (named effects, confounded groups, candidates' p-values).
    """
    rng = np.random.default_rng(seed)
    comp, sig_d, sig_p = data_ctx_rows
    P0 = pred.ctx.P
    tilt = np.max(np.abs(P0[:, 3:]), axis=0) if P0.shape[1] == 6 else None
    Pp, Wp, F, M = _pool(model, pred.ctx.W, forces_only, rng, tilt)
    from ..effects.context import unique_postures

    U, idx = unique_postures(Pp)
    ctx = Context(model, U, idx, Wp, pred.ctx.noise_t)
    pool = Predictor(model, ctx, pred.terms, pred.fixed)
    usable = [c for c in pred.terms if c != CALIBRATION]
    # the nonlinear candidate costs a Newton solve per pool row: only when it is named
    if "geometric_nonlinearity" not in found.named:
        usable = [c for c in usable if c != "geometric_nonlinearity"]

    groups = [list(g) for g in found.confounded if all(x in usable or x == CALIBRATION for x in g)]
    named = [x for x in found.named if x in usable]
    # the group to separate: the one holding a named effect, else the first reported
    grp = next((g for g in groups if any(x in named for x in g)), groups[0] if groups else None)
    if grp is not None:
        a = next((x for x in grp if x in named), next(x for x in grp if x != CALIBRATION))
        others = [b for b in grp if b != a]
        pairs_d, pairs_p = [], []
        kc = len(pred.terms[CALIBRATION].params)
        ka = len(pred.terms[a].params)
        for b in others:
            # "calibration" as the rival: A's signature against the calibration alone
            names = (CALIBRATION, a) if b == CALIBRATION else (CALIBRATION, a, b)
            th = _theta(pred.terms, names, final_values)
            Xd = _columns(pred, names, th, comp, sig_d)
            Xp = _columns(pool, names, th, comp, sig_p)
            null_a = np.array([p.null for p in pred.terms[a].params])
            spans = np.array([observe.span(p) for p in pred.terms[a].params])
            da = (th[kc:kc + ka] - null_a) / spans
            sd = Xd[..., kc:kc + ka] @ da
            sp = Xp[..., kc:kc + ka] @ da
            keep = np.r_[0:kc, kc + ka:Xd.shape[-1]]
            pairs_d.append((Xd[..., keep], sd))
            pairs_p.append((Xp[..., keep], sp))
        chosen, before, after, enough = _greedy_t(pairs_d, pairs_p, n)
        criterion = (f"T-optimal: separates {a} from {', '.join(others)} (chi-square distance between {a}'s "
                     f"signature and its best imitation by the others plus the calibration)")
        targets = [a] + others
    else:
        pv = {c: p for c, p in found.p_values.items() if c in usable}
        ranked = sorted((c for c in pv if pv[c] is not None and c not in named), key=lambda c: pv[c])
        targets = named + ranked[:3]
        if not named:
            unseen = [c for c in found.unobservable if c in usable]
            targets += unseen[:3]
        names = (CALIBRATION,) + tuple(targets)
        th = _theta(pred.terms, names, final_values)
        Xd = _columns(pred, names, th, comp, sig_d)
        Xp = _columns(pool, names, th, comp, sig_p)
        chosen, before, after = _greedy_d(Xd, Xp, n)
        enough = None
        criterion = ("Bayesian D-optimal: log det(I + information) of the calibration and "
                     + ", ".join(targets) + " (parameters in units of their allowed range)")
    rows = np.hstack([Pp[chosen], Wp[chosen]])
    return Suggestion(rows, criterion, list(targets), after - before, before, after, enough)

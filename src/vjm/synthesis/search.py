"""The search: evaluated link designs, their surrogates, and the machine's constraints solved on them.

Each round:

1. every combination of the links' evaluated designs is a machine whose links were all computed (by
   FEA, or in closed form): its constraints are evaluated exactly, and the lightest feasible one is
   the incumbent (the only designs ever reported);
2. each link's :class:`~vjm.synthesis.surrogate.LinkSurrogate` is fitted on its designs;
3. the lightest machine the surrogates predict feasible is found (a Sobol pool of candidates, then
   SLSQP from the best three, every candidate's constraints from the exact machine map on the
   predicted compliances); with none predicted feasible, the stiffest one instead;
4. its links are evaluated (those not evaluated yet, side by side), which is where the FEA runs go.

It stops when the surrogates predict nothing lighter than the incumbent (by :data:`RTOL`), when the
proposal was evaluated already, or when the next round would exceed the budget.  A proposal that
the FEA finds infeasible makes the next one keep a margin of half the surrogate's error there.

Starting designs: a Latin hypercube of ``2 d + 1`` designs per link (``d`` free parameters), seeded.
Everything is deterministic for a given spec, seed and set of FEA results, so a rerun replays the
same rounds from the cache.
"""
from __future__ import annotations

import itertools
from dataclasses import dataclass, field

import numpy as np

from ..errors import VjmError
from .links import LinkRunner, LinkSample
from .machine import Machine
from .spec import Constraint, DesignSpec, FreeLink
from .surrogate import LinkSurrogate

#: relative mass gain below which the surrogates' proposal does not earn another round
RTOL = 1e-3
#: the neighbourhood (unit coordinates) of the first exploring round; each one halves it, down to R_MIN
R_START = 0.2
R_MIN = 0.02
#: an exploring candidate may be predicted this much heavier than the incumbent (near a local optimum of
#: the surrogates, nothing predicted feasible is lighter: what is learnt is on the boundary beside it)
EXPLORE_MASS = 0.01
#: candidates drawn per round (a power of two: a balanced Sobol sequence)
POOL = 128
#: combinations of evaluated designs checked exactly per round at most (the rest: with the incumbent's links)
MAX_COMBOS = 4000
#: points (of the grids and poses) constrained one by one in the gradient search: the nearest to their limits
ACTIVE = 40


def initial_count(link: FreeLink) -> int:
    return 2 * len(link.free) + 1


def minimum_budget(spec: DesignSpec) -> int:
    """The starting designs of every link and one round more (a design per link)."""
    return sum(initial_count(link) for link in spec.links) + len(spec.links)


@dataclass
class Combo:
    """A machine built from evaluated designs: ``keys`` per link, its mass and constraint values."""

    keys: tuple
    mass: float
    values: dict
    top: dict            # the values with every link at the top of its FEA error bar
    feasible: bool = False


@dataclass
class Outcome:
    """What the search found for one set of constraints."""

    constraints: tuple
    best: Combo | None
    feasible: bool
    reason: str
    rounds: list = field(default_factory=list)


class Search:
    """The evaluated designs (shared by every target of a front) and the rounds on them."""

    def __init__(self, spec: DesignSpec, machine: Machine, runner: LinkRunner, progress=None):
        self.spec, self.machine, self.runner = spec, machine, runner
        self.progress = progress or (lambda line: None)
        self.samples: dict = {link.name: [] for link in spec.links}
        self.order: list = []        # (link, LinkSample) in evaluation order: the history
        self.combos: dict = {}
        self.links = {link.name: link for link in spec.links}

    # -- evaluated designs ---------------------------------------------------------------------------
    @property
    def runs(self) -> int:
        return len(self.order)

    def _known(self, name: str, params: dict) -> LinkSample | None:
        return next((s for s in self.samples[name] if s.params == params), None)

    def evaluate(self, wanted: dict) -> None:
        """``{link: [params ...]}``: evaluate the designs not evaluated yet."""
        batches = {}
        for name, plist in wanted.items():
            new = []
            for p in plist:
                if self._known(name, p) is None and p not in new:
                    new.append(p)
            if new:
                batches[name] = (self.links[name], new)
        if not batches:
            return
        done = self.runner.evaluate(batches)
        for name in self.samples:  # spec order: the history does not depend on which FEA finished first
            for s in done.get(name, []):
                self.samples[name].append(s)
                self.order.append(s)

    def ok(self, name: str) -> list:
        return [s for s in self.samples[name] if s.ok]

    # -- exact combinations ----------------------------------------------------------------------------
    def _combo(self, picks: tuple) -> Combo:
        keys = tuple(s.key for s in picks)
        c = self.combos.get(keys)
        if c is None:
            comps = {s.link: s.compliance for s in picks}
            errs = {s.link: s.error for s in picks}
            mass = sum(self.machine.count(s.link) * s.mass for s in picks)
            vals = self.machine.values(comps, errs)
            top = self.machine.values(comps, errs, 1.0) if any(e is not None for e in errs.values()) else vals
            c = self.combos[keys] = Combo(keys, float(mass), vals, top)
        return c

    def feasible(self, c: Combo, cons: tuple) -> bool:
        v = c.top if self.spec.conservative else c.values
        return all(v[k.label] <= k.limit for k in cons)

    def violation(self, c: Combo, cons: tuple) -> float:
        v = c.top if self.spec.conservative else c.values
        return max(np.log(v[k.label] / k.limit) for k in cons)

    def best(self, cons: tuple, incumbent: Combo | None = None) -> Combo | None:
        """The lightest feasible combination of evaluated designs, else the one nearest to feasible."""
        pools = [self.ok(name) for name in self.samples]
        if not all(pools):
            return None
        n = int(np.prod([len(p) for p in pools]))
        if n <= MAX_COMBOS or incumbent is None:
            combos = [self._combo(c) for c in itertools.islice(itertools.product(*pools), MAX_COMBOS)]
        else:  # too many: each link's designs with the incumbent's other links
            inc = [next(s for s in p if s.key == k) for p, k in zip(pools, incumbent.keys)]
            combos = [self._combo(tuple(s if j == i else inc[j] for j in range(len(pools))))
                      for i, p in enumerate(pools) for s in p]
        feas = [c for c in combos if self.feasible(c, cons)]
        if feas:
            return min(feas, key=lambda c: (c.mass, c.keys))
        return min(combos, key=lambda c: (self.violation(c, cons), c.mass, c.keys))

    # -- the rounds ------------------------------------------------------------------------------------
    def start(self) -> None:
        from scipy.stats import qmc

        wanted = {}
        for i, link in enumerate(self.spec.links):
            u = qmc.LatinHypercube(d=len(link.free), rng=np.random.default_rng([self.spec.seed, i])).random(
                initial_count(link))
            wanted[link.name] = [link.params(x) for x in u]
        fea = sum(len(v) for k, v in wanted.items() if self.links[k].kind == "cad")
        self.progress(f"design: {sum(map(len, wanted.values()))} starting designs "
                      f"({', '.join(f'{k} {len(v)}' for k, v in wanted.items())}; {fea} by FEA, cached ones are read), "
                      f"then rounds of one design per link; at most {self.spec.fea_runs} runs")
        self.evaluate(wanted)

    def run(self, cons: tuple, cap: int | None = None) -> Outcome:
        """Rounds until converged or out of budget (``cap`` runs in all, at most the spec's), for ``cons``."""
        cap = self.spec.fea_runs if cap is None else min(cap, self.spec.fea_runs)
        out = Outcome(cons, None, False, "")
        margin, rnd, radius = 0.0, 0, R_START
        while True:
            rnd += 1
            inc = self.best(cons, out.best)
            out.best = inc
            self._note(out, inc, cons)
            if inc is None:
                out.reason = "a link has no successful design to start from"
                break
            prop = propose(self, cons, margin, rnd, inc)
            inc_ok = self.feasible(inc, cons)
            if prop is None:
                out.reason = "the surrogates found no candidate"
                break
            params, pmass, pg = prop
            new = {n: [p] for n, p in params.items() if self._known(n, p) is None}
            if (inc_ok and pmass >= inc.mass * (1.0 - RTOL)) or not new:
                # the surrogates see nothing lighter: look around the incumbent where they know least,
                # in a shrinking neighbourhood, before calling it converged
                reason = "converged: the surrogates predict nothing lighter" if new else \
                    "converged: the proposed design was evaluated already"
                prop = None
                while prop is None and radius >= R_MIN:
                    prop = propose(self, cons, margin, rnd, inc, radius) if inc_ok else None
                    radius /= 2.0
                    if prop is not None:
                        params = prop[0]
                        new = {n: [p] for n, p in params.items() if self._known(n, p) is None}
                        prop = prop if new else None
                if prop is None:
                    out.reason = reason
                    break
                pg = prop[2]
            if self.runs + len(new) > cap:
                out.reason = f"budget: {cap} runs" + ("" if cap == self.spec.fea_runs else " (this target's share)")
                break
            self.evaluate(new)
            picks = tuple(self._known(n, params[n]) for n in self.samples)
            if all(s is not None and s.ok for s in picks):
                err = self.violation(self._combo(picks), cons) - pg
                margin = 0.5 * max(err, 0.0) if err > -margin else 0.5 * margin
        out.feasible = out.best is not None and self.feasible(out.best, cons)
        return out

    def _note(self, out: Outcome, inc: Combo | None, cons: tuple) -> None:
        if inc is None:
            return
        ok = self.feasible(inc, cons)
        first = cons[0]
        v = (inc.top if self.spec.conservative else inc.values)[first.label]
        out.rounds.append({"runs": self.runs, "mass_kg": inc.mass, "feasible": ok, first.label: v})
        self.progress(f"design: {self.runs}/{self.spec.fea_runs} runs; "
                      f"{'lightest feasible' if ok else 'nearest to feasible'} {inc.mass:.4g} kg, "
                      f"{first.label} {v:.4g} (limit {first.limit:g})")


def _slices(links) -> list:
    out, a = [], 0
    for link in links:
        out.append(slice(a, a + len(link.free)))
        a += len(link.free)
    return out


def propose(search: Search, cons: tuple, margin: float, rnd: int, inc: Combo, radius: float | None = None):
    """The lightest machine the surrogates predict feasible (with ``margin`` in log units), or the stiffest.

    With ``radius``, an exploring proposal instead: within ``radius`` (unit coordinates) of the incumbent,
    predicted feasible and at most EXPLORE_MASS heavier than it, the candidate that best balances a low predicted mass and a
    large distance from the links' evaluated designs (where the surrogates know least); None if there is none.

    Returns ``({link: params}, predicted mass, predicted violation)`` of the snapped design, or None."""
    from scipy.optimize import minimize
    from scipy.stats import qmc

    links = list(search.spec.links)
    sl = _slices(links)
    dim = sl[-1].stop
    surr = []
    for link in links:
        ok = search.ok(link.name)
        U = np.array([link.unit(s.params) for s in ok])
        C = np.array([s.compliance for s in ok])
        if search.spec.conservative:  # the surrogate of the top of each design's error bar
            C = np.array([_top(s) for s in ok])
        surr.append((link, LinkSurrogate.fit(U, C, np.array([s.mass for s in ok]))))
    counts = [search.machine.count(link.name) for link in links]

    known: dict = {}  # SLSQP asks again for points it has seen (a constraint's value, then its gradient there)

    def predict(u):
        key = u.tobytes()
        if key not in known:
            comps, mass = {}, 0.0
            for (link, s), k, part in zip(surr, counts, sl):
                C, m = s.predict(u[part][None, :])
                comps[link.name] = C[0]
                mass += k * float(m[0])
            known[key] = comps, mass
        return known[key]

    here = np.concatenate([link.unit(next(s for s in search.samples[link.name] if s.key == k).params)
                           for link, k in zip(links, inc.keys)])
    # candidates are screened on the points that bind near the incumbent, the answer on the whole grid
    near = search.machine.reduced(predict(here)[0])

    def viol(u, machine=near):
        comps, _ = predict(np.clip(u, 0.0, 1.0))
        v = machine.values(comps)
        return max(np.log(max(v[c.label], 1e-300) / c.limit) if np.isfinite(v[c.label]) else 50.0 for c in cons)

    def mass(u):
        return predict(np.clip(u, 0.0, 1.0))[1]

    seen: dict = {}

    def pointwise(u):
        u = np.clip(u, 0.0, 1.0)
        key = u.tobytes()
        if key not in seen:
            seen[key] = near.pointwise(predict(u)[0], cons)
        return seen[key]

    pool = qmc.Sobol(d=dim, rng=np.random.default_rng([search.spec.seed, 1000 + rnd])).random(POOL)
    if radius is not None:
        pool = np.clip(here + radius * (2.0 * pool - 1.0), 0.0, 1.0)
    pool = np.vstack([here[None, :], pool])
    g = np.array([viol(u) for u in pool])
    m = np.array([mass(u) for u in pool])
    if radius is not None:
        got = _explore(search, links, sl, pool, g, m, margin, inc)
        return None if got is None else (got[0], got[2], viol(got[1], search.machine))
    feas = np.flatnonzero(g <= -margin)
    bounds = [(0.0, 1.0)] * dim
    opts = {"maxiter": 100, "ftol": 1e-10, "eps": 1e-6}
    results = []
    if len(feas):
        starts = [int(i) for i in feas[np.argsort(m[feas], kind="stable")][:2]]
        if 0 in feas and 0 not in starts:  # the incumbent too: its surrogate is exact there
            starts.append(0)
        for i in starts:
            # the worst case over the points is not smooth where the worst point changes: the points
            # nearest to their limit at the start are constrained one by one instead
            top = np.argsort(pointwise(pool[i]))[-ACTIVE:]
            r = minimize(mass, pool[i], method="SLSQP", bounds=bounds, options=opts,
                         constraints=[{"type": "ineq", "fun": lambda u, top=top: -margin - pointwise(u)[top]}])
            for u in (r.x, pool[i]):
                results.append(_snapped(links, sl, u))
    else:
        for i in np.argsort(g, kind="stable")[:3]:
            r = minimize(viol, pool[i], method="SLSQP", bounds=bounds, options=opts)
            for u in (r.x, pool[i]):
                results.append(_snapped(links, sl, u))
    scored = [(params, u, mass(u), viol(u, search.machine)) for params, u in results]
    good = [x for x in scored if x[3] <= -margin + 1e-9]
    if good:
        params, u, pm, pg = min(good, key=lambda x: x[2])
    else:
        params, u, pm, pg = min(scored, key=lambda x: x[3])
    return params, pm, pg


def _explore(search: Search, links, sl, pool, g, m, margin: float, inc: Combo):
    """The exploring choice among ``pool`` (see :func:`propose`): equal weights on the predicted mass and the
    distance (both scaled to [0, 1] over the eligible candidates), as in stochastic RBF methods."""
    ok = np.flatnonzero((g <= -margin) & (m <= inc.mass * (1.0 + EXPLORE_MASS)))
    ok = ok[ok > 0]  # not the incumbent itself
    if not len(ok):
        return None
    dist = np.zeros(len(ok))
    for link, part in zip(links, sl):
        U = np.array([link.unit(x.params) for x in search.samples[link.name]])
        dist += np.min(np.linalg.norm(pool[ok][:, None, part] - U[None, :, :], axis=2), axis=1)

    def scaled(x):
        span = np.ptp(x)
        return (x - x.min()) / span if span > 0 else np.zeros_like(x)

    i = ok[int(np.argmin(0.5 * scaled(m[ok]) + 0.5 * scaled(-dist)))]
    params, u = _snapped(links, sl, pool[i])
    return params, u, float(m[i])


def _snapped(links, sl, u) -> tuple:
    u = np.clip(np.asarray(u, dtype=float), 0.0, 1.0)
    params = {link.name: link.params(u[part]) for link, part in zip(links, sl)}
    return params, np.concatenate([link.unit(params[link.name]) for link in links])


def _top(s: LinkSample) -> np.ndarray:
    if s.error is None:
        return np.asarray(s.compliance)
    d = np.sqrt(1.0 + s.error)
    return d[:, None] * s.compliance * d[None, :]


def target_constraints(spec: DesignSpec, target: float | None) -> tuple:
    """The spec's constraints, with the workspace k_tran_max limit set to ``target`` (added if absent)."""
    if target is None:
        return spec.constraints
    rest = tuple(c for c in spec.constraints if not (c.quantity == "k_tran_max" and c.poses is None))
    return (Constraint("k_tran_max", float(target)),) + rest


def check_budget(spec: DesignSpec) -> None:
    need = minimum_budget(spec)
    if spec.fea_runs < need:
        raise VjmError(f"budget: {spec.fea_runs} runs is below the search's minimum of {need} (2 d + 1 starting "
                       f"designs per link: {', '.join(f'{x.name} {initial_count(x)}' for x in spec.links)}, "
                       "and one round of a design per link)")

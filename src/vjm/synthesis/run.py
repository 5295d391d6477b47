"""``vjm design`` as a function: check everything, search, verify, and answer with a :class:`DesignResult`."""
from __future__ import annotations

import dataclasses
import json
import os
import tempfile
from pathlib import Path

import numpy as np

from ..errors import VjmError
from .links import LinkRunner, check_beam, check_cad
from .machine import load_machine
from .result import DESIGN_FILES, ConstraintValue, DesignResult
from .search import Outcome, Search, check_budget, target_constraints
from .spec import UNITS, DesignSpec, read_spec

#: a parameter this close to an end of its range (in unit coordinates) is at its bound
AT_BOUND = 1e-3


def prepare(spec, budget=None, workers=None, scheduler=None, seed=None, targets=None,
            conservative=None) -> DesignSpec:
    """The spec (a path or a DesignSpec) with the command line's overrides, checked (no FEA)."""
    if not isinstance(spec, (DesignSpec, str, os.PathLike)):
        raise VjmError(f"spec must be the path of a design spec (YAML) or a DesignSpec, got {type(spec).__name__}")
    s = spec if isinstance(spec, DesignSpec) else read_spec(spec)
    over = {k: v for k, v in (("fea_runs", budget), ("workers", workers), ("scheduler", scheduler), ("seed", seed),
                              ("conservative", conservative)) if v is not None}
    if targets is not None:
        if isinstance(targets, (str, bytes)) or not isinstance(targets, (list, tuple, np.ndarray)) or not len(targets) \
                or not all(isinstance(t, (int, float, np.floating)) and not isinstance(t, bool) for t in targets):
            raise VjmError(f"--targets must be a list of k_tran_max limits > 0 (mm/N), got {targets!r}")
        ts = tuple(float(t) for t in targets)
        if any(not (np.isfinite(t) and t > 0) for t in ts):
            raise VjmError(f"--targets must be k_tran_max limits > 0 (mm/N), got {targets!r}")
        over["targets"] = ts
    s = dataclasses.replace(s, **over)
    for name, v, lo, hi in (("--budget", s.fea_runs, 1, None), ("--workers", s.workers, 1, None),
                            ("--seed", s.seed, 0, 2 ** 32 - 1)):
        if v is None and name == "--workers":
            continue
        if isinstance(v, bool) or not isinstance(v, (int, np.integer)) or v < lo or (hi is not None and v > hi):
            raise VjmError(f"{name} must be an integer >= {lo}{'' if hi is None else f' and <= {hi}'}, got {v!r}")
    if not isinstance(s.conservative, bool):
        raise VjmError(f"conservative must be True or False, got {s.conservative!r}")
    if s.scheduler is not None and not isinstance(s.scheduler, str):
        raise VjmError(f"--scheduler must be an address such as tcp://host:8786, got {s.scheduler!r}")
    check_budget(s)
    return s


def design(spec, out=None, *, budget: int | None = None, workers: int | None = None, scheduler: str | None = None,
           seed: int | None = None, targets=None, conservative: bool | None = None, force: bool = False,
           progress=None) -> DesignResult:
    """The lightest machine whose constraints hold, its links computed by FEA (or in closed form).

    ``spec``: a spec file (:mod:`vjm.synthesis.spec`) or a DesignSpec; ``out``: the output folder
    (design.json ..., and ``links/``, the FEA cache a rerun resumes from), required for CAD links;
    the keywords override the spec.  Every check (spec, machine, the scripts' parameters, the CAD at
    the corners of the bounds, the budget, the output folder) runs before the first FEA.
    """
    s = prepare(spec, budget, workers, scheduler, seed, targets, conservative)
    if not isinstance(force, bool):
        raise VjmError(f"force must be True or False, got {force!r}")
    if progress is not None and not callable(progress):
        raise VjmError(f"progress must be a callable taking one line of text, got {type(progress).__name__}")
    if out is not None and not isinstance(out, (str, os.PathLike)):
        raise VjmError(f"out must be a folder's path, got {type(out).__name__}")
    machine = load_machine(s)
    for link in s.links:
        (check_cad if link.kind == "cad" else check_beam)(link)
    if out is None and any(link.kind == "cad" for link in s.links):
        raise VjmError("a design with CAD links needs an output folder: its links/ folder is the FEA cache")
    tmp = None
    if out is not None:
        from linkfea.files.outputs import check_folder, claim

        check_folder(out, list(DESIGN_FILES) + optimum_names(s), force=force)
        claim(out, ["links/"], "vjm design links")
        where = Path(out)
    else:
        tmp = tempfile.TemporaryDirectory(prefix="vjm-design-")
        where = Path(tmp.name)
    runner = LinkRunner(where, s.workers, s.scheduler)
    search = Search(s, machine, runner, progress)
    try:
        search.start()
        # loosest first: each target starts from the designs of the ones before it, and gets an equal share
        # of the runs left (the last, tightest one, the one design.json reports, gets what they leave)
        ts = sorted(s.targets, reverse=True) or [None]
        outcomes = []
        for i, t in enumerate(ts):
            cap = search.runs + (s.fea_runs - search.runs) // (len(ts) - i)
            outcomes.append((t, search.run(target_constraints(s, t), cap)))
    finally:
        runner.close()
        if tmp is not None:
            tmp.cleanup()
    res = _result(s, search, outcomes, runner.computed)
    if out is not None:
        res.save(out, force=True, files=_optimum_files(s, search, outcomes[-1][1]))
    return res


def _params_of(search: Search, keys: tuple) -> dict:
    out = {}
    for name, k in zip(search.samples, keys):
        out[name] = next(x for x in search.samples[name] if x.key == k)
    return out


def _active(spec: DesignSpec, picks: dict) -> tuple:
    out = []
    for link in spec.links:
        for p, u in zip(link.free, link.unit(picks[link.name].params)):
            if p.kind != "choice" and u <= AT_BOUND:
                out.append(f"{link.name}.{p.name} (lower)")
            elif p.kind != "choice" and u >= 1 - AT_BOUND:
                out.append(f"{link.name}.{p.name} (upper)")
    return tuple(out)


def optimum_names(s: DesignSpec) -> list:
    """The files of the optimum's links: ``optimum_<link>.json`` and, for a CAD link, ``.step``."""
    return [f"optimum_{link.name}.{ext}" for link in s.links for ext in (("json", "step") if link.kind == "cad"
                                                                          else ("json",))]


def _message(o: Outcome, mass: float, vals: dict, active: tuple) -> str:
    if o.feasible:
        cut = "; the budget ended the search before it converged" if o.reason.startswith("budget") else ""
        return f"the lightest verified design meets every constraint: {mass:.4g} kg{cut}"
    c = max(o.constraints, key=lambda c: vals[c.label] / c.limit)
    bounds = "none" if not active else active[0] if len(active) == 1 else ", ".join(active[:-1]) + " and " + active[-1]
    return (f"no design within the bounds reaches {c.label} <= {c.limit:g} {UNITS[c.quantity]}; the stiffest "
            f"found is {vals[c.label]:.4g} at {mass:.4g} kg; the active bounds are {bounds}")


def _result(s: DesignSpec, search: Search, outcomes: list, computed: int) -> DesignResult:
    t, o = outcomes[-1]
    if o.best is None:
        raise VjmError(f"every design of a link failed; see the errors in {search.runner.folder(s.links[0])}/results "
                       f"(first: {next((x.error_text for x in search.order if not x.ok), '')})")
    picks = _params_of(search, o.best.keys)
    vals, top = o.best.values, o.best.top
    cons = tuple(ConstraintValue(c.quantity, c.limit, vals[c.label], max(top[c.label] - vals[c.label], 0.0),
                                 c.limit - (top if s.conservative else vals)[c.label], UNITS[c.quantity], c.poses)
                 for c in o.constraints)
    active = _active(s, picks)
    history = tuple({"run": i + 1, "link": x.link, "params": x.params, "key": x.key,
                     "status": "ok" if x.ok else "failed", "mass_kg": x.mass if x.ok else None,
                     "error": x.error_text or None, "result": x.result} for i, x in enumerate(search.order))
    front = []
    for tt, oo in outcomes:
        if tt is None or oo.best is None:
            continue
        fp = _params_of(search, oo.best.keys)
        front.append({"target": tt, "feasible": oo.feasible, "moving_mass_kg": oo.best.mass,
                      "k_tran_max": oo.best.values["k_tran_max"], "k_rot_max": oo.best.values["k_rot_max"],
                      "runs": oo.rounds[-1]["runs"] if oo.rounds else 0,
                      "parameters": {n: x.params for n, x in fp.items()}})
    return DesignResult(o.feasible, _message(o, o.best.mass, top if s.conservative else vals, active),
                        {n: x.params for n, x in picks.items()}, o.best.mass, vals["k_tran_max"], vals["k_rot_max"],
                        cons, search.runs, computed, s.fea_runs, o.reason, active, history, tuple(o.rounds),
                        tuple(front), s.conservative, s.path, s.machine,
                        {n: {"kind": search.links[n].kind, "result": x.result} for n, x in picks.items()})


def _optimum_files(s: DesignSpec, search: Search, o: Outcome) -> dict:
    """``optimum_<link>.json`` (and ``.step`` for a CAD link) writers of the reported design."""
    if o.best is None:
        return {}
    files = {}
    for name, x in _params_of(search, o.best.keys).items():
        link = search.links[name]
        if link.kind == "cad":
            files[f"optimum_{name}.json"] = _copier(str(x.result))
            files[f"optimum_{name}.step"] = _stepper(link, x.params)
        else:
            doc = {"schema": "vjm.design-beam/1", "link": name, "beam": {**dict(link.source), **x.params},
                   "mass_kg": x.mass, "compliance": np.asarray(x.compliance).tolist(),
                   "units": "compliance t = C w in the beam's tip frame (x along the beam): mm/N, rad/(N mm), "
                            "1/N, rad/N by block; order Fx..Mz"}
            files[f"optimum_{name}.json"] = _texter(json.dumps(doc, indent=1) + "\n")
    return files


def _copier(src: str):
    return lambda p: Path(p).write_bytes(Path(src).read_bytes())


def _texter(text: str):
    return lambda p: Path(p).write_text(text, encoding="utf-8")


def _stepper(link, params: dict):
    return lambda p: _step(link, params, p)


def _step(link, params: dict, path: str) -> None:
    from linkfea.cad import build_link

    body = build_link(str(link.source), params).body
    body.exportStep(os.fspath(path))

"""The stages' diagnosis of deflections and stiffness observations: calibrate, locate, name, add, show.

:func:`diagnose_stages` runs the stages of :mod:`vjm.discrepancy.stages` in turn on a model and a data set
read, with the strategy of its kind (:mod:`vjm.discrepancy.stages.kinds`), and returns a
:class:`~vjm.discrepancy.diagnosis.Diagnosis`.  The data kinds of :mod:`vjm.discrepancy.kinds` call it.
"""
from __future__ import annotations

from . import covariance
from .diagnosis import Diagnosis, stage_model, write_diagnosis
from .stages import outliers as outl
from .stages.calibrate import calibrate
from .stages.candidates import candidates
from .stages.confounding import confounding
from .stages.design import next_measurements
from .stages.goodness import goodness
from .stages.kinds import kind_of
from .stages.load_levels import level_check
from .stages.locate import locate
from .stages.noise import check_stated
from .stages.observability import observability
from .stages.outliers import Outliers, untrusted_model
from .stages.problem import build_problem, with_weights
from .stages.record import Pass, assemble
from .stages.select import select
from .stages.strength import weak_design
from .stages.update import updated_model
from .stages.verdict import verdict
from .tracker import TrackerNoise


def run_stages(model, data, alpha, effects, folds, max_effects, progress, scale=None, kind=None) -> Pass:
    """The stages from the problem to the verdict on the rows of ``data``, each returning its value.
    ``scale`` (translations, rotations): the stated sigmas widened by these factors from the start and not
    looked at again (the outlier reruns keep the first run's); None: widened, and the selection run
    again, only if the noise check finds them too small and the excess noise-like.  ``kind``: the strategy
    of the data's kind (:mod:`~vjm.discrepancy.stages.kinds`; None: by the data read)."""
    s = build_problem(model, data, kind_of(data) if kind is None else kind, effects)
    terms = dict(s.terms)
    if scale is not None and any(f != 1.0 for f in scale):
        s = with_weights(s, terms, s.weights.scaled(scale[0], scale[1], _widened(s, scale)))
    cal, obs, chosen, fit = _name(s, alpha, max_effects, folds, progress)
    nc = check_stated(s, chosen.sel.final, alpha, (1.0, 1.0) if scale is None else scale)
    if nc is not None and nc.rescale and scale is None:
        # the stated sigmas look too small and the excess is noise-like: the tests again, at the residuals' scale
        if progress:
            progress(f"stated sigmas look too small (x{nc.scale[0]:.2f} translations, x{nc.scale[1]:.2f} rotations): "
                     "selecting again at that scale")
        s = with_weights(s, terms, s.weights.scaled(nc.scale[0], nc.scale[1], _widened(s, nc.scale)))
        cal, obs, chosen, fit = _name(s, alpha, max_effects, folds, progress)
        nc = check_stated(s, chosen.sel.final, alpha, nc.scale)
    lev = level_check(s, chosen, fit)
    loc = locate(s, chosen, fit)
    table = candidates(s, obs, chosen)
    conf = confounding(s.prob, chosen.sel, obs.sens, cal.cols, table.entries, alpha, chosen.rivals)
    v = verdict(s, cal, chosen, fit, lev, weak_design(s, chosen))
    return Pass(s, cal, obs, chosen, fit, nc, lev, loc, table, conf, v)


def set_aside(first: Pass, run, sigma_known: bool) -> tuple[Pass, Outliers | None]:
    """(the run to report, the rows set aside or None): the stages run again (``run(rows)``) without the
    rows the last run flags as gross outliers until the set aside is the set flagged
    (:mod:`~vjm.discrepancy.stages.outliers` decides each step)."""
    full = first.s
    got = outl.first_look(full, first.final, sigma_known, judged=first.fit.lack_of_fit.get("p_value") is not None)
    if got is None or isinstance(got, Outliers):
        return first, got
    seen: set = {()}
    cur, aside, passes = first, (), 1
    while outl.again(got, aside, seen, passes):
        aside = got[0]
        seen.add(aside)
        cur = run(outl.kept_rows(full, aside))
        passes += 1
        got = outl.flag(full, cur.s, cur.final, sigma_known)
        if cur.verdict.verdict == "unexplained":
            break  # the other rows still lack fit: the rows flagged are part of a gap, not gross errors
    found = outl.decide(full, got, aside, passes, cur.verdict.verdict)
    return (cur if found.accepted else first), found


DIAGNOSE_BYTES_PER_ROW = 2.1e5
"""Peak memory of ``vjm diagnose`` per data row with every candidate of the registry (25): measured on the
3-PUU, 247 MB at 601 rows, 640 MB at 2,401, 2.1 GB at 9,601 (205-218 kB per added row, outlier stage
included); the candidates' Jacobians make most of it, so ``--effect`` scales it by its share of them."""
DIAGNOSE_SECONDS_PER_ROW = 5.8e-3
"""Seconds per row of the same runs (25 s at 2,401 rows, 67 s at 9,601, on this 2-core machine)."""


def diagnose_plan(n_rows: int, n_candidates: int | None = None):
    """The :class:`vjm.maps.grid.Plan` of a diagnosis of ``n_rows`` rows (``n_candidates``: None for the whole
    registry); VjmError naming the figures if it cannot fit in memory."""
    from ..effects import REGISTRY
    from ..maps.grid import plan

    share = 1.0 if n_candidates is None else min(1.0, max(1, n_candidates) / max(1, len(REGISTRY)))
    return plan("vjm diagnose", n_rows, DIAGNOSE_BYTES_PER_ROW * share, DIAGNOSE_SECONDS_PER_ROW, unit="rows",
                hint="diagnose a subset of the rows (the diagnosis needs postures and loads, not repeats), "
                     "or fewer candidates (--effect)")


def diagnose_stages(model, data, kind, alpha: float, effects=None, folds: int = 5, max_effects: int = 3,
                    model_name: str | None = None, progress=None, suggest: int = 0, forces_only: bool = False,
                    outliers: bool = True, noise: TrackerNoise | None = None, name: str = "deflection") -> Diagnosis:
    """The stages on ``data`` (read) with the strategy ``kind`` of its data kind ``name`` (arguments checked,
    see :func:`vjm.discrepancy.workflow.diagnose`)."""
    diagnose_plan(data.n, len(effects) if effects else None)  # before the stages: 120k rows passed 12 GB in 45 s
    if noise is not None:
        data = kind.with_noise(data, noise)

    def run(rows, scale=None) -> Pass:
        return run_stages(model, rows, alpha, effects, folds, max_effects, progress, scale, kind)

    p, found = run(data), None
    if outliers:  # the reruns on the rows kept use the first run's noise scale
        p, found = set_aside(p, lambda rows, first=p: run(rows, first.scale), p.s.weights.sigma_known)
    s, chosen = p.s, p.chosen
    untrusted = found is not None and found.untrusted
    if found is not None and progress:
        progress(f"outliers: {len(found.positions)} rows beyond the threshold after {found.passes} diagnoses; "
                 f"{'set aside' if found.accepted else 'kept (part of the gap)'}")
    if untrusted:
        upd, cov = untrusted_model(s, chosen.sel.baseline), covariance.calibration(s.prob, s.pred, chosen.sel.baseline)
    else:
        upd, cov = updated_model(s, chosen), covariance.calibration(s.prob, s.pred, chosen.sel.final)
    sg = (next_measurements(s, p.obs, chosen, p.fit, p.table, p.conf, untrusted, suggest, forces_only)
          if suggest else None)
    rep = assemble(p, found, sg, model_name=model_name or "<model>", alpha=alpha, folds=folds)
    return Diagnosis(rep, name, write_diagnosis, stage_model, model=upd, P=s.U, rms_pose_before=p.loc.per_before,
                     rms_pose_after=p.loc.per_after, next_measurements=sg.rows if sg is not None else None,
                     covariance=cov)


def _name(s, alpha, max_effects, folds, progress):
    """Calibration, observability, selection, goodness of fit."""
    cal = calibrate(s, progress)
    obs = observability(s, cal, progress)
    chosen = select(s, cal, obs, alpha, max_effects, folds, progress)
    return cal, obs, chosen, goodness(s, obs, chosen, alpha)


def _widened(s, scale) -> str:
    """The weights' source once the stated sigmas are widened by ``scale``."""
    return f"{s.weights.source}, x{scale[0]:.3g} translations, x{scale[1]:.3g} rotations (see noise)"

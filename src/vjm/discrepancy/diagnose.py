"""The discrepancy workflow: calibrate, locate, name, add, show.

:func:`diagnose` takes a model and a data set and returns a
:class:`Diagnosis` (report dictionary + updated model + per-posture residuals);
:func:`write_diagnosis` writes it to a directory as one output set.
"""
from __future__ import annotations

import os
from dataclasses import dataclass

import numpy as np
from scipy import stats

from linkfea.checks import Bounds, integer, number

from ..errors import ArgumentError, VjmError
from . import covariance, observe
from . import effects as fx
from . import modelops as mo
from .data import StiffnessObs, read_csv, write_design
from .fit.select import (
    OCCAM_WINDOW,
    Z95,
    Term,
    backward_eliminate,
    clipped,
    fit_terms,
    forward_select,
    lack_of_fit,
    screen_pairs,
    swap_alternatives,
)
from .locate import localize
from .plausible import usable_data, workspace_flags
from .predict import (
    CALIBRATION,
    Context,
    Predictor,
    apply_calibration,
    calibration_term,
    deflection_problem,
    stiffness_problem,
)
from .report import check_report_dir, plot_before_after, plot_residuals, write_report_dir
from .summary import alternative_lines, verdict_line

DEFAULT_ALPHA = 0.01
#: valid ranges of diagnose's numeric arguments: a level of 0 or 1 makes every test pass or fail
ALPHA = Bounds(0, 1, lo_open=True, hi_open=True)
FOLDS = Bounds(2)
MAX_EFFECTS = Bounds(1)
SUGGEST = Bounds(0)


def check_arguments(alpha=DEFAULT_ALPHA, folds=5, max_effects=3, suggest=0):
    """The numeric arguments of :func:`diagnose`, checked (type, finiteness, range): ArgumentError naming one."""
    return (number(alpha, "alpha", ALPHA, ArgumentError), integer(folds, "folds", FOLDS, ArgumentError),
            integer(max_effects, "max_effects", MAX_EFFECTS, ArgumentError),
            integer(suggest, "suggest", SUGGEST, ArgumentError))


@dataclass(frozen=True)
class Diagnosis:
    """Outcome of :func:`diagnose`: the report dictionary (what report.json holds), the updated
    model, per-posture residuals, and the suggested next measurements (or None)."""

    report: dict
    model: object  # updated model
    P: np.ndarray  # unique postures
    rms_pose_before: np.ndarray  # normalized RMS per posture, calibrated baseline
    rms_pose_after: np.ndarray
    next_measurements: np.ndarray | None = None  # (N, 9) x, y, z, Fx..Mz
    covariance: dict | None = None  # final fit's parameters and covariance: model_updated.yaml's calibration:

    @property
    def verdict(self) -> str:
        """"no_discrepancy", "explained" or "unexplained"."""
        return self.report["verdict"]

    @property
    def named(self) -> list:
        """Names of the effects added to the model."""
        return list(self.report["named_effects"])

    @property
    def confounded(self) -> list:
        """Groups of candidates (or a candidate and "calibration") this data cannot tell apart."""
        return [list(g) for g in self.report["confounded"]]

    @property
    def updated_model(self):
        """The model with the calibration and the named effects (what model_updated.yaml holds)."""
        return self.model

    def summary(self):
        """A :class:`~vjm.discrepancy.summary.Summary` (``str()`` text, ``as_html()``), like statsmodels'."""
        from .summary import Summary

        return Summary(self.report)

    def save(self, out_dir, force: bool = False) -> None:
        """Write report.json, report.html, figures, model_updated.yaml (and next_measurements.csv)."""
        write_diagnosis(self, out_dir, force=force)

    def _repr_html_(self) -> str:
        return self.summary().as_html()

    def __repr__(self) -> str:
        return f"<Diagnosis {self.verdict}: named {self.named or 'nothing'}>"


def _candidates(model, data_kind, names=None):
    names = list(fx.REGISTRY) if names is None else list(names)
    cands, skipped = [], {}
    for nm in names:
        eff = fx.get(nm)
        why = eff.applies_to(model, data_kind)
        if why:
            skipped[nm] = why
        else:
            cands.append(nm)
    return cands, skipped


def _rms(x):
    x = np.asarray(x, float)
    x = x[np.isfinite(x)]
    return float(np.sqrt(np.mean(x * x))) if x.size else float("nan")


def _robust_scale(r):
    r = r[np.isfinite(r)]
    if r.size == 0:
        return 1.0
    s = 1.4826 * np.median(np.abs(r - np.median(r)))
    return float(s if s > 0 else max(np.sqrt(np.mean(r * r)), 1e-300))


def diagnose(model, data, alpha: float = DEFAULT_ALPHA, effects=None, folds: int = 5, max_effects: int = 3,
             model_name: str = "<model>", log=None, suggest: int = 0, forces_only: bool = False) -> Diagnosis:
    """Run the workflow on a loaded model and a data set (:func:`read_csv` output).

    Parameters
    ----------
    alpha : family-wise significance level of each selection round.
    effects : candidate names (default: the whole registry).
    suggest : number of (posture, load) rows to suggest measuring next (0: none).
    forces_only : suggest force loads only (a rig that cannot apply torques).
    """
    alpha, folds, max_effects, suggest = check_arguments(alpha, folds, max_effects, suggest)
    kind = "stiffness" if isinstance(data, StiffnessObs) else "deflection"
    data, U, idx, q = usable_data(model, data)  # the model's rows, reachable, in plausible units
    W = data.W if kind == "deflection" else np.zeros((data.n, 6))
    ctx = Context(model, U, idx, W)
    cands, skipped = _candidates(model, kind, effects)
    if kind == "deflection":
        if data.sigma_t is not None:
            ctx.noise_t = float(np.median(data.sigma_t))
        else:
            r0 = data.T[:, :3] - np.einsum("nij,nj->ni", mo.compliance_map(model, U)[idx][:, :3], W)
            ctx.noise_t = _robust_scale(r0)
    for nm in list(cands):
        why = fx.get(nm).prepare(ctx)
        if why:
            cands.remove(nm)
            skipped[nm] = why
    terms = {CALIBRATION: calibration_term(model)}
    for nm in cands:
        e = fx.get(nm)
        terms[nm] = Term(nm, tuple(e.param_specs(model, ctx)), e.description)
    pred = Predictor(model, ctx, terms)
    k_base = len(terms[CALIBRATION].params)
    k_max = k_base + max([len(terms[c].params) for c in cands] or [0])

    if kind == "deflection":
        n_obs = int(data.mask.sum())
        if n_obs <= k_max:
            raise VjmError(f"{os.path.basename(data.source)}: rows {int(data.rows[0])}-{int(data.rows[-1])}, "
                           f"columns dx..rz: {n_obs} measured values are fewer than the {k_max + 1} needed to fit "
                           f"the {k_max} parameters of the baseline plus one effect")
        has_t = data.mask[:, :3].any()
        has_r = data.mask[:, 3:].any()
        sigma_known = data.sigma_t is not None and (data.sigma_r is not None or not has_r)
        if sigma_known:
            sig_t = data.sigma_t
            sig_r = data.sigma_r if data.sigma_r is not None else np.ones(data.n)
            sigma_source = "from the file (sigma_t, sigma_r)"
        else:
            # relative weights of translations and rotations from the nominal model's residual scatter;
            # the common variance is then a nuisance parameter (F test, BIC with unknown variance)
            r0 = data.T - pred.twists((), np.zeros(0))
            st = data.sigma_t if data.sigma_t is not None else np.full(data.n, _robust_scale(r0[:, :3]) if has_t else 1.0)
            sr = data.sigma_r if data.sigma_r is not None else np.full(data.n, _robust_scale(r0[:, 3:]) if has_r else 1.0)
            sig_t, sig_r = st, sr
            sigma_source = "estimated from the residuals (F test)"
        prob = deflection_problem(pred, data, sig_t, sig_r, sigma_known, cands)
    else:
        n_obs = data.n
        if n_obs <= k_max:
            raise VjmError(f"{os.path.basename(data.source)}: rows {int(data.rows[0])}-{int(data.rows[-1])}, "
                           f"column 'value': {n_obs} observations are fewer than the {k_max + 1} needed to fit "
                           f"the {k_max} parameters of the baseline plus one effect")
        sigma_known = data.sigma_rel is not None
        sig_rel = data.sigma_rel if sigma_known else np.ones(data.n)
        sigma_source = "from the file (sigma_rel)" if sigma_known else "estimated from the residuals (F test)"
        prob = stiffness_problem(pred, data, sig_rel, sigma_known)

    # what this data can see.  The calibration first: a factor whose column is (nearly) a
    # combination of the ones before it (e.g. link_scale next to actuator_scale on postures near
    # Q0, where leg and actuator are in series along the same axis) is held at nominal
    cal_specs = terms[CALIBRATION].params
    th_cal = np.array([p.start for p in cal_specs])
    cal_free = observe.independent_columns(observe.calibration_columns(prob, th_cal, CALIBRATION))
    cal_held = {cal_specs[i].name: float(th_cal[i]) for i in range(len(cal_specs)) if i not in cal_free}
    if cal_held:
        pred.fixed[CALIBRATION] = (len(cal_specs), tuple(cal_free), list(th_cal))
        terms[CALIBRATION] = Term(CALIBRATION, tuple(cal_specs[i] for i in cal_free), terms[CALIBRATION].description)
        if log:
            log("calibration held at nominal (not separable on this data): " + ", ".join(cal_held))
    # then the candidates: those with no observable parameter are never fitted
    base0 = fit_terms(prob, (CALIBRATION,))
    cal_cols = observe.calibration_columns(prob, base0.theta, CALIBRATION)
    cal_q = observe._orth(cal_cols)
    sens, unobservable, full_terms = {}, {}, {}
    for nm in cands:
        ts = observe.term_sensitivity(prob, base0.theta, CALIBRATION, nm)
        sens[nm] = ts
        full_terms[nm] = terms[nm]
        if not ts.observable:
            unobservable[nm] = (f"not observable on this data: over its whole allowed range it changes the "
                                f"predictions by at most {float(np.max(ts.norms, initial=0.0)):.2g} sigma (root of the "
                                f"chi-square change); never fitted")
            continue
        # what is left of its signature once the calibration has done what it can
        part = observe.project_out(ts.Jfree, cal_q)
        left = float(np.max(np.linalg.norm(part, axis=0), initial=0.0))
        if left < observe.NOISE_NORM:
            unobservable[nm] = (f"not separable from the calibration on this data: what the calibration cannot "
                                f"imitate of it stays below {left:.2g} sigma over its whole range; never fitted")
        elif ts.fixed:
            specs = terms[nm].params
            pred.fixed[nm] = (len(specs), ts.free, [p.start for p in specs])
            terms[nm] = Term(nm, tuple(specs[i] for i in ts.free), terms[nm].description)
    tested = [c for c in cands if c not in unobservable]
    if log and unobservable:
        log("not observable on this data: " + ", ".join(unobservable))

    sel = forward_select(prob, tested, alpha=alpha, max_effects=max_effects, folds=folds, log=log, extra_tests=1)
    sel, rivals = _rival_check(prob, sel, tested, sens, cal_cols, alpha)
    # a named effect that another one (added or swapped in later) made redundant is dropped
    sel = backward_eliminate(prob, sel)
    # other explanations within Occam's window: each named effect swapped for its rivals, and the
    # pairs of candidates that a linearised screen ranks first (two effects that partly cancel are
    # each weak alone), then pruned; one with a lower BIC is named.  Clean data (nothing named)
    # are not searched: the selection's family-wise level stands
    swaps = {a: [b for b, d, _ in rivals.get(a, []) if np.isfinite(d)] for a in sel.selected}
    tries: list = []
    if sel.selected:
        first = sel.rounds[0]
        r0 = observe.project_out(prob.residuals(sel.baseline.names, sel.baseline.theta)[:, None], cal_q)[:, 0]
        cols = {c: observe.project_out(sens[c].Jfree, cal_q) for c in tested
                if c in first and first[c]["converged"] and not first[c]["clipped"]}
        tries = screen_pairs(r0, cols, PAIR_SCREEN)
    explanations = swap_alternatives(prob, sel, swaps, tries=tries)
    sel = explanations[0]
    rivals = {a: v for a, v in rivals.items() if a in sel.selected}
    base, final = sel.baseline, sel.final

    # lack of fit of the final model; its level shares alpha with the selection (Bonferroni)
    pe = _pure_error(prob, data, kind) if not sigma_known else None
    lof = lack_of_fit(final, pe)
    lof["alpha"] = alpha / (len(tested) + 1)
    lof["significant"] = bool(lof["p_value"] is not None and lof["p_value"] < lof["alpha"])

    # scale of the whitened residuals: 1 with known sigma, else the final model's residual variance
    s2 = 1.0 if sigma_known else final.chi2 / max(final.dof, 1)
    r_nom = prob.residuals((), np.zeros(0))
    chi2_nominal = float(r_nom @ r_nom / s2 / r_nom.size)
    chi2_before = float(base.chi2 / s2 / max(base.dof, 1))
    chi2_after = float(final.chi2 / s2 / max(final.dof, 1))

    # physical residuals for RMS and per-posture plots
    if kind == "deflection":
        mask = data.mask
        sigm = np.where(np.arange(6) < 3, sig_t[:, None], sig_r[:, None]) * np.sqrt(s2)

        def phys(names, theta):
            return data.T - pred.twists(names, theta)

        res_nom, res_base, res_fin = phys((), np.zeros(0)), phys(base.names, base.theta), phys(final.names, final.theta)
        tr = mask[:, :3].any()
        comp = slice(0, 3) if tr else slice(3, 6)
        units = "mm (translations)" if tr else "rad (rotations)"

        def rms_of(r):
            return _rms(np.where(mask[:, comp], r[:, comp], np.nan))

        rms_nom, rms_before, rms_after = rms_of(res_nom), rms_of(res_base), rms_of(res_fin)
        rn_base = np.where(mask, res_base / sigm, np.nan)
        rn_fin = np.where(mask, res_fin / sigm, np.nan)
        loc = localize(U, W, rn_base, mask, idx, q)
        per_before = _per_pose(rn_base, mask, idx, len(U))
        per_after = _per_pose(rn_fin, mask, idx, len(U))
    else:
        s = np.sqrt(s2)
        rw_b = prob.residuals(base.names, base.theta)  # ln(pred/obs) / sigma_rel
        rw_f = prob.residuals(final.names, final.theta)
        units = "relative (ln of predicted/observed)"
        rms_nom = _rms(r_nom * sig_rel)
        rms_before, rms_after = _rms(rw_b * sig_rel), _rms(rw_f * sig_rel)
        m1 = np.ones((data.n, 1), bool)
        loc = localize(U, np.zeros((data.n, 6)), (rw_b / s)[:, None], m1, idx, q)
        loc["by_quantity"] = {qn: _rms(rw_b[data.quantity == i] * sig_rel[data.quantity == i])
                              for i, qn in enumerate(("k_tran", "k_rot")) if np.any(data.quantity == i)}
        per_before = _per_pose((rw_b / s)[:, None], m1, idx, len(U))
        per_after = _per_pose((rw_f / s)[:, None], m1, idx, len(U))

    # updated model: calibration + named effects
    upd = apply_calibration(model, pred.full_theta(CALIBRATION, final.term_theta(prob, CALIBRATION)))
    for nm in sel.selected:
        upd = fx.get(nm).save(upd, pred.full_theta(nm, final.term_theta(prob, nm)))
    if kind == "deflection":
        loc_after = localize(U, W, rn_fin, mask, idx, q)
    else:
        loc_after = localize(U, np.zeros((data.n, 6)), (rw_f / s)[:, None], m1, idx, q)

    cand_rep = {}
    first = sel.rounds[0] if sel.rounds else {}
    for nm in cands:
        d = first.get(nm)
        if d is None:
            continue
        vals = d["fit"].values(prob)
        cand_rep[nm] = {"description": fx.get(nm).description, "kind": fx.get(nm).kind,
                        "delta_bic": d["delta_bic"], "p_value": d["p_value"], "cv_error": d["cv_error"],
                        "params": vals[nm], "named": nm in sel.selected, "observable": True,
                        "converged": bool(d["converged"]), "at_bound": list(d["clipped"]),
                        "threshold": d["threshold"]}
    for nm in sel.selected:
        i = sel.round_of(nm)
        d = sel.rounds[i][nm]
        cand_rep[nm]["selected_at_round"] = i + 1
        cand_rep[nm]["round_delta_bic"] = d["delta_bic"]
        cand_rep[nm]["round_p_value"] = d["p_value"]
        cand_rep[nm]["final_params"] = final.values(prob)[nm]
    dropped = {}
    for nm, (dchi2, dbic, p) in sel.dropped.items():
        cand_rep[nm]["dropped"] = {"delta_chi2": dchi2, "delta_bic": dbic, "p_value": p}
        dropped[nm] = (f"{nm} was selected, then dropped: with {', '.join(sel.selected) or 'the calibration'} in "
                       f"the model it is no longer needed (removing it raises chi-square by {dchi2:.1f}, p = {p:.2g}, "
                       f"BIC change {dbic:+.1f})")
    for nm, why in {**skipped, **unobservable}.items():
        cand_rep[nm] = {"description": fx.get(nm).description, "skipped": why, "delta_bic": None,
                        "p_value": None, "cv_error": None, "params": {}, "named": False,
                        "observable": nm not in unobservable if nm in sens else None}
    for nm, ts in sens.items():
        specs = full_terms[nm].params
        cand_rep[nm]["sensitivity"] = {p.name: float(v) for p, v in zip(specs, ts.norms)}
        if ts.fixed and ts.observable:
            cand_rep[nm]["fixed"] = {specs[i].name: float(specs[i].start) for i in ts.fixed}

    conf = _confounding(prob, sel, sens, cal_cols, cand_rep, alpha, rivals)
    flags = _flags(prob, sel, final, cand_rep) + workspace_flags(model, data)
    for k, v in cal_held.items():
        flags.append(f"calibration {k} held at {v:g}: on this data it cannot be told apart from "
                     f"{', '.join(p.name for p in prob.terms[CALIBRATION].params)}")
    cal_names = [p.name for p in prob.terms[CALIBRATION].params]
    for i in range(len(cal_names)):
        for j in range(i + 1, len(cal_names)):
            c = observe.canonical_correlation(cal_cols[:, [i]], cal_cols[:, [j]])
            if c >= COLLINEAR:
                flags.append(f"calibration {cal_names[i]} and {cal_names[j]} cannot be told apart on this data "
                             f"(correlation {c:.3f}): their values are not to be trusted separately")
    named = list(sel.selected)
    if lof["significant"]:
        verdict = "unexplained"
    elif named:
        verdict = "explained"
    else:
        verdict = "no_discrepancy"

    final_vals = final.values(prob)
    rep = {
        "model": model_name, "data": os.path.basename(str(data.source)), "data_kind": kind,
        "n_observations": int(prob.n), "n_postures": int(len(U)),
        "named_effects": list(sel.selected),
        "rms_before": rms_before, "rms_after": rms_after, "rms_nominal": rms_nom, "rms_units": units,
        "chi2_before": chi2_before, "chi2_after": chi2_after, "chi2_nominal": chi2_nominal,
        "chi2_definition": "reduced chi-square: sum of squared normalized residuals / (n - fitted parameters); "
                           "'before' = nominal parameters recalibrated, no effect",
        "sigma_source": sigma_source, "sigma_known": bool(sigma_known),
        "test": "likelihood-ratio chi2 test" if sigma_known else "F test",
        "alpha": alpha, "cv_baseline": sel.cv_baseline, "cv_folds": folds,
        "calibration": final_vals[CALIBRATION],
        "calibration_held": cal_held,
        "final_params": final_vals,
        "localization": loc,
        "localization_after": loc_after,
        "candidates": cand_rep,
        "verdict": verdict,
        "lack_of_fit": lof,
        "confounded": conf["groups"],
        "alternatives": [{"named_effects": list(x.selected), "delta_bic": float(x.final.bic - final.bic),
                          "chi2_red": float(x.final.chi2 / s2 / max(x.final.dof, 1))} for x in explanations[1:]],
        "alternatives_window": OCCAM_WINDOW,
        "confounding": conf["details"],
        "unobservable": unobservable,
        "dropped": dropped,
        "flags": flags,
        "n_tested": len(tested),
    }
    nxt = None
    if suggest:
        if kind != "deflection":
            raise VjmError("--suggest needs deflection data (x,y,z,Fx..Mz,dx..rz): stiffness observations "
                           "have no loads to design")
        from .suggest import suggest as _suggest

        vals = {}
        for nm in cands:
            d = first.get(nm)
            if d is not None:
                vals[nm] = d["fit"].term_theta(prob, nm)
        for nm in final.names:
            vals[nm] = final.term_theta(prob, nm)
        mcomp = np.flatnonzero(mask.any(axis=0))
        sd = np.where(mask, sigm, np.inf)[:, mcomp]
        sp = np.median(sigm[:, mcomp], axis=0)
        sg = _suggest(model, pred, (mcomp, sd, sp), vals, rep, int(suggest), forces_only)
        nxt = sg.rows
        rep["suggest"] = {"n": int(suggest), "file": "next_measurements.csv", "criterion": sg.criterion,
                          "targets": sg.targets, "criterion_before": sg.before, "criterion_after": sg.after,
                          "forces_only": bool(forces_only)}
    rep["summary"] = summary(rep)
    return Diagnosis(rep, upd, U, per_before, per_after, nxt, covariance.record(prob, pred, final))


#: pairs of candidates fitted after the selection, the first of a linearised screen (fit/select.py screen_pairs)
PAIR_SCREEN = 5
#: canonical correlation (calibration projected out) above which two candidates are reported as one group
COLLINEAR = 0.99
#: ... and, for a named effect, the lower correlation at which an alternative that fits almost as well joins it
NEAR_COLLINEAR = 0.9
#: an effect not named whose signature lies in the named ones' (COLLINEAR) joins their group when it
#: could carry at least this fraction of what they explain along it without the fit getting worse
#: by the chi-square(1) (1 - alpha) quantile
HIDDEN_SHARE = 0.1
#: the calibration "mimics" a candidate when its columns reproduce the candidate's with this correlation
MIMIC = 0.95
#: calibration factors outside this range are implausibly far from the nominal values
PLAUSIBLE = (0.5, 2.0)


def _pure_error(prob, data, kind):
    """(SS, dof) of repeated measurements (same posture and load) in the problem's whitened units, or None."""
    r = prob.residuals((), np.zeros(0))  # any fixed prediction: the within-group scatter of r is that of y
    if kind == "deflection":
        key = np.hstack([np.round(data.P, 6), np.round(data.W, 9)])
        _, g = np.unique(key, axis=0, return_inverse=True)
        mask = data.mask
        comp = np.broadcast_to(np.arange(6), mask.shape)[mask]
        grp = np.broadcast_to(g.reshape(-1, 1), mask.shape)[mask] * 6 + comp
    else:
        key = np.hstack([np.round(data.P, 6), data.quantity[:, None]])
        _, grp = np.unique(key, axis=0, return_inverse=True)
    grp = np.asarray(grp).reshape(-1)
    cnt = np.bincount(grp)
    dof = int(np.sum(np.maximum(cnt - 1, 0)))
    if dof == 0:
        return None
    mean = np.bincount(grp, r) / np.maximum(cnt, 1)
    ss = float(np.sum((r - mean[grp]) ** 2))
    return ss, dof


def _rival_check(prob, sel, tested, sens, cal_cols, alpha):
    """Each named effect against its rivals, with the OTHER named effects in the model.

    Forward selection compares candidates one round at a time, so an effect can
    win its round only because a second effect was not in the model yet.  Here
    every named effect A is swapped for each tested candidate B whose signature
    is correlated with A's (partial correlation >= NEAR_COLLINEAR) and the
    model refitted: B with a lower BIC replaces A; B within the chi-square(1)
    (1 - alpha) margin is a rival the data cannot exclude.  Returns the
    (possibly updated) selection and ``{A: [(B, chi2_B - chi2_A, corr), ...]}``
    over every B checked (fits that failed or were clipped have ``inf``).
    """
    import dataclasses

    Q = observe._orth(cal_cols)

    def corr(a, b):
        ra, rb = observe.project_out(sens[a].Jfree, Q), observe.project_out(sens[b].Jfree, Q)
        if np.linalg.norm(ra) <= 1e-6 * np.linalg.norm(sens[a].Jfree) or \
                np.linalg.norm(rb) <= 1e-6 * np.linalg.norm(sens[b].Jfree):
            return 0.0
        return observe.canonical_correlation(ra, rb)

    selected, final = list(sel.selected), sel.final
    rivals: dict = {}
    for k in range(len(selected)):
        a = selected[k]
        checked = []
        for b in tested:
            if b in final.names:
                continue
            c = corr(a, b)
            if c < NEAR_COLLINEAR:
                continue
            others = tuple(x for x in final.names if x != a)
            fb = fit_terms(prob, others + (b,), warm=final)
            ok = fb.success and not clipped(prob, fb, b)
            checked.append((b, (fb.chi2 - final.chi2) if ok else float("inf"), c, fb if ok else None))
        # swap on BIC, as the selection chose (a rival with more parameters must fit better by more)
        best = min((t for t in checked if t[3] is not None), key=lambda t: t[3].bic, default=None)
        if best is not None and best[3].bic < final.bic:
            # the rival explains the data better with the other named effects in place: swap
            b, d, c, fb = best
            selected[k] = b
            checked = [(a, -d, c, final)] + [(x, dx - d, cx, f) for x, dx, cx, f in checked if x != b]
            final, a = fb, b
        rivals[a] = [(x, dx, cx) for x, dx, cx, _ in checked]
    if selected != list(sel.selected):
        sel = dataclasses.replace(sel, selected=tuple(selected), final=final)
    return sel, rivals


def _named_signal(prob, final, named, Q):
    """What the named effects explain: the whitened residuals with them at their null values minus
    the final ones (the other terms at their final values), the calibration's span ``Q`` projected out."""
    th = [np.array([p.null for p in prob.terms[nm].params]) if nm in named else final.term_theta(prob, nm)
          for nm in final.names]
    s = prob.residuals(final.names, np.concatenate(th)) - prob.residuals(final.names, final.theta)
    return observe.project_out(s[:, None], Q)[:, 0]


def _confounding(prob, sel, sens, cal_cols, cand_rep, alpha, rivals=None):
    """Groups of candidates this data cannot tell apart, and candidates the calibration can mimic.

    * two observable candidates whose signatures, with the calibration's
      projected out, have a canonical correlation >= COLLINEAR form a group
      whatever the data's outcome (the design cannot separate them);
    * a named effect A and a candidate B of its selection round whose fit is
      not worse by a (1 - alpha) chi-square(1) margin and whose partial
      correlation with A is >= NEAR_COLLINEAR: "A or B";
    * a candidate B not named whose signature lies in the span of the named
      effects' (multiple correlation >= COLLINEAR, calibration projected out)
      and that could carry at least HIDDEN_SHARE of what they explain along
      it within the margin and within its own parameter range
      (:func:`observe.hiding_share`): grouped with the named effect(s) that
      imitate it, even where the swap test separated them (B cannot replace
      A, but may be present besides it);
    * a candidate whose signature the calibration reproduces (correlation
      >= MIMIC) is noted with the calibration change that imitates it, and
      grouped with "calibration" when it was not named and the calibration is
      flagged (at a bound or implausibly far from nominal): the calibration
      may have absorbed it.

    A pair that the selection did separate (a named effect whose rival fitted
    worse by more than the chi-square(1) margin in its round, or could not
    fit) is not grouped by the first rule, however collinear the linearised
    signatures; a rival with several parameters that could not fit at all
    is not grouped by the third either (a one-parameter rival on its bound
    only ran out of range).
    """
    names = [n for n, ts in sens.items() if ts.observable and cand_rep.get(n, {}).get("p_value") is not None]
    Q = observe._orth(cal_cols)
    resid = {n: observe.project_out(sens[n].Jfree, Q) for n in names}
    raw = {n: np.linalg.norm(sens[n].Jfree) for n in names}
    details = []
    parent = {n: n for n in names}

    def find(a):
        while parent[a] != a:
            a = parent[a]
        return a

    def corr(a, b):
        if np.linalg.norm(resid[a]) <= 1e-6 * raw[a] or np.linalg.norm(resid[b]) <= 1e-6 * raw[b]:
            return 0.0
        return observe.canonical_correlation(resid[a], resid[b])

    def span_corr(b, among):
        """Multiple (canonical) correlation of b's signature with the joint span of ``among``'s."""
        among = [a for a in among if np.linalg.norm(resid[a]) > 1e-6 * raw[a]]
        if not among or np.linalg.norm(resid[b]) <= 1e-6 * raw[b]:
            return 0.0
        return observe.canonical_correlation(resid[b], np.hstack([resid[a] for a in among]))

    # pairs the data did separate: a named effect whose rival fitted worse, in its round, by more
    # than a (1 - alpha) chi-square(1) margin (or could not fit at all)
    margin = float(stats.chi2.ppf(1.0 - alpha, 1))
    separated, unfit = set(), set()  # unfit: the rival could not fit at all in the named effect's place
    for a, checked in (rivals or {}).items():
        for b, d, _ in checked:
            if d >= margin:
                separated.add(frozenset((a, b)))
            if not np.isfinite(d):
                unfit.add(frozenset((a, b)))
    for a in sel.selected:  # rivals not re-checked: the selection round's evidence
        r = sel.round_of(a)
        info = sel.rounds[r] if r < len(sel.rounds) else {}
        if a not in info:
            continue
        for b, d in info.items():
            done = any(b == x for x, _, _ in (rivals or {}).get(a, []))
            if b != a and not done and (d["fit"].chi2 - info[a]["fit"].chi2 >= margin or not d["converged"]
                                        or d["clipped"]):
                separated.add(frozenset((a, b)))
            if b != a and not done and (not d["converged"] or d["clipped"]):
                unfit.add(frozenset((a, b)))
    pair_c = {}
    for i, a in enumerate(names):
        for b in names[i + 1:]:
            if frozenset((a, b)) in separated:
                continue
            c = corr(a, b)
            if c >= COLLINEAR:
                parent[find(b)] = find(a)
                pair_c[(a, b)] = c
    groups = {}
    for n in names:
        groups.setdefault(find(n), []).append(n)
    out = [g for g in groups.values() if len(g) > 1]
    for g in out:
        cs = [c for (a, b), c in pair_c.items() if a in g]
        details.append({"names": list(g), "correlation": min(cs),
                        "why": f"{' or '.join(g)}: this data cannot tell them apart (signature correlations "
                               f"{min(cs):.3f}-{max(cs):.3f} once the calibration is projected out)"})

    for a in sel.selected:
        alt = []
        for b, d, c in (rivals or {}).get(a, []):
            if b in resid and d < margin:
                alt.append(b)
                details.append({"names": [a, b], "correlation": c,
                                "why": f"{a} or {b}: this data cannot tell them apart (signature correlation "
                                       f"{c:.3f}; with the other named effects in place {b} fits worse by only "
                                       f"{d:.1f} in chi-square)"})
        if alt:
            grp = next((g for g in out if a in g), None)
            if grp is None:
                out.append([a] + alt)
            else:
                grp.extend(b for b in alt if b not in grp)

    # an effect not named can hide *inside* the named ones: a named effect with several parameters
    # imitates it with one of them, or two named effects do it together.  The swap test above
    # only shows whether it can replace a named effect entirely, not whether it can be present
    # besides it: it joins the group when the data cannot exclude that it carries a tenth or
    # more of what the named effects explain along its signature
    named = [a for a in sel.selected if a in resid]
    sig = _named_signal(prob, sel.final, named, Q) if named else None
    z = float(np.sqrt(margin))
    for b in names:
        if b in sel.selected or not named or np.linalg.norm(resid[b]) <= 1e-6 * raw[b]:
            continue
        specs = prob.terms[b].params  # the observable (fitted) parameters: the columns of resid[b]
        R, share = observe.hiding_share(resid[b], np.hstack([resid[a] for a in named]), sig, z,
                                        [observe.reach(p) for p in specs])
        if R < COLLINEAR or share < HIDDEN_SHARE:
            continue
        # the named effects it cannot do without (or, when any subset imitates it, the closest one)
        carriers = [a for a in named if span_corr(b, [x for x in named if x != a]) < COLLINEAR]
        for a in carriers or [max(named, key=lambda a: corr(a, b))]:
            grp = next((g for g in out if a in g), None)
            # a linearised imitation the fit itself could not reach (out of range, no convergence):
            # with one parameter (its size) b only needed more than its range to replace a, which
            # the share's range cap accounts for; with several, a bound can mean its shape does not fit
            if (grp is not None and b in grp) or (frozenset((a, b)) in unfit and len(specs) > 1):
                continue
            if grp is None:
                out.append([a, b])
            else:
                grp.append(b)
            with_ = f" with {', '.join(x for x in named if x != a)}" if len(named) > 1 else ""
            part = "all" if share >= 1.0 else f"{100 * share:.0f} %"
            details.append({"names": [a, b], "correlation": R, "share": share,
                            "why": f"{a} or {b}: this data cannot tell them apart (the signature of {b} lies in that "
                                   f"of {a}{with_}, multiple correlation {R:.4f} once the calibration is projected "
                                   f"out: {b} could carry {part} of what the named effects explain along it, "
                                   f"unseen)"})

    cal_params = prob.terms["calibration"].params
    cal_fit = sel.final.term_theta(prob, "calibration")
    cal_flag = any(not (PLAUSIBLE[0] <= v <= PLAUSIBLE[1]) for v in cal_fit) or bool(clipped(prob, sel.final, "calibration"))
    for n in names:
        R, coef = observe.mimicry(sens[n].Jfree, cal_cols)
        if R < MIMIC:
            continue
        c = cand_rep.get(n, {})
        # the calibration change imitating the candidate at its round-1 fitted value (or one typical step)
        ps = prob.terms[n].params
        if c.get("params"):
            dth = np.array([c["params"][p.name]["value"] - p.null for p in ps])
        else:
            dth = np.array([p.scale for p in ps])
        spans = np.array([observe.span(p) for p in ps])
        dcal = (coef @ (dth / spans)) * np.array([p.scale for p in cal_params])
        looks = {p.name: float(p.null + v) for p, v in zip(cal_params, dcal)}
        words = ", ".join(f"{k} = {v:.3g}" for k, v in looks.items())
        c["mimicked_by_calibration"] = {"correlation": R, "looks_like": looks}
        # a named effect was significant on top of the calibration: the data did separate them
        if n not in sel.selected and cal_flag:
            out.append([n, "calibration"])
            details.append({"names": [n, "calibration"], "correlation": R,
                            "why": f"{n} or calibration: on these postures and loads {n} looks like a calibration "
                                   f"change ({words}; correlation {R:.3f})"})
    return {"groups": out, "details": details}


def _flags(prob, sel, final, cand_rep):
    """Warnings: calibration at a bound or far from nominal, fits that did not converge or were clipped."""
    flags = []
    vals = final.values(prob)["calibration"]
    at = set(clipped(prob, final, "calibration"))
    for k, v in vals.items():
        if k in at:
            flags.append(f"calibration {k} = {v['value']:.3g} is at a bound of its range: the calibration is "
                         "absorbing something it should not (a missing effect or a wrong model)")
        elif not (PLAUSIBLE[0] <= v["value"] <= PLAUSIBLE[1]):
            flags.append(f"calibration {k} = {v['value']:.3g} +- {Z95 * v['se']:.2g} is implausibly far from nominal "
                         f"(outside {PLAUSIBLE[0]}-{PLAUSIBLE[1]}x): check the model or a missing effect it absorbs")
    for r, info in enumerate(sel.rounds):
        for nm, d in info.items():
            if not d["converged"]:
                flags.append(f"round {r + 1}: the fit of {nm} did not converge ({d['fit'].message}); not named")
            elif d["clipped"] and d["p_value"] < d["threshold"]:
                flags.append(f"round {r + 1}: {nm} ended with {', '.join(d['clipped'])} on a bound of its range; "
                             "not named (the effect's shape or range does not fit the data)")
    return flags


def _per_pose(rn, mask, idx, m):
    r2 = np.where(mask, np.nan_to_num(rn) ** 2, 0.0).sum(axis=1)
    c = mask.sum(axis=1)
    num = np.bincount(idx, r2, minlength=m)
    den = np.bincount(idx, c, minlength=m)
    return np.sqrt(num / np.maximum(den, 1))


def summary(rep) -> str:
    """The one-paragraph terminal summary."""
    cal = rep["calibration"]
    cal_s = ", ".join(f"{k} {v['value']:.3g} +- {Z95 * v['se']:.2g}" for k, v in cal.items())
    parts = [verdict_line(rep)]
    for nm in rep["named_effects"]:
        c = rep["candidates"][nm]
        ps = ", ".join(f"{k} = {v['value']:.4g} +- {Z95 * v['se']:.2g} {v['unit']}" for k, v in c["final_params"].items())
        parts.append(f"{nm}: {ps} (round dBIC {c['round_delta_bic']:.1f}, p = {c['round_p_value']:.2g}).")
    for why in rep.get("dropped", {}).values():
        parts.append(why + ".")
    for d in rep.get("confounding", []):
        parts.append(d["why"] + ".")
    parts += [a + "." for a in alternative_lines(rep)]
    if rep["verdict"] == "unexplained":
        parts.append(f"Where the remaining gap is: {rep['localization_after']['summary']}.")
    for f in rep.get("flags", []):
        parts.append(f"Warning: {f}.")
    if rep.get("unobservable"):
        parts.append("Not observable on this data (not fitted): " + ", ".join(rep["unobservable"]) + ".")
    return (" ".join(parts[:1]) + f" {rep['n_observations']} observations at {rep['n_postures']} postures "
            f"({rep['data_kind']} data, sigma {rep['sigma_source']}); baseline calibration: {cal_s}. "
            + " ".join(parts[1:]) +
            f" RMS {rep['rms_nominal']:.3g} (nominal) -> {rep['rms_before']:.3g} (calibrated) -> {rep['rms_after']:.3g} "
            f"{rep['rms_units']}; reduced chi2 {rep['chi2_nominal']:.3g} -> {rep['chi2_before']:.3g} -> "
            f"{rep['chi2_after']:.3g}. Gap before naming: {rep['localization']['summary']}.")


def write_diagnosis(dg: Diagnosis, out_dir, force: bool = False) -> None:
    """Write report.json, report.html, the PNGs and model_updated.yaml as one set (see write_report_dir)."""
    def figs(path_of):
        plot_before_after(path_of("before_after.png"), dg.rms_pose_before, dg.rms_pose_after, dg.verdict)
        plot_residuals(path_of("residuals_per_posture.png"), dg.P, dg.rms_pose_before, dg.rms_pose_after,
                       "residual per posture: before vs after")
        if dg.next_measurements is not None:
            write_design(path_of("next_measurements.csv"), dg.next_measurements,
                         "next measurements suggested by vjm diagnose: " + dg.report["suggest"]["criterion"])
        return ["before_after.png", "residuals_per_posture.png"]

    write_report_dir(out_dir, dg.report, lambda p: covariance.save_model_with(dg.model, dg.covariance, p), figs,
                     force=force)


def run(model_path, data_path, out_dir, force: bool = False, **kw) -> Diagnosis:
    """Check the arguments and the output folder, load, diagnose and write: the body of ``vjm diagnose``."""
    check_arguments(**{k: v for k, v in kw.items() if k in ("alpha", "folds", "max_effects", "suggest")})
    check_report_dir(out_dir, force)
    model, data = mo.load_model(model_path), read_csv(data_path)
    dg = diagnose(model, data, model_name=os.path.basename(str(model_path)), **kw)
    write_diagnosis(dg, out_dir, force=force)
    return dg

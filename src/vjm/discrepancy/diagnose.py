"""The discrepancy workflow: calibrate, locate, name, add, show.

:func:`diagnose` takes a model and a data set and returns a
:class:`Diagnosis` (report dictionary + updated model + per-posture residuals);
:func:`write_diagnosis` writes it to a directory atomically.
"""
from __future__ import annotations

import os
from dataclasses import dataclass

import numpy as np

from ..errors import VjmError
from . import effects as fx
from . import modelops as mo
from .data import StiffnessObs, read_csv
from .fit.select import Z95, Term, forward_select
from .locate import localize
from .predict import (
    CALIBRATION,
    Context,
    Predictor,
    apply_calibration,
    calibration_term,
    deflection_problem,
    stiffness_problem,
    unique_postures,
)
from .report import plot_residuals, write_report_dir

DEFAULT_ALPHA = 0.01


@dataclass(frozen=True)
class Diagnosis:
    report: dict
    model: object  # updated model
    P: np.ndarray  # unique postures
    rms_pose_before: np.ndarray  # normalized RMS per posture, calibrated baseline
    rms_pose_after: np.ndarray


def _check_reachable(model, data):
    """Unique postures, index; raises naming the first unreachable row."""
    U, idx = unique_postures(data.P)
    try:
        q = mo.actuator_coords(model, U)
    except VjmError:
        q = None
    if q is None or not np.all(np.isfinite(q)):
        for k in range(data.n):
            try:
                qq = mo.actuator_coords(model, data.P[k:k + 1])
                if not np.all(np.isfinite(qq)):
                    raise VjmError("no finite inverse kinematics")
            except VjmError as exc:
                row = int(data.rows[k]) if data.rows is not None else k + 2
                raise VjmError(f"{os.path.basename(data.source)}: row {row}, columns 'x,y,z': posture "
                               f"({data.P[k, 0]:g}, {data.P[k, 1]:g}, {data.P[k, 2]:g}) mm is unreachable: {exc}") from None
        raise VjmError(f"{os.path.basename(data.source)}: a posture is unreachable")
    return U, idx, q


def _rows_for_architecture(data: StiffnessObs, model) -> StiffnessObs:
    """Keep the rows of a stiffness table whose ``architecture`` column names the model's (if any)."""
    arch = data.extra.get("architecture")
    if arch is None:
        return data
    keep = np.array([a.strip() == model.architecture for a in arch])
    if not keep.any():
        raise VjmError(f"{os.path.basename(data.source)}: column 'architecture': no row for "
                       f"{model.architecture} (found {', '.join(sorted(set(arch)))})")
    ex = {k: [x for x, kk in zip(v, keep) if kk] for k, v in data.extra.items()}
    return StiffnessObs(data.P[keep], data.quantity[keep], data.value[keep],
                        None if data.sigma_rel is None else data.sigma_rel[keep],
                        None if data.rows is None else data.rows[keep], data.source, ex)


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
             model_name: str = "<model>", log=None) -> Diagnosis:
    """Run the workflow on a loaded model and a data set (:func:`read_csv` output).

    Parameters
    ----------
    alpha : family-wise significance level of each selection round.
    effects : candidate names (default: the whole registry).
    """
    kind = "stiffness" if isinstance(data, StiffnessObs) else "deflection"
    if kind == "stiffness":
        data = _rows_for_architecture(data, model)
    U, idx, q = _check_reachable(model, data)
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
        terms[nm] = Term(nm, tuple(e.param_specs(model)), e.description)
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

    sel = forward_select(prob, cands, alpha=alpha, max_effects=max_effects, folds=folds, log=log)
    base, final = sel.baseline, sel.final

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
    upd = apply_calibration(model, final.term_theta(prob, CALIBRATION))
    for nm in sel.selected:
        upd = fx.get(nm).save(upd, final.term_theta(prob, nm))

    cand_rep = {}
    first = sel.rounds[0] if sel.rounds else {}
    for nm in cands:
        d = first.get(nm)
        if d is None:
            continue
        vals = d["fit"].values(prob)
        cand_rep[nm] = {"description": fx.get(nm).description, "kind": fx.get(nm).kind,
                        "delta_bic": d["delta_bic"], "p_value": d["p_value"], "cv_error": d["cv_error"],
                        "params": vals[nm], "named": nm in sel.selected}
    for i, nm in enumerate(sel.selected):
        d = sel.rounds[i][nm]
        cand_rep[nm]["selected_at_round"] = i + 1
        cand_rep[nm]["round_delta_bic"] = d["delta_bic"]
        cand_rep[nm]["round_p_value"] = d["p_value"]
        cand_rep[nm]["final_params"] = final.values(prob)[nm]
    for nm, why in skipped.items():
        cand_rep[nm] = {"description": fx.get(nm).description, "skipped": why, "delta_bic": None,
                        "p_value": None, "cv_error": None, "params": {}}

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
        "final_params": final_vals,
        "localization": loc,
        "candidates": cand_rep,
    }
    rep["summary"] = summary(rep)
    return Diagnosis(rep, upd, U, per_before, per_after)


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
    if rep["named_effects"]:
        parts = []
        for nm in rep["named_effects"]:
            c = rep["candidates"][nm]
            ps = ", ".join(f"{k} = {v['value']:.4g} +- {Z95 * v['se']:.2g} {v['unit']}" for k, v in c["final_params"].items())
            parts.append(f"{nm} ({ps}; round dBIC {c['round_delta_bic']:.1f}, p = {c['round_p_value']:.2g})")
        verdict = "Missing effect(s) named: " + "; ".join(parts) + "."
    else:
        verdict = f"No missing effect: no candidate is significant at alpha = {rep['alpha']}."
    return (f"{rep['n_observations']} observations at {rep['n_postures']} postures ({rep['data_kind']} data, "
            f"sigma {rep['sigma_source']}). Baseline calibration: {cal_s}. {verdict} "
            f"RMS {rep['rms_nominal']:.3g} (nominal) -> {rep['rms_before']:.3g} (calibrated) -> {rep['rms_after']:.3g} "
            f"{rep['rms_units']}; reduced chi2 {rep['chi2_nominal']:.3g} -> {rep['chi2_before']:.3g} -> "
            f"{rep['chi2_after']:.3g}. Gap located: {rep['localization']['summary']}.")


def write_diagnosis(dg: Diagnosis, out_dir) -> None:
    """Write report.json, report.html, residuals PNG and model_updated.yaml atomically."""
    def figs(d):
        plot_residuals(os.path.join(d, "residuals_per_posture.png"), dg.P, dg.rms_pose_before, dg.rms_pose_after,
                       "residual per posture: before vs after")
        return ["residuals_per_posture.png"]

    write_report_dir(out_dir, dg.report, lambda p: mo.save_model(dg.model, p), figs)


def run(model_path, data_path, out_dir, **kw) -> Diagnosis:
    """Load, diagnose and write: the body of ``vjm diagnose``."""
    model = mo.load_model(model_path)
    data = read_csv(data_path)
    dg = diagnose(model, data, model_name=os.path.basename(str(model_path)), **kw)
    write_diagnosis(dg, out_dir)
    return dg

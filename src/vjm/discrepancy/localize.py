"""Where do model and measurements disagree?

Normalized residuals (residual / sigma) are summarised as RMS values grouped
by posture, by the dominant load direction and sign, by load magnitude and by
each actuator coordinate.  A group whose RMS is much larger than the overall
RMS is where the disagreement is concentrated.
"""
from __future__ import annotations

import numpy as np

from linkfea.mechanics.compliance import WRENCH as WRENCH_NAMES

from .loads import by_level, growth_words, load_levels


def _rms(r2_sum, cnt):
    return float(np.sqrt(r2_sum / cnt)) if cnt else float("nan")


def _group_rms(labels, r2, cnt):
    """RMS per label of per-measurement squared sums ``r2`` over ``cnt`` components."""
    out = {}
    for lab in np.unique(labels):
        m = labels == lab
        out[lab] = (_rms(r2[m].sum(), cnt[m].sum()), int(m.sum()))
    return out


def _bins(v, nb=4):
    """Quantile bin index (0..nb-1) and edges of values ``v``."""
    edges = np.unique(np.quantile(v, np.linspace(0, 1, nb + 1)))
    if edges.size < 2:
        return np.zeros(v.size, int), np.array([v.min(), v.max()])
    idx = np.clip(np.searchsorted(edges, v, side="right") - 1, 0, edges.size - 2)
    return idx, edges


def localize(P, W, rnorm, mask, pose_idx, q=None, top=5, tnorm=None) -> dict:
    """Summarise normalized residuals.

    Parameters
    ----------
    P : (m, 3) unique postures (or (m, 6) with the orientation ox, oy, oz of a 6-dof platform);
        ``pose_idx`` (n,) maps measurements to them.
    W : (n, 6) applied wrenches.
    rnorm : (n, 6) normalized residuals (NaN/ignored where ``mask`` is False).
    mask : (n, 6) measured components.
    q : optional (m, k) actuator coordinates of the unique postures (mm or rad).
    tnorm : optional (n, 6) the model's own deflections / sigma: with load levels, the residual along
        them per level (how much softer or stiffer the data are than the model at each level).
    """
    r2 = np.where(mask, np.nan_to_num(rnorm) ** 2, 0.0).sum(axis=1)
    cnt = mask.sum(axis=1)
    overall = _rms(r2.sum(), cnt.sum())
    out = {"overall_rms_normalized": overall}

    per = _group_rms(pose_idx, r2, cnt)
    keys = ("x", "y", "z", "ox", "oy", "oz")[:P.shape[1]]
    posture = [{**{k: float(P[i, j]) for j, k in enumerate(keys)},
                "rms_normalized": v[0], "n": v[1]} for i, v in sorted(per.items())]
    out["by_posture"] = posture
    out["worst_postures"] = sorted(posture, key=lambda d: -d["rms_normalized"])[:top]

    if not np.any(W):  # stiffness observations: no load to group by
        if q is not None:
            out.update(_by_actuator(q, pose_idx, r2, cnt))
        out["summary"] = _summary(out)
        return out
    dom = np.argmax(np.abs(W) / np.where(np.arange(6) < 3, 1.0, 100.0), axis=1)  # moments in N mm vs N: 100 mm arm
    sgn = np.sign(W[np.arange(W.shape[0]), dom])
    labels = np.array([("+" if s >= 0 else "-") + WRENCH_NAMES[d] for d, s in zip(dom, sgn)])
    out["by_load_direction"] = {k: {"rms_normalized": v[0], "n": v[1]} for k, v in _group_rms(labels, r2, cnt).items()}

    out["by_load_sign"] = _odd_even(W, rnorm, mask, pose_idx)

    fmag = np.linalg.norm(W[:, :3], axis=1)
    bi, edges = _bins(fmag)
    g = _group_rms(bi, r2, cnt)
    out["by_load_magnitude"] = [{"force_N": [float(edges[b]), float(edges[b + 1])], "rms_normalized": v[0], "n": v[1]}
                                for b, v in sorted(g.items())]
    lv = load_levels(W)
    if lv is not None:  # a few distinct magnitudes: the residual per level (a load-dependent stiffness shows)
        out["by_load_level"] = by_level(lv, W, rnorm, mask, tnorm)
    if q is not None:
        out.update(_by_actuator(q, pose_idx, r2, cnt))
    out["summary"] = _summary(out)
    return out


def _odd_even(W, rnorm, mask, pose_idx):
    """Split residuals of opposite-load pairs (same posture, w and -w) into the part that
    follows the load sign (odd: compliance, clearance) and the part that does not
    (even: weight, quadratic nonlinearity), as RMS normalized values."""
    key = {}
    for k in range(W.shape[0]):
        key[(int(pose_idx[k]), tuple(np.round(W[k], 9)))] = k
    odd, even = [], []
    for (pi, w), k in key.items():
        j = key.get((pi, tuple(np.round(-np.array(w), 9))))
        if j is None or j <= k:
            continue
        m = mask[k] & mask[j]
        odd.append(0.5 * (rnorm[k] - rnorm[j])[m])
        even.append(0.5 * (rnorm[k] + rnorm[j])[m])
    if not odd:
        return {"pairs": 0}
    o, e = np.concatenate(odd), np.concatenate(even)
    # under pure noise both parts have RMS 1/sqrt(2) of the normalized residual
    return {"pairs": len(odd), "odd_rms_normalized": float(np.sqrt(np.mean(o * o)) * np.sqrt(2)),
            "even_rms_normalized": float(np.sqrt(np.mean(e * e)) * np.sqrt(2))}


def _by_actuator(q, pose_idx, r2, cnt):
    qa = np.asarray(q)[pose_idx]
    act = {}
    for j in range(qa.shape[1]):
        bi, edges = _bins(qa[:, j])
        g = _group_rms(bi, r2, cnt)
        act[f"q{j + 1}"] = [{"range": [float(edges[b]), float(edges[b + 1])], "rms_normalized": v[0], "n": v[1]}
                            for b, v in sorted(g.items())]
    return {"by_actuator": act}


def _summary(loc) -> str:
    """One sentence naming the groups where the RMS is most above the overall level."""
    ov = loc["overall_rms_normalized"]
    if not np.isfinite(ov) or ov <= 0:
        return "no residuals"
    parts = []
    w = loc["worst_postures"][0] if loc["worst_postures"] else None
    if w:
        tilt = f" at orientation ({w['ox']:.3g}, {w['oy']:.3g}, {w['oz']:.3g}) rad" if "ox" in w else ""
        parts.append(f"worst posture ({w['x']:.1f}, {w['y']:.1f}, {w['z']:.1f}) mm{tilt} at "
                     f"{w['rms_normalized'] / ov:.1f}x the overall RMS")
    d = loc.get("by_load_direction")
    if d:
        k = max(d, key=lambda s: d[s]["rms_normalized"])
        parts.append(f"largest for loads along {k} ({d[k]['rms_normalized'] / ov:.1f}x)")
    ls = loc.get("by_load_sign", {})
    if ls.get("pairs"):
        o, e = ls["odd_rms_normalized"], ls["even_rms_normalized"]
        what = ("follows the load sign (a compliance-like or clearance term)" if o > 1.3 * e else
                "does not follow the load sign (a load-independent or quadratic term)" if e > 1.3 * o else
                "is split between load-following and load-independent parts")
        parts.append(f"over {ls['pairs']} opposite-load pairs the gap {what}: odd {o:.2f}, even {e:.2f} "
                     "(1 = noise)")
    mags = loc.get("by_load_magnitude", [])
    if len(mags) > 1:
        lo, hi = mags[0]["rms_normalized"], mags[-1]["rms_normalized"]
        trend = "grows" if hi > 1.3 * lo else ("shrinks" if lo > 1.3 * hi else "is flat")
        parts.append(f"residual {trend} with load magnitude ({lo:.2f} -> {hi:.2f})")
    if loc.get("by_load_level"):
        parts.append(growth_words(loc["by_load_level"]))
    for name, bins in loc.get("by_actuator", {}).items():
        if len(bins) > 1:
            lo, hi = bins[0]["rms_normalized"], bins[-1]["rms_normalized"]
            if hi > 1.5 * lo or lo > 1.5 * hi:
                parts.append(f"varies along actuator {name} ({lo:.2f} -> {hi:.2f})")
    return f"overall normalized RMS {ov:.2f}; " + "; ".join(parts)

"""The stages' strategy of a data kind: what differs between deflections and stiffness observations.

:class:`DeflectionKind` (``x,y,z,Fx..Mz,dx..rz``: twists under loads) and
:class:`StiffnessKind` (``x,y,z,quantity,value``: k_tran, k_rot per posture)
answer the same questions for the stages: which rows apply, the loads, the
weights and residual problem, the groups of repeats, the residuals in physical
units and where the gap is, and the scales a suggested design needs.  The data kinds themselves (recognising,
reading, running, the output files) are the registry of :mod:`vjm.discrepancy.kinds`.
"""
from __future__ import annotations

import os
from dataclasses import dataclass

import numpy as np

from linkfea.mechanics.compliance import TWIST

from ...effects import modelops as mo
from ...errors import VjmError
from ..data import QUANTITIES, Deflections, StiffnessObs
from ..localize import localize
from ..predict import deflection_problem, stiffness_problem
from .norms import per_pose, rms, robust_scale


@dataclass(frozen=True)
class Weights:
    """The standard deviations of the observations and where they come from.

    ``sig`` (deflections, (n, 6) mm and rad per row and component; ``sig_t``/``sig_r`` its
    translation / rotation row medians) or ``sig_rel`` (stiffness, relative); with ``sigma_known``
    False they are relative weights and the variance of each component group (translations,
    rotations) is fitted apart."""

    sigma_known: bool
    source: str
    sig_t: np.ndarray | None = None
    sig_r: np.ndarray | None = None
    sig_rel: np.ndarray | None = None
    sig: np.ndarray | None = None

    def scaled(self, factor_t: float, factor_r: float, source: str) -> "Weights":
        """The deflection weights with the translation and rotation sigmas multiplied by these factors."""
        f = np.where(np.arange(6) < 3, factor_t, factor_r)
        sig = self.sig * f
        return Weights(self.sigma_known, source, np.median(sig[:, :3], axis=1), np.median(sig[:, 3:], axis=1),
                       None, sig)


@dataclass(frozen=True)
class Located:
    """Residuals in the data's units (RMS nominal / calibrated / final) and where the gap is."""

    rms_nominal: float
    rms_before: float
    rms_after: float
    units: str
    before: dict  # localize() of the calibrated baseline's normalized residuals
    after: dict  # ... of the final model's
    per_before: np.ndarray  # (m,) normalized RMS per unique posture
    per_after: np.ndarray


def _size_error(data, columns, what, n_obs, k_max):
    return VjmError(f"{os.path.basename(data.source)}: rows {int(data.rows[0])}-{int(data.rows[-1])}, "
                    f"{columns}: {n_obs} {what} are fewer than the {k_max + 1} needed to fit "
                    f"the {k_max} parameters of the baseline plus one effect")


class DeflectionKind:
    """Twists measured under applied wrenches (some components may be missing)."""

    name = "deflection"
    #: rows carry loads: load levels are tested, a design of loads can be suggested
    loaded = True

    def with_noise(self, data, noise):
        """The data with a laser tracker's sigmas (:class:`~vjm.discrepancy.tracker.TrackerNoise`)."""
        return noise.apply(data)

    def rows(self, data, model):
        return data

    def wrenches(self, data) -> np.ndarray:
        return data.W

    def noise_t(self, data, model, U, idx, W) -> float:
        """Typical translation noise (mm): the file's sigma_t, else the nominal model's residual scatter."""
        st = data.stated_sigmas()[:, :3]
        if np.isfinite(st).any():
            return float(np.nanmedian(st))
        r0 = data.T[:, :3] - np.einsum("nij,nj->ni", mo.compliance_map(model, U)[idx][:, :3], W)
        return robust_scale(r0)

    def check_size(self, data, k_max) -> None:
        n_obs = int(data.mask.sum())
        if n_obs <= k_max:
            raise _size_error(data, "columns dx..rz", "measured values", n_obs, k_max)

    def weights(self, data, pred) -> Weights:
        """Known when the file states a sigma for every measured component (``sigma_t``/``sigma_r`` or
        ``sigma_dx..sigma_rz``, per row); else relative weights: the stated ones where given, the
        nominal model's robust residual scatter of the group (translations, rotations) where not,
        and each group's variance is fitted (likelihood-ratio tests with the variances profiled)."""
        mask = data.mask
        stated = data.stated_sigmas()
        if np.all(np.isfinite(stated) | ~mask):
            sig = np.where(mask, stated, 1.0)
            return Weights(True, "from the file (" + ("sigma_dx..sigma_rz" if data.sigma is not None
                                                      else "sigma_t, sigma_r") + ")",
                           np.median(sig[:, :3], axis=1), np.median(sig[:, 3:], axis=1), None, sig)
        r0 = data.T - pred.twists((), np.zeros(0))
        sig = stated.copy()
        for g in (slice(0, 3), slice(3, 6)):
            if not np.isfinite(stated[:, g][mask[:, g]]).all():
                sig[:, g] = robust_scale(r0[:, g]) if mask[:, g].any() else 1.0
        sig = np.where(np.isfinite(sig), sig, 1.0)
        return Weights(False, "estimated from the residuals (translations and rotations apart; likelihood-ratio "
                              "test with the variances profiled)",
                       np.median(sig[:, :3], axis=1), np.median(sig[:, 3:], axis=1), None, sig)

    def problem(self, pred, data, w: Weights, cands):
        return deflection_problem(pred, data, w.sig, w.sigma_known, cands)

    def repeat_groups(self, data) -> np.ndarray:
        """Group id of each observation: same posture, same load, same component."""
        key = np.hstack([np.round(data.P, 6), np.round(data.W, 9)])
        _, g = np.unique(key, axis=0, return_inverse=True)
        mask = data.mask
        comp = np.broadcast_to(np.arange(6), mask.shape)[mask]
        return np.broadcast_to(g.reshape(-1, 1), mask.shape)[mask] * 6 + comp

    def sigmas(self, w: Weights, s2) -> np.ndarray:
        """(n, 6) standard deviation of each component (the fitted scale included: ``s2`` one for all,
        or (translations, rotations))."""
        s2 = np.atleast_1d(np.asarray(s2, float))
        f = np.where(np.arange(6) < 3, s2[0], s2[-1])
        return w.sig * np.sqrt(f)

    def locate(self, data, pred, prob, w: Weights, s2, base, final, U, idx, q) -> Located:
        mask = data.mask
        sigm = self.sigmas(w, s2)

        def phys(names, theta):
            return data.T - pred.twists(names, theta)

        res_nom, res_base, res_fin = phys((), np.zeros(0)), phys(base.names, base.theta), phys(final.names, final.theta)
        tr = mask[:, :3].any()
        comp = slice(0, 3) if tr else slice(3, 6)

        def rms_of(r):
            return rms(np.where(mask[:, comp], r[:, comp], np.nan))

        rn_base = np.where(mask, res_base / sigm, np.nan)
        rn_fin = np.where(mask, res_fin / sigm, np.nan)
        W = data.W
        return Located(rms_of(res_nom), rms_of(res_base), rms_of(res_fin),
                       "mm (translations)" if tr else "rad (rotations)",
                       localize(U, W, rn_base, mask, idx, q, tnorm=pred.twists(base.names, base.theta) / sigm),
                       localize(U, W, rn_fin, mask, idx, q, tnorm=pred.twists(final.names, final.theta) / sigm),
                       per_pose(rn_base, mask, idx, len(U)), per_pose(rn_fin, mask, idx, len(U)))

    def design_scales(self, data, w: Weights, s2) -> tuple:
        """(measured components, their sigmas per row (inf where not measured), typical sigma of each)."""
        mask = data.mask
        sigm = self.sigmas(w, s2)
        mcomp = np.flatnonzero(mask.any(axis=0))
        return mcomp, np.where(mask, sigm, np.inf)[:, mcomp], np.median(sigm[:, mcomp], axis=0)

    def subset(self, data, keep: np.ndarray) -> Deflections:
        """The rows ``keep`` (bool), file row numbers and text columns kept."""
        rows = None if data.rows is None else np.asarray(data.rows)[keep]
        return Deflections(data.P[keep], data.W[keep], data.T[keep],
                           None if data.sigma_t is None else data.sigma_t[keep],
                           None if data.sigma_r is None else data.sigma_r[keep], rows, data.source,
                           {k: [x for x, kk in zip(v, keep) if kk] for k, v in data.meta.items()},
                           None if data.sigma is None else data.sigma[keep])

    def whitened(self, full, pred, final) -> tuple:
        """(residual / sigma of every measured component of ``full``'s data under ``final``, row position of
        each, component name of each): the outlier stage's view."""
        data, w = full.data, full.weights
        mask = data.mask
        # the file's own sigmas where it states them: the noise check may have widened the weights, and a
        # share of gross values would then hide among them; the robust scale (flag) takes a misstated level
        stated = data.stated_sigmas()
        sig = np.where(np.isfinite(stated), stated, w.sig) if w.sigma_known else w.sig
        r = ((data.T - pred.twists(final.names, final.theta)) / sig)[mask]
        pos, comp = np.nonzero(mask)
        return r, pos, [TWIST[c] for c in comp]


class StiffnessKind:
    """k_tran / k_rot observed per posture (no loads); residuals are ln(predicted / observed)."""

    name = "stiffness"
    loaded = False

    def with_noise(self, data, noise):
        raise VjmError("noise: a tracker noise model applies to deflection data (x,y,z,Fx..Mz,dx..rz)")

    def rows(self, data, model) -> StiffnessObs:
        """The rows whose ``architecture`` column names the model's (all rows without that column)."""
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

    def wrenches(self, data) -> np.ndarray:
        return np.zeros((data.n, 6))

    def noise_t(self, data, model, U, idx, W) -> None:
        return None

    def check_size(self, data, k_max) -> None:
        if data.n <= k_max:
            raise _size_error(data, "column 'value'", "observations", data.n, k_max)

    def weights(self, data, pred) -> Weights:
        known = data.sigma_rel is not None
        return Weights(known, "from the file (sigma_rel)" if known else "estimated from the residuals (F test)",
                       sig_rel=data.sigma_rel if known else np.ones(data.n))

    def problem(self, pred, data, w: Weights, cands):
        return stiffness_problem(pred, data, w.sig_rel, w.sigma_known)

    def repeat_groups(self, data) -> np.ndarray:
        """Group id of each observation: same posture, same quantity."""
        key = np.hstack([np.round(data.P, 6), data.quantity[:, None]])
        _, grp = np.unique(key, axis=0, return_inverse=True)
        return grp

    def locate(self, data, pred, prob, w: Weights, s2, base, final, U, idx, q) -> Located:
        s = np.sqrt(s2)
        sig_rel = w.sig_rel
        r_nom = prob.residuals((), np.zeros(0))
        rw_b = prob.residuals(base.names, base.theta)  # ln(pred/obs) / sigma_rel
        rw_f = prob.residuals(final.names, final.theta)
        m1 = np.ones((data.n, 1), bool)
        W = np.zeros((data.n, 6))
        before = localize(U, W, (rw_b / s)[:, None], m1, idx, q)
        before["by_quantity"] = {qn: rms(rw_b[data.quantity == i] * sig_rel[data.quantity == i])
                                 for i, qn in enumerate(("k_tran", "k_rot")) if np.any(data.quantity == i)}
        return Located(rms(r_nom * sig_rel), rms(rw_b * sig_rel), rms(rw_f * sig_rel),
                       "relative (ln of predicted/observed)", before, localize(U, W, (rw_f / s)[:, None], m1, idx, q),
                       per_pose((rw_b / s)[:, None], m1, idx, len(U)), per_pose((rw_f / s)[:, None], m1, idx, len(U)))

    def design_scales(self, data, w: Weights, s2) -> tuple:
        raise VjmError("--suggest needs deflection data (x,y,z,Fx..Mz,dx..rz): stiffness observations "
                       "have no loads to design")

    def subset(self, data, keep: np.ndarray) -> StiffnessObs:
        """The rows ``keep`` (bool), file row numbers and text columns kept."""
        rows = None if data.rows is None else np.asarray(data.rows)[keep]
        return StiffnessObs(data.P[keep], data.quantity[keep], data.value[keep],
                            None if data.sigma_rel is None else data.sigma_rel[keep], rows, data.source,
                            {k: [x for x, kk in zip(v, keep) if kk] for k, v in data.extra.items()})

    def whitened(self, full, pred, final) -> tuple:
        """(ln(predicted / observed) / sigma_rel of every observation under ``final``, its row, its quantity)."""
        data, w = full.data, full.weights
        k = pred.kvalues(final.names, final.theta)[full.ctx.idx, data.quantity]
        r = (np.log(np.maximum(k, 1e-300)) - np.log(data.value)) / w.sig_rel
        return r, np.arange(data.n), [QUANTITIES[q] for q in data.quantity]


#: the strategy of a data kind that goes through the stages
DataKind = DeflectionKind | StiffnessKind


def kind_of(data) -> DataKind:
    """The strategy of a data set read by :func:`~vjm.discrepancy.data.read_csv` (in memory: the data kinds of
    :mod:`vjm.discrepancy.kinds` give theirs)."""
    return StiffnessKind() if isinstance(data, StiffnessObs) else DeflectionKind()

"""Stage 0: the weighted residual problem of a model and a data set.

Checks that every posture is reachable, keeps the candidates that apply to
the model and the data (each prepares its precomputations on the data's
context), and builds the predictor and the whitened residual problem with
the calibration as baseline.
"""
from __future__ import annotations

import os
from dataclasses import dataclass

import numpy as np

from ...errors import VjmError
from .. import effects as fx
from .. import modelops as mo
from ..data import Deflections, StiffnessObs
from ..fit.select import Problem, Term
from ..predict import CALIBRATION, Context, Predictor, calibration_term, unique_postures
from .kinds import DataKind, Weights


@dataclass(frozen=True)
class Setup:
    """Everything the later stages share.  ``terms`` and ``pred`` are the problem's own (the
    calibration and observability stages hold unseen parameters fixed in them)."""

    model: object
    data: Deflections | StiffnessObs  # (the rows for the model only)
    kind: DataKind
    U: np.ndarray  # (m, 3) unique postures
    idx: np.ndarray  # (n,) row -> posture
    q: np.ndarray  # (m, n_chains) actuator coordinates of U
    ctx: Context
    candidates: list  # names that apply and prepared
    skipped: dict  # name -> why not a candidate
    terms: dict  # name -> Term (calibration + candidates)
    pred: Predictor
    weights: Weights
    prob: Problem


def reachable_postures(model, data):
    """Unique postures, row index, actuator coordinates; raises naming the first unreachable row."""
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


def applicable(model, data_kind: str, names=None):
    """(candidates, {name: why skipped}) among ``names`` (default: the whole registry)."""
    names = list(fx.REGISTRY) if names is None else list(names)
    cands, skipped = [], {}
    for nm in names:
        why = fx.get(nm).applies_to(model, data_kind)
        if why:
            skipped[nm] = why
        else:
            cands.append(nm)
    return cands, skipped


def build_problem(model, data, kind: DataKind, effects=None) -> Setup:
    """Stage 0: rows, postures, candidates, predictor and weighted residual problem."""
    data = kind.rows(data, model)
    U, idx, q = reachable_postures(model, data)
    W = kind.wrenches(data)
    ctx = Context(model, U, idx, W)
    cands, skipped = applicable(model, kind.name, effects)
    ctx.noise_t = kind.noise_t(data, model, U, idx, W)
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
    k_max = len(terms[CALIBRATION].params) + max([len(terms[c].params) for c in cands] or [0])
    kind.check_size(data, k_max)
    w = kind.weights(data, pred)
    return Setup(model, data, kind, U, idx, q, ctx, cands, skipped, terms, pred, w, kind.problem(pred, data, w, cands))

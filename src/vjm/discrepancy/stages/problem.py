"""Problem: the weighted residual problem of a model and a data set.

Checks that every posture is reachable and the data's units plausible
(:mod:`vjm.discrepancy.plausible`), keeps the candidates that apply to
the model and the data (each prepares its precomputations on the data's
context), and builds the predictor and the whitened residual problem with
the calibration as baseline.
"""
from __future__ import annotations

import dataclasses
from dataclasses import dataclass

import numpy as np

from ... import effects as fx
from ...effects.context import Context
from ...stats.terms import Problem, Term
from ..data import Deflections, StiffnessObs
from ..plausible import check_reachable, check_units
from ..predict import CALIBRATION, Predictor, calibration_term
from .kinds import DataKind, Weights


@dataclass(frozen=True)
class Setup:
    """Everything the later stages share.  ``terms`` and ``pred`` are the problem's own (the
    calibration and observability stages hold unseen parameters fixed in them)."""

    model: object
    data: Deflections | StiffnessObs  # (the rows for the model only)
    kind: DataKind
    U: np.ndarray  # (m, 3) unique postures; (m, 6) with the orientations of a 6-dof platform
    idx: np.ndarray  # (n,) row -> posture
    q: np.ndarray  # (m, n_chains) actuator coordinates of U
    ctx: Context
    candidates: list  # names that apply and prepared
    skipped: dict  # name -> why not a candidate
    terms: dict  # name -> Term (calibration + candidates)
    pred: Predictor
    weights: Weights
    prob: Problem


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
    """Rows, postures, candidates, predictor and weighted residual problem."""
    data = kind.rows(data, model)
    U, idx, q = check_reachable(model, data)  # every posture reachable, named by its row if not
    check_units(model, data, U, idx)  # a scale far beyond any effect is a unit: refused before any fit
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


def with_weights(s: Setup, terms: dict, w: Weights) -> Setup:
    """``s`` with other weights: a fresh predictor on the same data context (its precomputations kept) with
    ``terms`` (the terms as :func:`build_problem` made them, before any stage held a parameter)."""
    pred = Predictor(s.model, s.ctx, dict(terms))
    return dataclasses.replace(s, terms=pred.terms, pred=pred, weights=w,
                               prob=s.kind.problem(pred, s.data, w, s.candidates))

"""The front door of a diagnosis, for every data kind: :func:`diagnose` checks the arguments, loads the model,
asks the registry of data kinds (:mod:`vjm.discrepancy.kinds`) which kind the data are, reads them and runs
that kind, to one :class:`~vjm.discrepancy.diagnosis.Diagnosis`.

The stages' diagnosis of deflections and stiffness observations is :mod:`vjm.discrepancy.pipeline`;
absolute poses go to the calibration engine (:mod:`vjm.calibration.diagnosis`).
"""
from __future__ import annotations

import os

from linkfea.runtime.checks import Bounds, integer, number

from ..errors import ArgumentError
from ..modelio.read import load_model
from . import kinds
from .diagnosis import Diagnosis
from .pipeline import diagnose_plan, run_stages, set_aside
from .tracker import TrackerNoise

__all__ = ["diagnose", "check_arguments", "diagnose_plan", "run_stages", "set_aside"]

#: valid ranges of diagnose's numeric arguments: a level of 0 or 1 makes every test pass or fail
ALPHA = Bounds(0, 1, lo_open=True, hi_open=True)
MAX_EFFECTS = Bounds(1)
SUGGEST = Bounds(0)


def check_arguments(alpha=None, folds=None, max_effects=3, suggest=0):
    """The numeric arguments of :func:`diagnose` that every kind reads alike, checked (type, finiteness, range):
    ArgumentError naming one (``folds`` is the kind's to check: absolute poses take 0, none)."""
    return (None if alpha is None else number(alpha, "alpha", ALPHA, ArgumentError), folds,
            integer(max_effects, "max_effects", MAX_EFFECTS, ArgumentError),
            integer(suggest, "suggest", SUGGEST, ArgumentError))


def diagnose(model, data, alpha: float | None = None, effects=None, folds: int | None = None, max_effects: int = 3,
             model_name: str | None = None, progress=None, suggest: int = 0, forces_only: bool = False,
             outliers: bool = True, noise: TrackerNoise | None = None, columns=None, validate=(),
             register: int = 30, frame=None, kind: str | None = None, same_setup: bool = False,
             min_gain: float | None = None) -> Diagnosis:
    """Diagnose a model (loaded, or a model file) on a data set (read, or a file) of any registered kind.

    Parameters
    ----------
    alpha : family-wise significance level of each selection round (default 0.01; absolute poses: the F test
        level of an effect, default 1e-3).
    effects : candidate names (default: the whole registry; absolute poses: geometry, compliance, payload).
    folds : cross-validation folds (default 5; absolute poses: 0 none, and 0 with ``validate``).
    model_name : the model's name in the report (default: the file name of a path, else "<model>").
    suggest : number of (posture, load) rows to suggest measuring next (0: none).
    forces_only : suggest force loads only (a rig that cannot apply torques).
    outliers : set aside the rows holding a gross outlier and diagnose the others
        (:mod:`~vjm.discrepancy.stages.outliers`); False: every row is used as it is.
    noise : the translations' sigmas of a laser tracker (:class:`~vjm.discrepancy.tracker.TrackerNoise`:
        growing with the distance from it, per axis) for deflection data whose file states none.
    columns, validate, register, frame, same_setup : absolute poses: a column map file, held-out files (each
        on the fitted registration when its rows are in the fitted set-up -- a ``group`` column of fitted
        groups, or none and ``same_setup`` -- else registered on ``register`` of its poses), the measured
        points fitted.
    kind : the name of the data kind (:mod:`vjm.discrepancy.kinds`); None: the registry recognises the data.
    min_gain : absolute poses: what an effect must buy held out to be named (mm; None: 1 % of the error it
        starts from, at least 10 % of the stated sigma).
    progress : called with a line per selection round.
    """
    alpha, folds, max_effects, suggest = check_arguments(alpha, folds, max_effects, suggest)
    if isinstance(model, (str, os.PathLike)):
        model_name = model_name or os.path.basename(os.fspath(model))
        model = load_model(model)
    k = kinds.get(kind) if kind is not None else kinds.find(data, model, columns)
    options = dict(alpha=alpha, effects=effects, folds=folds, max_effects=max_effects, model_name=model_name,
                   progress=progress, suggest=suggest, forces_only=forces_only, outliers=outliers, noise=noise,
                   columns=columns, validate=validate, register=register, frame=frame, same_setup=same_setup)
    if min_gain is not None:
        options["min_gain"] = min_gain
    k.check(options)
    if isinstance(data, (str, os.PathLike)):
        data = k.read(data, model, columns)
    return k.run(model, data, **options)

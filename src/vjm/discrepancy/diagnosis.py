"""The outcome of a diagnosis of any data kind: :class:`Diagnosis`, and :func:`write_diagnosis` (the output folder
of the stages' kinds, deflections and stiffness observations).

One result type for every data kind (:mod:`vjm.discrepancy.kinds`): a typed, frozen report (what report.json
holds: :class:`~vjm.discrepancy.stages.record.Report` of the stages, or
:class:`~vjm.calibration.diagnosis.PoseReport` of absolute poses), one summary
(:class:`~vjm.discrepancy.summary.Summary`), one HTML renderer (:mod:`vjm.discrepancy.report`), ``save``, and
the updated model in memory.  What differs between kinds (the files written, how the updated model is built)
is carried by the two callables the kind's run gives it.
"""
from __future__ import annotations

from dataclasses import dataclass
from functools import cached_property
from typing import Any, Callable

import numpy as np

from ..calibration.result import Calibration
from . import covariance
from .data import write_design
from .report import plot_before_after, plot_residuals, write_report_dir
from .stages.record import FrozenReport
from .summary import Summary


@dataclass(frozen=True, eq=False)
class Diagnosis:
    """Outcome of :func:`vjm.diagnose`: the report (what report.json holds), the kind of data it came from, and
    what the kind kept beside it: the stages' updated ``model``, per-posture residuals and suggested
    measurements; absolute poses' ``calibration`` (and ``commands``, the text of commands.csv)."""

    report: FrozenReport
    kind: str  # the data kind's name (vjm.discrepancy.kinds)
    writer: Callable  # writer(diagnosis, out_dir, force, set_name): the kind's output set
    updater: Callable  # updater(diagnosis) -> the updated model in memory
    model: object = None  # the stages' updated model (model_updated.yaml)
    P: np.ndarray | None = None  # unique postures
    # normalized RMS per posture, calibrated baseline (absolute poses: each fitted row's position error, mm, with
    # the registration only)
    rms_pose_before: np.ndarray | None = None
    rms_pose_after: np.ndarray | None = None  # the same after (absolute poses: calibrated)
    next_measurements: np.ndarray | None = None  # (N, 9) x, y, z, Fx..Mz
    covariance: Calibration | None = None  # what the final fit calibrated: model_updated.yaml's calibration:
    calibration: Any = None  # absolute poses: the fitted measurement model (vjm.calibration.result.Calibration)
    commands: str | None = None  # absolute poses with targets: the text of commands.csv

    @property
    def verdict(self) -> str:
        """"no_discrepancy", "explained", "unexplained", "insufficient_data" (the design is too weak to name
        what fits) or "untrusted_data" (more than 10 % of the rows are gross outliers: no effect named)."""
        return self.report["verdict"]

    @property
    def named(self) -> list:
        """Names of the effects added to the model."""
        return list(self.report["named_effects"])

    @property
    def confounded(self) -> list:
        """Groups of candidates (or a candidate and "calibration") this data cannot tell apart (absolute poses:
        none, the parameters the data cannot tell apart are removed by rank, listed in ``not_identifiable``)."""
        return [list(g) for g in self.report.get("confounded", ())]

    @cached_property
    def updated_model(self):
        """The model with the calibration and the named effects, in memory (a :class:`vjm.Model`; what
        model_updated.yaml, or calibrated.urdf and calibrated.yaml, hold); None where the kind writes no model
        (a parallel machine's absolute poses)."""
        return self.updater(self)

    def summary(self) -> Summary:
        """A :class:`~vjm.discrepancy.summary.Summary` (``str()`` text, ``as_html()``), like statsmodels'."""
        return Summary(self.report)

    def save(self, out_dir, force: bool = False, set_name: str = "vjm diagnose") -> None:
        """Write the kind's output set into ``out_dir`` (report.json, report.html, ...; see
        :mod:`vjm.discrepancy.kinds`), as one set ``set_name``."""
        self.writer(self, out_dir, force, set_name)

    def _repr_html_(self) -> str:
        return self.summary().as_html()

    def __repr__(self) -> str:
        return f"<Diagnosis {self.verdict}: named {self.named or 'nothing'}>"


def stage_model(dg: Diagnosis):
    """The stages' updated model (kept as it was built)."""
    return dg.model


def write_diagnosis(dg: Diagnosis, out_dir, force: bool = False, set_name: str = "vjm diagnose") -> None:
    """Write report.json, report.html, the PNGs and model_updated.yaml (with the calibration's
    covariance) as one output set (:func:`~vjm.discrepancy.report.write_report_dir`)."""
    def figs(path_of):
        plot_before_after(path_of("before_after.png"), dg.rms_pose_before, dg.rms_pose_after, dg.verdict)
        plot_residuals(path_of("residuals_per_posture.png"), dg.P, dg.rms_pose_before, dg.rms_pose_after,
                       "residual per posture: before vs after")
        if dg.next_measurements is not None:
            write_design(path_of("next_measurements.csv"), dg.next_measurements,
                         "next measurements suggested by vjm diagnose: " + dg.report["suggest"]["criterion"])
        return ["before_after.png", "residuals_per_posture.png"]

    write_report_dir(out_dir, dg.report.to_dict(), lambda p: covariance.save_model_with(dg.model, dg.covariance, p),
                     figs, force=force, set_name=set_name)

"""The outcome of a diagnosis: :class:`Diagnosis` and :func:`write_diagnosis` (its output folder)."""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..calibration.result import Calibration
from . import covariance
from .data import write_design
from .report import plot_before_after, plot_residuals, write_report_dir
from .stages.record import Report
from .summary import Summary


@dataclass(frozen=True)
class Diagnosis:
    """Outcome of :func:`~vjm.discrepancy.workflow.diagnose`: the report (what report.json holds), the
    updated model, per-posture residuals, and the suggested next measurements (or None)."""

    report: Report
    model: object  # updated model
    P: np.ndarray  # unique postures
    rms_pose_before: np.ndarray  # normalized RMS per posture, calibrated baseline
    rms_pose_after: np.ndarray
    next_measurements: np.ndarray | None = None  # (N, 9) x, y, z, Fx..Mz
    covariance: Calibration | None = None  # what the final fit calibrated: model_updated.yaml's calibration:

    @property
    def verdict(self) -> str:
        """"no_discrepancy", "explained", "unexplained", "insufficient_data" (the design is too weak to name
        what fits) or "untrusted_data" (more than 10 % of the rows are gross outliers: no effect named)."""
        return self.report.verdict

    @property
    def named(self) -> list:
        """Names of the effects added to the model."""
        return list(self.report.named_effects)

    @property
    def confounded(self) -> list:
        """Groups of candidates (or a candidate and "calibration") this data cannot tell apart."""
        return [list(g) for g in self.report.confounded]

    @property
    def updated_model(self):
        """The model with the calibration and the named effects (what model_updated.yaml holds)."""
        return self.model

    def summary(self) -> Summary:
        """A :class:`~vjm.discrepancy.summary.Summary` (``str()`` text, ``as_html()``), like statsmodels'."""
        return Summary(self.report)

    def save(self, out_dir, force: bool = False) -> None:
        """Write report.json, report.html, figures, model_updated.yaml (and next_measurements.csv)
        as one output set (see :func:`write_diagnosis`)."""
        write_diagnosis(self, out_dir, force=force)

    def _repr_html_(self) -> str:
        return self.summary().as_html()

    def __repr__(self) -> str:
        return f"<Diagnosis {self.verdict}: named {self.named or 'nothing'}>"


def write_diagnosis(dg: Diagnosis, out_dir, force: bool = False) -> None:
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
                     figs, force=force)

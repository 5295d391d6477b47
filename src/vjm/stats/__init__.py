"""Statistics of the discrepancy workflow: least squares, evidence, selection."""
from .selection import FitResult, Param, Term, fit_terms, forward_select, grouped_folds

__all__ = ["FitResult", "Param", "Term", "fit_terms", "forward_select", "grouped_folds"]

"""Levels of the discrepancy workflow that are not statistical tests (those live in :mod:`vjm.stats`)."""
from __future__ import annotations

#: family-wise significance level of each selection round
DEFAULT_ALPHA = 0.01
#: pairs of candidates fitted after the selection, the first of a linearised screen (vjm.stats.selection.screen_pairs)
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

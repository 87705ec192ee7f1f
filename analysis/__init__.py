"""Analysis of SceneSuggest studies: trial measures from the event log, bootstrap confidence intervals,
mixed models that reproduce lme4, the paper's tables and figures, and a report.

Reads a study export (``scenesuggest study export``) or the study database directly; it never imports the
study server. Times are seconds, distances metres, angles degrees.
"""

from .errors import AnalysisError

__all__ = ["AnalysisError"]

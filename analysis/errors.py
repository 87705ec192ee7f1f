"""The one exception type for user-facing failures of the analysis."""

from __future__ import annotations


class AnalysisError(Exception):
    """Bad input the analyst can act on; ``where`` names the file, table or column (``trials.csv: column
    'condition'``)."""

    def __init__(self, message: str, where: str | None = None):
        self.message = message
        self.where = where
        super().__init__(f"{where}: {message}" if where else message)

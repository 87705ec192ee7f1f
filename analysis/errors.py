"""The one exception type for user-facing failures of the analysis."""

from __future__ import annotations

from scenesuggest.errors import SceneSuggestError


class AnalysisError(SceneSuggestError):
    """Bad input the analyst can act on; ``where`` names the file, table or column (``trials.csv: column
    'condition'``). A :class:`SceneSuggestError`, so the command line reports it like every other input error."""

    def __init__(self, message: str, where: str | None = None):
        self.where = where
        super().__init__(message)

    def __str__(self) -> str:
        return f"{self.where}: {self.message}" if self.where else self.message

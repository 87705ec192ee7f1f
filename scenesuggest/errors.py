"""The one exception type for user-facing failures of the engine."""

from __future__ import annotations


class SceneSuggestError(Exception):
    """A failure the user can act on: bad input, a missing file, an unknown name.

    ``file``, ``line`` and ``field`` locate the problem when it comes from an input file; the
    string form reads ``FILE:LINE: field 'FIELD': message`` so that editors can jump to it.
    """

    def __init__(self, message: str, *, file: str | None = None, line: int | None = None,
                 field: str | None = None):
        self.message = message
        self.file = file
        self.line = line
        self.field = field
        super().__init__(str(self))

    def __str__(self) -> str:
        where = ""
        if self.file:
            where = f"{self.file}:{self.line}: " if self.line else f"{self.file}: "
        what = f"field '{self.field}': " if self.field else ""
        return f"{where}{what}{self.message}"

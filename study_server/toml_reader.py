"""Reading a study file's TOML: the file's bytes and document (errors give the line), and typed look-ups whose
errors name the key (``conditions[1].engine``). What the keys mean is :mod:`study_server.study_file`'s business."""

from __future__ import annotations

import math
import re
import tomllib
from pathlib import Path

from scenesuggest.errors import SceneSuggestError


class StudyFileError(SceneSuggestError):
    """A study file that cannot be used: the message, the file, and the key or line."""


class Reader:
    """Typed look-ups in a parsed TOML document; each failure is a :class:`StudyFileError` naming the key."""

    def __init__(self, file: Path):
        self.file = str(file)

    def fail(self, key: str, message: str) -> StudyFileError:
        return StudyFileError(message, file=self.file, field=key)

    def table(self, doc: dict, key: str, path: str, required: bool = True) -> dict:
        v = doc.get(key)
        if v is None and not required:
            return {}
        if not isinstance(v, dict):
            raise self.fail(path, "missing table" if v is None else "expected a table")
        return v

    def tables(self, doc: dict, key: str, path: str, required: bool = True) -> list[dict]:
        v = doc.get(key)
        if v is None and not required:
            return []
        if not isinstance(v, list) or not v or not all(isinstance(t, dict) for t in v):
            raise self.fail(path, "expected one or more [[" + key + "]] tables")
        return v

    def string(self, doc: dict, key: str, path: str, default: str | None = None) -> str:
        v = doc.get(key, default)
        if not isinstance(v, str) or not v.strip():
            raise self.fail(path, "missing" if key not in doc else "expected a non-empty string")
        return v

    def number(self, doc: dict, key: str, path: str, default=None, minimum: float = 0.0) -> float:
        v = doc.get(key, default)
        if isinstance(v, bool) or not isinstance(v, int | float) or not math.isfinite(v) or v < minimum:
            raise self.fail(path, f"expected a finite number ≥ {minimum:g}" if key in doc else "missing")
        return float(v)

    def boolean(self, doc: dict, key: str, path: str, default: bool) -> bool:
        v = doc.get(key, default)
        if not isinstance(v, bool):
            raise self.fail(path, "expected true or false")
        return v

    def choice(self, doc: dict, key: str, path: str, allowed, default: str | None = None) -> str:
        v = doc.get(key, default)
        if v not in allowed:
            raise self.fail(path, f"{v!r} is not one of {', '.join(allowed)}")
        return v

    def unknown(self, doc: dict, allowed, path: str) -> None:
        for key in doc:
            if key not in allowed:
                raise self.fail(f"{path}.{key}" if path else key, "unknown key")



def parse(path: Path) -> tuple[bytes, dict]:
    """The file's bytes and its TOML document (errors give the line)."""
    try:
        data = path.read_bytes()
    except OSError as e:
        raise StudyFileError(f"cannot read: {e}", file=str(path)) from None
    try:
        return data, tomllib.loads(data.decode("utf-8"))
    except (tomllib.TOMLDecodeError, UnicodeDecodeError) as e:
        where = re.search(r"\(at line (\d+), column (\d+)\)", str(e))
        message = re.sub(r"\s*\(at line \d+, column \d+\)", "", str(e))
        raise StudyFileError(f"not valid TOML: {message}" + (f" (column {where.group(2)})" if where else ""),
                             file=str(path), line=int(where.group(1)) if where else None) from None

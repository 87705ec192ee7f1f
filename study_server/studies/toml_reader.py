"""Reading a study file's TOML: the file's bytes and document (errors give the line), and typed look-ups whose
errors name the key (``conditions[1].engine``). What the keys mean is :mod:`study_server.studies.study_file`'s
business."""

from __future__ import annotations

import math
import re
import tomllib
from pathlib import Path

from scenesuggest.errors import SceneSuggestError


class StudyFileError(SceneSuggestError):
    """A study file that cannot be used: the message, the file, and the key or line."""


class StudyFileErrors(StudyFileError):
    """Every problem one reading of a study file found (``problems``, in the order of their lines); it stands for
    the first (its message, file, line and field), and its text lists them all, one a line."""

    def __init__(self, problems: list[StudyFileError]):
        self.problems = sorted(problems, key=lambda e: (e.line is None, e.line or 0))
        first = self.problems[0]
        super().__init__(first.message, file=first.file, line=first.line, field=first.field)

    def __str__(self) -> str:
        return "\n".join(SceneSuggestError.__str__(e) for e in self.problems) + \
            (f"\n({len(self.problems)} problems)" if len(self.problems) > 1 else "")


class Reader:
    """Typed look-ups in a parsed TOML document; each failure is a :class:`StudyFileError` naming the key and,
    given the file's ``text``, the line it is on (or the line of the table it is missing from).

    A reading that should name every problem at once reads each part through :meth:`attempt`, which records a
    failure and goes on with a stand-in, and ends with :meth:`finish`."""

    def __init__(self, file: Path, text: str | None = None):
        self.file = str(file)
        self.text = text
        self.problems: list[StudyFileError] = []

    def attempt(self, read, default=None):
        """``read()``, or — when it fails — ``default``, the failure recorded (once) for :meth:`finish`."""
        try:
            return read()
        except StudyFileError as e:
            if not any(e is seen for seen in self.problems):
                self.problems.append(e)
            return default

    def record(self, error: StudyFileError) -> None:
        """Record a problem found outside any :meth:`attempt` (reading goes on)."""
        self.problems.append(error)

    def finish(self) -> None:
        """Raise :class:`StudyFileErrors` naming every problem recorded, if any."""
        if self.problems:
            raise StudyFileErrors(self.problems)

    def fail(self, key: str, message: str) -> StudyFileError:
        line = locate(self.text, key) if self.text is not None else None
        return StudyFileError(message, file=self.file, field=key, line=line)

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

    def number(self, doc: dict, key: str, path: str, default=None, minimum: float = 0.0,
               maximum: float = math.inf) -> float:
        v = doc.get(key, default)
        if (isinstance(v, bool) or not isinstance(v, int | float) or not math.isfinite(v) or v < minimum
                or v > maximum):
            if key not in doc:
                raise self.fail(path, "missing")
            raise self.fail(path, f"expected a finite number ≥ {minimum:g}" + (f" and ≤ {maximum:g}" if
                                                                                  maximum < math.inf else ""))
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
        """Raise for the first key of ``doc`` not ``allowed``; the others are recorded for :meth:`finish`."""
        wrong = [self.fail(f"{path}.{key}" if path else key, "unknown key") for key in doc if key not in allowed]
        if wrong:
            self.problems += wrong[1:]
            raise wrong[0]



_HEADER = re.compile(r"^\s*(\[\[?)\s*([^\]]+?)\s*\]\]?\s*(#.*)?$")
_KEY = re.compile(r"^\s*([A-Za-z0-9_-]+|\"[^\"]*\")\s*=\s*(.*)$")
_INLINE_KEY = re.compile(r"(?:^|[{,])\s*([A-Za-z0-9_-]+)\s*=")
_PART = re.compile(r"([^.\[\]]+)|\[(\d+)\]")


def _parts(key: str) -> list:
    """``conditions[2].engine.name`` → ["conditions", 2, "engine", "name"]."""
    return [int(index) if index else name for name, index in _PART.findall(key)]


def locate(text: str, key: str) -> int | None:
    """The line (1-based) of a dotted key in a TOML document (``conditions[2].engine.lambda9``: in the third
    ``[[conditions]]``, the key ``engine``'s inline table), or of its deepest table or key that is there; None when
    nothing of it is. Dotted and quoted keys inside tables are matched by their first part only (best effort:
    the key in the message is what counts)."""
    want = _parts(key)
    counts: dict[tuple, int] = {}
    table: list = []
    best, best_depth = None, 0

    def consider(path: list, line: int) -> None:
        nonlocal best, best_depth
        depth = 0
        for a, b in zip(path, want, strict=False):
            if a != b:
                break
            depth += 1
        if depth == len(path) and depth > best_depth:
            best, best_depth = line, depth

    for number, line in enumerate(text.splitlines(), start=1):
        header = _HEADER.match(line)
        if header:
            names = [n.strip().strip('"') for n in header.group(2).split(".")]
            path: list = []
            for name in names[:-1]:  # a sub-table belongs to the last element of any array of tables above it
                path.append(name)
                if tuple(path) in counts:
                    path.append(counts[tuple(path)] - 1)
            path.append(names[-1])
            if header.group(1) == "[[":
                counts[tuple(path)] = counts.get(tuple(path), 0) + 1
                path.append(counts[tuple(path)] - 1)
            table = path
            consider(table, number)
            continue
        found = _KEY.match(line)
        if found:
            name = found.group(1).strip('"')
            consider([*table, name], number)
            value = found.group(2).lstrip()
            if value.startswith("{"):
                for inner in _INLINE_KEY.findall(value):
                    consider([*table, name, inner], number)
    return best


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

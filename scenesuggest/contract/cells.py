"""Spreadsheet-safe CSV cells, shared by the study export and the readers of its tables.

A text cell beginning with ``=``, ``+``, ``-``, ``@``, a tab or a carriage return is run as a formula by
spreadsheets (CSV injection). :func:`safe_cell` prefixes such cells, and cells that begin with the prefix
itself, with one ``'`` (OWASP's advice); numbers stay as they are. :func:`unescape_cell` is its exact inverse.
"""

from __future__ import annotations

import re

#: First characters that make a spreadsheet read a cell as a formula (and the escape itself).
FORMULA_START = ("=", "+", "-", "@", "\t", "\r", "'")
NUMBER = re.compile(r"-?(?:\d+\.?\d*|\.\d+)(?:[eE][-+]?\d+)?")


def safe_cell(value):
    """A CSV cell that a spreadsheet shows as text, never runs as a formula, and that encodes as UTF-8."""
    if not isinstance(value, str):
        return value
    try:
        value.encode("utf-8")
    except UnicodeEncodeError:
        value = value.encode("utf-8", "backslashreplace").decode("utf-8")
    if value.startswith(FORMULA_START) and not NUMBER.fullmatch(value):
        return "'" + value
    return value


def unescape_cell(value):
    """The stored value of a cell written by :func:`safe_cell`."""
    if isinstance(value, str) and value.startswith("'") and value[1:].startswith(FORMULA_START):
        return value[1:]
    return value

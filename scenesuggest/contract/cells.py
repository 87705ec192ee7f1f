"""Spreadsheet-safe CSV cells, shared by the study export and the readers of its tables.

A spreadsheet runs a text cell as a formula when it begins with ``=``, ``+``, ``-``, ``@``, a tab or a carriage
return (OWASP's list), and some do after a space, a no-break space, a byte-order mark or another invisible
character, or with a full-width ``＝`` or a ``|`` (DDE) first. So the rule is an allowance, not a list of dangers:
:func:`safe_cell` writes a text cell as it is only when it is a number or begins with a letter or digit (of any
script) or one of :data:`INERT` (JSON's braces, brackets and quotes among them); any other text cell, and one that
begins with the prefix itself, gets one leading ``'``. :func:`unescape_cell` is its exact inverse.
"""

from __future__ import annotations

import re

#: First characters (besides letters and digits) that no spreadsheet reads as the start of a formula.
INERT = frozenset('{["(#_./<*:')
NUMBER = re.compile(r"-?(?:\d+\.?\d*|\.\d+)(?:[eE][-+]?\d+)?")


def _escaped(value: str) -> bool:
    """Whether :func:`safe_cell` writes the text ``value`` with the prefix."""
    return bool(value) and not (value[0].isalnum() or value[0] in INERT) and not NUMBER.fullmatch(value)


def safe_cell(value):
    """A CSV cell that a spreadsheet shows as text, never runs as a formula, and that encodes as UTF-8."""
    if not isinstance(value, str):
        return value
    try:
        value.encode("utf-8")
    except UnicodeEncodeError:
        value = value.encode("utf-8", "backslashreplace").decode("utf-8")
    return "'" + value if _escaped(value) else value


def unescape_cell(value):
    """The stored value of a cell written by :func:`safe_cell`."""
    if isinstance(value, str) and value.startswith("'") and _escaped(value[1:]):
        return value[1:]
    return value

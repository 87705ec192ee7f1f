"""JSON parsing that remembers where each object and key came from, for error messages.

``loads_with_lines(text)`` returns ordinary dicts and lists plus a :class:`LineIndex` that answers
"on which line does this object start / does this key of this object appear?".
"""

from __future__ import annotations

import json
import json.decoder
import json.scanner
import re
from dataclasses import dataclass, field


@dataclass
class LineIndex:
    text: str
    spans: dict[int, tuple[int, int]] = field(default_factory=dict)  # id(obj) -> (start, end) offsets
    parsed: list[object] = field(default_factory=list, repr=False)  # keeps id() keys unique
    _newlines: list[int] = field(default_factory=list)

    def __post_init__(self) -> None:
        self._newlines = [m.start() for m in re.finditer("\n", self.text)]

    def line_at(self, offset: int) -> int:
        lo, hi = 0, len(self._newlines)
        while lo < hi:
            mid = (lo + hi) // 2
            if self._newlines[mid] < offset:
                lo = mid + 1
            else:
                hi = mid
        return lo + 1

    def line_of(self, obj: object, key: str | None = None) -> int | None:
        """Line of ``obj`` (a dict parsed by :func:`loads_with_lines`), or of ``key`` inside it."""
        span = self.spans.get(id(obj))
        if span is None:
            return None
        start, end = span
        if key is None:
            return self.line_at(start)
        nested = sorted(s for o, s in self.spans.items() if o != id(obj) and start < s[0] and s[1] <= end)
        pattern = re.compile(re.escape(json.dumps(key)) + r"\s*:")
        for m in pattern.finditer(self.text, start, end):
            if not any(a <= m.start() < b for a, b in nested):
                return self.line_at(m.start())
        return self.line_at(start)


def loads_with_lines(text: str) -> tuple[object, LineIndex]:
    """Parse ``text`` as JSON; raise ``json.JSONDecodeError`` (with line and column) when malformed."""
    index = LineIndex(text)
    def parse_object(s_and_end, strict, scan_once, object_hook, object_pairs_hook, memo=None,
                     _w=json.decoder.WHITESPACE.match):
        start = s_and_end[1] - 1
        obj, end = json.decoder.JSONObject(s_and_end, strict, scan_once, object_hook, object_pairs_hook,
                                           memo, _w)
        index.parsed.append(obj)
        index.spans[id(obj)] = (start, end)
        return obj, end

    decoder = json.JSONDecoder()
    decoder.parse_object = parse_object
    decoder.scan_once = json.scanner.py_make_scanner(decoder)
    value = decoder.decode(text)
    return value, index

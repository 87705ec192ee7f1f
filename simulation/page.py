"""What a participant page says about itself: its step (``<body data-step="…">``), its form, its boot data.

Pages mark their step, so a walker never recognises a page by its wording or markup. The steps: ``device``,
``consent``, ``demographics``, ``instructions``, ``briefing`` (the instructions of the next trial's condition,
where the interface changes), ``trial``, ``exit``, ``saving`` (the exit survey waits for the
last events), ``done`` (the end page, with the completion code in ``#completion-code``), ``message`` (a notice,
such as a link that cannot be used) and ``mturk-preview`` (an MTurk HIT not yet accepted).
"""

from __future__ import annotations

import json
from dataclasses import dataclass, field
from html.parser import HTMLParser


@dataclass
class Page:
    """A participant page as read from its HTML."""

    step: str | None = None
    #: the form's CSRF token, when the page has a form
    csrf: str | None = None
    #: the scene editor's boot data (``<script id="boot">``), on trial pages
    boot: dict | None = None
    #: the completion code on the end page
    code: str | None = None
    #: radio groups: name → values, in page order
    radios: dict[str, list[str]] = field(default_factory=dict)
    #: number inputs: name → (min, max)
    numbers: dict[str, tuple[float, float]] = field(default_factory=dict)
    texts: list[str] = field(default_factory=list)
    hidden: dict[str, str] = field(default_factory=dict)
    #: what a notice page says (``<p id="message">``), e.g. why an entry link was refused
    message: str | None = None


class _Reader(HTMLParser):
    def __init__(self):
        super().__init__()
        self.page = Page()
        self._capture: str | None = None  # "boot" or "code" while inside that element
        self._text: list[str] = []

    def handle_starttag(self, tag, attrs):
        a = dict(attrs)
        p = self.page
        if tag == "body":
            p.step = a.get("data-step") or None
        elif tag == "input":
            kind, name = a.get("type"), a.get("name")
            if name == "csrf_token":
                p.csrf = a.get("value", "")
            elif kind == "radio":
                p.radios.setdefault(name, []).append(a.get("value", ""))
            elif kind == "number":
                p.numbers[name] = (float(a.get("min", 0)), float(a.get("max", 99)))
            elif kind == "hidden":
                p.hidden[name] = a.get("value", "")
        elif tag == "textarea":
            p.texts.append(a["name"])
        elif tag == "script" and a.get("id") == "boot":
            self._capture, self._text = "boot", []
        elif a.get("id") == "completion-code":
            self._capture, self._text = "code", []
        elif a.get("id") == "message":
            self._capture, self._text = "message", []

    def handle_data(self, data):
        if self._capture:
            self._text.append(data)

    def handle_endtag(self, tag):
        if self._capture == "boot" and tag == "script":
            self.page.boot = json.loads("".join(self._text))
            self._capture = None
        elif self._capture in ("code", "message"):
            setattr(self.page, self._capture, " ".join("".join(self._text).split()))
            self._capture = None


def read_page(html: bytes | str) -> Page:
    """Read a participant page (its step, form fields, boot data and completion code)."""
    reader = _Reader()
    reader.feed(html.decode(errors="replace") if isinstance(html, bytes) else html)
    reader.close()
    return reader.page

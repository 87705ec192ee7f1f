"""The device check: what a participant's browser reports before consent, and whether it can run the trial.

The page (``templates/device.html``, ``static/js/device.js``) tests for real what the trial page needs: JavaScript
modules with the import map, a WebGL 2 context of the kind the editor creates, the editor's shaders compiling,
``localStorage`` (the outbox and the scene kept across reloads), pointer events, ``ResizeObserver`` and modal
dialogs; then it draws a small scene with the editor's renderer and materials for at most :data:`PROBE_SECONDS`
and reports the frame rate. A browser that lacks a feature reports its name in ``missing``; one without
JavaScript posts the form's default, ``missing=script``.

:func:`parse_report` turns the posted form into a report or refuses it (422, naming the field): a report that
lies about what a browser can measure (a negative size, a frame rate no display draws, a missing field, unknown
features) stores nothing. :func:`screen` lists the reasons a study screens the browser out, as codes;
:func:`reason_text` says each in the participant's language.
"""

from __future__ import annotations

import math
import re

from flask_babel import gettext as _

from ..base.errors import RequestError

#: What the trial page needs, as the device page names it when missing (in the order it tests them).
FEATURES = ("script", "modules", "importmap", "storage", "pointer_events", "resize_observer", "dialog", "webgl2",
            "shaders")
#: Features without which no frame rate can be measured: a report that lacks one of them has no ``fps``.
NO_FRAMES = frozenset({"script", "modules", "importmap", "webgl2", "shaders"})
#: The longest the frame-rate probe draws, in seconds (it stops sooner once it has counted its frames).
PROBE_SECONDS = 2.0
#: The highest frame rate a report may claim (frames per second): no display refreshes faster.
MAX_FPS = 1000.0
MAX_PIXELS = 100_000
MAX_RENDERER = 200
MOBILE = re.compile(r"Mobi|Android|iPhone|iPad|iPod|Windows Phone", re.I)
PRINTABLE = re.compile(r"[\x20-\x7e\u00a0-\uffff]*")


def _bad(field: str, expected: str) -> RequestError:
    return RequestError(422, f"the device check's {field} is not valid: expected {expected}", field)


def _required(form, field: str) -> str:
    value = form.get(field)
    if value is None:
        raise RequestError(422, f"the device check's report has no {field}", field)
    return value


def _pixels(form, field: str) -> int:
    raw = _required(form, field)
    if not (raw.isascii() and raw.isdigit()) or int(raw) > MAX_PIXELS:
        raise _bad(field, f"whole CSS pixels from 0 to {MAX_PIXELS}")
    return int(raw)


def _number(form, field: str, low: float, high: float, low_open: bool = False) -> float:
    raw = _required(form, field)
    try:
        value = float(raw) if len(raw) <= 32 else math.nan
    except ValueError:
        value = math.nan
    if not math.isfinite(value) or value > high or value < low or (low_open and value == low):
        raise _bad(field, f"a number {'above' if low_open else 'from'} {low:g} {'up ' if low_open else ''}to {high:g}")
    return value


def parse_report(form) -> dict:
    """The browser's report from the posted device form, or :class:`RequestError` (422) naming the field that is
    missing or not what a browser measures. Sizes are CSS pixels; ``fps`` is frames per second (None when
    a missing feature left nothing to draw)."""
    missing_raw = _required(form, "missing")
    missing = [m for m in missing_raw.split(",") if m] if len(missing_raw) <= 200 else None
    if missing is None or any(m not in FEATURES for m in missing) or len(set(missing)) != len(missing):
        raise _bad("missing", "a comma-separated list of the features " + ", ".join(FEATURES))
    if "script" in missing:  # no JavaScript ran: the form's defaults, nothing measured
        return {"width": 0, "height": 0, "pixel_ratio": None, "touch_only": False, "missing": missing, "fps": None,
                "renderer": ""}
    touch = _required(form, "touch_only")
    if touch not in ("true", "false"):
        raise _bad("touch_only", "true or false")
    report = {"width": _pixels(form, "width"), "height": _pixels(form, "height"),
              "pixel_ratio": round(_number(form, "pixel_ratio", 0, 16, low_open=True), 4),
              "touch_only": touch == "true", "missing": missing, "fps": None}
    if NO_FRAMES.isdisjoint(missing):
        report["fps"] = round(_number(form, "fps", 0, MAX_FPS), 2)
    elif form.get("fps", "") != "":
        raise _bad("fps", "no frame rate from a browser that could not draw (missing " + ", ".join(missing) + ")")
    renderer = form.get("renderer", "")
    if len(renderer) > MAX_RENDERER or not PRINTABLE.fullmatch(renderer):
        raise _bad("renderer", f"the WebGL renderer's name (printable, at most {MAX_RENDERER} characters)")
    report["renderer"] = renderer
    return report


def screen(report: dict, study, user_agent: str) -> list[str]:
    """Why ``study`` screens this browser out, as codes: the features it lacks (:data:`FEATURES`), then
    ``desktop`` (a phone or tablet where the study is desktop-only), ``window`` (smaller than the study's
    minimum) and ``slow`` (a frame rate under ``device.min_fps``). Empty: the browser can take part."""
    reasons = list(report["missing"])
    if "script" in reasons:
        return reasons
    if study.desktop_only and (MOBILE.search(user_agent or "") or report["touch_only"]):
        reasons.append("desktop")
    if report["width"] < study.min_width or report["height"] < study.min_height:
        reasons.append("window")
    if report["fps"] is not None and report["fps"] < study.min_fps:
        reasons.append("slow")
    return reasons


def reason_text(code: str, study, report: dict) -> str:
    """One reason of :func:`screen`, in the participant's language."""
    texts = {
        "script": _("JavaScript is switched off in this browser."),
        "modules": _("This browser is too old to run the 3D editor (it cannot load JavaScript modules)."),
        "importmap": _("This browser is too old to run the 3D editor (it does not support import maps)."),
        "storage": _("This browser does not let the page keep your work (storage is blocked, as in some private "
                     "windows)."),
        "pointer_events": _("This browser is too old to run the 3D editor (it lacks pointer events)."),
        "resize_observer": _("This browser is too old to run the 3D editor (it lacks ResizeObserver)."),
        "dialog": _("This browser is too old to run the 3D editor (it lacks dialogs)."),
        "webgl2": _("This browser cannot show 3D graphics: WebGL 2 is switched off, blocked or not supported."),
        "shaders": _("This browser's 3D graphics could not draw the editor's materials."),
        "desktop": _("This study needs a desktop or laptop computer with a mouse or trackpad."),
        "window": _("The browser window is %(width)s × %(height)s pixels; the 3D editor needs at least %(min_width)s"
                    " × %(min_height)s.", width=report.get("width", 0), height=report.get("height", 0),
                    min_width=study.min_width, min_height=study.min_height),
        "slow": _("This computer drew %(fps)s frames a second; the 3D editor needs at least %(min_fps)s.",
                  fps=f"{report.get('fps') or 0:.1f}", min_fps=f"{study.min_fps:g}"),
    }
    return texts[code]

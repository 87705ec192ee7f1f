"""three.js as the npm registry ships it, at the version package-lock.json pins (:mod:`study_server.base.importmap`).

Served under /vendor/three/: ``build/`` (three.module.js imports ./three.core.js) and ``examples/jsm/`` (the
loaders and controls, which import the bare specifier ``three`` — resolved by the page's import map,
:mod:`study_server.base.importmap`)."""

from __future__ import annotations

from flask import Blueprint, send_from_directory
from werkzeug.exceptions import NotFound

from ..base.importmap import three_folder

bp = Blueprint("vendor", __name__, url_prefix="/vendor")


@bp.get("/three/<path:filename>")
def three(filename: str):
    if not (filename.startswith("build/") or filename.startswith("examples/jsm/")) or not filename.endswith(".js"):
        raise NotFound()
    response = send_from_directory(three_folder(), filename, max_age=24 * 3600)
    response.headers["Cache-Control"] = "public, max-age=86400"
    return response

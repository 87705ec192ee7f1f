"""three.js from node_modules (installed from the npm registry at the version package-lock.json pins).

Served under /vendor/three/: ``build/`` (three.module.js imports ./three.core.js) and ``examples/jsm/`` (the
loaders and controls, which import the bare specifier ``three`` — resolved by the page's import map, whose
hash the Content-Security-Policy allows)."""

from __future__ import annotations

import base64
import hashlib
import json

from flask import Blueprint, send_from_directory
from werkzeug.exceptions import NotFound

from ..config import ROOT

bp = Blueprint("vendor", __name__, url_prefix="/vendor")
THREE = ROOT / "node_modules" / "three"
IMPORT_MAP = json.dumps({"imports": {"three": "/vendor/three/build/three.module.js",
                                     "three/addons/": "/vendor/three/examples/jsm/"}})
IMPORT_MAP_HASH = "sha256-" + base64.b64encode(hashlib.sha256(IMPORT_MAP.encode()).digest()).decode()


@bp.get("/three/<path:filename>")
def three(filename: str):
    if not (filename.startswith("build/") or filename.startswith("examples/jsm/")) or not filename.endswith(".js"):
        raise NotFound()
    response = send_from_directory(THREE, filename, max_age=24 * 3600)
    response.headers["Cache-Control"] = "public, max-age=86400"
    return response

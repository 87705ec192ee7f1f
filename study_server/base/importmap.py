"""Where three.js comes from and the page's import map (its hash is what the Content-Security-Policy allows).

three.js is installed from the npm registry at the version package-lock.json pins: in a checkout ``npm ci`` puts it
in ``node_modules/three``; an installed package carries the files the client imports in ``study_server/vendor/three``
(copied there when the wheel is built, see ``setup.py``). The ``vendor`` blueprint serves ``build/`` and
``examples/jsm/`` of that folder under ``/vendor/three/``.
"""

from __future__ import annotations

import base64
import hashlib
import json
from pathlib import Path

from .config import PACKAGE, checkout


def three_folder() -> Path:
    """node_modules/three of the checkout the server runs from, else the copy the installed package carries."""
    root = checkout()
    return root / "node_modules" / "three" if root is not None else PACKAGE / "vendor" / "three"


IMPORT_MAP = json.dumps({"imports": {"three": "/vendor/three/build/three.module.js",
                                     "three/addons/": "/vendor/three/examples/jsm/"}})
IMPORT_MAP_HASH = "sha256-" + base64.b64encode(hashlib.sha256(IMPORT_MAP.encode()).digest()).decode()

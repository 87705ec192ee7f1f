"""Where three.js comes from and the page's import map (its hash is what the Content-Security-Policy allows).

three.js is installed from the npm registry at the version package-lock.json pins, into ``node_modules/three``;
the ``vendor`` blueprint serves ``build/`` and ``examples/jsm/`` from there under ``/vendor/three/``.
"""

from __future__ import annotations

import base64
import hashlib
import json

from .config import ROOT

THREE = ROOT / "node_modules" / "three"
IMPORT_MAP = json.dumps({"imports": {"three": "/vendor/three/build/three.module.js",
                                     "three/addons/": "/vendor/three/examples/jsm/"}})
IMPORT_MAP_HASH = "sha256-" + base64.b64encode(hashlib.sha256(IMPORT_MAP.encode()).digest()).decode()

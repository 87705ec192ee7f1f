"""Packaging beyond pyproject.toml: the wheel carries the three.js files the browser client imports.

three.js comes from the npm registry at the version package-lock.json pins (``npm ci`` puts it in node_modules);
it is never committed. Building the wheel copies into ``study_server/vendor/three/`` exactly the files the
client's modules import — ``three``, the ``three/addons/…`` modules, and what those import in turn — with three's
licence, so an installed server needs neither node_modules nor a CDN (its Content-Security-Policy allows
scripts from itself only, and a study must run offline from a CDN's outages). An editable install reads
node_modules directly.
"""

from __future__ import annotations

import os
import re
import shutil
from pathlib import Path

from setuptools import setup
from setuptools.command.build_py import build_py

HERE = Path(__file__).resolve().parent
THREE = HERE / "node_modules" / "three"
CLIENT = HERE / "study_server" / "static" / "js"
#: static imports and re-exports (``import … from "x"``, ``export … from "x"``, ``import "x"``) at a line's start
IMPORT = re.compile(r"""^(?:import|export)\s(?:[^;]*?\sfrom\s*)?["']([^"']+)["']""", re.M | re.S)


def _resolve(spec: str, importer: Path) -> Path | None:
    """The file of node_modules/three an import specifier names (None for the client's own modules)."""
    if spec == "three":
        return THREE / "build" / "three.module.js"
    if spec.startswith("three/addons/"):
        return THREE / "examples" / "jsm" / spec.removeprefix("three/addons/")
    if spec.startswith(".") and importer.is_relative_to(THREE):
        return Path(os.path.normpath(importer.parent / spec))  # node_modules may be a link: do not follow it
    return None


def three_files() -> set[Path]:
    """The three.js files the client needs: the closure of the imports of its modules."""
    todo = [(spec, js) for js in CLIENT.glob("*.js") for spec in IMPORT.findall(js.read_text(encoding="utf-8"))]
    found: set[Path] = set()
    while todo:
        spec, importer = todo.pop()
        path = _resolve(spec, importer)
        if path is None or path in found:
            continue
        if not path.is_file():
            raise SystemExit(f"{importer} imports {spec!r}, which node_modules/three does not have")
        found.add(path)
        todo += [(s, path) for s in IMPORT.findall(path.read_text(encoding="utf-8"))]
    return found


class BuildWithThree(build_py):
    def run(self):
        super().run()
        if getattr(self, "editable_mode", False):
            return
        if not (THREE / "package.json").is_file():
            raise SystemExit("three.js is missing: build the wheel with 'make wheel' (it runs npm ci first)")
        target = Path(self.build_lib) / "study_server" / "vendor" / "three"
        for path in sorted(three_files()) + [THREE / "LICENSE", THREE / "package.json"]:
            out = target / path.relative_to(THREE)
            out.parent.mkdir(parents=True, exist_ok=True)
            shutil.copyfile(path, out)


setup(cmdclass={"build_py": BuildWithThree})

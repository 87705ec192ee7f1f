"""The layering, read from the source: the engine imports neither the server nor the analysis; in the server,
services never import blueprints and no blueprint imports another."""

from __future__ import annotations

import ast
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def imports(path: Path) -> set[str]:
    """Absolute names of the modules ``path`` imports (relative imports resolved against its package)."""
    package = path.relative_to(ROOT).with_suffix("").parts[:-1]
    out = set()
    for node in ast.walk(ast.parse(path.read_text())):
        if isinstance(node, ast.Import):
            out |= {a.name for a in node.names}
        elif isinstance(node, ast.ImportFrom):
            base = list(package[:len(package) - node.level + 1]) if node.level else []
            module = ".".join([*base, *(node.module.split(".") if node.module else [])])
            out.add(module)
            out |= {f"{module}.{a.name}" for a in node.names}
    return out


def test_the_engine_imports_neither_the_server_nor_the_analysis():
    for path in (ROOT / "scenesuggest").rglob("*.py"):
        bad = {m for m in imports(path) if m.split(".")[0] in ("study_server", "analysis", "simulation")}
        assert not bad, (path, bad)


def test_the_analysis_does_not_import_the_server():
    for path in (ROOT / "analysis").rglob("*.py"):
        assert not {m for m in imports(path) if m.startswith("study_server")}, path


def test_server_layers_point_down_only():
    blueprints = ROOT / "study_server" / "blueprints"
    for path in (ROOT / "study_server").glob("*.py"):
        if path.name in ("__init__.py", "cli.py"):  # the composition roots
            continue
        assert not {m for m in imports(path) if m.startswith("study_server.blueprints")}, path
    for path in blueprints.glob("*.py"):
        others = {m for m in imports(path) if m.startswith("study_server.blueprints.")
                  and m.split(".")[2] != path.stem}
        assert not others, (path, others)

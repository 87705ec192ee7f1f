"""The layering, read from the source: the engine imports none of the other packages; the simulation drives the
server from outside; the analysis reads data only; in the server, services never import blueprints and no blueprint
imports another; no package has an import cycle."""

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


def test_the_analysis_imports_neither_the_server_nor_the_simulation():
    for path in (ROOT / "analysis").rglob("*.py"):
        assert not {m for m in imports(path) if m.split(".")[0] in ("study_server", "simulation")}, path


def test_the_server_never_imports_the_simulation():
    for path in (ROOT / "study_server").rglob("*.py"):
        assert not {m for m in imports(path) if m.split(".")[0] == "simulation"}, path


#: The engine's stages in the order its data flows; each imports only stages before it. The modules at the top of
#: the package (errors, atomic writes, JSON positions, npz, digests) are shared by all and import no stage; cli.py
#: files are composition roots (the ``scenesuggest`` command and its groups) and may import anything.
STAGES = ("scenes", "contract", "library", "corpora", "assets", "learning", "suggestion", "engines", "evaluation")


def test_the_engine_stages_point_down():
    package = ROOT / "scenesuggest"
    assert {p.name for p in package.iterdir() if (p / "__init__.py").is_file()} == set(STAGES)
    for path in package.rglob("*.py"):
        parts = path.relative_to(package).parts
        if path.name == "cli.py":
            continue
        below = STAGES[:STAGES.index(parts[0])] if len(parts) > 1 else ()
        for m in imports(path):
            names = m.split(".")
            if names[0] == "scenesuggest" and len(names) > 1 and names[1] in STAGES:
                assert names[1] == parts[0] or names[1] in below, (path, m)


def test_the_simulation_drives_the_server_from_outside():
    """Bots reach the server over HTTP or a test client and never read the analysis. Only the composition roots
    build an app (with the public factory), read a study's answers in process (the offline answers) or sign their
    bots' entry links as pilots', and only
    the ones that score simulated studies, as an analyst would, use the analysis: the calibration and the power
    analysis."""
    factory = {"study_server", "study_server.create_app", "study_server.upgrade_database"}
    offline = {"study_server.trials", "study_server.trials.offline", "study_server.trials.offline.OfflineAnswers"}
    # entry links signed as pilots', and the pilot database
    pilots = {"study_server.participants", "study_server.participants.pilots"}
    roots = {"cli.py": factory | offline | pilots, "calibrate.py": offline, "power.py": factory}
    readers = {"calibrate.py", "power.py"}
    for path in (ROOT / "simulation").rglob("*.py"):
        found = imports(path)
        server = {m for m in found if m.split(".")[0] == "study_server"}
        assert server <= roots.get(path.name, set()), (path, server)
        if path.name not in readers:
            assert not {m for m in found if m.split(".")[0] == "analysis"}, path


#: The server's rooms, each importing only those before it; blueprints (routes) stand on all of them and the package's
#: faces — ``__init__.py`` (the app factory) and ``cli.py`` (the ``study`` commands) — are composition roots.
ROOMS = ("base", "studies", "participants", "trials", "experimenter")
#: What else the server's folder holds: routes, and folders of data (templates, scripts, migrations, study files).
SERVER_FOLDERS = {"blueprints", "templates", "static", "translations", "migrations", "demo", "starter", "deploy"}


def test_the_server_root_holds_its_faces_and_rooms_only():
    server = ROOT / "study_server"
    assert {p.name for p in server.glob("*.py")} == {"__init__.py", "cli.py"}
    folders = {p.name for p in server.iterdir() if p.is_dir() and p.name != "__pycache__"}
    assert folders == set(ROOMS) | SERVER_FOLDERS
    assert all((server / room / "__init__.py").is_file() for room in ROOMS)


def test_the_server_rooms_point_down():
    server = ROOT / "study_server"
    for room in ROOMS:
        below = set(ROOMS[:ROOMS.index(room) + 1])
        for path in (server / room).rglob("*.py"):
            reached = {m.split(".")[1] for m in imports(path) if m.startswith("study_server.")}
            assert reached <= below, (path, reached - below)


def test_server_layers_point_down_only():
    blueprints = ROOT / "study_server" / "blueprints"
    for room in ROOMS:
        for path in (ROOT / "study_server" / room).rglob("*.py"):
            assert not {m for m in imports(path) if m.startswith("study_server.blueprints")}, path
    for path in blueprints.glob("*.py"):
        others = {m for m in imports(path) if m.startswith("study_server.blueprints.")
                  and m.split(".")[2] != path.stem}
        assert not others, (path, others)


#: What records a participant's history (the session log and the flags): services' business, never a route's.
RECORDERS = {"flag", "log", "log_again"}


def test_routes_record_nothing_themselves():
    """A route parses, calls one service and answers: it writes no session log and raises no flag."""
    for path in (ROOT / "study_server" / "blueprints").glob("*.py"):
        recorded = {m.rsplit(".", 1)[1] for m in imports(path) if m.startswith("study_server.base.models.")}
        assert not recorded & RECORDERS, (path, recorded & RECORDERS)


#: The tests' helpers that bring the server in (its app, a participant's walk, a served instance).
SERVER_HELPERS = ("study_server", "demostudy", "flowhelp", "serverproc", "integrityhelp")


def test_the_engines_tests_stand_without_the_server():
    """tests/engine/ tests the library: no module of it, nor a helper it imports, brings the server in."""
    helpers = {p.stem: p for p in (ROOT / "tests").glob("*.py")}
    for path in (ROOT / "tests" / "engine").rglob("*.py"):
        found = {m.split(".")[0] for m in imports(path)}
        found |= {m.split(".")[0] for name in found & helpers.keys() for m in imports(helpers[name])}
        assert not found & set(SERVER_HELPERS), (path, found & set(SERVER_HELPERS))


def test_no_test_imports_a_conftest():
    """pytest's conftest files hold hooks and fixtures; helpers live in modules of their own (support.py,
    demostudy.py, the *help.py modules), so that no conftest can stand in for another."""
    for path in (ROOT / "tests").rglob("*.py"):
        assert not {m for m in imports(path) if "conftest" in m.split(".")}, path


PACKAGES = ("scenesuggest", "study_server", "simulation", "analysis")


def _module_graph(package: str) -> dict[str, set[str]]:
    """Which modules of ``package`` each of its modules imports, function-level imports included. ``from . import
    x`` counts as importing the submodule ``x`` only: a package is initialised before any of its modules runs, so
    counting it too would make every ``__init__`` that imports its own modules look circular."""
    files = {".".join(p.relative_to(ROOT).with_suffix("").parts).removesuffix(".__init__"): p
             for p in (ROOT / package).rglob("*.py")}
    graph = {}
    for name, path in files.items():
        found = imports(path)
        edges = found & files.keys() - {name}
        for pkg in {m for m in edges if files[m].name == "__init__.py"}:
            members = {m for m in found if m.startswith(f"{pkg}.") and "." not in m[len(pkg) + 1:]}
            if members and members <= files.keys():
                edges.discard(pkg)
        graph[name] = edges
    return graph


def _cycles(graph: dict[str, set[str]]) -> list[set[str]]:
    """The strongly connected components with more than one module."""
    import networkx as nx

    g = nx.DiGraph([(a, b) for a, targets in graph.items() for b in targets])
    return [set(c) for c in nx.strongly_connected_components(g) if len(c) > 1]


def test_no_import_cycles_within_a_package():
    assert [c for package in PACKAGES for c in _cycles(_module_graph(package))] == []


def test_the_server_reaches_engines_by_name_only():
    """Engines are a registry: the server loads them through it (scenesuggest.engines and its protocol) and imports
    no engine's own module — but the http engine's published schemas (wire), which the OpenAPI document carries."""
    engine_modules = {p.stem for p in (ROOT / "scenesuggest" / "engines").glob("*.py")} - {"__init__", "protocol"}
    engine_modules |= {p.name for p in (ROOT / "scenesuggest" / "engines").iterdir() if (p / "__init__.py").is_file()}
    assert {"paper", "learned", "frequency", "http"} <= engine_modules
    schemas = {"scenesuggest.engines.wire", "scenesuggest.engines.wire.QUERY_SCHEMA",
               "scenesuggest.engines.wire.ANSWER_SCHEMA"}
    for path in (ROOT / "study_server").rglob("*.py"):
        reached = {m for m in imports(path) if m.split(".")[:2] == ["scenesuggest", "engines"] and len(m.split(".")) > 2
                   and m.split(".")[2] in engine_modules}
        assert reached <= schemas, (path, reached - schemas)

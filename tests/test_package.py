"""The package ships what it needs: built as a wheel and installed into a fresh virtual environment outside the
checkout, it prepares, migrates and serves the built-in demo study — templates, static files, migrations, the
demo's files and three.js all come from the installed package."""

from __future__ import annotations

import json
import os
import re
import shutil
import signal
import subprocess
import sys
import sysconfig
import urllib.request
from pathlib import Path

import pytest
from conftest import ROOT
from serverproc import free_port

from simulation.transport import HttpTransport
from simulation.walker import Walker

IMPORT = re.compile(r"""^(?:import|export)\s(?:[^;]*?\sfrom\s*)?["']([^"']+)["']""", re.M | re.S)


@pytest.fixture(scope="module")
def installed(tmp_path_factory) -> Path:
    """A virtual environment outside the checkout with the wheel installed (without its dependencies, which the
    test environment's site-packages lends it: installing numpy, scipy … from the registry would take minutes)."""
    if not (ROOT / "node_modules" / "three" / "package.json").is_file():
        pytest.fail("node_modules/three is missing: run 'make setup' (npm ci) first")
    tmp = tmp_path_factory.mktemp("wheel")
    source = tmp / "source"  # the checkout's files as they are, without what earlier builds left in build/
    files = subprocess.run(["git", "ls-files", "--cached", "--others", "--exclude-standard", "-z"], cwd=ROOT,
                           capture_output=True, check=True).stdout.decode().split("\0")
    for name in filter(None, files):
        if (ROOT / name).is_file():
            (source / name).parent.mkdir(parents=True, exist_ok=True)
            shutil.copy2(ROOT / name, source / name)
    (source / "node_modules").symlink_to(ROOT / "node_modules")
    built = subprocess.run([sys.executable, "-m", "pip", "wheel", "--no-deps", "-q", "-w", str(tmp / "dist"),
                            str(source)], capture_output=True, text=True)
    assert built.returncode == 0, built.stdout + built.stderr
    venv = tmp / "venv"
    subprocess.run([sys.executable, "-m", "venv", str(venv)], check=True)
    site = next((venv / "lib").glob("python*/site-packages"))
    (site / "dependencies.pth").write_text(sysconfig.get_paths()["purelib"] + "\n")
    wheel = next((tmp / "dist").glob("scenesuggest_studio-*.whl"))
    subprocess.run([str(venv / "bin" / "python"), "-m", "pip", "install", "-q", "--no-deps", str(wheel)], check=True,
                   capture_output=True)
    return venv


def run(venv: Path, *args: str, env: dict, cwd: Path) -> subprocess.CompletedProcess:
    return subprocess.run([str(venv / "bin" / "scenesuggest"), *args], env=env, cwd=cwd, capture_output=True,
                          text=True, timeout=600)


@pytest.mark.slow
def test_the_wheel_installed_elsewhere_prepares_migrates_and_serves_the_demo(installed, tmp_path):
    elsewhere, home = tmp_path / "elsewhere", tmp_path / "home"
    elsewhere.mkdir()
    env = {k: v for k, v in os.environ.items() if not k.startswith(("SCENESUGGEST_", "DATABASE_URL"))}
    env |= {"SCENESUGGEST_HOME": str(home), "PYTHONPATH": ""}
    where = subprocess.run([str(installed / "bin" / "python"), "-c", "import study_server, simulation; "
                            "print(study_server.__file__); print(simulation.__file__)"],
                           env=env, cwd=elsewhere, capture_output=True, text=True, check=True).stdout.split()
    assert all(Path(w).is_relative_to(installed) for w in where), where

    prepared = run(installed, "study", "prepare", "--json", env=env, cwd=elsewhere)
    assert prepared.returncode == 0, prepared.stderr
    assert json.loads(prepared.stdout) == {"built": ["demo: library", "demo: priors"]}
    assert (home / "priors" / "ai2thor.npz").is_file() and (home / "library" / "ai2thor" / "library.json").is_file()
    again = run(installed, "study", "prepare", "--json", env=env, cwd=elsewhere)
    assert json.loads(again.stdout) == {"built": []}  # nothing twice

    migrated = run(installed, "study", "migrate", env=env, cwd=elsewhere)
    assert migrated.returncode == 0 and "newest schema revision" in migrated.stdout, migrated.stderr
    assert (home / "instance" / "studies.sqlite3").is_file()

    port = free_port()
    server = subprocess.Popen([str(installed / "bin" / "scenesuggest"), "study", "serve", "--port", str(port),
                               "--workers", "1"], env=env, cwd=elsewhere, stdout=subprocess.PIPE,
                              stderr=subprocess.STDOUT, start_new_session=True)
    base = f"http://127.0.0.1:{port}"
    try:
        http = HttpTransport(base, retry_for=60.0)
        page = Walker(http, "demo").to_first_trial(
            {"pid": "installed"}, lambda _: {"age": "40", "experience_3d": "Never", "pointing_device": "Mouse"})
        assert page.step == "trial" and page.boot["trial"]["scene"] == "practice"
        assert http.get("/static/css/study.css").status == 200
        # every module the trial page loads, through the import map, down to three.js's own imports
        imports = json.loads(re.search(r'<script type="importmap">(.*?)</script>',
                                       http.get("/study/demo/").text, re.S).group(1))["imports"]
        seen = _module_graph(http, "/static/js/trial.js", imports)
        assert {"/vendor/three/build/three.core.js", "/vendor/three/examples/jsm/loaders/GLTFLoader.js"} <= seen
        models = http.get("/api/models", headers={"Authorization": f"Bearer {page.boot['token']}"}).json()["models"]
        glb = http.get(models[0]["asset"])
        assert glb.status == 200 and glb.body[:4] == b"glTF"
    finally:
        os.killpg(server.pid, signal.SIGTERM)
        output = server.communicate(timeout=30)[0].decode(errors="replace")
    assert f"participant link: {base}/study/demo/start" in output


def _module_graph(http: HttpTransport, entry: str, imports: dict[str, str]) -> set[str]:
    """The URLs of every ES module reachable from ``entry`` by static imports (bare specifiers through the import
    map), each fetched once and required to answer 200 with JavaScript."""
    todo, seen = [entry], set()
    while todo:
        url = todo.pop()
        if url in seen:
            continue
        seen.add(url)
        r = http.get(url)
        assert r.status == 200, (url, r.status)
        for spec in IMPORT.findall(r.text):
            if spec in imports:
                todo.append(imports[spec])
            elif any(spec.startswith(p) for p in imports if p.endswith("/")):
                prefix = next(p for p in imports if p.endswith("/") and spec.startswith(p))
                todo.append(imports[prefix] + spec[len(prefix):])
            else:
                todo.append(urllib.request.urljoin(url, spec))
    return seen


def test_serving_from_the_checkout_needs_no_copy_of_three(tmp_path):
    """In a checkout the server reads node_modules/three as npm installed it; installed, its bundled copy."""
    from study_server.config import checkout
    from study_server.importmap import three_folder

    assert checkout() == ROOT and three_folder() == ROOT / "node_modules" / "three"


def test_prepare_names_what_a_study_lacks(tmp_path, demo_resources):
    """Missing resources, and a priors file this engine cannot read, are what ``study prepare`` builds; resources
    a study file does not name are the server's own for its corpus, in its data folder."""
    import shutil

    from study_server.config import data_home
    from study_server.prepare import missing
    from study_server.study_file import load_study

    default = load_study(demo_resources)
    assert default.priors == data_home() / "priors" / "ai2thor.npz" and missing(default) == []
    study = tmp_path / "study.toml"
    shutil.copytree(demo_resources.parent / "scenes", tmp_path / "scenes")
    study.write_text(demo_resources.read_text().replace('corpus = "ai2thor"',
                                                        'corpus = "ai2thor"\npriors = "p.npz"\nlibrary = "lib"'))
    assert missing(load_study(study)) == ["library", "priors"]
    (tmp_path / "p.npz").write_bytes(b"not a priors file")
    assert missing(load_study(study)) == ["library", "priors"]
    shutil.copyfile(default.priors, tmp_path / "p.npz")
    (tmp_path / "lib").symlink_to(default.library)
    assert missing(load_study(study)) == []

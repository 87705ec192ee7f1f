"""The package ships what it needs: built as a wheel and installed into a fresh virtual environment outside the
checkout, it prepares, migrates and serves the built-in demo study — templates, static files, migrations, the
demo's files and three.js all come from the installed package, and the editor runs in Chromium."""

from __future__ import annotations

import json
import os
import shutil
import signal
import subprocess
import sys
import sysconfig
from pathlib import Path

import pytest
from serverproc import free_port
from support import ROOT

from simulation.transport import HttpTransport
from simulation.walker import Walker


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
    # the packaging says what it ships: setuptools finds no importable folder it was not told about
    assert "would be ignored" not in built.stdout + built.stderr, built.stderr[:2000]
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
@pytest.mark.browser
def test_the_wheel_installed_elsewhere_starts_a_study_prepares_migrates_and_serves(installed, tmp_path):
    elsewhere, home = tmp_path / "elsewhere", tmp_path / "home"
    elsewhere.mkdir()
    env = {k: v for k, v in os.environ.items() if not k.startswith(("SCENESUGGEST_", "DATABASE_URL"))}
    env |= {"SCENESUGGEST_HOME": str(home), "PYTHONPATH": ""}
    where = subprocess.run([str(installed / "bin" / "python"), "-c", "import study_server, simulation; "
                            "print(study_server.__file__); print(simulation.__file__)"],
                           env=env, cwd=elsewhere, capture_output=True, text=True, check=True).stdout.split()
    assert all(Path(w).is_relative_to(installed) for w in where), where

    started = run(installed, "study", "init", "kitchen-study", "--title", "Kitchens", env=env, cwd=elsewhere)
    assert started.returncode == 0 and "wrote" in started.stdout, started.stderr
    valid = run(installed, "study", "validate", "kitchen-study/study.toml", env=env, cwd=elsewhere)
    assert "study 'kitchen-study' is valid" in valid.stdout and "are not built yet" in valid.stdout, valid.stderr
    demo = Path(where[0]).parent / "demo" / "study.toml"
    env["SCENESUGGEST_STUDIES"] = f"{demo}:{elsewhere / 'kitchen-study' / 'study.toml'}"

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
        loaded, failed = _open_in_chromium(base, http)
        assert failed == [] and {"/static/js/trial.js", "/vendor/three/build/three.core.js",
                                 "/vendor/three/examples/jsm/loaders/GLTFLoader.js"} <= loaded
        models = http.get("/api/models", headers={"Authorization": f"Bearer {page.boot['token']}"}).json()["models"]
        glb = http.get(models[0]["asset"])
        assert glb.status == 200 and glb.body[:4] == b"glTF"
        mine = Walker(HttpTransport(base), "kitchen-study").to_first_trial(
            {"pid": "new-study"}, lambda _: {"age": "40", "experience_3d": "Never", "pointing_device": "Mouse"})
        assert mine.step == "trial" and mine.boot["trial"]["scene"] == "practice"  # the new study runs as written
    finally:
        os.killpg(server.pid, signal.SIGTERM)
        output = server.communicate(timeout=30)[0].decode(errors="replace")
    assert f"participants' link (link): {base}/study/demo/start\n" in output
    test_link = output.split("test link (a pilot, new at each start: kept out of the data; open it yourself): ")[1]
    assert test_link.startswith(f"{base}/study/demo/start?pid=pilot-") and "&pilot=" in test_link.split()[0]


def _open_in_chromium(base: str, http: HttpTransport) -> tuple[set[str], list[str]]:
    """The participant's trial page in Chromium (the walker's cookies, the page's test hook on): waits until the
    editor runs; returns the paths of everything it loaded and the URLs that failed."""
    from browser.pagehelp import ARGS, CHROMIUM, TEST_HOOK, require_browser
    from playwright.sync_api import sync_playwright

    require_browser()
    failed = []
    with sync_playwright() as p:
        browser = p.chromium.launch(executable_path=CHROMIUM, args=ARGS)
        context = browser.new_context(viewport={"width": 1280, "height": 720})
        context.add_cookies(http.cookies())
        context.add_init_script(TEST_HOOK)
        page = context.new_page()
        page.on("response", lambda r: r.status >= 400 and failed.append(f"{r.status} {r.url}"))
        page.on("pageerror", lambda e: failed.append(str(e)))
        page.goto(f"{base}/study/demo/")
        page.wait_for_function("() => window.sceneSuggestTest && window.sceneSuggestTest.ready", timeout=60_000)
        loaded = page.evaluate("() => performance.getEntriesByType('resource').map(r => new URL(r.name).pathname)")
        browser.close()
    return set(loaded), failed


def test_serving_from_the_checkout_needs_no_copy_of_three(tmp_path):
    """In a checkout the server reads node_modules/three as npm installed it; installed, its bundled copy."""
    from study_server.base.config import checkout
    from study_server.base.importmap import three_folder

    assert checkout() == ROOT and three_folder() == ROOT / "node_modules" / "three"


def test_prepare_builds_only_the_servers_own_resources(tmp_path, demo_resources):
    """A study that names only its corpus uses the server's own priors and library, which ``study prepare``
    builds; what a study file names is checked (missing, or a file this engine cannot read) but never built over."""
    import shutil

    from scenesuggest.learning.priors import Priors
    from study_server.base.config import data_home
    from study_server.studies.prepare import prepare, problems
    from study_server.studies.study_file import StudyFileError, load_study

    default = load_study(demo_resources)
    assert default.server_resources and default.priors == data_home() / "priors" / "ai2thor.npz"
    assert problems(default, current=True) == {}
    shutil.copytree(demo_resources.parent / "scenes", tmp_path / "scenes")
    study = tmp_path / "study.toml"

    def named(resources: str):
        study.write_text(demo_resources.read_text().replace('corpus = "ai2thor"', resources))
        return load_study(study)

    own = named('corpus = "ai2thor"\npriors = "p.npz"\nlibrary = "lib"')
    assert not own.server_resources and sorted(problems(own)) == ["library", "priors"]
    (tmp_path / "p.npz").write_bytes(b"not a priors file")
    assert "not a priors file" in problems(own)["priors"] or "cannot read" in problems(own)["priors"]
    built = prepare(own, lambda items, label="": items, lambda message: None)
    assert built == [] and (tmp_path / "p.npz").read_bytes() == b"not a priors file"  # never built over
    shutil.copyfile(default.priors, tmp_path / "p.npz")
    (tmp_path / "lib").symlink_to(default.library)
    assert problems(own) == {}
    older = Priors.load(default.priors)
    older.meta["code"] = "trained-by-older-code"
    (tmp_path / "p.npz").unlink()
    older.save(tmp_path / "p.npz")
    assert problems(own) == {} and "other engine code" in problems(own, current=True)["priors"]
    for resources, key in [('corpus = "ai2thor"\npriors = "p.npz"', "resources.library"),
                           ('corpus = "json:elsewhere"', "resources.priors")]:
        with pytest.raises(StudyFileError) as info:
            named(resources)
        assert info.value.field == key

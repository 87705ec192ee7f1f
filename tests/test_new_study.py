"""``scenesuggest study init``: a new study that validates and runs as written, with the demo's keys, its own
completion codes, and nothing ever overwritten."""

import tomllib

import pytest
from conftest import DEMO_STUDY, make_app

from simulation.run import simulate
from study_server.new_study import InitError, init_study
from study_server.study_file import load_study


def keys(doc, prefix=""):
    """Every key path of a TOML document (arrays of tables merged)."""
    out = set()
    for k, v in doc.items():
        path = f"{prefix}{k}"
        out.add(path)
        for item in (v if isinstance(v, list) and all(isinstance(i, dict) for i in v) else [v]):
            if isinstance(item, dict):
                out |= keys(item, path + ".")
    return out


def test_a_new_study_has_the_demos_keys_its_own_codes_and_runs_as_written(tmp_path):
    written = init_study(tmp_path / "Kitchen Study", title='Kitchens "as they are"')
    folder = tmp_path / "Kitchen Study"
    assert [p.relative_to(folder).as_posix() for p in written] == [
        "README.md", "scenes/desk-corner.json", "scenes/practice.json", "study.toml"]
    study = load_study(folder / "study.toml")
    assert study.id == "kitchen-study" and study.title == 'Kitchens "as they are"'
    assert [list(p) for p in study.periods] == [["desk-corner"]] and study.practice == ("practice", "full")
    new = tomllib.loads((folder / "study.toml").read_text())
    demo = tomllib.loads(DEMO_STUDY.read_text())
    assert keys(new) == keys(demo)  # every key of the demo's, none of its own
    codes, demo_codes = new["platform"]["codes"], demo["platform"]["codes"]
    assert set(codes) == set(demo_codes) and not set(codes.values()) & set(demo_codes.values())
    assert len(set(codes.values())) == 5 and all(len(c.split("-")[0]) == 12 for c in codes.values())
    other = tomllib.loads(init_study(tmp_path / "other")[-1].read_text())
    assert not set(other["platform"]["codes"].values()) & set(codes.values())  # made at random each time
    assert "study validate" in (folder / "README.md").read_text()

    app = make_app(tmp_path / "server", studies=[folder / "study.toml"])
    summary = simulate(2, seed=1, study="kitchen-study", app=app)
    assert summary["completed"] == 2 and summary["trials"] == 6 and not summary["failures"]


def test_init_never_overwrites_and_names_what_is_wrong(tmp_path):
    used = tmp_path / "used"
    used.mkdir()
    (used / "notes.txt").write_text("mine")
    with pytest.raises(InitError) as info:
        init_study(used)
    assert "not an empty folder" in info.value.message and (used / "notes.txt").read_text() == "mine"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["used"]  # nothing left beside it either
    (tmp_path / "empty").mkdir()
    assert init_study(tmp_path / "empty")  # an empty folder is free
    for kwargs, field in (({"corpus": "stanford:/nowhere"}, "--corpus"), ({"study_id": "a b"}, "--id"),
                          ({"title": "two\nlines"}, "--title")):
        with pytest.raises(InitError) as info:
            init_study(tmp_path / "x", **kwargs)
        assert info.value.field == field
    assert not (tmp_path / "x").exists()


def test_the_command_writes_a_study_and_refuses_a_folder_in_use(tmp_path):
    import json
    import subprocess
    import sys

    def cli(*args):
        return subprocess.run([sys.executable, "-m", "scenesuggest.cli", "study", "init", *args],
                              capture_output=True, text=True, cwd=tmp_path)

    made = cli("pilot", "--title", "A pilot", "--json")
    assert made.returncode == 0, made.stderr
    assert [p.rsplit("/", 1)[-1] for p in json.loads(made.stdout)["files"]] == [
        "README.md", "desk-corner.json", "practice.json", "study.toml"]
    again = cli("pilot")
    assert again.returncode == 2 and "already exists and is not an empty folder" in again.stderr

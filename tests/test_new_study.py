"""``scenesuggest study init``: a new study that validates and runs as written, with the demo's keys, its own
completion codes, and nothing ever overwritten."""

import re
import tomllib

import pytest
from demostudy import DEMO_STUDY, make_app

from simulation.run import simulate
from study_server.studies.new_study import InitError, init_study
from study_server.studies.study_file import load_study

LANGUAGES = {"en", "de"}


def keys(doc, prefix=""):
    """Every key path of a TOML document (arrays of tables merged; a text given per language counts as its key)."""
    out = set()
    for k, v in doc.items():
        if isinstance(v, list) and v and all(isinstance(i, dict) and set(i) <= LANGUAGES for i in v):
            v = v[0]["en"]  # options, each given per language
        if isinstance(v, dict) and v and set(v) <= LANGUAGES:
            v = v["en"]
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
                          ({"title": "two\nlines"}, "--title"), ({"title": "lone \udc80 byte"}, "--title"),
                          ({"title": "x" * 10_000_000}, "--title"), ({"study_id": "a" * 65}, "--id"),
                          ({"corpus": "stanford:/tmp/\0x"}, "--corpus"), ({"meshes": "m\0"}, "--meshes")):
        with pytest.raises(InitError) as info:
            init_study(tmp_path / "x", **kwargs)
        assert info.value.field == field
    assert not (tmp_path / "x").exists()
    with pytest.raises(InitError) as info:
        init_study(str(tmp_path / "nul\0name"))
    assert info.value.field == "FOLDER"
    long = init_study(tmp_path / ("a" * 100))  # a long folder name: its id is cut to 64 characters
    assert load_study(long[-1]).id == "a" * 64
    assert sorted(p.name for p in tmp_path.iterdir()) == ["a" * 100, "empty", "used"]  # nothing else written


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
    here = tmp_path / "here"
    here.mkdir()
    made = subprocess.run([sys.executable, "-m", "scenesuggest.cli", "study", "init", ".", "--json"],
                          capture_output=True, text=True, cwd=here)  # the working directory, empty
    assert made.returncode == 0, made.stderr
    assert sorted(p.name for p in here.iterdir()) == ["README.md", "scenes", "study.toml"]


def test_what_init_writes_is_safe_whatever_the_folder_and_title(tmp_path):
    """A control character in the title, a folder named to run a command when its next steps are pasted, a ':'
    that SCENESUGGEST_STUDIES would split, names in other scripts, and the codes' file kept private."""
    import shlex
    import stat
    import subprocess
    import sys

    from study_server.studies.new_study import study_id_for

    for title in ("A\x7fpilot", "A\x85pilot", "two\nlines"):
        with pytest.raises(InitError) as info:
            init_study(tmp_path / "t", title=title)
        assert info.value.field == "--title" and not (tmp_path / "t").exists()
    with pytest.raises(InitError, match="holds ':'"):
        init_study(tmp_path / "a:b")
    assert not (tmp_path / "a:b").exists()
    assert study_id_for(tmp_path / "Étude Café") == "etude-cafe"
    ids = {study_id_for(tmp_path / name) for name in ("研究", "実験", "исследование")}
    assert len(ids) == 3 and all(re.fullmatch(r"study-[0-9a-f]{8}", i) for i in ids)
    hostile = tmp_path / "$(touch pwned)"
    made = subprocess.run([sys.executable, "-m", "scenesuggest.cli", "study", "init", str(hostile)],
                          capture_output=True, text=True, cwd=tmp_path)
    assert made.returncode == 0, made.stderr
    pasted = next(line for line in made.stdout.splitlines() if "study validate" in line).split("next:", 1)[1]
    assert shlex.split(pasted)[-1] == str(hostile / "study.toml")  # one word, as written
    ran = subprocess.run(["sh", "-c", pasted], cwd=tmp_path, capture_output=True, text=True)  # works as printed
    assert ran.returncode == 0 and "is valid" in ran.stdout, ran.stderr
    readme = (hostile / "README.md").read_text()
    assert "study validate study.toml`" in readme and str(tmp_path) not in readme  # the folder may move
    assert not (tmp_path / "pwned").exists()
    assert stat.S_IMODE((hostile / "study.toml").stat().st_mode) == 0o600


@pytest.mark.slow  # builds a real 100-model library: about a minute and a half
def test_a_study_on_the_stanford_corpus_gets_its_own_library_priors_and_scenes(tmp_path, stanford_dir,
                                                                               stanford_meshes, stanford):
    """`--corpus stanford:DIR`: a library of one model per top-100 category, priors trained on every scene of
    the corpus, starter scenes composed from the library's models; the study validates and runs as written."""
    import numpy as np

    from scenesuggest.corpora.representatives import read_representatives
    from scenesuggest.learning.priors import Priors
    from scenesuggest.library.index import load_index
    from scenesuggest.scenes import scene_json

    folder = tmp_path / "desks"
    said = []
    written = init_study(folder, corpus=f"stanford:{stanford_dir}", meshes=stanford_meshes, say=said.append)
    assert [p.relative_to(folder).as_posix() for p in written] == [
        "README.md", "library/stanford", "priors/stanford.npz", "scenes/desk-corner.json", "scenes/practice.json",
        "study.toml"]
    assert "100 models" in said[0]
    study = load_study(folder / "study.toml")
    assert study.corpus == f"stanford:{stanford_dir.resolve()}"
    assert study.priors == folder / "priors" / "stanford.npz" and study.library == folder / "library" / "stanford"
    new, demo = tomllib.loads((folder / "study.toml").read_text()), tomllib.loads(DEMO_STUDY.read_text())
    assert keys(new) == keys(demo) | {"resources.priors", "resources.library"}

    reps = read_representatives(stanford_meshes.parent / "representatives.tsv")
    index = load_index(study.library)
    built = {m for m, info in index.items() if info.asset}
    assert built == {m for _, m in reps} and all((study.library / index[m].asset).is_file() for m in built)
    saved, fitted = Priors.load(study.priors), Priors.fit(stanford.scenes, stanford.taxonomy)
    assert all(np.array_equal(getattr(saved, a), getattr(fitted, a)) for a in Priors.ARRAY_NAMES)

    practice = scene_json.load(folder / "scenes" / "practice.json")
    target = scene_json.load(folder / "scenes" / "desk-corner.json")
    model_of = dict(reps)  # representatives category → model id
    assert sorted(o.model_id for o in practice if o.parent) == sorted(model_of[c] for c in ("Clock", "EndTable", "Mug"))
    assert target.scene_type == "Study" and all(o.model_id in built for o in target if o.parent)
    chair = next(o for o in target if o.model_id == model_of["OfficeChair"])
    desk = next(o for o in target if o.model_id == model_of["Desk"])
    front = chair.transform[:3, 2]  # where the chair's canonical front (+Z) points in the world
    to_desk = desk.transform[:3, 3] - chair.transform[:3, 3]
    assert front @ to_desk / np.linalg.norm(front) / np.linalg.norm(to_desk) > 0.95  # turned to face the desk

    app = make_app(tmp_path / "server", studies=[folder / "study.toml"])
    summary = simulate(2, seed=3, study="desks", app=app)
    assert summary["completed"] == 2 and summary["trials"] == 6 and not summary["failures"]


def test_a_stanford_study_without_meshes_is_refused_before_anything_is_built(tmp_path, stanford_dir, monkeypatch):
    monkeypatch.delenv("SCENESUGGEST_STANFORD_MESHES", raising=False)
    copy = tmp_path / "db"
    copy.mkdir()
    (copy / "scenes").symlink_to(stanford_dir / "scenes")
    with pytest.raises(InitError) as info:
        init_study(tmp_path / "s", corpus=f"stanford:{copy}")
    assert info.value.field == "--meshes" and "SCENESUGGEST_STANFORD_MESHES" in info.value.message
    assert sorted(p.name for p in tmp_path.iterdir()) == ["db"]


def test_bad_mesh_folders_and_places_are_named_before_anything_is_built(tmp_path, stanford_dir, stanford_meshes):
    with pytest.raises(InitError) as info:
        init_study(tmp_path / "a", corpus=f"stanford:{stanford_dir}", meshes=tmp_path / "no-such-folder")
    assert info.value.field == "--meshes" and "no such folder" in info.value.message
    with pytest.raises(InitError) as info:
        init_study(tmp_path / "b", meshes=stanford_meshes)  # the built-in corpus has no meshes to find
    assert info.value.field == "--meshes"
    (tmp_path / "a-file").write_text("x")
    with pytest.raises(InitError) as info:
        init_study(tmp_path / "a-file" / "study")
    assert "cannot make the study folder" in info.value.message
    # a representatives file without the starter scenes' categories: refused before the minute of building
    meshes = tmp_path / "copy" / "models"
    meshes.parent.mkdir()
    meshes.symlink_to(stanford_meshes)
    lines = (stanford_meshes.parent / "representatives.tsv").read_text().splitlines()
    (meshes.parent / "representatives.tsv").write_text("\n".join(l for l in lines if not l.startswith("Desk\t")))
    with pytest.raises(InitError) as info:
        init_study(tmp_path / "c", corpus=f"stanford:{stanford_dir}", meshes=meshes)
    assert "Desk" in info.value.message and info.value.field == "--corpus"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["a-file", "copy"]  # nothing written

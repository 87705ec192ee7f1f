"""Study files: the demo validates; mistakes are reported with the key that is wrong."""

import json
import os
import shutil
import subprocess
import sys

import pytest
from demostudy import DEMO_STUDY

from study_server.studies.study_file import StudyFileError, load_study

#: Lines of the demo study the mistakes below are made in.
TITLE = 'title = { en = "Furnish a room", de = "Ein Zimmer einrichten" }'
LABEL = 'label = { en = "Suggestions", de = "Vorschläge" }'
OPTIONS = ('options = [{ en = "Never", de = "Nie" }, { en = "A few times", de = "Ein paar Mal" }, '
           '{ en = "Regularly", de = "Regelmäßig" }]')


@pytest.fixture
def study_dir(tmp_path):
    shutil.copytree(DEMO_STUDY.parent, tmp_path / "demo")
    return tmp_path / "demo"


def edit(study_dir, old: str, new: str):
    path = study_dir / "study.toml"
    text = path.read_text()
    assert old in text, old
    path.write_text(text.replace(old, new, 1))
    return path


def test_the_demo_study_is_valid():
    study = load_study(DEMO_STUDY)
    assert study.id == "demo" and [c.id for c in study.conditions] == ["none", "basic", "full"]
    assert study.n_rows == 6 and len(study.hash) == 64
    assert len([t for t in study.plan(0) if t.kind == "trial"]) == 9
    assert [q.id for q in study.exit_survey][:4] == ["enjoy_list", "competent_list", "enjoy_suggestions",
                                                      "competent_suggestions"]


@pytest.mark.parametrize(("old", "new", "key", "words"), [
    ('id = "demo"', 'id = "de mo"', "id", "letters"),
    (TITLE + "\n", TITLE + '\ncolour = "red"\n', "colour", "unknown key"),
    ('id = "basic"', 'id = "fancy"', "conditions[1].id", "not one of"),
    ('[[conditions]]\nid = "full"', '[[conditions]]\nid = "none"', "conditions[2].id", "twice"),
    ('target = "scenes/bedside.json"', 'target = "scenes/nowhere.json"', "scenes[2].target", "no such file"),
    ('scenes = ["desk-corner", "bedside", "sofa-corner"]', 'scenes = ["desk-corner", "attic"]', "periods[0].scenes[1]",
     "no scene 'attic'"),
    ('kind = "williams"', 'kind = "latin"', "design.kind", "not one of"),
    ('participants = 12', 'participants = -3', "design.participants", "number"),
    (LABEL + "\n", LABEL + "\nengine = { lambda2 = -1 }\n", "conditions[1].engine.lambda2",
     "≥ 0"),
    (LABEL + "\n", LABEL + "\nengine = { lambda9 = 1 }\n", "conditions[1].engine.lambda9",
     "unknown key"),
    ('engine = { orientation = "learned" }', 'engine = { orientation = "sideways" }',
     "conditions[2].engine.orientation", "one of learned, paper"),
    ('engine = { orientation = "learned" }', 'engine = { orientation = 5 }', "conditions[2].engine.orientation",
     "one of learned, paper"),
    ('engine = { orientation = "learned" }', 'engine = { name = "learned", frames = "yes" }',
     "conditions[2].engine.frames", "expected true or false"),
    ('no_consent = "DEMO-NOCONSENT"\n', '', "platform.codes.no_consent", "missing"),
    ('kind = "link"', 'kind = "link"\ncompletion_url = "https://x.org/done"', "platform.completion_url", "{code}"),
    ('kind = "link"', 'kind = "link"\ncompletion_url = "javascript:alert({code})"', "platform.completion_url",
     "http(s) URL"),
    (OPTIONS, 'options = ["Only"]', "demographics[1].options", "two"),
    ('kind = "likert"', 'kind = "slider"', "exit_survey[0].kind", "not one of"),
    ('condition = "full"', 'condition = "sideways"', "practice.condition", "not one of"),
    ('kind = "link"', 'kind = "link"\nstudy_id = 5', "platform.study_id", "non-empty string"),
    ('min_objects_placed = 1', 'min_objects_placed = -1', "limits.min_objects_placed", "number ≥ 0"),
    ('min_trial_seconds = 10', 'min_trial_seconds = "ten"', "limits.min_trial_seconds", "number ≥ 0"),
    ('arrivals_per_address_per_hour = 100', 'arrivals_per_address_per_hour = 0',
     "limits.arrivals_per_address_per_hour", "number ≥ 1"),
    ('max_events_per_participant = 100000', 'max_events_per_participant = 1e400',
     "limits.max_events_per_participant", "finite number"),
    ('trial_minutes = 8', 'trial_minutes = inf', "limits.trial_minutes", "finite number"),
    ('max_mb_per_participant = 32', 'max_mb_per_participant = true', "limits.max_mb_per_participant", "number"),
])
def test_mistakes_name_the_key(study_dir, old, new, key, words):
    path = edit(study_dir, old, new)
    with pytest.raises(StudyFileError) as info:
        load_study(path)
    assert info.value.field == key and words in str(info.value)
    assert str(info.value).startswith(str(path))


def test_invalid_toml_reports_the_line(study_dir):
    path = edit(study_dir, 'title = { en = "Furnish a room",', 'title = { en = "Furnish a room')
    broken = 'title = { en = "Furnish a room de'
    line = next(i for i, t in enumerate(path.read_text().splitlines(), 1) if t.startswith(broken))
    with pytest.raises(StudyFileError) as info:
        load_study(path)
    assert info.value.line == line and str(info.value).startswith(f"{path}:{line}: not valid TOML")


@pytest.mark.slow
def test_validate_command(study_dir, demo_resources):
    cli = [sys.executable, "-m", "scenesuggest.cli", "study", "validate"]
    ok = subprocess.run([*cli, str(DEMO_STUDY), "--json"], capture_output=True, text=True)
    assert ok.returncode == 0, ok.stderr
    assert json.loads(ok.stdout)["trials_per_participant"] == 9
    bad = subprocess.run([*cli, str(edit(study_dir, 'kind = "williams"', 'kind = "latin"'))], capture_output=True,
                         text=True)
    assert bad.returncode == 2 and "field 'design.kind'" in bad.stderr
    empty_home = {**os.environ, "SCENESUGGEST_HOME": str(study_dir / "empty")}
    unbuilt = subprocess.run([*cli, str(edit(study_dir, 'kind = "latin"', 'kind = "williams"')), "--json"],
                             capture_output=True, text=True, env=empty_home)  # the server's own: not built yet
    assert unbuilt.returncode == 0 and json.loads(unbuilt.stdout)["to_prepare"] == ["library", "priors"]
    said = subprocess.run([*cli, str(study_dir / "study.toml")], capture_output=True, text=True, env=empty_home)
    assert "'scenesuggest study prepare" in said.stdout
    named = edit(study_dir, 'corpus = "ai2thor"\n', 'corpus = "ai2thor"\npriors = "none.npz"\nlibrary = "none"\n')
    missing = subprocess.run([*cli, str(named)], capture_output=True, text=True)  # what a study names must exist
    assert missing.returncode == 2 and "field 'resources.priors'" in missing.stderr
    assert "scenesuggest priors train" in missing.stderr
    edit(study_dir, 'priors = "none.npz"\nlibrary = "none"\n', "")
    bad_scene = study_dir / "scenes" / "bedside.json"
    bad_scene.write_text(bad_scene.read_text().replace('"scene_type"', '"scene_kind"', 1))
    broken = subprocess.run([*cli, str(study_dir / "study.toml"), "--no-resources"], capture_output=True, text=True)
    assert broken.returncode == 2 and "bedside.json" in broken.stderr and "scene_kind" in broken.stderr


def test_one_reading_names_every_problem_with_its_line(study_dir):
    """Adding a language touches every text: validate lists each text missing in it (and every other problem) in
    one run, each with its line, in the order of the lines — not the first alone."""
    path = study_dir / "study.toml"
    text = path.read_text()
    text = text.replace(TITLE, 'title = { en = "Furnish a room" }')  # no German title
    text = text.replace(LABEL, 'label = { en = "Suggestions" }')  # nor this condition's label
    text = text.replace(OPTIONS, 'options = [{ en = "Never" }, { en = "A few times", de = "Ein paar Mal" }]')
    text = text.replace("trial_minutes = 8", "trial_minutes = -1\ncolour = \"blue\"")
    text = text.replace('target = "scenes/bedside.json"', 'target = "scenes/nowhere.json"')
    path.write_text(text)
    with pytest.raises(StudyFileError) as info:
        load_study(path)
    found = [(e.field, e.line) for e in info.value.problems]
    lines = text.splitlines()

    def line_of(start: str, after: int = 0) -> int:
        return next(i for i, t in enumerate(lines, 1) if i > after and t.startswith(start))

    assert found == [
        ("title.de", line_of("title = ")),
        ("conditions[1].label.de", line_of('label = { en = "Suggestions" }')),
        ("scenes[2].target", line_of('target = "scenes/nowhere.json"')),
        ("demographics[1].options[0].de", line_of('options = [{ en = "Never" }')),
        ("limits.trial_minutes", line_of("trial_minutes = -1")),
        ("limits.colour", line_of("colour = ")),
    ]
    said = str(info.value).splitlines()
    assert len(said) == 7 and said[-1] == "(6 problems)"
    assert said[0] == f"{path}:{line_of('title = ')}: field 'title.de': missing: the text in 'de', a language of " \
                      "the study"
    cli = subprocess.run([sys.executable, "-m", "scenesuggest.cli", "study", "validate", str(path)],
                         capture_output=True, text=True)
    assert cli.returncode == 2 and cli.stderr.count(f"{path}:") == 6 and "Traceback" not in cli.stderr


def test_validate_warns_of_participants_the_rows_cannot_balance(study_dir, demo_resources):
    path = edit(study_dir, "participants = 12", "participants = 10")
    run = subprocess.run([sys.executable, "-m", "scenesuggest.cli", "study", "validate", str(path), "--json"],
                         capture_output=True, text=True)
    assert run.returncode == 0, run.stderr
    (warning,) = json.loads(run.stdout)["warnings"]
    assert warning.startswith("[design] participants = 10 is not a multiple of the design's 6 schedule rows") \
        and "(6 or 12 would)" in warning
    human = subprocess.run([sys.executable, "-m", "scenesuggest.cli", "study", "validate", str(DEMO_STUDY)],
                           capture_output=True, text=True)
    assert "warning" not in human.stdout


@pytest.mark.parametrize("old, new, key", [
    ('id = "full"', 'id = "ful"', "conditions[2].id"),  # not again as the practice's condition
    ('id = "bedside"\n', "", "scenes[2].id"),  # not again as a period's scene
    ("[consent]\nversion", "[agreement]\nversion", ""),  # not again as each of its keys
    ("[design]\n", "[layout]\n", ""),
    ("[[conditions]]", "[[condition]]", ""),  # every condition table misnamed: not again as the practice's
])
def test_one_mistake_is_reported_once(study_dir, old, new, key):
    path = edit(study_dir, old, new)
    if not key:  # a table renamed: its unknown name, and the table missing, and nothing under it
        text = path.read_text()
        if "[agreement]" in text:
            path.write_text(text.replace("[consent.text]", "[agreement.text]"))
        path.write_text(path.read_text().replace(old, new))
    with pytest.raises(StudyFileError) as info:
        load_study(path)
    problems = [e.field for e in info.value.problems]
    if key:
        assert problems == [key]
    else:
        table = {"[agreement]": "consent", "[layout]": "design", "[[condition]]": "conditions"}[new.split("\n")[0]]
        assert sorted(problems) == sorted([new.split("\n")[0].strip("[]"), table]), problems


def test_a_relative_database_url_keeps_its_meaning_and_a_command_lines_is_relative_to_where_it_runs(tmp_path,
                                                                                                   monkeypatch):
    from study_server import create_app

    monkeypatch.chdir(tmp_path)
    instance = tmp_path / "instance"
    from study_server.base.extensions import db

    configured = create_app({"INSTANCE_PATH": str(instance), "SQLALCHEMY_DATABASE_URI": "sqlite:///rel.sqlite3",
                             "STUDY_FILES": [DEMO_STUDY], "CHECK_RESOURCES": False, "WARM_STUDIES": False})
    with configured.app_context():
        assert db.engine.url.database == str(instance / "rel.sqlite3")  # Flask-SQLAlchemy's: the instance folder
    assert (instance / "rel.sqlite3").stat().st_mode & 0o777 == 0o600  # the one file, made private
    assert not (tmp_path / "rel.sqlite3").exists()  # and no other beside it
    given = create_app({"INSTANCE_PATH": str(instance), "SQLALCHEMY_DATABASE_URI": "sqlite:///rel.sqlite3",
                        "DATABASE_FROM_COMMAND_LINE": True, "STUDY_FILES": [DEMO_STUDY], "CHECK_RESOURCES": False,
                        "WARM_STUDIES": False})
    with given.app_context():
        assert db.engine.url.database == str(tmp_path / "rel.sqlite3")


def test_a_malformed_list_of_tables_is_reported_once(study_dir):
    """`conditions = []` or `scenes = "oops"`: the list is wrong once, and nothing that refers to its items is
    reported again (the Williams design's two conditions, the practice's condition and scene, the periods)."""
    path = study_dir / "study.toml"
    text = path.read_text().replace('languages = ["en", "de"]', 'languages = ["en", "de"]\nconditions = []\n'
                                    'scenes = "oops"')
    path.write_text(text.replace("[[conditions]]", "[[condition]]").replace("[[scenes]]", "[[scene]]"))
    with pytest.raises(StudyFileError) as info:
        load_study(path)
    assert sorted(e.field for e in info.value.problems) == ["condition", "conditions", "scene", "scenes"]


@pytest.fixture(scope="module")
def damaged_engine(tmp_path_factory):
    """A learned engine's file (trained on the synthetic corpus) whose ranker has one changed split_feature line:
    unchecked, LightGBM aborts the process that reads it."""
    import numpy as np
    import synthetic

    from scenesuggest import engines
    from scenesuggest.npz import npz_bytes, read_npz

    corpus = synthetic.corpus()
    folder = tmp_path_factory.mktemp("engine")
    engines.kind("learned").train(None, corpus.scenes, corpus.taxonomy, folder / "good.npz", seed=0)
    payload = read_npz(folder / "good.npz")
    lines = payload["ranker"].tobytes().decode().split("\n")
    i = next(k for k, line in enumerate(lines) if line.startswith("split_feature="))
    lines[i] = "split_feature=" + " ".join(["999"] * len(lines[i].split("=", 1)[1].split()))
    payload["ranker"] = np.frombuffer("\n".join(lines).encode(), dtype=np.uint8)
    (folder / "damaged.npz").write_bytes(npz_bytes(payload))
    return folder / "damaged.npz"


def test_a_damaged_engine_file_fails_validate_and_stops_serve_once_naming_it(study_dir, demo_resources,
                                                                              damaged_engine, tmp_path):
    """`study validate` loads what the study names; `study serve` loads it before any worker starts, so that a
    damaged engine file is one message naming it (exit 2), not workers booting over and over."""
    shutil.copy(damaged_engine, study_dir / "bad.learned.npz")
    path = edit(study_dir, 'engine = { orientation = "learned" }', 'engine = { name = "learned", file = '
                                                                    '"bad.learned.npz" }')
    cli = [sys.executable, "-m", "scenesuggest.cli", "study"]
    checked = subprocess.run([*cli, "validate", str(path)], capture_output=True, text=True, timeout=120)
    assert checked.returncode == 2 and "bad.learned.npz" in checked.stderr, checked.stderr
    assert "ranker model is damaged" in checked.stderr and "Traceback" not in checked.stderr
    env = {**os.environ, "SCENESUGGEST_STUDIES": str(path), "SCENESUGGEST_INSTANCE": str(tmp_path / "instance"),
           "DATABASE_URL": f"sqlite:///{tmp_path / 'serve.sqlite3'}",
           "SCENESUGGEST_SECRET_KEY": "loopback-only-" + "x" * 32}
    served = subprocess.run([*cli, "serve", "--no-prepare", "--port", "1"], capture_output=True, text=True,
                            env=env, timeout=120)
    assert served.returncode == 2 and "bad.learned.npz" in served.stderr, served.stderr
    assert "ranker model is damaged" in served.stderr and "Booting worker" not in served.stderr

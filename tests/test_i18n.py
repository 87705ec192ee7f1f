"""Participants in their own language: every string the pages use is in every shipped catalogue, a broken
placeholder is named with its file and line, a study's texts are given in each of its languages (a missing one, or a
language without a catalogue, is named), a participant's browser chooses among the study's languages at arrival, and
the export records the language each participant saw, which the analysis can group by."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest
from demostudy import DEMO_STUDY, copy_demo_study, make_app
from flowhelp import csrf

from analysis.load import read_database
from analysis.measures import trials_table
from simulation.run import simulate
from simulation.walker import CAPABLE_DEVICE
from study_server.base.extensions import db
from study_server.base.i18n import TRANSLATIONS, CatalogueError, check_catalogue, shipped
from study_server.base.models import Participant
from study_server.studies.study_file import StudyFileError, load_study

ROOT = Path(__file__).resolve().parents[1]
GERMAN = {"Accept-Language": "de-DE,de;q=0.9,en;q=0.5"}


def extracted(tmp_path) -> set[str]:
    """The strings the server's code and templates give the catalogues (``make translations`` extracts them)."""
    pot = tmp_path / "messages.pot"
    done = subprocess.run([str(Path(sys.executable).parent / "pybabel"), "extract", "-F",
                           str(TRANSLATIONS / "babel.cfg"), "-o", str(pot), "."], cwd=ROOT, capture_output=True,
                          text=True)
    assert done.returncode == 0, done.stderr
    return {m.id for m in check_catalogue(pot) if m.id}


def test_every_string_the_pages_use_is_translated_in_every_catalogue(tmp_path):
    wanted = extracted(tmp_path)
    assert {"I agree to take part", "Please answer this question.", "Scene {n} of {of}"} <= wanted
    assert shipped() == ("en", "de")
    for language in shipped()[1:]:
        catalog = check_catalogue(TRANSLATIONS / language / "LC_MESSAGES" / "messages.po")
        translated = {m.id for m in catalog if m.id and not m.fuzzy
                      and (all(m.string) if isinstance(m.string, tuple) else m.string)}
        assert not wanted - translated, f"{language}: untranslated {sorted(wanted - translated)}"
        assert not translated - wanted, f"{language}: no longer used {sorted(translated - wanted)}"


def test_a_broken_placeholder_is_named_with_its_file_and_line(tmp_path):
    po = tmp_path / "messages.po"
    po.write_text('msgid ""\nmsgstr ""\n"Content-Type: text/plain; charset=utf-8\\n"\n\n'
                  'msgid "Fine"\nmsgstr "Gut"\n\n'
                  'msgid "Page %(page)s of %(pages)s"\nmsgstr "Seite %(seite)s von %(pages)s"\n')
    with pytest.raises(CatalogueError) as e:
        check_catalogue(po)
    assert str(e.value).startswith(f"{po}:8: field 'msgstr': ") and "%(seite)s" in str(e.value)
    po.write_text('msgid "Scene {n} of {of}"\nmsgstr "Szene {n}"\n')
    with pytest.raises(CatalogueError, match=r"\{of\}"):
        check_catalogue(po)


@pytest.mark.parametrize("change, key, message", [
    ('languages = ["en", "de"]', "languages[1]", "no catalogue for the language 'xx'"),
    ('languages = ["en", "de"]', "consent.text.de", "missing: the text in 'de'"),
    ('languages = ["en", "de"]', "title", "give this text in each"),
    ('languages = ["en", "de"]', "languages", "give either language"),
])
def test_a_study_says_which_language_a_text_is_missing_in(tmp_path, change, key, message):
    path = copy_demo_study(tmp_path)
    text = path.read_text()
    assert change in text
    if key == "languages[1]":
        text = text.replace(change, 'languages = ["en", "xx"]')
    elif key == "consent.text.de":
        start = text.index("[consent.text]")
        de = text.index('de = """', start)
        text = text[:de] + text[text.index('"""\n', de + 10) + 4:]
    elif key == "title":
        text = text.replace('title = { en = "Furnish a room", de = "Ein Zimmer einrichten" }', 'title = "Furnish"')
    else:
        text = text.replace(change, change + '\nlanguage = "de"')
    path.write_text(text)
    with pytest.raises(StudyFileError) as e:
        load_study(path)
    assert e.value.field == key and message in e.value.message and e.value.line


def test_a_participants_browser_chooses_the_language_and_the_export_records_it(tmp_path, demo_resources):
    app = make_app(tmp_path)
    german, english = app.test_client(), app.test_client()
    page = german.get("/study/demo/start?pid=de-1", headers=GERMAN, follow_redirects=True)
    assert '<html lang="de">' in page.get_data(as_text=True) and "Ein Zimmer einrichten" in page.get_data(as_text=True)
    assert english.get("/study/demo/start?pid=en-1", follow_redirects=True).get_data(as_text=True).count(
        '<html lang="en">') == 1
    # the language stays the participant's, whatever the browser says later
    german.post("/study/demo/device", data={**CAPABLE_DEVICE, "csrf_token": csrf(page)})
    consent = german.get("/study/demo/")
    assert "Ich stimme der Teilnahme zu" in consent.get_data(as_text=True)
    german.post("/study/demo/consent", data={"csrf_token": csrf(consent), "agree": "yes"})
    survey = german.post("/study/demo/demographics", data={"csrf_token": csrf(german.get("/study/demo/"))},
                         headers={"Accept-Language": "en"})
    text = survey.get_data(as_text=True)
    assert "Bitte beantworten Sie diese Frage." in text and "Wie alt sind Sie?" in text and "Nie" in text
    with app.app_context():
        assert {p.platform_id: p.language for p in db.session.query(Participant)} == {"de-1": "de", "en-1": "en"}


def test_the_analysis_groups_by_the_language_participants_saw(tmp_path, demo_resources):
    app = make_app(tmp_path)
    assert simulate(2, seed=4, study="demo", app=app)["completed"] == 2
    with app.app_context():
        db.session.query(Participant).filter_by(id=1).update({"language": "de"})
        db.session.commit()
    trials = trials_table(read_database(app.config["SQLALCHEMY_DATABASE_URI"]))
    assert trials.groupby("language")["participant"].nunique().to_dict() == {"de": 1, "en": 1}


def test_the_demo_speaks_english_and_german(demo_resources):
    study = load_study(DEMO_STUDY)
    assert study.languages == ("en", "de")
    assert study.consent_text.in_language("de").strip().startswith("Dies ist")
    assert [o.in_language("de") for o in study.demographics[1].options] == ["Nie", "Ein paar Mal", "Regelmäßig"]
    assert [str(o) for o in study.exit_survey[4].options][2] == "Suggestions, oriented"  # stored as the default's


def test_the_browsers_preference_decides_by_quality_and_primary_language(tmp_path, demo_resources):
    from werkzeug.datastructures import LanguageAccept
    from werkzeug.http import parse_accept_header

    from study_server.base.i18n import choose

    study = load_study(DEMO_STUDY)
    for header, language in (("de-CH,en;q=0.9", "de"), ("de-AT,en-US;q=0.7,en;q=0.3", "de"), ("fr,en;q=0.5", "en"),
                             ("en-GB,de;q=0.8", "en"), ("de;q=0,en", "en"), ("fr", "en"), ("", "en")):
        assert choose(study, parse_accept_header(header, LanguageAccept)) == language, header


def test_pages_without_a_participant_speak_the_browsers_language_and_a_stored_one_the_study_dropped_is_not_used(
        tmp_path, demo_resources):
    app = make_app(tmp_path)
    c = app.test_client()
    assert "Diese Seite gibt es nicht" in c.get("/study/demo/nope", headers=GERMAN).get_data(as_text=True)
    assert "Diese Seite gibt es nicht" in c.get("/study/unknown/", headers=GERMAN).get_data(as_text=True)
    c.get("/study/demo/start?pid=de-2", headers=GERMAN)
    expired = c.post("/study/demo/consent", data={"agree": "yes"}, headers=GERMAN)  # no form token
    assert expired.status_code == 400 and "Das Formular ist abgelaufen" in expired.get_data(as_text=True)
    with app.app_context():
        db.session.query(Participant).update({"language": "fr"})  # a language the study no longer speaks
        db.session.commit()
    assert '<html lang="de">' in c.get("/study/demo/", headers=GERMAN).get_data(as_text=True)


def test_a_lone_percent_sign_or_a_catalogue_copied_with_an_older_time_is_caught(tmp_path):
    import os

    from study_server.base.i18n import compile_catalogues

    po = tmp_path / "messages.po"
    po.write_text('msgid "Fine"\nmsgstr "50 % fertig"\n')
    with pytest.raises(CatalogueError, match="write a % as %%"):
        check_catalogue(po)
    out = compile_catalogues(tmp_path / "compiled")
    mo = out / "de" / "LC_MESSAGES" / "messages.mo"
    mo.write_bytes(b"stale")
    os.utime(mo, (2e9, 2e9))  # newer than the catalogue: compiled again all the same, by content
    compile_catalogues(out)
    assert mo.read_bytes() != b"stale"


def test_the_corpus_speaks_german_too_on_tiles_and_in_search(tmp_path, demo_resources):
    """The categories of the demo's corpus have German names: the model list, the suggestions and the search give
    them to a German participant, and a German word finds its models; an English participant sees the models'
    own names."""
    from flowhelp import auth, boot, finish_all_trials  # noqa: F401 (the walk's helpers)

    from study_server.base.i18n import category_names

    app = make_app(tmp_path)
    rt = app.extensions["studies"]["demo"]
    named = category_names("de")
    assert {m.category for m in rt.library.values()} <= set(named), "categories without a German name"
    german = app.test_client()
    page = german.get("/study/demo/start?pid=de-3", headers=GERMAN, follow_redirects=True)
    german.post("/study/demo/device", data={**CAPABLE_DEVICE, "csrf_token": csrf(page)})
    german.post("/study/demo/consent", data={"csrf_token": csrf(german.get("/study/demo/")), "agree": "yes"})
    with app.app_context():
        token = db.session.query(Participant).filter_by(platform_id="de-3").one().token
    models = german.get("/api/models", headers={"Authorization": f"Bearer {token}"}).json["models"]
    chair = next(m for m in models if m["category"] == "Chair")
    assert chair["label"] == "Stuhl" and chair["name"] == "Chair"
    hits = german.get("/api/search?q=Stuhl", headers={"Authorization": f"Bearer {token}"}).json["hits"]
    assert hits and hits[0]["category"] == "Chair" and hits[0]["label"] == "Stuhl"
    assert german.get("/api/search?q=Kühlschrank", headers={"Authorization": f"Bearer {token}"}).json[
        "hits"][0]["category"] == "Fridge"
    english = app.test_client()
    english.get("/study/demo/start?pid=en-3", follow_redirects=True)
    with app.app_context():
        token = db.session.query(Participant).filter_by(platform_id="en-3").one().token
    models = english.get("/api/models", headers={"Authorization": f"Bearer {token}"}).json["models"]
    assert next(m for m in models if m["category"] == "Chair")["label"] == "Chair"

"""A condition served by the learned engine, in a real browser: the participant's shift-click is answered by the
learned engine (trained here on sixteen AI2-THOR rooms), its first suggestion placed, and the page looks right
(test-artifacts/learned-condition.png)."""

from __future__ import annotations

import pytest

from .pagehelp import floor_pixel, objects, screenshot, start, suggest_at


@pytest.fixture(scope="module")
def learned_server(tmp_path_factory, demo_resources):
    """gunicorn serving a copy of the demo whose 'full' condition is the learned engine."""
    from demostudy import copy_demo_study, make_app
    from serverproc import StudyServer

    from scenesuggest import engines
    from scenesuggest.corpora import load_corpus

    from .pagehelp import require_browser

    require_browser()
    tmp = tmp_path_factory.mktemp("learned")
    corpus = load_corpus("ai2thor")
    rooms = [s for s in corpus.scenes if s.scene_type in ("Bedroom", "LivingRoom")][:16]
    learned = tmp / "ai2thor-16.learned.npz"
    engines.kind("learned").train(None, rooms, corpus.taxonomy, learned, seed=0)
    study = copy_demo_study(tmp)
    study.write_text(study.read_text().replace('engine = { orientation = "learned" }',
                                               f'engine = {{ name = "learned", file = "{learned}" }}', 1))
    make_app(tmp, f"sqlite:///{tmp / 'study.sqlite3'}", studies=[study])
    with StudyServer(tmp / "instance", f"sqlite:///{tmp / 'study.sqlite3'}", migrate=False, study=study) as server:
        yield server.base


def test_a_condition_served_by_the_learned_engine(page, learned_server):
    start(page, learned_server, "learned-engine")
    assert page.evaluate("() => window.sceneSuggestTest.condition") == "full"  # the practice trial
    x, y = floor_pixel(page, -0.6, 0.4)
    response = suggest_at(page, x, y)
    assert response["engine"] == "learned" and len(response["suggestions"]) > 5
    top = response["suggestions"][0]
    placed = [o for o in objects(page).values() if o["id"] != "room"]
    assert placed[-1]["category"] == top["category"] and placed[-1]["model_id"] == top["models"][0]["id"]
    assert all(len(s["placement"]) == 16 and s["models"] for s in response["suggestions"])
    screenshot(page, "learned-condition")
    assert not page.console_problems, page.console_problems

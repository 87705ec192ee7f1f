"""The `none` condition's model panel with a library of 1,580 models (the size of the Stanford database's), in a
real browser: every model is in the list in its fixed order and in the log as shown, the browser renders only
the tiles near the visible part, and a model at the end of the list is chosen and placed like any other
(test-artifacts/none-panel-1580.png)."""

from __future__ import annotations

import json
import sqlite3

import pytest

from .pagehelp import floor_pixel, hook, objects, screenshot, start, until

MODELS = 1580
#: Tiles whose contents are rendered (not skipped by ``content-visibility``), and all tiles of the panel.
RENDERED = """() => { const tiles = [...document.querySelectorAll("#model-panel .tile")];
  return [tiles.filter((t) => t.lastChild.checkVisibility({ contentVisibilityAuto: true })).length, tiles.length]; }"""


@pytest.fixture(scope="module")
def large_server(tmp_path_factory, demo_resources):
    """gunicorn serving a copy of the demo with a 1,580-model library and its practice trial in `none`."""
    from demostudy import make_app
    from large_library import STUDY_ID, write_study
    from serverproc import StudyServer

    from .pagehelp import require_browser

    require_browser()

    tmp = tmp_path_factory.mktemp("large-library")
    study = write_study(tmp / "study", MODELS)
    make_app(tmp, f"sqlite:///{tmp / 'study.sqlite3'}", studies=[study])
    with StudyServer(tmp / "instance", f"sqlite:///{tmp / 'study.sqlite3'}", migrate=False, study=study) as server:
        yield server.base, STUDY_ID, tmp / "study.sqlite3"


def test_the_none_panel_holds_the_whole_library_and_renders_what_is_visible(page, large_server):
    base, study_id, database = large_server
    start(page, base, "large-library", study=study_id)
    assert hook(page, "condition") == "none"
    rendered, tiles = page.evaluate(RENDERED)
    assert tiles == MODELS
    assert 0 < rendered < 150, rendered  # the visible tiles and a margin, not the 1,580
    screenshot(page, "none-panel-1580")
    last = page.locator("#model-panel .tile").last
    wanted = last.get_attribute("data-model")
    assert last.get_attribute("data-rank") == str(MODELS) and wanted.rsplit(".", 1)[1].isdigit()  # a copy
    last.scroll_into_view_if_needed()
    rendered_after, _ = page.evaluate(RENDERED)
    assert 0 < rendered_after < 150
    last.click()
    page.mouse.click(*floor_pixel(page, -0.6, 0.4))
    until(page, f"window.sceneSuggestTest.objects().some((o) => o.model_id === {wanted!r})")
    assert any(o["model_id"] == wanted for o in objects(page).values())
    assert not page.console_problems, page.console_problems
    # the fixed list as shown, all of it, is in the log (not set aside as too long), and nothing was rejected
    until(page, "window.sceneSuggestTest.pending() === 0")
    with sqlite3.connect(database) as conn:
        shown = [json.loads(p) for (p,) in conn.execute(
            "SELECT e.payload FROM events e JOIN participants p ON p.id = e.participant_id "
            "WHERE p.platform_id = 'large-library' AND e.type = 'list_shown'")]
        errors = conn.execute("SELECT count(*) FROM events WHERE type = 'client_error'").fetchone()[0]
    assert errors == 0 and any(p["source"] == "fixed" and len(p["items"]) == MODELS for p in shown)

"""The admin's replay in Chromium: a simulated participant's trial rebuilt step by step; wherever one scrubs or
clicks, the objects on screen are those the server's replay gives after that event."""

from __future__ import annotations

import sqlite3

import numpy as np
import pytest
from demostudy import DEMO_STUDY, make_app

from scenesuggest.contract.replay import replay
from simulation.participant import Bot
from simulation.transport import HttpTransport
from study_server.studies.served import load_studies

from .pagehelp import require_browser, screenshot, until

PASSWORD = "replay-password"


@pytest.fixture(scope="module")
def replay_server(tmp_path_factory, demo_resources):
    """gunicorn on the demo with an admin password, after one simulated participant took the whole study."""
    from serverproc import StudyServer
    from werkzeug.security import generate_password_hash

    require_browser()
    tmp = tmp_path_factory.mktemp("replay")
    database = tmp / "study.sqlite3"
    make_app(tmp, f"sqlite:///{database}")
    server = StudyServer(tmp / "instance", f"sqlite:///{database}", migrate=False)
    server.env["SCENESUGGEST_ADMIN_PASSWORD_HASH"] = generate_password_hash(PASSWORD)
    with server:
        result = Bot(HttpTransport(server.base), "demo", "replayed", np.random.default_rng(3)).run()
        assert result.code
        yield server.base, database


def _trial(database, index: int) -> tuple[int, str, list[dict]]:
    """(participant id, scene, events) of the simulated participant's trial ``index``."""
    import json

    with sqlite3.connect(database) as con:
        pid, scene = con.execute('SELECT t.participant_id, t.scene_id FROM trials t WHERE t."index" = ?',
                                 (index,)).fetchone()
        rows = con.execute("SELECT seq, client_t, type, payload FROM events WHERE participant_id = ? AND trial = ? "
                           "ORDER BY seq", (pid, index)).fetchall()
    return pid, scene, [{"seq": s, "t": t, "type": k, "payload": json.loads(p)} for s, t, k, p in rows]


def _on_screen(page) -> dict:
    return page.evaluate("() => window.sceneSuggestReplay.onScreen()")


def _same(on_screen: dict, scene: dict) -> bool:
    expected = {i: o["transform"] for i, o in scene.items() if o["parent"] is not None}
    return on_screen.keys() == expected.keys() and all(
        np.allclose(on_screen[i], expected[i], atol=1e-6) for i in expected)


def test_an_experimenter_replays_a_trial_and_sees_what_replay_gives(page, replay_server):
    base, database = replay_server
    pid, scene_id, events = _trial(database, 0)
    start = next(iter(load_studies([DEMO_STUDY]).values())).scene(scene_id, "start")["objects"]
    scenes = replay(start, events)
    page.goto(f"{base}/admin/login")
    page.fill("input[name=password]", PASSWORD)
    page.click("button[type=submit]")
    page.goto(f"{base}/admin/demo/participants/{pid}")
    assert page.locator("td", has_text="match").count() == 10  # every trial's events rebuild its scene
    page.click(f"a[href='/admin/demo/participants/{pid}/trials/0/replay']")
    until(page, "!!window.sceneSuggestReplay")
    assert page.locator("#events li").count() == len(events)
    assert _on_screen(page) == {}  # the start: the room alone
    # click an event in the list: the scene after it
    changes = [i for i, e in enumerate(events) if e["type"] in ("insert", "move_end", "rotate_end", "replace")]
    middle = changes[len(changes) // 2]
    page.click(f"#events li[data-position='{middle + 1}']")
    assert _same(_on_screen(page), scenes[middle])
    assert page.get_attribute(f"#events li[data-position='{middle + 1}']", "aria-current") == "true"
    screenshot(page, "replay-middle")
    # scrub to another event
    page.locator("#scrubber").fill(str(changes[1] + 1))
    assert _same(_on_screen(page), scenes[changes[1]])
    # play at 16× from the start to the end: the final scene
    page.locator("#speed").select_option("16")
    page.locator("#scrubber").fill("0")
    page.click("#play")
    until(page, "window.sceneSuggestReplay.position > 0", timeout=30)
    until(page, f"window.sceneSuggestReplay.position === {len(events)}", timeout=120)
    assert page.get_attribute("#play", "aria-pressed") == "false" and _same(_on_screen(page), scenes[-1])
    page.locator("#scrubber").fill(str(changes[-1] + 1))
    screenshot(page, "replay-end")
    assert not page.console_problems, page.console_problems

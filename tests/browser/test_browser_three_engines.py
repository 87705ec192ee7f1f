"""A participant's whole way through a study in each of the three browser engines a crowd uses — Chromium, Firefox
and WebKit (Safari's) — driven the same way (tests/browsers.py), behind a proxy that brings the field's faults
(faultproxy.py): the device check, consent, surveys, instructions, a trial in each condition with shift-click
suggestions, another suggestion swapped in, search, a drag along the floor, Q/E, the ring, delete, undo and redo,
a reload mid-trial, going on in a fresh browser (the scene rebuilt from the server's events), a spell without
network, a refused event (422), a busy server (429), seqs another sender took (409), done, the exit survey and
the code. The database must then hold every event once, gap-free, and each trial's events must rebuild the scene
it submitted.

The study is the demo cut to one scene per condition (four trials with the practice): every step and fault of a
trial is in it, at a third of the demo's length, which keeps the three runs within the CI budget."""

from __future__ import annotations

import json
import math
import sqlite3
import time

import pytest
import urllib3

from scenesuggest.contract.replay import differences

from .engines import DRIVERS, ENGINES, Display, require
from .faultproxy import FaultProxy
from .pagehelp import ARTIFACTS, db_replays, heading_deg


@pytest.fixture(scope="module")
def walk_study(tmp_path_factory, demo_resources):
    """gunicorn serving the demo cut to one scene per condition, on a fresh SQLite database, behind a fault proxy:
    (proxy, database)."""
    from demostudy import copy_demo_study, make_app
    from serverproc import StudyServer

    from .pagehelp import require_browser

    require_browser()
    tmp = tmp_path_factory.mktemp("engines")
    study = copy_demo_study(tmp)
    text = study.read_text()
    assert 'scenes = ["desk-corner", "bedside", "sofa-corner"]' in text
    text = text.replace('scenes = ["desk-corner", "bedside", "sofa-corner"]', 'scenes = ["desk-corner"]')
    study.write_text(text.replace('kind = "link"', 'kind = "prolific"'))  # its SESSION_ID lets a browser resume
    database = tmp / "study.sqlite3"
    make_app(tmp, f"sqlite:///{database}", studies=[study])
    with StudyServer(tmp / "instance", f"sqlite:///{database}", migrate=False, study=study) as server, \
            FaultProxy(server.base) as proxy:
        yield proxy, database


@pytest.fixture(scope="module")
def display():
    from pathlib import Path

    from .engines import XVFB
    if not Path(XVFB).exists():
        yield None
        return
    screen = Display()
    yield screen
    screen.close()


def hook(d, expression):
    return d.evaluate(f"window.sceneSuggestTest.{expression}")


def objects(d) -> dict:
    return {o["id"]: o for o in hook(d, "objects()")}


def ready(d):
    """Past the condition's instructions (when they come first), on a trial page ready for input."""
    if d.until("document.body && document.body.dataset.step") == "briefing":
        d.submit("button[name=go][value=start]")
    d.until("!!(window.sceneSuggestTest && window.sceneSuggestTest.ready)")
    hook(d, "loaded().then(() => true)")


def placed_objects(d) -> list[dict]:
    return [o for o in objects(d).values() if o["id"] != "room"]


def suggest(d, x, y) -> dict:
    before = hook(d, "lastSuggest ? window.sceneSuggestTest.lastSuggest.list_id : null")
    d.click_at(x, y, shift=True)
    d.until(f"window.sceneSuggestTest.lastSuggest && window.sceneSuggestTest.lastSuggest.list_id !== "
            f"{json.dumps(before)}")
    hook(d, "loaded().then(() => true)")
    return hook(d, "lastSuggest")


def with_suggestions(d, engine: str, shoot: bool) -> dict:
    """Shift-click the floor: the top suggestion is placed there; another suggestion is swapped in."""
    x, y = hook(d, "worldToPixel(-0.6, 0, 0.4)")
    response = suggest(d, x, y)
    placed = placed_objects(d)[-1]
    top = response["suggestions"][0]
    assert placed["category"] == top["category"] and placed["model_id"] == top["models"][0]["id"]
    if shoot:
        d.screenshot(ARTIFACTS / f"engine-{engine}-full.png")
    second = response["suggestions"][1]
    d.click(f".suggestions .tile[data-rank='2'][data-category='{second['category']}']")
    d.until(f"!window.sceneSuggestTest.objects().some(o => o.id === {json.dumps(placed['id'])})")
    swapped = placed_objects(d)[-1]
    assert swapped["category"] == second["category"]
    assert math.dist(swapped["contact_point"], placed["contact_point"]) < 1e-9
    d.click(".suggestions button.close")
    return swapped


def from_the_list(d, proxy: FaultProxy):
    """The fixed list, then search (which the server first answers 429, and the page waits out)."""
    d.click(".side-panel .tile")
    x, y = hook(d, "worldToPixel(0.6, 0, 0.2)")
    d.click_at(x, y)
    d.until("window.sceneSuggestTest.objects().length === 2")
    busy = []
    proxy.rules.append(("/api/search", lambda *_: None if busy else busy.append(1) or (
        429, {"Retry-After": "1", "Content-Type": "application/json"},
        b'{"error": "more lists than a person asks for: wait a moment", "field": "search"}')))
    d.fill(".side-panel input[type=search]", "lamp")
    d.until("document.querySelector('.side-panel .tile[data-model]') && "
            "document.querySelector('.side-panel .tile[data-model]').dataset.model.includes('Lamp')")
    assert busy == [1]
    d.click(".side-panel .tile")
    x, y = hook(d, "worldToPixel(-0.6, 0, 0.2)")
    d.click_at(x, y)
    d.until("window.sceneSuggestTest.objects().length === 3")
    assert any("Lamp" in o["category"] for o in placed_objects(d))


def turn_and_move(d, obj: dict):
    """Drag the object across the floor, turn it with E and with the ring, delete it and undo, redo, undo."""
    grab = hook(d, f"grabPixel({json.dumps(obj['id'])})")
    assert grab, f"no visible pixel of {obj['category']} to grab"
    x1, y1 = hook(d, "worldToPixel(0.0, 0, 1.2)")
    d.drag([(grab[0] + (x1 - grab[0]) * k / 10, grab[1] + (y1 - grab[1]) * k / 10) for k in range(11)])
    moved = objects(d)[obj["id"]]
    assert math.dist(moved["contact_point"], obj["contact_point"]) > 0.3
    d.press("e")
    turned = objects(d)[obj["id"]]
    assert (heading_deg(turned["transform"]) - heading_deg(moved["transform"]) + 180) % 360 - 180 == \
        pytest.approx(-15, abs=0.01)
    path = [hook(d, f"ringPixel({a})") for a in range(0, 91, 10)]
    d.drag(path)  # whole pixels, as a person's pointer
    ringed = objects(d)[obj["id"]]
    assert abs((heading_deg(ringed["transform"]) - heading_deg(turned["transform"]) + 180) % 360 - 180) == \
        pytest.approx(90, abs=3)
    d.press("Delete")
    assert obj["id"] not in objects(d)
    d.press("Control+z")
    assert obj["id"] in objects(d)
    d.click("#redo-button")
    assert obj["id"] not in objects(d)
    d.click("#undo-button")
    assert obj["id"] in objects(d)


def until_true(predicate, timeout: float, message) -> None:
    """Poll ``predicate`` (on this side, not the page's) until it holds; ``message()`` says what the page shows."""
    end = time.time() + timeout
    while not predicate():
        if time.time() > end:
            raise AssertionError(message())
        time.sleep(0.05)


def state(d) -> str:
    """The outbox and banner as the page holds them, for a failure's message."""
    return json.dumps(d.evaluate("({pending: window.sceneSuggestTest.pending(), "
                                 "banner: document.getElementById('banner').dataset.state ?? null})"))


def faults(d, proxy: FaultProxy):
    """A reload mid-trial keeps the scene; a spell without network and an event the server refuses lose nothing."""
    before = objects(d)
    d.reload()
    ready(d)
    assert objects(d).keys() == before.keys()
    assert "brought back" not in d.evaluate("document.getElementById('banner').textContent")  # its own copy
    d.until("window.sceneSuggestTest.pending() === 0")
    gone, dropped = {"on": True}, proxy.hits["/api/events"]
    proxy.rules.append(("/api/events", lambda *_: "drop" if gone["on"] else None))
    obj = placed_objects(d)[-1]
    x, y = hook(d, f"grabPixel({json.dumps(obj['id'])})")
    d.click_at(x, y)  # select
    for _ in range(4):
        d.press("q")
    until_true(lambda: proxy.hits["/api/events"] > dropped, 20,
               lambda: f"no batch reached the proxy to be dropped: {state(d)}")
    d.until("document.getElementById('banner').dataset.state === 'offline'", timeout=20)
    assert hook(d, "pending()") > 0
    gone["on"] = False

    def refuse_a_select(method, path, body):  # 422 for the first batch holding a select event, naming it
        events = json.loads(body or b"{}").get("events", [])
        index = next((i for i, e in enumerate(events) if e.get("type") == "select"), None)
        if index is None or refused:
            return None
        refused.append(events[index]["seq"])
        return 422, {"Content-Type": "application/json"}, json.dumps(
            {"error": "refused by the proxy", "field": f"events[{index}].payload"}).encode()
    refused = []
    proxy.rules.append(("/api/events", refuse_a_select))
    d.click_at(*hook(d, "worldToPixel(1.5, 0, -1.5)"))  # deselect: a select event
    d.until("window.sceneSuggestTest.pending() === 0", timeout=40)
    assert refused
    proxy.rules.clear()
    return refused[0]


def taken_seqs(d, base: str, n: int = 3) -> None:
    """Another sender (an old tab) stores events under the seqs this page will use next: the page gets 409."""
    token = d.evaluate("JSON.parse(document.getElementById('boot').textContent).token")
    trial = hook(d, "trial")
    seq = hook(d, "lastSeq()") + 1
    events = [{"seq": seq + k, "t": 1.0e12 + k, "type": "focus", "trial": trial, "payload": {"state": "focus"}}
              for k in range(n)]
    r = urllib3.request("POST", f"{base}/api/events", json={"page_id": "old-tab", "events": events},
                        headers={"Authorization": f"Bearer {token}"})
    assert r.status == 200, r.data


def enter(d, base: str, entry: str) -> None:
    """Follow the entry link in a page that asks for the trial page's test hook (on the study's origin)."""
    d.goto(f"{base}/study/demo/")
    d.evaluate("sessionStorage.setItem('sceneSuggestTestHook', '1')")
    d.goto(entry)


def done(d):
    d.click("#done-button")
    d.submit("#confirm-yes", timeout=60)


@pytest.mark.parametrize("engine", ENGINES)
def test_a_participant_walks_the_study_in_every_engine(engine, walk_study, display):
    require(engine)
    proxy, database = walk_study
    n = ENGINES.index(engine) + 1
    base, pid = proxy.base, f"{n:024x}"
    entry = f"{base}/study/demo/start?PROLIFIC_PID={pid}&SESSION_ID={n + 1000:024x}"
    proxy.rules.clear()  # (an engine that failed earlier may have left its faults in place)
    proxy.hits.clear()
    d = DRIVERS[engine](display)
    try:
        enter(d, base, entry)
        assert d.until("document.body.dataset.step !== 'device' && document.body.dataset.step") == "consent"
        with sqlite3.connect(database) as con:
            (report,) = con.execute("SELECT viewport FROM participants WHERE platform_id = ?", (pid,)).fetchone()
        report = json.loads(report)
        assert report["missing"] == [] and report["reasons"] == [] and report["fps"] > 0, report
        d.submit("button[name=agree][value=yes]")
        d.fill("input[name=age]", "29")
        d.click("input[name=experience_3d][value='A few times']")
        d.click("input[name=pointing_device][value=Trackpad]")
        d.submit("button[type=submit]")
        while d.evaluate("document.body.dataset.step") == "instructions":
            d.submit("button[name=go][value=next]")
        conditions, refused = [], None
        for position in range(4):
            ready(d)
            condition = hook(d, "condition")
            conditions.append(condition)
            if condition == "none":
                from_the_list(d, proxy)
            else:
                obj = with_suggestions(d, engine, shoot=condition == "full" and position > 0)
                if position == 0:  # the practice: every way to change an object, and the field's faults
                    turn_and_move(d, obj)
                    refused = faults(d, proxy)
            if position == 1:
                d.until("window.sceneSuggestTest.pending() === 0")
                taken_seqs(d, base)
                d.click_at(*hook(d, "worldToPixel(1.5, 0, -1.5)"))  # events under the seqs taken: 409, renumbered
            if position == 2:  # the participant goes on in a fresh browser: the scene comes back from the server
                d.until("window.sceneSuggestTest.pending() === 0")
                before = objects(d)
                d.close()
                d = DRIVERS[engine](display)
                enter(d, base, entry)
                ready(d)
                assert not differences(before, list(objects(d).values()))  # (states as the events round them)
                assert "brought back from the study's server" in d.evaluate("document.getElementById('banner')"
                                                                             ".textContent")
            done(d)
        assert d.evaluate("document.body.dataset.step") == "exit"
        assert conditions[0] == "full" and sorted(conditions[1:]) == ["basic", "full", "none"]
        for q in ("enjoy_list", "competent_list", "enjoy_suggestions", "competent_suggestions"):
            d.click(f"input[name={q}][value='4']")
        d.click("input[name=preference][value='Suggestions, oriented']")
        d.submit("button[type=submit]")
        assert d.evaluate("document.querySelector('.code').textContent") == "DEMO-DONE-7F3A"
        problems = d.problems()  # beyond the browser's own lines for the faults the proxy brought
        assert not [m for m in problems or [] if not m.startswith("Failed to load resource")], problems
    finally:
        d.close()
    with sqlite3.connect(database) as con:
        stored = con.execute("SELECT e.seq, e.type, e.payload FROM events e JOIN participants p ON "
                             "p.id = e.participant_id WHERE p.platform_id = ? ORDER BY e.seq", (pid,)).fetchall()
    seqs = [s for s, _, _ in stored]
    assert seqs == list(range(len(seqs)))  # every event stored once, none missing
    kinds = {t for _, t, _ in stored}
    assert {"insert", "replace", "move_end", "rotate_end", "delete", "undo", "redo", "search", "resume",
            "client_error"} <= kinds, kinds
    assert any(s == refused and t == "client_error" for s, t, _ in stored)  # the refused event's note
    assert [t for s, t, _ in stored].count("focus") >= 3  # the other sender's, kept; the page's renumbered
    replays = db_replays(database, pid)
    assert len(replays) == 4 and set(replays.values()) == {"match"}, replays

"""A participant's run in a real browser: Playwright driving Debian's Chromium (WebGL on SwiftShader) against
the study server run as `make serve` runs it. Clicks land on real pixels of real objects (the page's test hook
converts world points to pixels); the database is compared with what the page logged."""

from __future__ import annotations

import math
import re
import sqlite3

import pytest

from .pagehelp import (
    ARTIFACTS,
    db_batches,
    db_events,
    db_replays,
    done,
    exit_survey,
    floor_pixel,
    heading_deg,
    hook,
    objects,
    place_with_suggestions,
    ready,
    screenshot,
    start,
    suggest_at,
    until,
)


def run_none_trial(page):
    # from the fixed list: the first model, then a click on the floor
    page.click(".side-panel .tile >> nth=0")
    x, y = floor_pixel(page, 0.6, 0.2)
    page.mouse.click(x, y)
    until(page, "window.sceneSuggestTest.objects().length === 2")
    # by search: a lamp; the server's first answer is "too many lists" (429), which the page waits out
    busy = []

    def once_busy(route):
        if busy:
            return route.continue_()
        busy.append(route.request.url)
        return route.fulfill(status=429, headers={"Retry-After": "1", "Content-Type": "application/json"},
                             body='{"error": "more lists than a person asks for: wait a moment", "field": "search"}')
    page.route("**/api/search?*", once_busy)
    page.fill(".side-panel input[type=search]", "lamp")
    until(page, "document.querySelector('.side-panel .tile[data-model]') && "
                "document.querySelector('.side-panel .tile[data-model]').dataset.model.includes('Lamp')")
    page.unroute("**/api/search?*")
    assert len(busy) == 1  # refused once, asked again after the wait, answered
    expected = [m for m in page.console_problems if "status of 429" in m]
    assert len(expected) == 1  # the browser's own line for the refused request, and nothing else
    page.console_problems.remove(expected[0])
    page.click(".side-panel .tile >> nth=0")
    x, y = floor_pixel(page, -0.6, 0.2)
    page.mouse.click(x, y)
    until(page, "window.sceneSuggestTest.objects().length === 3")
    placed = [o for o in objects(page).values() if o["id"] != "room"]
    assert any("Lamp" in o["category"] for o in placed)
    assert all(abs(heading_deg(o["transform"])) < 1e-6 for o in placed)  # canonical pose
    return placed


def move_rotate_delete_undo(page):
    """Drag an object across the floor, turn it, delete it and undo the deletion."""
    obj = [o for o in objects(page).values() if o["id"] != "room"][-1]
    page.evaluate("() => window.sceneSuggestTest.loaded()")
    grab = hook(page, f"grabPixel({obj['id']!r})")
    assert grab, f"no visible pixel of {obj['category']} to grab"
    x0, y0 = grab
    x1, y1 = floor_pixel(page, 0.0, 1.2)
    page.mouse.move(x0, y0)
    page.mouse.down()
    for k in range(1, 11):
        page.mouse.move(x0 + (x1 - x0) * k / 10, y0 + (y1 - y0) * k / 10)
    page.mouse.up()
    moved = objects(page)[obj["id"]]
    assert math.dist(moved["contact_point"], obj["contact_point"]) > 0.3
    before = heading_deg(moved["transform"])
    page.keyboard.press("e")
    turned = objects(page)[obj["id"]]
    assert abs(((heading_deg(turned["transform"]) - before + 180) % 360) - 180) == pytest.approx(15, abs=0.01)
    # the ring: grab it at the front (0°) and drag it a quarter turn round the object
    start_deg = heading_deg(turned["transform"])
    path = [hook(page, f"ringPixel({a})") for a in range(0, 91, 10)]
    page.mouse.move(*path[0])
    page.mouse.down()
    for px in path[1:]:
        page.mouse.move(*px)
    page.mouse.up()
    ringed = objects(page)[obj["id"]]
    assert abs(((heading_deg(ringed["transform"]) - start_deg + 180) % 360) - 180) == pytest.approx(90, abs=3)
    assert hook(page, "events.at(-1).type") == "rotate_end"
    page.keyboard.press("Delete")
    assert obj["id"] not in objects(page)
    page.keyboard.press("Control+z")
    assert obj["id"] in objects(page)
    page.evaluate("() => window.sceneSuggestTest.loaded()")
    grab = hook(page, f"grabPixel({obj['id']!r})")
    assert grab, (obj, hook(page, f"pickAt(...window.sceneSuggestTest.centrePixel({obj['id']!r}))"))
    x, y = grab
    page.mouse.click(x, y)  # a click on an object selects it …
    assert hook(page, "events.at(-1).payload") == {"object": obj["id"]}
    x, y = floor_pixel(page, 1.5, -1.5)
    page.mouse.click(x, y)  # … and one on empty floor deselects
    assert hook(page, "events.at(-1).type") == "select" and hook(page, "events.at(-1).payload.object") is None


def test_a_whole_participant_run(page, server):
    base, database = server
    pid = "browser-run"
    start(page, base, pid)
    seen = set()
    conditions = []
    briefed = False
    while True:
        cond = hook(page, "condition")
        trial = hook(page, "trial")
        conditions.append(cond)
        shoot = cond not in seen and trial >= 0
        if cond == "none":
            assert page.locator(".side-panel .tile").count() == 118
            run_none_trial(page)
            if shoot:
                screenshot(page, f"condition-{cond}")
            move_rotate_delete_undo(page)
        else:
            response, placed = place_with_suggestions(page, mode_toggle=(trial % 2 == 1))
            if cond == "full":  # oriented as the engine said
                engine_heading = response["suggestions"][0]["heading_deg"] % 360
                assert heading_deg(placed["transform"]) == pytest.approx(engine_heading, abs=0.01)
            else:  # canonical pose
                assert heading_deg(placed["transform"]) == pytest.approx(0, abs=1e-6)
            if shoot:
                screenshot(page, f"condition-{cond}")
            # another suggestion replaces it in place
            second = response["suggestions"][1]
            page.click(f".suggestions .tile[data-rank='2'][data-category='{second['category']}']")
            replaced = [o for o in objects(page).values() if o["id"] not in ("room", placed["id"])]
            assert placed["id"] not in objects(page) and replaced[-1]["category"] == second["category"]
            assert math.dist(replaced[-1]["contact_point"], placed["contact_point"]) < 1e-9
            if cond not in seen:
                page.click(".suggestions button.close")
                move_rotate_delete_undo(page)
        if shoot:
            seen.add(cond)
        done(page)
        if "Almost done" in page.content():
            break
        if page.evaluate("() => document.body.dataset.step") == "briefing" and not briefed:
            assert "you add objects in a different way" in page.inner_text("main")
            screenshot(page, "briefing")
            briefed = True
        ready(page)
    assert sorted(conditions[1:]) == sorted(["none", "basic", "full"] * 3) and conditions[0] == "full"
    page.fill("textarea[name=comments]", "The suggestions were handy.")
    assert exit_survey(page, "4", "Suggestions, oriented") == "DEMO-DONE-7F3A"
    events = db_events(database, pid)
    seqs = [s for s, _ in events]
    assert seqs == list(range(len(seqs)))  # every event stored once, none missing
    replays = db_replays(database, pid)  # each trial's events rebuild the scene it submitted
    assert len(replays) == 10 and set(replays.values()) == {"match"}, replays
    kinds = [t for _, t in events]  # the condition explained before the practice and each block, then the trial
    assert kinds.count("briefing") == 4 and all(kinds[i + 1] == "trial_start" for i, t in enumerate(kinds)
                                                if t == "briefing")
    types = set(kinds)
    assert {"trial_start", "trial_done", "context_query", "list_shown", "insert", "replace", "move_start", "move_end",
            "rotate_start", "rotate_end", "delete", "undo", "search", "select", "pointer"} <= types
    assert not page.console_problems, page.console_problems
    record_what_the_page_sent(db_batches(database, pid), len(events))


def record_what_the_page_sent(batches: list[list[float]], n_events: int) -> None:
    """What a real page sent in this run (at a test's speed, not a person's): batch sizes and events per minute,
    written to test-artifacts/browser-batches.json beside the outbox's limit it must keep."""
    import json

    from crowd import percentile

    sizes = sorted(len(b) for b in batches)
    minutes = (max(map(max, batches)) - min(map(min, batches))) / 60000
    assert len(batches) < n_events  # the outbox batches
    assert sizes[-1] <= 200  # the outbox's MAX_BATCH
    ARTIFACTS.mkdir(exist_ok=True)
    (ARTIFACTS / "browser-batches.json").write_text(json.dumps({
        "events": n_events, "batches": len(batches), "minutes": round(minutes, 2),
        "events_per_min": round(n_events / minutes, 1), "batches_per_min": round(len(batches) / minutes, 1),
        "batch_size": {"median": percentile(sizes, 50), "p95": percentile(sizes, 95), "max": sizes[-1]},
        "batch_span_ms": {"max": round(max(max(b) - min(b) for b in batches))}}, indent=1))


def test_a_moving_view_may_drop_resolution_and_is_sharp_again_when_still(page, server):
    base, _ = server
    start(page, base, "browser-resolution")
    until(page, "window.sceneSuggestTest.resolution().scale === 1", timeout=10.0)  # the first frames have settled
    sharp = hook(page, "resolution()")
    assert sharp["buffer"] == sharp["css"] and sharp["scale"] == 1
    page.evaluate("() => window.sceneSuggestTest.setSlowFrameMs(0)")  # every moving frame counts as slow
    result = page.evaluate("() => window.sceneSuggestTest.orbit(600)")
    assert result["scale"] == pytest.approx(0.7) and result["fps"] > 0
    # once the camera has been still for the settle time the view is drawn sharp again (waited for, not timed: a
    # loaded machine may draw its next frame late)
    until(page, "window.sceneSuggestTest.resolution().scale === 1", timeout=10.0)
    assert hook(page, "resolution()") == sharp
    x, y = floor_pixel(page)  # picking still maps pixels to the world at full resolution
    assert hook(page, f"pickAt({x}, {y})")["room"]


def test_a_model_that_fails_to_load_offers_a_retry(page, server):
    base, _ = server
    fail = {"on": True}

    def glb(route):
        if fail["on"] and "GarbageCan" in route.request.url:
            route.abort()
        else:
            route.continue_()
    page.route(re.compile(r".*\.glb$"), glb)
    start(page, base, "browser-retry")
    x, y = floor_pixel(page, 0.0, 0.0)
    page.click("#suggest-mode")
    response = suggest_at(page, x, y, shift=False)
    assert response["suggestions"][0]["category"] == "GarbageCan"  # the demo's top pick on this floor spot
    until(page, "!document.getElementById('banner').hidden")
    assert "did not load" in page.inner_text("#banner")
    screenshot(page, "model-retry")
    fail["on"] = False
    page.click("#banner button")
    until(page, "document.getElementById('banner').hidden")


def test_an_excluded_participants_page_says_the_session_has_ended(page, server):
    """The experimenter excludes a participant mid-trial: the page's next query and events get 410, it stops
    sending and says so, and its Continue leads to the calm end page."""
    base, database = server
    pid = "browser-excluded"
    start(page, base, pid)
    until(page, "window.sceneSuggestTest.pending() === 0")
    with sqlite3.connect(database) as conn:
        conn.execute("UPDATE participants SET status = 'excluded', excluded_reason = 'test' WHERE platform_id = ?",
                     (pid,))
    x, y = floor_pixel(page, -0.6, 0.4)
    page.keyboard.down("Shift")
    page.mouse.click(x, y)  # a query (410) and its events (410)
    page.keyboard.up("Shift")
    until(page, "document.getElementById('banner').textContent.includes('This session has ended')", timeout=30)
    page.click("#banner button")
    page.wait_for_selector("text=This session has ended")
    assert "Traceback" not in page.content()

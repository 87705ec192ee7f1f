"""The page's outbox in a real browser: every event the page logs reaches the server once, through a reload, a
spell offline, a server that cannot store, a second tab, seqs another sender took and a shared outbox that another
tab overwrites; and only a test's page loads the test hook that these tests read."""

from __future__ import annotations

import sqlite3
import time

from .pagehelp import (
    db_event_times,
    db_events,
    db_replays,
    done,
    floor_pixel,
    hook,
    new_context,
    objects,
    place_with_suggestions,
    ready,
    start,
    suggest_at,
    until,
)


def test_reload_in_the_middle_of_a_trial_resumes_without_loss(page, server):
    base, database = server
    pid = "browser-reload"
    start(page, base, pid)
    place_with_suggestions(page)
    before_objects = objects(page)
    logged = hook(page, "events.map(e => [e.seq, e.type])")
    page.reload()
    ready(page)
    assert objects(page).keys() == before_objects.keys()
    assert hook(page, "trial") == -1
    x, y = floor_pixel(page, 0.8, -0.5)
    suggest_at(page, x, y)
    logged += hook(page, "events.map(e => [e.seq, e.type])")
    until(page, "window.sceneSuggestTest.pending() === 0")
    stored = [list(e) for e in db_events(database, pid)]
    assert [s for s, _ in stored] == list(range(len(stored)))  # nothing lost, nothing twice
    assert all(e in stored for e in logged)  # everything the page logged, including what it sent while unloading
    assert {"resume", "visibility"} <= {t for _, t in stored}
    done(page)  # the scene kept across the reload is the one the events rebuild
    assert db_replays(database, pid) == {-1: "match"}


def test_offline_for_a_while_then_every_event_arrives_once(page, server):
    base, database = server
    pid = "browser-offline"
    start(page, base, pid)
    place_with_suggestions(page)
    until(page, "window.sceneSuggestTest.pending() === 0")
    page.context.set_offline(True)
    obj = [o for o in objects(page).values() if o["id"] != "room"][-1]
    x, y = hook(page, f"grabPixel({obj['id']!r})")
    page.mouse.click(x, y)  # select
    for _ in range(6):
        page.keyboard.press("q")
    page.keyboard.press("Control+z")
    time.sleep(2.5)
    assert hook(page, "pending()") > 0
    assert "Connection lost" in page.inner_text("#banner")
    page.context.set_offline(False)
    until(page, "window.sceneSuggestTest.pending() === 0", timeout=60)
    logged = sorted(tuple(e) for e in hook(page, "events.map(e => [e.seq, e.type])"))
    assert [tuple(e) for e in db_events(database, pid)] == logged
    assert not page.is_visible("#banner") or "Connection lost" not in page.inner_text("#banner")
    done(page)  # turns and an undo made offline rebuild the scene the page submits
    assert db_replays(database, pid) == {-1: "match"}


def test_while_the_server_cannot_store_the_outbox_keeps_every_event(page, server):
    """The server answers 503 (its database full or read-only) for a while: the page keeps the events and sends
    them once the server stores again."""
    base, database = server
    pid = "browser-503"
    start(page, base, pid)
    place_with_suggestions(page)
    until(page, "window.sceneSuggestTest.pending() === 0")
    refused = []

    def full(route):
        refused.append(route.request.url)
        route.fulfill(status=503, content_type="application/json", headers={"Retry-After": "5"},
                      body='{"error": "the study\'s database cannot store data right now", "field": null}')
    page.route("**/api/events", full)
    obj = [o for o in objects(page).values() if o["id"] != "room"][-1]
    x, y = hook(page, f"grabPixel({obj['id']!r})")
    page.mouse.click(x, y)
    for _ in range(4):
        page.keyboard.press("e")
    until(page, "window.sceneSuggestTest.pending() > 0")
    page.wait_for_timeout(3000)  # (a plain sleep would not let Playwright answer the routed requests)
    assert refused and hook(page, "pending()") > 0
    page.unroute("**/api/events", full)
    until(page, "window.sceneSuggestTest.pending() === 0", timeout=60)
    logged = sorted(tuple(e) for e in hook(page, "events.map(e => [e.seq, e.type])"))
    assert [tuple(e) for e in db_events(database, pid)] == logged


def test_a_second_tab_takes_over_and_nothing_is_numbered_twice(page, server):
    base, database = server
    pid = "browser-tabs"
    start(page, base, pid)
    place_with_suggestions(page)
    second = page.context.new_page()
    second.goto(f"{base}/study/demo/")
    ready(second)
    until(page, "document.body.classList.contains('inactive')")
    assert "another tab" in page.inner_text("#banner")
    placed = page.evaluate("() => window.sceneSuggestTest.objects().length")
    # an undo here would change a scene the other tab now keeps; a listener added after the editor's runs after it
    page.evaluate("() => { window.keyHandled = new Promise((done) => addEventListener('keydown', "
                  "() => setTimeout(done, 0), { once: true })); }")
    page.keyboard.press("Control+z")
    page.evaluate("() => window.keyHandled")  # the editor has had the key
    assert page.evaluate("() => window.sceneSuggestTest.objects().length") == placed
    x, y = second.evaluate("() => window.sceneSuggestTest.worldToPixel(0.8, 0, -0.5)")
    second.keyboard.down("Shift")
    second.mouse.click(x, y)
    second.keyboard.up("Shift")
    until(second, "window.sceneSuggestTest.objects().length === 3")  # the first tab's object came along
    until(second, "window.sceneSuggestTest.pending() === 0")
    seqs = [s for s, _ in db_events(database, pid)]
    assert seqs == list(range(len(seqs)))
    logged = [e[0] for e in hook(page, "events.map(e => [e.seq])")] + \
        [e[0] for e in second.evaluate("() => window.sceneSuggestTest.events.map(e => [e.seq])")]
    assert len(logged) == len(set(s for s in logged if s >= 0))


def test_only_a_page_that_asks_for_the_test_hook_loads_it(page, browser, server):
    """A participant's page neither loads the test hook nor keeps its events for it; a test's page does."""
    base, _ = server
    start(page, base, "browser-hook")
    scripts = "performance.getEntriesByType('resource').map(r => r.name).filter(n => n.endsWith('.js'))"
    assert any(n.endswith("/js/test-hook.js") for n in page.evaluate(f"() => {scripts}"))
    plain = new_context(browser, test_hook=False, storage_state=page.context.storage_state())
    try:
        participant = plain.new_page()
        requested = []
        participant.on("request", lambda r: requested.append(r.url))
        participant.goto(f"{base}/study/demo/")
        until(participant, "document.getElementById('hint').textContent !== ''")  # the condition is wired: after
        until(participant, "document.querySelector('#editor canvas')")           # the hook would have loaded
        assert participant.evaluate("() => typeof window.sceneSuggestTest") == "undefined"
        loaded = participant.evaluate(f"() => {scripts}")
        assert any(n.endswith("/js/trial.js") for n in loaded)
        assert not [u for u in requested + loaded if "test-hook" in u]
    finally:
        plain.close()


def test_events_whose_seqs_another_sender_took_are_renumbered_never_lost(page, server):
    """Someone (another browser with the token, a tab that numbered alike) stores other events under the seqs
    the page is about to use: the server answers 409, the page sends its events under the seqs it is given."""
    import requests

    base, database = server
    pid = "browser-conflict"
    start(page, base, pid)
    until(page, "window.sceneSuggestTest.pending() === 0")
    token = page.evaluate("() => JSON.parse(document.getElementById('boot').textContent).token")
    acked = len(db_event_times(database, pid)) - 1
    foreign = [{"seq": acked + 1 + i, "t": 1.0 + i, "type": "search", "trial": -1, "payload": {"text": f"x{i}"}}
               for i in range(4)]
    r = requests.post(f"{base}/api/events", json={"page_id": "elsewhere", "events": foreign},
                      headers={"Authorization": f"Bearer {token}"}, timeout=10)
    assert r.ok
    place_with_suggestions(page)  # the page numbers these from acked + 1: taken
    until(page, "window.sceneSuggestTest.pending() === 0", timeout=60)
    stored = db_event_times(database, pid)
    assert [s for s, _, _ in stored] == list(range(len(stored)))
    logged = hook(page, "events.map(e => e.type)")
    mine = [t for _, t, client_t in stored if client_t > 1000]  # the page's own events (real clock)
    assert sorted(mine) == sorted(logged) and len([t for t in stored if t[2] < 1000]) == 4
    with sqlite3.connect(database) as conn:
        assert conn.execute("SELECT COUNT(*) FROM session_log WHERE kind = 'event_conflict'").fetchone()[0] >= 1


def test_a_tab_that_overwrites_the_shared_outbox_cannot_erase_this_pages_events(page, server):
    """Two tabs read and write one localStorage entry: the other tab's write drops this page's pending events
    from it. The page still holds its own events in memory until the server acknowledges them."""
    base, database = server
    pid = "browser-overwrite"
    start(page, base, pid)
    until(page, "window.sceneSuggestTest.pending() === 0")
    page.route("**/api/events", lambda route: route.abort())  # nothing reaches the server for a while
    place_with_suggestions(page)
    assert hook(page, "pending()") > 0
    page.evaluate("""() => {
      const boot = JSON.parse(document.getElementById('boot').textContent);
      const key = `scenesuggest-outbox-${boot.study}-${boot.token.slice(-12)}`;
      const state = JSON.parse(localStorage.getItem(key));
      localStorage.setItem(key, JSON.stringify({ nextSeq: state.nextSeq, acked: state.acked, pending: [] }));
    }""")
    page.unroute("**/api/events")
    page.evaluate("() => window.dispatchEvent(new Event('online'))")
    until(page, "window.sceneSuggestTest.pending() === 0", timeout=60)
    stored = db_event_times(database, pid)
    assert [s for s, _, _ in stored] == list(range(len(stored)))
    assert sorted(t for _, t, _ in stored) == sorted(hook(page, "events.map(e => e.type)"))

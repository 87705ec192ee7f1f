"""Driving the trial page in the browser tests: waiting on it, asking its test hook (world points to pixels,
the objects, the events it logged), placing a suggestion, and reading what the server stored."""

from __future__ import annotations

import math
import sqlite3
import time
from pathlib import Path

from browsers import CHROMIUM, CHROMIUM_ARGS
from support import ROOT, lacking

ARTIFACTS = ROOT / "test-artifacts"
#: The flags every browser test launches Chromium with.
ARGS = CHROMIUM_ARGS


def require_browser():
    """Playwright and Chromium, or a skip naming what is missing (under CI=true: a failure)."""
    try:
        import playwright  # noqa: F401
    except ImportError:
        lacking("playwright is not installed (make setup installs it)")
    if not Path(CHROMIUM).exists():
        lacking("Chromium is not installed (apt-get install chromium)")


IGNORED_CONSOLE = ("GPU stall due to ReadPixels", "favicon", "dbus")
TEST_HOOK = "window.sceneSuggestTestHook = true"  # set before the page's scripts: trial.js then loads test-hook.js


def new_context(browser, test_hook: bool = True, **options):
    """A browser context whose pages load the trial page's test hook (``window.sceneSuggestTest``) unless
    ``test_hook`` is false, as a participant's page does not."""
    context = browser.new_context(**{"viewport": {"width": 1280, "height": 720}, **options})
    if test_hook:
        context.add_init_script(TEST_HOOK)
    return context


def until(page, expression: str, timeout: float = 20.0):
    """Poll a JS expression (the page's CSP forbids Playwright's eval-based waiting)."""
    from playwright.sync_api import Error

    end = time.time() + timeout
    while time.time() < end:
        try:
            value = page.evaluate(f"() => {expression}")
        except Error:  # the page is navigating
            value = None
        if value:
            return value
        time.sleep(0.05)
    raise AssertionError(f"timed out waiting for {expression}")


def hook(page, expression: str):
    return page.evaluate(f"() => window.sceneSuggestTest.{expression}")


def past_briefing(page) -> bool:
    """On the page of the next trial's condition's instructions (before the first trial and wherever the
    condition changes), start the trial; whether there was one."""
    step = until(page, "document.body && document.body.dataset.step")
    if step != "briefing":
        return False
    with page.expect_navigation():
        page.click("button[name=go][value=start]")
    return True


def ready(page):
    """The trial page ready for input (past the condition's instructions, when they come first)."""
    past_briefing(page)
    until(page, "!!(window.sceneSuggestTest && window.sceneSuggestTest.ready)")
    page.evaluate("() => window.sceneSuggestTest.loaded()")


def start(page, base: str, pid: str, study: str = "demo", query: str | None = None):
    """From the entry link (``?pid=…``, or ``query`` as a platform sends it) through consent, demographics and
    instructions to the first trial, ready."""
    page.goto(f"{base}/study/{study}/start?{query or f'pid={pid}'}")
    page.click("text=I agree to take part")
    page.fill("input[name=age]", "29")
    page.check("input[name=experience_3d][value='A few times']")
    page.check("input[name=pointing_device][value=Trackpad]")
    page.click("button:has-text('Continue')")
    while page.locator("button[name=go][value=next]").count():
        page.click("button[name=go][value=next]")
    ready(page)


def objects(page) -> dict:
    return {o["id"]: o for o in hook(page, "objects()")}


def floor_pixel(page, x=0.0, z=0.3):
    return hook(page, f"worldToPixel({x}, 0, {z})")


def heading_deg(transform, face="bottom"):
    """Yaw of the front (+Z column of the column-major matrix) about +Y, degrees in [0, 360)."""
    fx, fz = transform[8], transform[10]
    return math.degrees(math.atan2(fx, fz)) % 360


def suggest_at(page, x, y, shift=True):
    before = hook(page, "lastSuggest?.list_id") or None
    if shift:
        page.keyboard.down("Shift")
    page.mouse.click(x, y)
    if shift:
        page.keyboard.up("Shift")
    until(page, f"window.sceneSuggestTest.lastSuggest && window.sceneSuggestTest.lastSuggest.list_id !== {before!r}"
          .replace("None", "null"))
    page.evaluate("() => window.sceneSuggestTest.loaded()")
    return hook(page, "lastSuggest")


def done(page):
    page.click("#done-button")
    with page.expect_navigation(timeout=30000):
        page.click("#confirm-yes")


def exit_survey(page, likert: str, preference: str) -> str:
    """Answer every Likert item with ``likert``, choose ``preference``, submit; returns the completion code."""
    for q in ("enjoy_list", "competent_list", "enjoy_suggestions", "competent_suggestions"):
        page.check(f"input[name={q}][value='{likert}']")
    page.check(f"input[name=preference][value='{preference}']")
    page.click("button:has-text('Continue')")
    page.wait_for_selector(".code")
    return page.inner_text(".code")


def db_events(database: Path, pid: str) -> list[tuple[int, str]]:
    with sqlite3.connect(database) as conn:
        return conn.execute("SELECT e.seq, e.type FROM events e JOIN participants p ON p.id = e.participant_id "
                            "WHERE p.platform_id = ? ORDER BY e.seq", (pid,)).fetchall()


def db_batches(database: Path, pid: str) -> list[list[float]]:
    """The batches the page sent, as stored (the events of a batch share its page and arrival time): each as its
    events' client times (ms), in seq order."""
    batches: dict[tuple, list[float]] = {}
    with sqlite3.connect(database) as conn:
        for page_id, arrived, t in conn.execute(
                "SELECT e.page_id, e.server_t, e.client_t FROM events e JOIN participants p ON "
                "p.id = e.participant_id WHERE p.platform_id = ? ORDER BY e.seq", (pid,)):
            batches.setdefault((page_id, arrived), []).append(t)
    return list(batches.values())


def db_replays(database: Path, pid: str) -> dict[int, str]:
    """Trial index → whether its events rebuild the scene it submitted (``match``), for the trials done."""
    with sqlite3.connect(database) as conn:
        return dict(conn.execute('SELECT t."index", t.replay FROM trials t JOIN participants p ON '
                                 "p.id = t.participant_id WHERE p.platform_id = ? AND t.done_at IS NOT NULL", (pid,)))


def db_event_times(database: Path, pid: str) -> list[tuple[int, str, float]]:
    with sqlite3.connect(database) as conn:
        return conn.execute("SELECT e.seq, e.type, e.client_t FROM events e JOIN participants p ON "
                            "p.id = e.participant_id WHERE p.platform_id = ? ORDER BY e.seq", (pid,)).fetchall()


def screenshot(page, name: str):
    ARTIFACTS.mkdir(exist_ok=True)
    page.screenshot(path=str(ARTIFACTS / f"{name}.png"))


def place_with_suggestions(page, mode_toggle=False):
    """Ask for suggestions on the floor; the top one is placed at once on the clicked surface."""
    x, y = floor_pixel(page, -0.6, 0.4)
    if mode_toggle:
        page.click("#suggest-mode")
    response = suggest_at(page, x, y, shift=not mode_toggle)
    if mode_toggle:
        page.click("#suggest-mode")
    placed = [o for o in objects(page).values() if o["parent"] == response["hit"]["parent"] and o["id"] != "room"]
    top = response["suggestions"][0]
    newest = placed[-1]
    assert newest["category"] == top["category"] and newest["model_id"] == top["models"][0]["id"]
    assert page.inner_text("#hint") == ""  # the shift-click hint goes once suggestions were asked for
    assert newest["parent"] == "room" and newest["surface_type"] == "up_interior"
    assert math.dist(newest["contact_point"], response["hit"]["point"]) < 1e-6  # on the clicked point
    return response, newest


def walked_to_exit(base: str, pid: str, headers: dict | None = None):
    """A participant walked over HTTP (with ``headers`` on arrival: a browser's language) through every trial to
    the exit survey; the transport, whose cookies a browser takes to go on from there."""
    http, step = walked(base, pid, headers)
    assert step == "exit"
    return http


def walked(base: str, pid: str, headers: dict | None = None, trials: int | None = None):
    """A participant walked over HTTP (with ``headers`` on arrival) through its first ``trials`` trials (all when
    None) and on to the next page; (the transport, that page's step)."""
    from demostudy import play_empty_trial
    from flowhelp import DEMOGRAPHICS

    from simulation.transport import HttpTransport
    from simulation.walker import Walker

    http = HttpTransport(base)
    seq, played = 0, 0

    def trial(b: dict) -> bool:
        nonlocal seq, played
        seq = play_empty_trial(http, b, seq, "walk", 1.0e12, 12000)
        played += 1
        return trials is None or played < trials

    walker = Walker(http, "demo")
    page = walker.walk(lambda _: DEMOGRAPHICS, trial, until=("exit",), page=walker.enter({"pid": pid}, headers=headers))
    if trials is not None and played == trials:
        page = walker.current()
    return http, page.step

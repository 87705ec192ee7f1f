"""Panel benchmark: the `none` condition's model panel in headless Chromium (WebGL on SwiftShader) with a large
model library (a copy of the demo study whose library holds N models, :mod:`large_library`; default 100 and 1,580).

Each run is a new participant whose first trial (the practice, in `none`) opens at 1100×650 CSS pixels — the 3D
view then measures about 800×600, as in the client benchmark — with the client benchmark's 60 objects on the floor.
Measured in the page, per run:

- ``first_paint_ms``: from the moment the panel's list has been filled (a mutation observer's callback right after
  the script that filled it; the building itself is ``build_ms``) to the end of the next rendered frame (a message
  posted from that frame's animation-frame callback, which runs after the frame's style, layout and paint). The
  3D view's first frame is drawn in the same frame, and the end of the frame waits for the software renderer to
  hand over that frame's picture, so this varies with more than the panel.
- ``rendering_ms``: of that frame, the main thread's style, layout, pre-paint and paint of the page (from the
  start of style and layout to the end of the frame's rendering, as the browser's long-animation-frame entry for
  it reports them): the part of the first paint that the panel's size changes.
- ``build_ms``: how long the panel's script took to build the list's elements (the page's own
  ``model-list-build`` performance measure).
- ``fps``: frames per second while the camera orbits for ``--seconds`` with the panel open (the test hook's orbit,
  as participants get it: the view may drop resolution while it moves when frames are slow).
- ``scroll_paint_ms``: from jumping the list to its end to the end of the next rendered frame.
- ``rendered_tiles``: tiles whose contents the browser renders when the panel opens (the others are skipped).

Each is given as the median and range of ``--runs`` runs, for each library size and each variant: ``as_shipped``
(the page as it is) and ``all_tiles`` (the same page with every tile rendered, ``content-visibility: visible``, as
the panel did before it rendered only what is visible). Budgets: first paint ≤ 300 ms with 1,580 models, ≥ 30 fps.
Usage: .venv/bin/python benchmarks/bench_panel.py [--models 100 1580] [--runs 3] [--seconds 3]
"""

from __future__ import annotations

import argparse
import json
import statistics
import sys
import tempfile
import time
from pathlib import Path

import checkout
import tests_path  # noqa: F401 (tests/ on the path, for the shared test infrastructure)
from bench_client import scene_with
from browsers import CHROMIUM, CHROMIUM_ARGS
from demostudy import to_first_trial
from large_library import STUDY_ID, demo_resources, library_models, write_study
from serverproc import StudyServer, demo_missing

from simulation.transport import HttpTransport

ROOT = Path(__file__).resolve().parents[1]

VIEWPORT = {"width": 1100, "height": 650}
VARIANTS = {"as_shipped": "", "all_tiles": ".tile { content-visibility: visible !important; }"}

#: Runs before the page's scripts: records when the panel's list is filled and when the next frame has been drawn,
#: and adds the variant's style sheet (a constructed one: the page's policy refuses inline styles).
MEASURE = """
window.panelPaint = {};
new PerformanceObserver(() => {}).observe({ type: "long-animation-frame", buffered: true });
if (%(css)s) {
  const sheet = new CSSStyleSheet();
  sheet.replaceSync(%(css)s);
  document.adoptedStyleSheets = [sheet];
}
new MutationObserver((records, observer) => {
  const list = document.querySelector("#model-panel .tiles");
  if (!list || !list.children.length) return;
  observer.disconnect();
  panelPaint.filled = performance.now();
  requestAnimationFrame(() => {
    panelPaint.frame = performance.now();
    const channel = new MessageChannel();
    channel.port1.onmessage = () => { panelPaint.painted = performance.now(); };
    channel.port2.postMessage(null);
  });
}).observe(document, { childList: true, subtree: true });
"""

#: Jump the list to its end; resolves the milliseconds until the next frame has been drawn.
SCROLL = """() => new Promise((resolve) => {
  const list = document.querySelector("#model-panel .tiles");
  const t0 = performance.now();
  list.scrollTop = list.scrollHeight;
  requestAnimationFrame(() => {
    const channel = new MessageChannel();
    channel.port1.onmessage = () => resolve(performance.now() - t0);
    channel.port2.postMessage(null);
  });
})"""

#: The style, layout, pre-paint and paint (ms) of the frame after the panel was filled: its long-animation-frame
#: entry, which every first frame has (the 3D view's first frame alone takes longer than the entries' 50 ms).
RENDERING = """() => { const at = window.panelPaint.frame;
  const e = performance.getEntriesByType("long-animation-frame").find((f) => f.startTime <= at
    && at <= f.startTime + f.duration);
  return e ? e.startTime + e.duration - e.styleAndLayoutStart : null; }"""

#: Tiles whose contents are rendered (not skipped by content-visibility), and all tiles.
RENDERED = """() => { const tiles = [...document.querySelectorAll("#model-panel .tile")];
  return [tiles.filter((t) => t.lastChild.checkVisibility({ contentVisibilityAuto: true })).length, tiles.length]; }"""


def wait_for(page, expression: str, timeout_s: float = 30.0):
    deadline = time.monotonic() + timeout_s
    while time.monotonic() < deadline:
        value = page.evaluate(f"() => {expression}")
        if value:
            return value
        time.sleep(0.05)
    raise RuntimeError(f"timed out waiting for {expression}")


def one_run(browser, base: str, pid: str, scene: dict, css: str, seconds: float) -> dict:
    """A new participant's first trial in a new browser context; what it measured (see the module's docstring)."""
    http = HttpTransport(base)
    boot = to_first_trial(http, pid, STUDY_ID).boot
    assert boot["trial"]["condition"] == "none", boot["trial"]
    key = f"scenesuggest-scene-{boot['study']}-{boot['token'][-12:]}-{boot['trial']['index']}"
    context = browser.new_context(viewport=VIEWPORT)
    try:
        context.add_cookies(http.cookies())
        context.add_init_script(f"localStorage.setItem({json.dumps(key)}, {json.dumps(json.dumps(scene))}); "
                                "window.sceneSuggestTestHook = true;" + MEASURE % {"css": json.dumps(css)})
        page = context.new_page()
        page.goto(f"{base}/study/{STUDY_ID}/")
        paint = wait_for(page, "window.panelPaint && window.panelPaint.painted && window.panelPaint")
        build = page.evaluate("() => performance.getEntriesByName('model-list-build')[0]?.duration ?? null")
        rendering = page.evaluate(RENDERING)
        wait_for(page, "!!(window.sceneSuggestTest && window.sceneSuggestTest.ready)")
        page.evaluate("() => window.sceneSuggestTest.loaded()")
        rendered, tiles = page.evaluate(RENDERED)
        canvas = page.evaluate("() => window.sceneSuggestTest.resolution().css")
        time.sleep(0.5)
        orbit = page.evaluate(f"() => window.sceneSuggestTest.orbit({seconds * 1000})")
        time.sleep(0.3)
        scroll = page.evaluate(SCROLL)
    finally:
        context.close()
    return {"first_paint_ms": paint["painted"] - paint["filled"], "rendering_ms": rendering,
            "build_ms": build, "fps": orbit["fps"], "motion_scale": orbit["scale"], "scroll_paint_ms": scroll,
            "rendered_tiles": rendered, "tiles": tiles, "canvas": canvas}


def summary(values: list[float | None]) -> dict | None:
    """Median and range (min, max) of a measure over the runs that have it (``missing``: how many have not)."""
    have = [v for v in values if v is not None]
    if not have:
        return None
    out = {"median": round(statistics.median(have), 1), "min": round(min(have), 1), "max": round(max(have), 1)}
    return out if len(have) == len(values) else {**out, "missing": len(values) - len(have)}


def measure(browser, n: int, scene: dict, variants: list[str], runs: int, seconds: float) -> list[dict]:
    """Every variant ``runs`` times (in turn, so that drift of the machine affects them alike) on a library of
    ``n`` models."""
    with tempfile.TemporaryDirectory() as tmp:
        study = write_study(Path(tmp) / "study", n)
        with StudyServer(Path(tmp) / "instance", f"sqlite:///{tmp}/db.sqlite3", study=study) as server:
            got = {v: [] for v in variants}
            for r in range(runs):
                for v in variants:
                    got[v].append(one_run(browser, server.base, f"bench-panel-{n}-{v}-{r}", scene, VARIANTS[v],
                                          seconds))
    out = []
    for v, results in got.items():
        row = {"models": n, "variant": v, "tiles": results[0]["tiles"], "canvas": results[0]["canvas"]}
        for k in ("first_paint_ms", "rendering_ms", "build_ms", "fps", "scroll_paint_ms", "rendered_tiles"):
            row[k] = summary([x[k] for x in results])
        row["motion_scale"] = min(x["motion_scale"] for x in results)
        out.append(row)
    return out


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--models", type=int, nargs="+", default=[100, 1580])
    parser.add_argument("--runs", type=int, default=3)
    parser.add_argument("--seconds", type=float, default=3.0, help="how long the camera orbits in each run")
    parser.add_argument("--objects", type=int, default=60, help="objects on the floor of the trial's scene")
    parser.add_argument("--variants", nargs="+", choices=list(VARIANTS), default=list(VARIANTS))
    args = parser.parse_args()
    checkout.require(ROOT)
    if not Path(CHROMIUM).exists() or demo_missing():
        print(json.dumps({"benchmark": "panel", "error": demo_missing() or "needs Chromium (apt)"}))
        return 1
    from playwright.sync_api import sync_playwright

    # the same scene for every library size: models of the smallest library are in every larger one
    shared = [m.to_dict() for m in library_models(demo_resources()[1], min(args.models))]
    scene = scene_with(shared, args.objects)
    rows = []
    with sync_playwright() as p:
        browser = p.chromium.launch(executable_path=CHROMIUM, args=CHROMIUM_ARGS)
        try:
            for n in args.models:
                rows.extend(measure(browser, n, scene, args.variants, args.runs, args.seconds))
        finally:
            browser.close()
    head = json.dumps({"benchmark": "panel", "viewport": f"{VIEWPORT['width']}x{VIEWPORT['height']}",
                       "objects": args.objects, "runs": args.runs, "orbit_seconds": args.seconds,
                       "renderer": "SwiftShader (software WebGL)"}, indent=1)
    # one line per library size and variant
    print(head[:-2] + ',\n "results": [\n  ' + ",\n  ".join(json.dumps(r) for r in rows) + "\n ]\n}")
    return 0


if __name__ == "__main__":
    sys.exit(main())

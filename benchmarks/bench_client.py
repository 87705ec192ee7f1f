"""Client benchmark: the trial page with 60 objects, at 800×600 and at 1920×1080, in each browser engine a crowd
uses — Chromium (headless, WebGL on SwiftShader), Firefox ESR and WebKitGTK (Safari's engine; both on Xvfb, WebGL
on Mesa's llvmpipe) — each run in a fresh profile, driven as the browser tests drive them (``browsers.py``).

Measures the frame rate while the camera orbits (one step per animation frame, through the page's own orbit
controls) — ``fps`` as participants get it (the view drops to ``motion_scale`` of its resolution while the camera
moves if frames come slower than 30 ms, sharp again when it stops) and ``fps_sharp`` with that adaptation off —,
the time from navigation to the first rendered frame, and the bytes transferred for the trial page (HTML, JS, CSS,
models, thumbnails). Each engine is measured ``--runs`` times, the engines taking turns within a run so that the
machine's noise falls on each alike; it prints each figure's median and range per engine, and the other engines'
medians as a ratio of Chromium's. With software WebGL these are figures of this machine, to compare engines by —
not a promise for a participant's GPU. Budgets on a 2-core machine, in every engine: ≥ 30 fps, first frame ≤ 2 s on
localhost, ≤ 5 MB for the demo trial page.
Usage: .venv/bin/python benchmarks/bench_client.py [--objects 60] [--seconds 5] [--runs 3]
       [--engines chromium,firefox,webkit]
"""

from __future__ import annotations

import argparse
import itertools
import json
import math
import statistics
import sys
import tempfile
from pathlib import Path

import checkout
import tests_path  # noqa: F401 (tests/ on the path, for the shared test infrastructure)
from browsers import DRIVERS, ENGINES, Display, Driver, missing
from demostudy import to_first_trial
from serverproc import StudyServer, demo_missing

from simulation.transport import HttpTransport

ROOT = Path(__file__).resolve().parents[1]
#: The page's sizes in CSS pixels: the budgets' 800×600, and a full-HD screen, where software WebGL falls below
#: the display's refresh rate (which caps every engine's frame rate at 800×600) and the engines' speeds show.
VIEWPORTS = {"800x600": (800, 600), "1920x1080": (1920, 1080)}


def scene_with(models: list[dict], n: int) -> dict:
    """A 5 m × 4 m room with ``n`` objects standing on its floor in a grid, each a different model."""
    objects = [{"id": "room", "model_id": "ai2thor:Room", "category": "Room", "size": [1, 1, 1],
                "transform": [5, 0, 0, 0, 0, 2.7, 0, 0, 0, 0, 4, 0, 0, 0, 0, 1], "parent": None, "surface_type": None,
                "attachment_face": None, "contact_point": None, "contact_normal": None}]
    usable = [m for m in models if m["category"] != "Room" and max(m["size"]) < 1.2]
    cols = math.ceil(math.sqrt(n))
    for i in range(n):
        m = usable[i % len(usable)]
        x, z = -2.2 + 4.4 * (i % cols) / max(cols - 1, 1), -1.7 + 3.4 * (i // cols) / max(cols - 1, 1)
        objects.append({"id": f"o{i}", "model_id": m["id"], "category": m["category"], "size": m["size"],
                        "transform": [1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, x, 0, z, 1], "parent": "room",
                        "surface_type": "up_interior", "attachment_face": "bottom", "contact_point": [x, 0, z],
                        "contact_normal": [0, 1, 0]})
    return {"format": "scenesuggest-scene", "version": 1, "id": "bench", "scene_type": "Room", "source": "bench",
            "objects": objects}


TRANSFERRED = """() => {
  const nav = performance.getEntriesByType('navigation')[0];
  // what a participant's page loads (the test hook is loaded for the measurement only)
  const res = performance.getEntriesByType('resource').filter(r => !r.name.endsWith('/test-hook.js'));
  const sum = (k) => res.reduce((s, r) => s + (r[k] || 0), 0);
  return {page: (nav.transferSize || nav.encodedBodySize), transfer: sum('transferSize'),
          body: sum('encodedBodySize'),
          models: res.filter(r => r.name.endsWith('.glb')).reduce((s, r) => s + r.encodedBodySize, 0),
          js: res.filter(r => r.name.endsWith('.js')).reduce((s, r) => s + r.encodedBodySize, 0),
          count: res.length};
}"""


RENDERER = """(() => {
  const gl = document.createElement('canvas').getContext('webgl2');
  const info = gl && gl.getExtension('WEBGL_debug_renderer_info');
  return gl ? String(gl.getParameter(info ? info.UNMASKED_RENDERER_WEBGL : gl.RENDERER)).slice(0, 120) : null;
})()"""


def parse_args() -> argparse.Namespace:
    """The command line: objects in the room, the length of each orbit (s), runs, engines."""
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--objects", type=int, default=60)
    parser.add_argument("--seconds", type=float, default=5.0)
    parser.add_argument("--runs", type=int, default=3)
    parser.add_argument("--engines", default=",".join(ENGINES),
                        help="comma-separated, of " + ", ".join(ENGINES) + " (default: all)")
    args = parser.parse_args()
    args.engines = list(dict.fromkeys(e.strip() for e in args.engines.split(",") if e.strip()))
    unknown = [e for e in args.engines if e not in ENGINES]
    if unknown:
        parser.error(f"--engines: no engine {', '.join(unknown)} (there are {', '.join(ENGINES)})")
    if not args.engines:
        parser.error("--engines: name at least one engine")
    if args.runs < 1 or args.objects < 1 or not (math.isfinite(args.seconds) and 0 < args.seconds <= 300):
        parser.error("--runs and --objects must be ≥ 1, --seconds more than 0 and at most 300")
    return args


def walk_to_trial(base: str, objects: int, who: str) -> tuple[HttpTransport, str, str]:
    """Participant ``who``'s walk to the first trial over HTTP: its transport, the page's scene key, the scene
    (``objects`` on the floor) as JSON."""
    http = HttpTransport(base)
    boot = to_first_trial(http, who).boot
    models = http.get("/api/models", headers={"Authorization": f"Bearer {boot['token']}"}).json()["models"]
    key = f"scenesuggest-scene-{boot['study']}-{boot['token'][-12:]}-{boot['trial']['index']}"
    return http, key, json.dumps(scene_with(models, objects))


def open_trial(driver: Driver, http: HttpTransport, base: str, key: str, scene: str) -> None:
    """The trial page in ``driver``'s fresh profile as the participant ``http`` walked there, resumed from
    ``scene`` (put in the origin's localStorage first), with the test hook asked for; waits until it is ready."""
    driver.goto(f"{base}/healthz")  # the study's origin, for its cookies and storage
    driver.add_cookies(base, http.cookies())
    driver.evaluate(f"(localStorage.setItem({json.dumps(key)}, {json.dumps(scene)}), "
                    "sessionStorage.setItem('sceneSuggestTestHook', '1'), true)")
    driver.goto(f"{base}/study/demo/")
    driver.until("!!(window.sceneSuggestTest && window.sceneSuggestTest.ready)", timeout=60)


def measure(driver: Driver, seconds: float) -> dict:
    """The page's first frame (ms), objects, orbits of ``seconds`` s sharp and adaptive, draws, bytes loaded and
    the WebGL renderer."""
    hook = "window.sceneSuggestTest"
    driver.evaluate(f"{hook}.loaded().then(() => true)")
    measured = {"first_frame": driver.evaluate(f"{hook}.firstFrameAt()"),
                "count": driver.evaluate(f"{hook}.objects().length") - 1}
    driver.evaluate("new Promise((r) => setTimeout(r, 500))")
    measured["sharp"] = driver.evaluate(f"{hook}.orbit({seconds * 1000}, {{adaptive: false}})")
    driver.evaluate("new Promise((r) => setTimeout(r, 500))")
    measured["orbit"] = driver.evaluate(f"{hook}.orbit({seconds * 1000})")
    measured["drawn"] = driver.evaluate(f"{hook}.renderInfo()")
    measured["transferred"] = driver.evaluate(f"({TRANSFERRED.strip()})()")
    measured["renderer"] = driver.evaluate(RENDERER)
    measured["viewport"] = driver.evaluate("`${innerWidth}x${innerHeight}@${devicePixelRatio}`")
    return measured


def figures(measured: dict) -> dict:
    """One run's figures: frame rates (fps), first frame (ms), sizes (MB) and requests."""
    orbit, sharp, drawn, transferred = (measured[k] for k in ("orbit", "sharp", "drawn", "transferred"))
    total = transferred["page"] + max(transferred["transfer"], transferred["body"])
    return {"viewport": measured["viewport"], "objects": measured["count"], "fps": round(orbit["fps"], 1),
            "motion_scale": orbit["scale"],
            "fps_sharp": round(sharp["fps"], 1), "draw_calls": drawn["calls"], "triangles": drawn["triangles"],
            "first_frame_ms": round(measured["first_frame"], 1), "page_mb": round(total / 2**20, 3),
            "js_mb": round(transferred["js"] / 2**20, 3), "models_mb": round(transferred["models"] / 2**20, 3),
            "requests": transferred["count"] + 1, "renderer": measured["renderer"]}


SPREAD = ("fps", "fps_sharp", "first_frame_ms", "page_mb")


def summary(runs: dict[str, list[dict]], versions: dict[str, str]) -> dict:
    """Of one viewport, per engine: each figure of :data:`SPREAD` as median and [min, max] over the runs, the
    others from the last run; and each engine's medians as a ratio of Chromium's (when Chromium ran)."""
    engines = {}
    for engine, figs in runs.items():
        out = {"version": versions[engine], **{k: v for k, v in figs[-1].items() if k not in SPREAD}}
        for k in SPREAD:
            values = [f[k] for f in figs]
            out[k] = {"median": round(statistics.median(values), 3), "range": [min(values), max(values)]}
        engines[engine] = out
    ratios = {} if "chromium" in engines else {"note": "no ratios: Chromium, the baseline, was not measured"}
    if "chromium" in engines:
        base = engines["chromium"]
        for engine, out in engines.items():
            if engine != "chromium":
                ratios[f"{engine}/chromium"] = {k: round(out[k]["median"] / base[k]["median"], 3) for k in SPREAD
                                               if base[k]["median"]}
    return {"engines": engines, "ratios": ratios}


def main() -> int:
    args = parse_args()
    checkout.require(ROOT)
    absent = {e: missing(e) for e in args.engines if missing(e)}
    if absent or demo_missing():
        print(json.dumps({"benchmark": "client", "error": demo_missing() or absent}))
        return 1
    runs = {size: {e: [] for e in args.engines} for size in VIEWPORTS}
    versions: dict[str, str] = {}
    display = Display() if set(args.engines) - {"chromium"} else None  # Firefox and WebKit draw on Xvfb
    try:
        with tempfile.TemporaryDirectory() as tmp, \
                StudyServer(Path(tmp) / "instance", f"sqlite:///{tmp}/db.sqlite3") as server:
            for run, (size, viewport), engine in itertools.product(range(args.runs), VIEWPORTS.items(),
                                                                  args.engines):
                # each participant walks to the first trial over HTTP; the browser carries on with its cookies
                http, key, scene = walk_to_trial(server.base, args.objects, f"bench-{engine}-{size}-{run}")
                driver = DRIVERS[engine](display, viewport=viewport)
                try:
                    versions[engine] = driver.version
                    open_trial(driver, http, server.base, key, scene)
                    measured = figures(measure(driver, args.seconds))
                finally:
                    driver.close()
                if measured["objects"] != args.objects or not measured["viewport"].startswith(f"{size}@"):
                    print(json.dumps({"benchmark": "client", "error": f"{engine} drew {measured['objects']} "
                                      f"objects at {measured['viewport']}, not {args.objects} at {size}"}))
                    return 1
                runs[size][engine].append(measured)
                print(f"run {run + 1}/{args.runs} {size} {engine}: {json.dumps(runs[size][engine][-1])}",
                      file=sys.stderr)
    finally:
        if display:
            display.close()
    print(json.dumps({"benchmark": "client", "runs": args.runs,
                      "viewports": {size: summary(r, versions) for size, r in runs.items()}}, indent=1))
    return 0


if __name__ == "__main__":
    sys.exit(main())

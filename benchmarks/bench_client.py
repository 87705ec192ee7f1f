"""Client benchmark: the trial page in headless Chromium (WebGL on SwiftShader) at 800×600 with 60 objects.

Measures the frame rate while the camera orbits (one step per animation frame, through the page's own orbit
controls) — ``fps`` as participants get it (the view drops to ``motion_scale`` of its resolution while the camera
moves if frames come slower than 30 ms, sharp again when it stops) and ``fps_sharp`` with that adaptation off —,
the time from navigation to the first rendered frame, and
the bytes transferred for the trial page (HTML, JS, CSS, models, thumbnails). Budgets on a 2-core machine:
≥ 30 fps, first frame ≤ 2 s on localhost, ≤ 5 MB for the demo trial page.
Usage: .venv/bin/python benchmarks/bench_client.py [--objects 60] [--seconds 5]
"""

from __future__ import annotations

import argparse
import json
import math
import shutil
import sys
import tempfile
import time
from pathlib import Path

import checkout
from demostudy import to_first_trial
from serverproc import StudyServer, demo_missing

from simulation.transport import HttpTransport

ROOT = Path(__file__).resolve().parents[1]

ARGS = ["--headless", "--no-sandbox", "--disable-gpu", "--disable-quic", "--no-first-run",
        "--disable-background-networking", "--disable-component-update", "--disable-sync",
        "--enable-unsafe-swiftshader", "--use-angle=swiftshader"]


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


def parse_args() -> argparse.Namespace:
    """The command line: objects in the room and the length of each orbit (s)."""
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--objects", type=int, default=60)
    parser.add_argument("--seconds", type=float, default=5.0)
    return parser.parse_args()


def walk_to_trial(base: str, objects: int) -> tuple[HttpTransport, str, str]:
    """The participant's walk to the first trial over HTTP: its transport, the page's scene key, the scene as JSON."""
    http = HttpTransport(base)
    boot = to_first_trial(http, "bench-client").boot
    models = http.get("/api/models", headers={"Authorization": f"Bearer {boot['token']}"}).json()["models"]
    key = f"scenesuggest-scene-{boot['study']}-{boot['token'][-12:]}-{boot['trial']['index']}"
    return http, key, json.dumps(scene_with(models, objects))


def open_trial(browser, http: HttpTransport, base: str, key: str, scene: str):
    """The trial page at 800×600 with the participant's cookies, resumed from ``scene``, its hook ready (≤ 20 s)."""
    fresh = browser.new_context(viewport={"width": 800, "height": 600})
    fresh.add_cookies(http.cookies())
    # the scene the page resumes from, and the test hook (loaded only when asked for)
    fresh.add_init_script(f"localStorage.setItem({json.dumps(key)}, {json.dumps(scene)}); "
                          "window.sceneSuggestTestHook = true")
    page = fresh.new_page()
    page.goto(f"{base}/study/demo/")
    for _ in range(400):
        if page.evaluate("() => !!(window.sceneSuggestTest && window.sceneSuggestTest.ready)"):
            break
        time.sleep(0.05)
    return page


def measure(page, seconds: float) -> dict:
    """The page's first frame (ms), objects, orbits of ``seconds`` s sharp and adaptive, draws and bytes loaded."""
    page.evaluate("() => window.sceneSuggestTest.loaded()")
    first_frame = page.evaluate("() => window.sceneSuggestTest.firstFrameAt()")
    count = len(page.evaluate("() => window.sceneSuggestTest.objects()")) - 1
    time.sleep(0.5)
    sharp = page.evaluate(f"() => window.sceneSuggestTest.orbit({seconds * 1000}, {{adaptive: false}})")
    time.sleep(0.5)
    orbit = page.evaluate(f"() => window.sceneSuggestTest.orbit({seconds * 1000})")
    drawn = page.evaluate("() => window.sceneSuggestTest.renderInfo()")
    return {"first_frame": first_frame, "count": count, "sharp": sharp, "orbit": orbit, "drawn": drawn,
            "transferred": page.evaluate(TRANSFERRED)}


def report(measured: dict) -> dict:
    """The printed result: frame rates (fps), first frame (ms), sizes (MB) and requests."""
    orbit, sharp, drawn, transferred = (measured[k] for k in ("orbit", "sharp", "drawn", "transferred"))
    total = transferred["page"] + max(transferred["transfer"], transferred["body"])
    return {
        "benchmark": "client",
        "viewport": "800x600",
        "objects": measured["count"],
        "fps": round(orbit["fps"], 1),
        "motion_scale": orbit["scale"],
        "fps_sharp": round(sharp["fps"], 1),
        "draw_calls": drawn["calls"],
        "triangles": drawn["triangles"],
        "first_frame_ms": round(measured["first_frame"], 1),
        "page_mb": round(total / 2**20, 3),
        "js_mb": round(transferred["js"] / 2**20, 3),
        "models_mb": round(transferred["models"] / 2**20, 3),
        "requests": transferred["count"] + 1,
        "renderer": "SwiftShader (software WebGL)",
    }


def main() -> int:
    args = parse_args()
    checkout.require(ROOT)
    chromium = shutil.which("chromium") or "/usr/bin/chromium"
    if not Path(chromium).exists() or demo_missing():
        print(json.dumps({"benchmark": "client", "error": demo_missing() or "needs Chromium (apt)"}))
        return 1
    from playwright.sync_api import sync_playwright

    with tempfile.TemporaryDirectory() as tmp, \
            StudyServer(Path(tmp) / "instance", f"sqlite:///{tmp}/db.sqlite3") as server:
        # the participant walks to the first trial over HTTP; the browser then carries on with its cookies
        http, key, scene = walk_to_trial(server.base, args.objects)
        with sync_playwright() as p:
            browser = p.chromium.launch(executable_path=chromium, args=ARGS)
            measured = measure(open_trial(browser, http, server.base, key, scene), args.seconds)
            browser.close()
    print(json.dumps(report(measured), indent=1))
    return 0


if __name__ == "__main__":
    sys.exit(main())

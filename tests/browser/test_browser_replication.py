"""The replication study and the admin's scene editor in a real browser: a person completes the SceneSuggest
replication, an experimenter authors a target scene, and oriented suggestions come turned as the target has
them."""

from __future__ import annotations

import json
import math
import re

import numpy as np
from PIL import Image

from .pagehelp import (
    done,
    exit_survey,
    floor_pixel,
    heading_deg,
    hook,
    objects,
    ready,
    screenshot,
    start,
    suggest_at,
    until,
)


def test_a_person_completes_the_replication(page, replication_server):
    """Consent, practice and nine trials of the replication with the paper's models: in each, one object placed
    (the top suggestion on a shift-click; a model from the list in `none`), then done; the survey; the code."""
    start(page, replication_server, "replication-run", study="scenesuggest-2015")
    conditions, scenes, shot = [], set(), set()
    while True:
        cond = hook(page, "condition")
        conditions.append(cond)
        target = page.evaluate("() => fetch('/api/scenes/' + JSON.parse(document.getElementById('boot').textContent)"
                               ".trial.scene + '?which=target', {headers: {Authorization: 'Bearer ' + JSON.parse("
                               "document.getElementById('boot').textContent).token}}).then(r => r.json())")
        scenes.add(target["id"])
        if cond == "none":
            assert page.locator(".side-panel .tile").count() == 100
            page.click(".side-panel .tile >> nth=0")
            x, y = floor_pixel(page, 0.5, 0.5)
            page.mouse.click(x, y)
            until(page, "window.sceneSuggestTest.objects().length === 2")
        else:
            x, y = floor_pixel(page, 0.5, 0.5)
            response = suggest_at(page, x, y)
            assert response["suggestions"] and len(objects(page)) == 2
            assert page.evaluate("""() => {  // the panel and its tiles fit on screen, long names and all
              const p = document.querySelector('.suggestions'), t = p.querySelector('.tiles');
              const r = p.getBoundingClientRect();
              return t.scrollWidth <= t.clientWidth + 1 && r.left >= 0 && r.right <= innerWidth
                && r.bottom <= innerHeight; }""")
            labels = page.locator(".suggestions .tile[data-category] > span").all_inner_texts()
            assert labels and not [t for t in labels if re.search(r"[a-z][A-Z]", t)]
        if cond not in shot and hook(page, "trial") >= 0:
            page.evaluate("() => window.sceneSuggestTest.loaded()")
            screenshot(page, f"replication-{cond}")
            shot.add(cond)
        done(page)
        if "Almost done" in page.content():
            break
        ready(page)
    assert conditions[0] == "full" and sorted(conditions[1:]) == sorted(["none", "basic", "full"] * 3)
    assert len(scenes) == 4  # the practice scene and the three scenes of this participant's period
    assert exit_survey(page, "3", "Suggestions") == "SS2015-DONE"
    assert not page.console_problems, page.console_problems


def test_an_experimenter_authors_a_target_scene(page, authoring_server):
    """Log in, open a target in the editor, add an object with a suggestion, move nothing else, save it, render
    its image: the scene file has the new object, the PNG shows the scene, and participants are served it."""
    base, folder = authoring_server
    page.goto(f"{base}/admin/login")
    page.fill("input[name=password]", "author-password")
    page.click("button[type=submit]")
    page.goto(f"{base}/admin/demo/preview")
    page.click("a[href='/admin/demo/author/bedside']")
    ready(page)
    assert "Editing target" in page.inner_text(".trial-title") and page.locator("#done-button").count() == 0
    before = objects(page)
    assert len(before) == 7  # the target itself is opened, not an empty room
    x, y = floor_pixel(page, 1.6, 0.6)
    response = suggest_at(page, x, y)
    added = [o for o in objects(page).values() if o["id"] not in before]
    assert len(added) == 1 and added[0]["category"] == response["suggestions"][0]["category"]
    page.click(".suggestions button.close")
    assert hook(page, "targetObjects()") == 6  # the inset shows the saved target, not the edits
    page.click("#save-button")
    until(page, "window.sceneSuggestTest.saved")
    until(page, "document.getElementById('banner').textContent.startsWith('Saved')")  # said after the hook hears it
    assert "Saved bedside.json (7 objects)" in page.inner_text("#banner")
    page.evaluate("document.getElementById('banner').dataset.state = ''; window.dispatchEvent(new Event('online'))")
    until(page, "document.getElementById('banner').dataset.state === 'saved'")  # the outbox reached the server
    assert "Saved bedside.json (7 objects)" in page.inner_text("#banner")  # and the save's line stays
    assert hook(page, "targetObjects()") == 7 and page.locator("#target canvas").count() == 1  # the inset shows it
    saved = json.loads((folder / "scenes" / "bedside.json").read_text())
    assert {o["id"] for o in saved["objects"]} == set(before) | {added[0]["id"]}
    assert saved["source"].startswith("authored")  # provenance kept
    page.click("#image-button")
    until(page, "window.sceneSuggestTest.imageSaved", timeout=60)
    image = Image.open(folder / "scenes" / "bedside.png").convert("RGB")
    assert image.size == (1280, 960)
    pixels = np.asarray(image).reshape(-1, 3)
    assert len(np.unique(pixels // 16, axis=0)) > 20  # a rendered scene, not a blank canvas
    screenshot(page, "authoring")
    assert not page.console_problems, page.console_problems
    with page.expect_navigation():  # and back to the preview of every scene and condition
        page.click("#back-to-admin")
    assert page.url == f"{base}/admin/demo/preview"


def _facing_error_deg(transform, target_xz) -> float:
    """Angle (degrees) between an object's front and the direction from it to a point, in the floor plane."""
    front = math.atan2(transform[8], transform[10])
    towards = math.atan2(target_xz[0] - transform[12], target_xz[1] - transform[14])
    return abs((math.degrees(front - towards) + 180) % 360 - 180)


def test_oriented_suggestions_face_the_table_and_back_onto_the_wall(page, replication_admin):
    """The replication's dining table and bedroom corner in the scene editor (the full condition): each dining chair
    and the dresser taken away and asked for again with a shift-click where it stood; the suggestion of its category
    comes turned the way the target has it — the chairs facing the table, the dresser's back to the wall."""
    base = replication_admin
    page.goto(f"{base}/admin/login")
    page.fill("input[name=password]", "author-password")
    page.click("button[type=submit]")
    for scene_id, category in (("dining-table", "SideChair"), ("bedroom-corner", "Dresser")):
        page.goto(f"{base}/admin/scenesuggest-2015/author/{scene_id}")
        ready(page)
        table = next((o for o in objects(page).values() if o["category"] == "DiningTable"), None)
        for k, o in enumerate([o for o in objects(page).values() if o["category"] == category]):
            page.evaluate("() => window.sceneSuggestTest.loaded()")
            grab = hook(page, f"grabPixel({o['id']!r})")
            if grab:
                page.mouse.click(*grab)
            else:  # hidden behind the table from this view
                hook(page, f"select({o['id']!r})")
            page.keyboard.press("Delete")
            assert o["id"] not in objects(page)
            x, y = floor_pixel(page, o["contact_point"][0], o["contact_point"][2])
            assert hook(page, f"pickAt({x}, {y}).objectId") == "room"  # the floor where it stood is in view
            before = set(objects(page))
            response = suggest_at(page, x, y)
            assert category in [s["category"] for s in response["suggestions"][:10]]
            page.click(f".suggestions .tile[data-category={category}]")
            until(page, f"window.sceneSuggestTest.objects().some(o => o.category === {category!r} && "
                        f"!{sorted(before)!r}.includes(o.id))")
            [placed] = [p for p in objects(page).values() if p["id"] not in before]
            assert placed["category"] == category
            transform = placed["transform"]
            if table is not None:  # a dining chair faces the table
                assert _facing_error_deg(transform, (table["transform"][12], table["transform"][14])) <= 30
            else:  # the dresser stands with its back to the back wall, facing into the room (+Z)
                assert abs((heading_deg(transform) + 180) % 360 - 180) <= 15
            assert abs(((heading_deg(transform) - heading_deg(o["transform"])) + 180) % 360 - 180) <= 15
            page.click(".suggestions button.close")
            page.evaluate("() => window.sceneSuggestTest.loaded()")
            screenshot(page, f"full-{scene_id}-{category.lower()}-{k}")
    assert not page.console_problems, page.console_problems

"""The admin's scene editor, server side: opening a target, saving it back, saving its image; every bad request
is a 4xx JSON error naming the field, and nothing is written unless the whole request is good."""

import base64
import io
import json

import pytest
from demostudy import copy_demo_study, make_app
from flowhelp import auth, boot, csrf, to_trials
from PIL import Image
from werkzeug.security import generate_password_hash

from scenesuggest.scenes import scene_json

PASSWORD = "correct horse battery staple"


@pytest.fixture
def study_copy(tmp_path, demo_resources):
    """The demo study in a temporary folder (its targets are written by these tests), resources pointing at var/."""
    return copy_demo_study(tmp_path).parent


@pytest.fixture
def admin(tmp_path, study_copy):
    app = make_app(tmp_path, studies=[study_copy / "study.toml"], ADMIN_PASSWORD_HASH=generate_password_hash(PASSWORD))
    c = app.test_client()
    c.post("/admin/login", data={"csrf_token": csrf(c.get("/admin/login")), "password": PASSWORD})
    page = c.get("/admin/demo/author/bedside")
    assert page.status_code == 200
    c.token = boot(page)["author"]["csrf"]
    c.app_ = app
    return c


def post(c, path, doc, token=None):
    return c.post(path, data=json.dumps(doc), content_type="application/json",
                  headers={"X-CSRF-Token": c.token if token is None else token})


def png(width=64, height=48) -> str:
    out = io.BytesIO()
    Image.new("RGB", (width, height), (200, 120, 40)).save(out, format="PNG")
    return "data:image/png;base64," + base64.b64encode(out.getvalue()).decode()


def test_author_page_opens_the_target_in_full_mode_with_save_buttons(admin):
    page = admin.get("/admin/demo/author/bedside")
    b = boot(page)
    assert b["preview"] and b["trial"]["condition"] == "full" and b["trial"]["scene"] == "bedside"
    assert b["author"]["file"] == "bedside.json" and b["author"]["frozen"] == 0
    assert b"save-button" in page.data and b"image-button" in page.data and b"done-button" not in page.data
    grid = admin.get("/admin/demo/preview")
    assert b"/admin/demo/author/bedside" in grid.data
    assert admin.get("/admin/demo/author/nowhere").status_code == 404


def test_save_writes_the_target_and_the_study_serves_it(admin, study_copy):
    target = study_copy / "scenes" / "bedside.json"
    doc = json.loads(target.read_text())
    lamp = next(o for o in doc["objects"] if o["category"] == "DeskLamp")
    doc["objects"] = [o for o in doc["objects"] if o is not lamp]
    r = post(admin, "/admin/demo/author/bedside", {"scene": doc})
    assert r.status_code == 200, r.json
    assert r.json["objects"] == len(doc["objects"]) - 1
    saved = scene_json.load(target)
    assert lamp["id"] not in saved.objects and saved.id == "bedside"
    served = admin.get("/api/scenes/bedside?which=target", headers=auth(boot(admin.get("/admin/demo/author/bedside"))))
    assert {o["id"] for o in served.json["objects"]} == {o["id"] for o in doc["objects"]}


@pytest.mark.parametrize("mutate, status, field", [
    (lambda d: d.update(objects="no"), 400, "scene.objects"),
    (lambda d: d["objects"][1].update(transform=[1, 2]), 400, "scene.transform"),
    (lambda d: d["objects"][1].update(model_id="ai2thor:Spaceship"), 400, "scene.objects[1].model_id"),
    (lambda d: d.update(objects=d["objects"][:1]), 400, "scene.objects"),
    (lambda d: d["objects"][1].update(parent="nowhere"), 400, "scene.parent"),
])
def test_bad_scenes_are_refused_and_nothing_is_written(admin, study_copy, mutate, status, field):
    target = study_copy / "scenes" / "bedside.json"
    before = target.read_bytes()
    doc = json.loads(before)
    mutate(doc)
    r = post(admin, "/admin/demo/author/bedside", {"scene": doc})
    assert r.status_code == status and r.json["field"] == field, r.json
    assert target.read_bytes() == before
    assert not [p for p in target.parent.iterdir() if p.name.startswith(".")]  # no temporary file left behind


def test_save_needs_login_csrf_and_a_scene(admin, study_copy):
    target = study_copy / "scenes" / "bedside.json"
    doc = json.loads(target.read_text())
    assert post(admin, "/admin/demo/author/bedside", {"scene": doc}, token="forged").status_code == 400
    assert post(admin, "/admin/demo/author/bedside", {"nothing": 1}).json["field"] == "scene"
    assert post(admin, "/admin/demo/author/nowhere", {"scene": doc}).status_code == 404
    anonymous = admin.app_.test_client()
    r = anonymous.post("/admin/demo/author/bedside", data=json.dumps({"scene": doc}), content_type="application/json")
    assert r.status_code == 302 and "/admin/login" in r.headers["Location"]


def test_targets_are_frozen_once_participants_have_started(admin, study_copy):
    participant = admin.app_.test_client()
    to_trials(participant, query="pid=p-frozen")
    target = study_copy / "scenes" / "bedside.json"
    r = post(admin, "/admin/demo/author/bedside", {"scene": json.loads(target.read_text())})
    assert r.status_code == 409 and "frozen" in r.json["error"]
    assert boot(admin.get("/admin/demo/author/bedside"))["author"]["frozen"] == 1


def test_image_is_saved_beside_the_target_and_served_to_the_admin(admin, study_copy):
    r = post(admin, "/admin/demo/author/bedside/image", {"png": png(64, 48)})
    assert r.status_code == 200 and (r.json["width"], r.json["height"]) == (64, 48)
    path = study_copy / "scenes" / "bedside.png"
    assert Image.open(path).size == (64, 48)
    got = admin.get("/admin/demo/author/bedside/image")
    assert got.status_code == 200 and got.mimetype == "image/png" and got.data == path.read_bytes()
    assert b"/admin/demo/author/bedside/image" in admin.get("/admin/demo/preview").data


@pytest.mark.parametrize("value, status", [
    ("data:image/jpeg;base64,AAAA", 400),
    ("data:image/png;base64,not base64!", 400),
    ("data:image/png;base64," + base64.b64encode(b"GIF89a not a png").decode(), 400),
    (12, 400),
])
def test_bad_images_are_refused(admin, study_copy, value, status):
    r = post(admin, "/admin/demo/author/bedside/image", {"png": value})
    assert r.status_code == status and r.json["field"] == "png"
    assert not (study_copy / "scenes" / "bedside.png").exists()
    assert admin.get("/admin/demo/author/bedside/image").status_code == 404


def test_a_study_that_ships_with_the_installed_package_is_read_only(tmp_path, demo_resources, monkeypatch):
    """Installed, the built-in demo lives in site-packages, which a reinstall overwrites: its targets are not saved."""
    from study_server.base import config

    app = make_app(tmp_path, ADMIN_PASSWORD_HASH=generate_password_hash(PASSWORD))
    c = app.test_client()
    c.post("/admin/login", data={"csrf_token": csrf(c.get("/admin/login")), "password": PASSWORD})
    c.token = boot(c.get("/admin/demo/author/bedside"))["author"]["csrf"]
    target = demo_resources.parent / "scenes" / "bedside.json"
    before = target.read_bytes()
    monkeypatch.setattr(config, "checkout", lambda: None)  # as when installed from the wheel
    r = post(c, "/admin/demo/author/bedside", {"scene": json.loads(before)})
    assert r.status_code == 409 and "installed package" in r.json["error"] and target.read_bytes() == before
    assert post(c, "/admin/demo/author/bedside/image", {"png": png()}).status_code == 409


def test_scenes_are_parsed_once_and_read_again_when_their_file_changes(admin, study_copy, monkeypatch):
    """The server keeps each scene file (a click needs its scene type; no disk read per request) and reads it again
    when it has changed, whichever process changed it; callers get copies."""
    import os
    from pathlib import Path

    rt = admin.app_.extensions["studies"]["demo"]
    target = study_copy / "scenes" / "bedside.json"
    rt.scene("bedside")
    reads, read_text = [], Path.read_text
    monkeypatch.setattr(Path, "read_text", lambda self, *a, **k: reads.append(self) or read_text(self, *a, **k))
    rt.scene("bedside"), rt.scene("bedside", "start"), rt.scene_type("bedside")
    assert target not in reads  # unchanged: not read again
    first = rt.scene("bedside")
    first["objects"].clear()  # a caller's copy
    assert rt.scene("bedside")["objects"] and rt.scene_type("bedside") == json.loads(target.read_text())["scene_type"]
    text = target.read_text()
    kind = json.loads(text)["scene_type"]
    changed = text.replace(f'"scene_type": "{kind}"', f'"scene_type": "{kind[::-1]}"')  # the same size
    assert changed != text and len(changed) == len(text)
    stat = target.stat()
    target.write_text(changed)
    os.utime(target, ns=(stat.st_atime_ns, stat.st_mtime_ns + 1))
    before = reads.count(target)
    assert rt.scene_type("bedside") == kind[::-1] and rt.scene("bedside")["scene_type"] == kind[::-1]
    assert reads.count(target) == before + 1  # changed: read once more
